//! Sub-texel sampling (`sampling::subtexel`): the light pool refined into the texels of the map at
//! its own resolution. Its density is chi-square tested against exact solid angles, its sample
//! inverts, the renders stay unbiased (`fine_radiance_with_coarse_densities_is_unbiased` in
//! `unbiased.rs`), and on a sun it lowers the error.

use super::*;
use crate::unbiased::box_downsample;

/// The built-in sky at 32² beside its 8² box-filtered copy: a sun a texel wide inside a coarse
/// texel of 4 x 4.
fn sky_pair() -> (CubeMap, CubeMap) {
    let fine = envis::envmap::sky::sky_cube(32, 15.0);
    let coarse = box_downsample(&fine, 4);
    (fine, coarse)
}

#[test]
fn sub_texels_need_a_whole_multiple() {
    assert_eq!(SubTexels::ratio_of(128, 32), Some(4));
    assert_eq!(SubTexels::ratio_of(128, 64), Some(2));
    for (fine, coarse) in [(128, 48), (32, 32), (16, 32), (8, 0)] {
        assert_eq!(
            SubTexels::ratio_of(fine, coarse),
            None,
            "{fine} over {coarse}"
        );
    }
}

/// The refined samples of the sun's face and of another, binned by fine texel: they follow
/// `pdf_area * factor * Jacobian`, and each sample's returned density is that.
#[test]
fn sub_texel_pdf_chi2() {
    let (fine, coarse) = sky_pair();
    let dist = CubeDistribution::build(&coarse);
    let sub = SubTexels::new(&fine, coarse.size).unwrap();
    let pdf = |d: Vec3| dist.face_pdf(d).1 * sub.factor(d);
    let energies = dist.energies();
    let sun_face = (0..6)
        .max_by(|&a, &b| energies[a].total_cmp(&energies[b]))
        .unwrap();
    let mut r = Rng::new(41, 0);
    for face in [sun_face, (sun_face + 2) % 6] {
        let domain = FacePlane { face, n: 32, q: 4 };
        Chi2Test::new(
            format!("sub_texel_pdf_chi2 face {face}"),
            domain,
            200_000,
            2,
        )
        .run(
            || {
                let s = dist.faces[face].sample(face, 0, rng_vec2(&mut r))?;
                let coarse_sample = PoolSample {
                    dir: s.dir,
                    radiance: Vec3::ZERO,
                    pdf: s.pdf,
                };
                let p = sub.refine(&dist, &coarse_sample);
                let want = pdf(p.dir);
                assert!((p.pdf - want).abs() <= 1e-3 * want, "{} vs {want}", p.pdf);
                assert_eq!(p.radiance, fine.lookup(p.dir));
                Some(p.dir)
            },
            |d| pdf(d) as f64,
        )
        .assert();
    }
}

/// `invert` undoes `sample` inside every coarse texel of a face, and each coarse texel's factors
/// average to 1 (its density is only redistributed among its fine texels).
#[test]
fn sub_texel_sample_inverts_and_keeps_each_texel_mass() {
    let (fine, coarse) = sky_pair();
    let sub = SubTexels::new(&fine, coarse.size).unwrap();
    let mut r = Rng::new(3, 1);
    for face in 0..6 {
        for (col, row) in (0..8).flat_map(|c| (0..8).map(move |w| (c, w))) {
            let (du, dv) = (r.next_f32(), r.next_f32());
            let (fc, fr, fu, fv) = sub.sample(face, col, row, du, dv);
            assert_eq!((fc / 4, fr / 4), (col, row));
            let (bu, bv) = sub.invert(face, fc, fr, fu, fv);
            assert!(
                (bu - du).abs() < 1e-4 && (bv - dv).abs() < 1e-4,
                "({du}, {dv}) -> ({bu}, {bv})"
            );
            let mean = (0..16)
                .map(|k| sub.factors()[fine.index(face, col * 4 + k % 4, row * 4 + k / 4)])
                .sum::<f32>()
                / 16.0;
            assert!(
                (mean - 1.0).abs() < 1e-5,
                "texel {face} ({col}, {row}): {mean}"
            );
        }
    }
}

/// On a sun inside one coarse texel the refined pool is what the level is for: at equal samples
/// a glossy sphere's error against the fine map's reference drops. Fails if the pool is not
/// refined or the BRDF samples' densities ignore the factor (then the MIS weights are wrong and
/// the test of unbiasedness fails instead).
#[test]
fn sub_texels_lower_the_error_on_a_sun() {
    let (fine, coarse) = sky_pair();
    let (size, seeds) = (16usize, 8u32);
    let mat = Material::ggx(0.8, 0.1);
    let gbuf = sphere_gbuffer(size, size, mat);
    let (_, reference) = reference_image(&fine, &gbuf, size, size, 1.0);
    let lookup = |d: Vec3| fine.lookup(d);
    let error = |sub: Option<&CubeMap>| {
        let extras = envis::render::Extras {
            fine: Some(&lookup),
            sub_texels: sub,
            ..Default::default()
        };
        (0..seeds)
            .map(|seed| {
                let s = Settings {
                    light_samples: 4,
                    brdf_samples: 4,
                    seed,
                    ..Default::default()
                };
                let out = envis::render::render_with(&coarse, extras, &gbuf, size, size, &s);
                let img = out.unwrap().image.data;
                let (mut e, mut n) = (0.0, 0.0);
                for (x, r) in img.iter().zip(&reference) {
                    let (x, r) = (luminance(*x) as f64, luminance_f64(*r));
                    if r > 0.0 {
                        (e, n) = (e + (x - r).powi(2) / (r * r + 1e-2), n + 1.0);
                    }
                }
                e / n
            })
            .sum::<f64>()
            / seeds as f64
    };
    let (uniform, refined) = (error(None), error(Some(&fine)));
    assert!(
        refined < 0.7 * uniform,
        "relMSE {refined:.4} with sub-texels, {uniform:.4} without"
    );
}

/// The same seed gives the same image with sub-texels, whatever the threads' schedule (the
/// pool's refinement and the factors are built in parallel).
#[test]
fn sub_texel_renders_are_deterministic() {
    let fine = envis::envmap::sky::sky_cube(128, 15.0);
    let coarse = box_downsample(&fine, 4);
    let size = 64;
    let gbuf = sphere_gbuffer(size, size, Material::ggx(0.8, 0.02));
    let lookup = |d: Vec3| fine.lookup(d);
    let extras = envis::render::Extras {
        fine: Some(&lookup),
        sub_texels: Some(&fine),
        ..Default::default()
    };
    let s = Settings {
        light_samples: 8,
        brdf_samples: 8,
        ..Default::default()
    };
    let render = || envis::render::render_with(&coarse, extras, &gbuf, size, size, &s).unwrap();
    let first = render().image.data;
    for run in 0..8 {
        let again = render().image.data;
        let differ: Vec<usize> = (0..first.len()).filter(|&i| first[i] != again[i]).collect();
        assert!(
            differ.is_empty(),
            "run {run}: {} pixels differ, e.g. {:?}: {:?} vs {:?}",
            differ.len(),
            differ.first(),
            differ.first().map(|&i| first[i]),
            differ.first().map(|&i| again[i])
        );
    }
}
