//! Bit-identity of the estimator's specialised copies (the `Lambert` loops, the AVX2 + FMA
//! copy) with the general path.

use super::*;
use crate::render::sphere_gbuffer;
use crate::sampling::{Heuristic, Material};

/// The `Lambert`, `Ggx` and `Phong` specialisations of the hot loops give the general `Material` path's
/// values bit for bit, for every strategy and both heuristics.
#[test]
fn specialised_paths_are_bit_identical() {
    use crate::sampling::Lobe;
    let map = crate::envmap::sky::sky_cube(16, 10.0);
    let w = 24;
    let lobes = [
        Lobe::None,
        Lobe::Ggx { alpha: 0.3 },
        Lobe::Ggx { alpha: 0.05 },
        Lobe::GgxSchlick { alpha: 0.2 },
        Lobe::Phong { exponent: 150.0 },
        Lobe::Phong { exponent: 3.0 },
    ];
    for lobe in lobes {
        let gbuf = lobe_gbuffer(w, lobe);
        for strategy in [
            Strategy::Paper,
            Strategy::Global,
            Strategy::Light,
            Strategy::Brdf,
        ] {
            for mis in [Heuristic::Balance, Heuristic::Power] {
                let s = Settings {
                    strategy,
                    heuristic: mis,
                    light_samples: 7,
                    brdf_samples: 21,
                    seed: 11,
                    pool_layout: PoolLayout::Blocks,
                    pool_blocks: 3,
                    ..Default::default()
                };
                let lit = lit_and_identical(&FrameData::prepare(&map, &s), &s, &gbuf);
                assert!(lit > 100, "{lobe:?} {strategy:?}: only {lit} lit pixels");
            }
        }
    }
}

/// A `w`² sphere of `lobe` (diffuse for `Lobe::None`), its colour varying over pixels.
fn lobe_gbuffer(w: usize, lobe: crate::sampling::Lobe) -> Vec<Option<GPixel>> {
    use crate::sampling::Lobe;
    let mut gbuf = sphere_gbuffer(w, w, Material::diffuse(0.7));
    for (i, px) in gbuf.iter_mut().flatten().enumerate() {
        let c = Vec3::new(0.2 + 0.01 * (i % 50) as f32, 0.5, 0.9);
        px.material = match lobe {
            Lobe::None => Material {
                kd: c,
                ..Material::diffuse(1.0)
            },
            _ => Material {
                kd: Vec3::ZERO,
                ks: c,
                lobe,
            },
        };
    }
    gbuf
}

/// Every pixel's specialised path agrees with its `Material` path (asserted); how many are lit.
fn lit_and_identical(fd: &FrameData, s: &Settings, gbuf: &[Option<GPixel>]) -> usize {
    gbuf.iter()
        .enumerate()
        .filter_map(|(i, px)| Some((i, px.as_ref()?)))
        .filter(|&(i, px)| {
            let m = &px.material;
            if let Some(l) = m.as_lambert() {
                same_as_material(fd, s, px, &l, i)
            } else if let Some(g) = m.as_ggx() {
                same_as_material(fd, s, px, &g, i)
            } else if let Some(p) = m.as_phong() {
                same_as_material(fd, s, px, &p, i)
            } else {
                panic!("{m:?} has no specialised path")
            }
        })
        .count()
}

/// Pixel `i` shaded through `bsdf` and through its `Material` agree bit for bit (asserted);
/// whether it is lit.
fn same_as_material<B: LocalBsdf>(
    fd: &FrameData,
    s: &Settings,
    px: &GPixel,
    bsdf: &B,
    i: usize,
) -> bool {
    let (n, o) = (px.n.normalize(), px.o.normalize());
    let m = &px.material;
    let (mut a, mut b) = (Vec3::ZERO, Vec3::ZERO);
    let sa = shade_with(fd, s, m, bsdf, (n, o, None), i as u32, &mut a);
    let sb = shade_with(fd, s, m, m, (n, o, None), i as u32, &mut b);
    assert_eq!(
        a.to_array().map(f32::to_bits),
        b.to_array().map(f32::to_bits),
        "{m:?} {:?} {:?} pixel {i}",
        s.strategy,
        s.heuristic
    );
    assert_eq!(
        (sa.green, sa.yellow, sa.brdf),
        (sb.green, sb.yellow, sb.brdf)
    );
    a.max_element() > 0.0
}

/// Every SIMD copy of the shading this CPU can run (AVX2 + FMA, AVX-512) agrees bit for bit
/// with the baseline copy on every material kind.
#[test]
fn simd_copy_is_bit_identical() {
    // Calls the copies directly, whatever `ENVIS_ISA` says (which only steers `shade_pixel`'s
    // choice). A CPU without AVX2 + FMA can run no SIMD copy at all.
    let copies: Vec<_> = crate::cpu::Isa::available()
        .into_iter()
        .filter(|&i| i != crate::cpu::Isa::Portable)
        .collect();
    if copies.is_empty() {
        eprintln!("simd_copy_is_bit_identical: no AVX2 + FMA on this CPU; nothing to compare");
        return;
    }
    eprintln!("simd_copy_is_bit_identical: comparing {copies:?} with the baseline copy");
    let map = crate::envmap::sky::sky_cube(16, 10.0);
    for mat in [
        Material::diffuse(0.8),
        Material::phong(0.9, 150.0),
        Material::ggx(0.9, 0.3),
        Material {
            kd: Vec3::splat(0.4),
            ks: Vec3::splat(0.5),
            lobe: crate::sampling::Lobe::Ggx { alpha: 0.1 },
        },
    ] {
        let gbuf = sphere_gbuffer(20, 20, mat);
        for strategy in [Strategy::Paper, Strategy::Global] {
            let s = Settings {
                strategy,
                light_samples: 9,
                brdf_samples: 19,
                seed: 4,
                ..Default::default()
            };
            let fd = FrameData::prepare(&map, &s);
            for (i, px) in gbuf.iter().enumerate() {
                let Some(px) = px else { continue };
                let mut b = Vec3::ZERO;
                shade_pixel_portable(&fd, &s, px, None, i as u32, &mut b);
                for &isa in &copies {
                    let (a, _) = shade_pixel_on(isa, &fd, &s, px, None, i as u32);
                    assert_eq!(
                        a.to_array().map(f32::to_bits),
                        b.to_array().map(f32::to_bits),
                        "{isa:?} {mat:?} {strategy:?} pixel {i}"
                    );
                }
            }
        }
    }
}
