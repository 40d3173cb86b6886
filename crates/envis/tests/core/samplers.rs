//! Normalisation and goodness of fit of the BRDF samplers, Schlick's limits, degenerate maps and
//! the per-face sample counts.

use super::*;

/// Integral of a pdf over the sphere by midpoint quadrature on a fine (cos t, phi) grid.
fn integrate_sphere(pdf: impl Fn(Vec3) -> f32 + Sync) -> f64 {
    use rayon::prelude::*;
    let (nz, np) = (1024usize, 2048usize);
    (0..nz)
        .into_par_iter()
        .map(|i| {
            let z = -1.0 + 2.0 * (i as f64 + 0.5) / nz as f64;
            let s = (1.0 - z * z).sqrt();
            let mut acc = 0.0;
            for j in 0..np {
                let p = 2.0 * std::f64::consts::PI * (j as f64 + 0.5) / np as f64;
                acc += pdf(DVec3::new(s * p.cos(), s * p.sin(), z).as_vec3()) as f64;
            }
            acc * (2.0 / nz as f64) * (2.0 * std::f64::consts::PI / np as f64)
        })
        .sum()
}

#[test]
fn pdfs_integrate_to_one() {
    let map = smooth_cube(8);
    let dist = CubeDistribution::build(&map);
    let fw = face_weights(Vec3::new(0.2, 0.9, 0.1).normalize(), &dist.energies(), true);
    let mix = integrate_sphere(|d| {
        let (f, p) = dist.face_pdf(d);
        fw.mu[f] * p
    });
    assert!((mix - 1.0).abs() < 2e-3, "face-weighted mixture: {mix}");
    let g = GlobalDistribution::build(&map);
    let gi = integrate_sphere(|d| g.pdf(d));
    assert!((gi - 1.0).abs() < 2e-3, "global: {gi}");

    let n = Vec3::new(0.1, 0.3, 0.9).normalize();
    let fr = Frame::new(n);
    let o = Vec3::new(0.5, 0.1, 0.8).normalize();
    for (name, m) in [
        ("diffuse", Material::diffuse(0.7)),
        ("phong 20", Material::phong(0.7, 20.0)),
        ("phong 150", Material::phong(0.7, 150.0)),
    ] {
        let i = integrate_sphere(|d| m.pdf(&fr, o, d));
        assert!((i - 1.0).abs() < 3e-3, "{name}: {i}");
    }
    // GGX: the reflected visible normals that go below the horizon are lost, so the integral is
    // the fraction of valid samples (checked against sampling).
    for alpha in [0.2f32, 0.6] {
        let m = Material::ggx(0.7, alpha);
        let i = integrate_sphere(|d| m.pdf(&fr, o, d));
        let mut r = Rng::new(3, 3);
        let valid = (0..200_000)
            .filter(|_| m.sample(&fr, o, rng_vec2(&mut r)).is_some())
            .count() as f64
            / 200_000.0;
        assert!(
            i <= 1.0 + 2e-3 && (i - valid).abs() < 5e-3,
            "ggx {alpha}: integral {i}, valid fraction {valid}"
        );
    }
}

/// Bevy's Schlick GGX lobe at its limits: F0 = 0 has no glossy lobe at all (f90 = 0, so a
/// reflectance-0 dielectric is pure Lambert, the white-furnace case), F0 = 1 is the F = 1 lobe, and
/// a dielectric (F0 = 0.04) reflects more at grazing angles than head-on but never more than 1.
#[test]
fn schlick_lobe_limits() {
    use envis::sampling::brdf::{bevy_f90, fresnel_schlick};
    assert_eq!(bevy_f90(Vec3::ZERO), 0.0);
    assert_eq!(bevy_f90(Vec3::splat(0.04)), 1.0);
    assert_eq!(fresnel_schlick(Vec3::splat(0.04), 1.0), Vec3::splat(0.04));
    assert_eq!(fresnel_schlick(Vec3::splat(0.04), 0.0), Vec3::ONE);
    let schlick = |kd: f32, f0: f32| Material {
        kd: Vec3::splat(kd),
        ks: Vec3::splat(f0),
        lobe: Lobe::GgxSchlick { alpha: 0.3 },
    };
    let n = Vec3::new(0.1, 0.3, 0.9).normalize();
    let fr = Frame::new(n);
    let mut r = Rng::new(5, 1);
    for _ in 0..2000 {
        let o = Material::diffuse(1.0).sample(&fr, n, rng_vec2(&mut r));
        let i = Material::diffuse(1.0).sample(&fr, n, rng_vec2(&mut r));
        let (Some((o, _)), Some((i, _))) = (o, i) else {
            continue;
        };
        let lambert = Material::diffuse(0.5).eval(&fr, o, i);
        assert_eq!(schlick(0.5, 0.0).eval(&fr, o, i), lambert);
        let f1 = schlick(0.0, 1.0).eval(&fr, o, i);
        let ggx = Material::ggx(1.0, 0.3).eval(&fr, o, i);
        assert!(
            (f1 - ggx).abs().max_element() <= 1e-6 * ggx.x.max(1.0),
            "{f1} vs {ggx}"
        );
    }
    // Directional albedo of the dielectric lobe alone, head-on and at grazing view.
    let albedo =
        |o: Vec3| integrate_sphere(|d| schlick(0.0, 0.04).eval(&fr, o, d).x * n.dot(d).max(0.0));
    let head_on = albedo(n);
    let grazing = albedo(fr.to_world(Vec3::new(0.97, 0.0, 0.243)).normalize());
    assert!(head_on > 0.03 && head_on < 0.06, "head-on albedo {head_on}");
    assert!(
        grazing > 2.0 * head_on && grazing <= 1.0,
        "grazing albedo {grazing} vs {head_on}"
    );
}

#[test]
fn brdf_samplers_chi2() {
    let n = Vec3::new(0.2, 0.3, 0.93).normalize();
    let fr = Frame::new(n);
    let views = [
        Vec3::new(0.0, 0.0, 1.0),
        Vec3::new(0.8, 0.1, 0.35).normalize(),
    ];
    let mats = [
        ("cosine", Material::diffuse(1.0)),
        ("phong 10", Material::phong(1.0, 10.0)),
        ("phong 150", Material::phong(1.0, 150.0)),
        ("ggx 0.2", Material::ggx(1.0, 0.2)),
        ("ggx 0.6", Material::ggx(1.0, 0.6)),
        (
            "mix",
            Material {
                kd: Vec3::splat(0.5),
                ks: Vec3::splat(0.5),
                lobe: Lobe::Ggx { alpha: 0.3 },
            },
        ),
        (
            "bevy standard (schlick)",
            Material {
                kd: Vec3::splat(0.6),
                ks: Vec3::splat(0.04),
                lobe: Lobe::GgxSchlick { alpha: 0.25 },
            },
        ),
    ];
    for (k, (name, m)) in mats.iter().enumerate() {
        for (j, o) in views.iter().enumerate() {
            let o = fr.to_world(*o).normalize();
            // Bin around the lobe's axis (mirror direction for glossy lobes).
            let axis = if matches!(m.lobe, Lobe::None) {
                n
            } else {
                2.0 * n.dot(o) * n - o
            };
            // Samples below the surface are `None` in `Material::sample`; count them via raw warps
            // by asking the pdf only where the sampler can land (the lost bin takes the rest).
            chi2_sphere(
                format!("brdf {name} view {j}"),
                mats.len() * views.len(),
                axis,
                200_000,
                |r| m.sample(&fr, o, rng_vec2(r)).map(|(d, _)| d),
                |d| {
                    if n.dot(d) > 0.0 {
                        m.pdf(&fr, o, d)
                    } else {
                        0.0
                    }
                },
                (k * 10 + j) as u32,
            );
        }
    }
}

#[test]
fn degenerate_maps_have_defined_behaviour() {
    // All-zero map: no NaN, zero image, empty faces.
    let zero = CubeMap::new(4);
    let dist = CubeDistribution::build(&zero);
    assert!(
        dist.faces
            .iter()
            .all(|f| f.energy == 0.0 && f.sample(0, 0, Vec2::new(0.3, 0.7)).is_none())
    );
    let gbuf = sphere_gbuffer(8, 8, Material::diffuse(1.0));
    for strategy in [
        Strategy::Paper,
        Strategy::Global,
        Strategy::Light,
        Strategy::Brdf,
    ] {
        let out = render(
            &zero,
            &gbuf,
            8,
            8,
            &Settings {
                strategy,
                light_samples: 4,
                brdf_samples: 4,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(
            out.image.data.iter().all(|c| *c == Vec3::ZERO),
            "{strategy:?}"
        );
    }
    // One face lit, five black: only that face is ever sampled.
    let mut one = CubeMap::new(4);
    for r in 0..4 {
        for c in 0..4 {
            let i = one.index(2, c, r);
            one.data[i] = Vec3::ONE;
        }
    }
    let d = CubeDistribution::build(&one);
    let fw = face_weights(Vec3::new(0.0, 0.2, 1.0).normalize(), &d.energies(), true);
    assert!((fw.mu[2] - 1.0).abs() < 1e-6 && fw.mu.iter().sum::<f32>() <= 1.0 + 1e-6);
    // 1x1 faces work.
    let tiny = load_env(&EnvSource::Sky { hours: 12.0 }, 1).unwrap().cube;
    let out = render(
        &tiny,
        &gbuf,
        8,
        8,
        &Settings {
            light_samples: 2,
            brdf_samples: 2,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(
        out.image
            .data
            .iter()
            .all(|c| c.is_finite() && c.min_element() >= 0.0)
    );
}

#[test]
fn sample_counts_edge_cases() {
    let map = load_env(&EnvSource::Sky { hours: 10.0 }, 8).unwrap().cube;
    let gbuf = sphere_gbuffer(8, 8, Material::diffuse(1.0));
    for (nl, nb) in [(0usize, 4usize), (4, 0)] {
        let out = render(
            &map,
            &gbuf,
            8,
            8,
            &Settings {
                light_samples: nl,
                brdf_samples: nb,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(
            out.image
                .data
                .iter()
                .all(|c| c.is_finite() && c.min_element() >= 0.0)
        );
        assert!(out.image.data.iter().any(|c| c.max_element() > 0.0));
    }
    let err = render(
        &map,
        &gbuf,
        8,
        8,
        &Settings {
            light_samples: 0,
            brdf_samples: 0,
            ..Default::default()
        },
    )
    .err()
    .expect("both counts 0 must be refused");
    assert!(err.to_string().contains("both 0"), "{err}");
    // Counts within 1e-7 of an integer, exact integers, tiny mu, larger than the pool (M = 8):
    // the exact (taken, last weight, density), and fractional weights that add up to N_f.
    let frac = |nf| face_count(nf, 8, Counts::Fractional);
    let cases = [
        (2.0f32, 2usize, 1.0f32, 2.0f32),
        (2.000_000_2, 3, 2.000_000_2 - 2.0, 2.000_000_2),
        (1.999_999_9, 2, 1.999_999_9 - 1.0, 1.999_999_9),
        (1e-12, 1, 1e-12, 1e-12),
        (100.0, 8, 1.0, 8.0),
        (8.0, 8, 1.0, 8.0),
    ];
    for (nf, taken, last, density) in cases {
        let c = frac(nf);
        assert_eq!(
            (c.taken, c.last_weight, c.density),
            (taken, last, density),
            "{nf}"
        );
        assert_eq!(
            (c.taken - 1) as f32 + c.last_weight,
            c.density,
            "{nf}: weights"
        );
    }
    // Nothing to take: zero, negative, NaN, infinite N_f.
    for nf in [0.0f32, -1.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        for counts in [Counts::Fractional, Counts::Integer] {
            let c = face_count(nf, 8, counts);
            assert_eq!((c.taken, c.density), (0, 0.0), "{nf} {counts}");
        }
    }
    // Integer counts round (half away from zero) and keep the true density for the weights.
    for (nf, taken) in [(0.4f32, 0usize), (0.5, 1), (2.5, 3), (7.6, 8), (100.0, 8)] {
        let c = face_count(nf, 8, Counts::Integer);
        assert_eq!((c.taken, c.density), (taken, nf.min(8.0)), "{nf}");
    }
}
