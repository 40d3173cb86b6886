//! Unbiasedness: the mean over independent seeds against the exact f64 reference, for every
//! strategy, count mode and pool layout; the integer counts' bias is detected; the white furnace.

use super::*;

/// Image mean and quadrant means (luminance) of `k` renders with different seeds vs the reference.
pub(crate) fn unbiased_checks(
    map: &CubeMap,
    mat: Material,
    s: Settings,
    k: u32,
    size: usize,
    reference: &[DVec3],
) -> Vec<MeanCheck> {
    let gbuf = sphere_gbuffer(size, size, mat);
    unbiased_checks_with(map, Default::default(), &gbuf, s, k, size, reference)
}

/// The unbiasedness checks of `k` seeds of any `size x size` G-buffer, with [`Extras`]: the mean
/// luminance of the image and of its four quadrants against `reference`.
///
/// [`Extras`]: envis::render::Extras
pub(crate) fn unbiased_checks_with(
    map: &CubeMap,
    extras: envis::render::Extras<'_>,
    gbuf: &[Option<GPixel>],
    s: Settings,
    k: u32,
    size: usize,
    reference: &[DVec3],
) -> Vec<MeanCheck> {
    type Region = (String, Box<dyn Fn(usize, usize) -> bool>);
    let regions: Vec<Region> = vec![
        ("image".into(), Box::new(|_, _| true)),
        (
            "top-left".into(),
            Box::new(move |x, y| x < size / 2 && y < size / 2),
        ),
        (
            "top-right".into(),
            Box::new(move |x, y| x >= size / 2 && y < size / 2),
        ),
        (
            "bottom-left".into(),
            Box::new(move |x, y| x < size / 2 && y >= size / 2),
        ),
        (
            "bottom-right".into(),
            Box::new(move |x, y| x >= size / 2 && y >= size / 2),
        ),
    ];
    let lum = luminance_f64;
    let region_mean = |f: &dyn Fn(usize) -> f64, sel: &dyn Fn(usize, usize) -> bool| {
        let (mut s, mut n) = (0.0, 0.0);
        for y in 0..size {
            for x in 0..size {
                if sel(x, y) {
                    s += f(y * size + x);
                    n += 1.0;
                }
            }
        }
        s / n
    };
    let mut per_seed: Vec<Vec<f64>> = vec![Vec::new(); regions.len()];
    for seed in 0..k {
        let out = envis::render::render_with(
            map,
            extras,
            gbuf,
            size,
            size,
            &Settings {
                seed: seed * 7919 + 1,
                ..s
            },
        )
        .unwrap();
        assert!(
            out.image
                .data
                .iter()
                .all(|c| c.is_finite() && c.min_element() >= 0.0),
            "non-finite or negative pixel"
        );
        for (r, (_, sel)) in regions.iter().enumerate() {
            per_seed[r].push(region_mean(
                &|i| lum(out.image.data[i].as_dvec3()),
                sel.as_ref(),
            ));
        }
    }
    regions
        .iter()
        .enumerate()
        .map(|(r, (name, sel))| {
            MeanCheck::from_values(
                name.clone(),
                &per_seed[r],
                region_mean(&|i| lum(reference[i]), sel.as_ref()),
            )
        })
        .collect()
}

/// Radiance from the full-resolution map, densities from a coarse copy (what the Bevy pass
/// does), and the same with the light sampled inside the coarse texels by the fine luminance
/// (sub-texel sampling, what `envis render` does): still unbiased against the fine map's
/// reference, light-only sampling included, since each coarse texel (the mean of its fine
/// texels) is positive wherever one of them is. The same estimator reading the coarse map's
/// radiance misses the fine map's integral on a glossy lobe (the check that this test can
/// fail).
#[test]
fn fine_radiance_with_coarse_densities_is_unbiased() {
    let (size, k) = (16usize, 40u32);
    let fine = envis::envmap::sky::sky_cube(32, 15.0);
    let coarse = box_downsample(&fine, 4);
    let lookup = |d: Vec3| fine.lookup(d);
    let (base, configs) = few_sample_configs();
    let mut test = UnbiasedTest::new("fine_radiance_with_coarse_densities_is_unbiased");
    for (mname, mat) in [
        ("diffuse", Material::diffuse(0.8)),
        ("ggx 0.3", Material::ggx(0.8, 0.3)),
    ] {
        let gbuf = sphere_gbuffer(size, size, mat);
        let (_, reference) = reference_image(&fine, &gbuf, size, size, 1.0);
        for (sname, sub) in [("", None), (" sub-texels", Some(&fine))] {
            let extras = envis::render::Extras {
                fine: Some(&lookup),
                sub_texels: sub,
                ..Default::default()
            };
            for (cname, s) in configs {
                // `global` draws from its own table: sub-texels change nothing there.
                if sub.is_some() && s.strategy == Strategy::Global {
                    continue;
                }
                let checks = unbiased_checks_with(&coarse, extras, &gbuf, s, k, size, &reference);
                for c in checks {
                    test.push(MeanCheck {
                        label: format!("{mname} / {cname}{sname} / {}", c.label),
                        ..c
                    });
                }
            }
        }
    }
    test.assert();
    // Without the fine radiance, the coarse map's blurred sun gives the glossy lobe a different
    // integral: the same check fails.
    let mat = Material::ggx(0.8, 0.3);
    let gbuf = sphere_gbuffer(size, size, mat);
    let (_, reference) = reference_image(&fine, &gbuf, size, size, 1.0);
    let coarse_only = unbiased_checks_with(
        &coarse,
        Default::default(),
        &gbuf,
        base,
        k,
        size,
        &reference,
    );
    assert!(
        coarse_only.iter().any(|c| c.z() > 5.0),
        "reading the coarse radiance should be detectably biased here"
    );
}

/// Four light + four BRDF samples, and the three configurations the fine-radiance and shadow
/// tests check: the method, light samples alone, and the `global` baseline.
pub(crate) fn few_sample_configs() -> (Settings, [(&'static str, Settings); 3]) {
    let base = Settings {
        light_samples: 4,
        brdf_samples: 4,
        ..Default::default()
    };
    let configs = [
        ("paper", base),
        (
            "paper light-only",
            Settings {
                brdf_samples: 0,
                light_samples: 8,
                ..base
            },
        ),
        (
            "global",
            Settings {
                strategy: Strategy::Global,
                ..base
            },
        ),
    ];
    (base, configs)
}

/// Each texel of the result is the mean of the `k x k` texels it covers.
pub(crate) fn box_downsample(map: &CubeMap, k: usize) -> CubeMap {
    let n = map.size / k;
    let mut out = CubeMap::new(n);
    for (i, t) in out.data.iter_mut().enumerate() {
        let (f, row, col) = (i / (n * n), (i / n) % n, i % n);
        let mut sum = Vec3::ZERO;
        for y in 0..k {
            for x in 0..k {
                sum += map.texel(f, col * k + x, row * k + y);
            }
        }
        *t = sum / (k * k) as f32;
    }
    out
}

#[test]
fn estimators_are_unbiased() {
    let (size, face, k) = (16usize, 16usize, 40u32);
    let envs = test_envs(face, 3);
    let mats = [
        ("diffuse", Material::diffuse(0.8)),
        ("phong 150", Material::phong(0.8, 150.0)),
        ("ggx 0.2", Material::ggx(0.8, 0.2)),
        (
            "bevy metal (schlick)",
            Material {
                kd: Vec3::ZERO,
                ks: Vec3::new(0.9, 0.6, 0.3),
                lobe: Lobe::GgxSchlick { alpha: 0.3 },
            },
        ),
    ];
    let base = Settings {
        light_samples: 4,
        brdf_samples: 4,
        ..Default::default()
    };
    let configs = [
        ("paper fractional balance", base),
        (
            "paper fractional power",
            Settings {
                heuristic: Heuristic::Power,
                ..base
            },
        ),
        (
            "paper fractional offset pool=16",
            Settings {
                pool_layout: envis::render::PoolLayout::Offset,
                pool_size: 16,
                ..base
            },
        ),
        (
            "paper fractional blocks K=5",
            Settings {
                pool_layout: envis::render::PoolLayout::Blocks,
                pool_blocks: 5,
                ..base
            },
        ),
        (
            "paper light-only",
            Settings {
                brdf_samples: 0,
                light_samples: 6,
                ..base
            },
        ),
        // Tiles of 6, 5 and 5 texels (3 does not divide 16) on the paper's shared pool, and 2 x 2
        // tiles on blocks, with counts per face (each sample drawing its tile); then counts per
        // tile.
        (
            "paper tiles K=3 shared",
            Settings {
                tiles: 3,
                pool_layout: envis::render::PoolLayout::Shared,
                ..base
            },
        ),
        (
            "paper tiles K=2 blocks K=4",
            Settings {
                tiles: 2,
                pool_blocks: 4,
                ..base
            },
        ),
        (
            "paper tiles K=3 counts per tile",
            Settings {
                tiles: 3,
                tile_counts: envis::sampling::TileCounts::Tile,
                ..base
            },
        ),
        (
            "global power",
            Settings {
                strategy: Strategy::Global,
                heuristic: Heuristic::Power,
                ..base
            },
        ),
        (
            "light",
            Settings {
                strategy: Strategy::Light,
                ..base
            },
        ),
        (
            "brdf",
            Settings {
                strategy: Strategy::Brdf,
                ..base
            },
        ),
    ];
    let mut test = UnbiasedTest::new("estimators_are_unbiased");
    for (ename, map) in &envs {
        for (mname, mat) in &mats {
            let gbuf = sphere_gbuffer(size, size, *mat);
            let (_, reference) = reference_image(map, &gbuf, size, size, 1.0);
            for (cname, s) in &configs {
                // BRDF-only sampling of a 1.5-degree sun under a Phong/GGX lobe converges too
                // slowly for 40 seeds; it is still checked on diffuse.
                if s.strategy == Strategy::Brdf
                    && *mname != "diffuse"
                    && ename.starts_with("builtin")
                {
                    continue;
                }
                // BRDF-only sampling of small bright lights (the sun, studio lamps) is heavy-tailed:
                // with few seeds most runs miss the lights, so both the mean and its standard
                // error come out low. Checked with 400 seeds on studio.exr: mean within 0.7 se of
                // the reference, median 0.83x the mean. It gets 5x the seeds (it is cheap).
                let seeds = if s.strategy == Strategy::Brdf {
                    5 * k
                } else {
                    k
                };
                for c in unbiased_checks(map, *mat, *s, seeds, size, &reference) {
                    test.push(MeanCheck {
                        label: format!("{ename} / {mname} / {cname} / {}", c.label),
                        ..c
                    });
                }
            }
        }
    }
    test.assert();
}

#[test]
fn integer_counts_bias_is_detected() {
    // The test above has power: integer counts (round(N_f) samples weighted as N_f) are biased,
    // most where N_f is near 0.5. Two equally bright faces (+Y, +Z), N_L = 1, light only.
    let n = 8;
    let mut map = CubeMap::new(n);
    for f in [2usize, 4] {
        for i in 0..n * n {
            map.data[f * n * n + i] = Vec3::ONE;
        }
    }
    let mat = Material::diffuse(1.0);
    let size = 16;
    let gbuf = sphere_gbuffer(size, size, mat);
    let (_, reference) = reference_image(&map, &gbuf, size, size, 1.0);
    let base = Settings {
        light_samples: 1,
        brdf_samples: 0,
        pool_size: 4,
        ..Default::default()
    };
    let frac = unbiased_checks(&map, mat, base, 64, size, &reference);
    let int = unbiased_checks(
        &map,
        mat,
        Settings {
            counts: Counts::Integer,
            ..base
        },
        64,
        size,
        &reference,
    );
    let mut test = UnbiasedTest::new("integer_counts_bias_is_detected (fractional)");
    frac.into_iter().for_each(|c| test.push(c));
    test.assert();
    assert!(
        int[0].z() > 6.0 && int[0].p_value() < 1e-6,
        "integer bias not detected: z = {} (mean {} ref {})",
        int[0].z(),
        int[0].mean,
        int[0].reference
    );
}

#[test]
fn white_furnace() {
    // Constant radiance 1: diffuse albedo 1 reflects exactly 1; GGX with F = 1 never more than 1.
    let map = CubeMap::from_fn(8, |_| Vec3::ONE);
    let px = |m| GPixel {
        n: Vec3::new(0.3, 0.2, 0.93).normalize(),
        o: Vec3::new(0.1, 0.0, 1.0).normalize(),
        material: m,
    };
    let r = reference_pixel(&map, &px(Material::diffuse(1.0)), 2.0);
    assert!((r.x - 1.0).abs() < 1e-3, "diffuse furnace reference {r}");
    // Single-scattering GGX loses energy as alpha grows (0.69 at alpha 0.5, 0.31 at 1 for this
    // view: half the visible normals of alpha = 1 reflect below the horizon), never gains any.
    let mut last = 1.0 + 1e-3;
    for alpha in [0.05f32, 0.2, 0.5, 1.0] {
        let g = reference_pixel(&map, &px(Material::ggx(1.0, alpha)), 1.0).x;
        assert!(
            g <= last && g > 0.2,
            "ggx furnace reference alpha {alpha}: {g} (previous {last})"
        );
        last = g;
    }
    let gbuf = sphere_gbuffer(16, 16, Material::diffuse(1.0));
    let out = render(
        &map,
        &gbuf,
        16,
        16,
        &Settings {
            light_samples: 16,
            brdf_samples: 16,
            ..Default::default()
        },
    )
    .unwrap();
    let vals: Vec<f64> = out
        .image
        .data
        .iter()
        .zip(&gbuf)
        .filter(|(_, g)| g.is_some())
        .map(|(c, _)| c.x as f64)
        .collect();
    let (m, _) = mean_se(&vals);
    assert!((m - 1.0).abs() < 0.02, "diffuse furnace MC mean {m}");
}

#[test]
fn reference_quadrature_is_converged() {
    let map = load_env(&EnvSource::Sky { hours: 10.0 }, 16).unwrap().cube;
    for mat in [
        Material::diffuse(0.8),
        Material::phong(0.8, 150.0),
        Material::ggx(0.8, 0.2),
    ] {
        let gbuf = sphere_gbuffer(8, 8, mat);
        let (_, a) = reference_image(&map, &gbuf, 8, 8, 1.0);
        let (_, b) = reference_image(&map, &gbuf, 8, 8, 2.0);
        let (sa, sb): (f64, f64) = (a.iter().map(|c| c.y).sum(), b.iter().map(|c| c.y).sum());
        assert!(
            ((sa - sb) / sb).abs() < 2e-3,
            "{mat:?}: refine 1 vs 2: {sa} vs {sb}"
        );
    }
}

#[test]
fn renders_are_deterministic_per_seed() {
    let map = load_env(&EnvSource::Sky { hours: 10.0 }, 16).unwrap().cube;
    let gbuf = sphere_gbuffer(16, 16, Material::ggx(0.8, 0.3));
    let s = Settings {
        light_samples: 8,
        brdf_samples: 8,
        seed: 42,
        ..Default::default()
    };
    let a = render(&map, &gbuf, 16, 16, &s).unwrap().image.data;
    let b = render(&map, &gbuf, 16, 16, &s).unwrap().image.data;
    let c = render(&map, &gbuf, 16, 16, &Settings { seed: 43, ..s })
        .unwrap()
        .image
        .data;
    assert_eq!(a, b);
    assert_ne!(a, c);
}
