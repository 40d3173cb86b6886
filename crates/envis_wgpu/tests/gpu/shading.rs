//! The WGSL shading against the CPU: same-seed frames, unbiasedness, the integer counts' bias,
//! a stream followed frame by frame, and the material-driven budget.

use super::*;

/// The shading stage alone, and the whole frame: with the same seed the GPU image equals the CPU
/// image to float rounding (same pool, same per-pixel random streams).
#[test]
fn gpu_render_matches_cpu_same_seed() {
    let Some(ctx) = gpu() else { return };
    let size = 48;
    let map = load_env(&EnvSource::Sky { hours: 15.0 }, 32).unwrap().cube;
    let mats = [
        ("diffuse", Material::diffuse(0.8)),
        ("phong 150", Material::phong(0.8, 150.0)),
        ("ggx 0.2", Material::ggx(0.8, 0.2)),
        (
            "mix",
            Material {
                kd: Vec3::splat(0.4),
                ks: Vec3::splat(0.4),
                lobe: Lobe::Ggx { alpha: 0.3 },
            },
        ),
        (
            "bevy standard (schlick)",
            Material {
                kd: Vec3::splat(0.5),
                ks: Vec3::splat(0.04),
                lobe: Lobe::GgxSchlick { alpha: 0.25 },
            },
        ),
    ];
    // (strategy, counts, MIS, pool layout, tiles per face side): tiles of 11 and 10 texels
    // (3 does not divide 32) and of 8; 4 x 4 with counts per tile, the others per face.
    use Counts::{Fractional, Integer};
    use Heuristic::{Balance, Power};
    let strategies = [
        (Strategy::Paper, Fractional, Balance, PoolLayout::Shared, 1),
        (Strategy::Paper, Integer, Power, PoolLayout::Offset, 1),
        (Strategy::Paper, Fractional, Balance, PoolLayout::Blocks, 3),
        (Strategy::Paper, Integer, Power, PoolLayout::Shared, 4),
        (Strategy::Light, Fractional, Balance, PoolLayout::Blocks, 2),
        (Strategy::Brdf, Fractional, Balance, PoolLayout::Shared, 1),
        (Strategy::Global, Fractional, Power, PoolLayout::Shared, 1),
    ];
    for (mname, mat) in mats {
        let gbuf = sphere_gbuffer(size, size, mat);
        for (strategy, counts, mis, pool_layout, tiles) in strategies {
            let s = Settings {
                light_samples: 8,
                brdf_samples: 8,
                strategy,
                counts,
                heuristic: mis,
                pool_layout,
                pool_blocks: 4,
                seed: 11,
                tiles,
                tile_counts: if tiles == 4 {
                    TileCounts::Tile
                } else {
                    TileCounts::Face
                },
                ..Default::default()
            };
            let cpu = render(&map, &gbuf, size, size, &s).unwrap();
            let (gpu_img, timings) = render_gpu(ctx, &map, &gbuf, size, size, &s).unwrap();
            let label =
                format!("{mname} {strategy:?} {counts:?} {mis:?} pool={pool_layout} tiles={tiles}");
            // Per pixel: near-identical. A handful of pixels may take a different branch where a
            // cosine or a CDF comparison sits within rounding of its threshold.
            let mut off = 0;
            for (i, (a, b)) in gpu_img.image.data.iter().zip(&cpu.image.data).enumerate() {
                assert!(
                    a.is_finite() && a.min_element() >= 0.0,
                    "{label}: pixel {i} = {a}"
                );
                let d = (*a - *b).abs().max_element() / b.max_element().max(1e-3);
                if d > 1e-3 {
                    off += 1;
                }
            }
            assert!(
                off * 200 <= size * size,
                "{label}: {off} pixels differ by more than 0.1%"
            );
            let (ma, mb) = (mean_lum(&gpu_img.image.data), mean_lum(&cpu.image.data));
            assert!(rel(ma, mb) < 1e-3, "{label}: image mean gpu {ma} cpu {mb}");
            // Sample accounting (red / green / yellow) matches too.
            assert!(
                (gpu_img.stats.green - cpu.stats.green).abs() < 1e-3,
                "{label}: green {} vs {}",
                gpu_img.stats.green,
                cpu.stats.green
            );
            assert!(
                (gpu_img.stats.yellow - cpu.stats.yellow).abs() < 1e-3,
                "{label}: yellow {} vs {}",
                gpu_img.stats.yellow,
                cpu.stats.yellow
            );
            assert_eq!(gpu_img.stats.shaded_pixels, cpu.stats.shaded_pixels);
            assert!(
                [timings.build_wall_ms, timings.shade_wall_ms]
                    .iter()
                    .all(|t| t.is_finite() && *t >= 0.0)
            );
        }
    }
}

/// Different seeds: the mean of GPU renders is within statistical tolerance of the f64 reference
/// (diffuse, Phong 150, GGX 0.2), on the sky and a real map.
#[test]
fn gpu_render_is_unbiased() {
    let Some(ctx) = gpu() else { return };
    let mut renderer = envis_wgpu::GpuRenderer::new(ctx);
    let (size, face, k) = (16usize, 16usize, 40u32);
    let mut envs = vec![(
        "builtin:sky:10".to_string(),
        load_env(&EnvSource::Sky { hours: 10.0 }, face)
            .unwrap()
            .cube,
    )];
    if let Some(p) = real_map_paths().first() {
        envs.push((
            p.display().to_string(),
            load_env(&EnvSource::File(p.clone()), face).unwrap().cube,
        ));
    }
    let mats = [
        ("diffuse", Material::diffuse(0.8)),
        ("phong 150", Material::phong(0.8, 150.0)),
        ("ggx 0.2", Material::ggx(0.8, 0.2)),
    ];
    let mut test = UnbiasedTest::new("gpu_render_is_unbiased");
    for (ename, map) in &envs {
        for (mname, mat) in mats {
            let gbuf = sphere_gbuffer(size, size, mat);
            let (_, reference) = reference_image(map, &gbuf, size, size, 1.0);
            let want =
                reference.iter().map(|c| luminance_f64(*c)).sum::<f64>() / reference.len() as f64;
            let means: Vec<f64> = (0..k)
                .map(|seed| {
                    let s = Settings {
                        light_samples: 4,
                        brdf_samples: 4,
                        seed: seed * 7919 + 1,
                        ..Default::default()
                    };
                    gpu_mean(&mut renderer, map, &gbuf, size, &s)
                })
                .collect();
            test.push(MeanCheck::from_values(
                format!("{ename} {mname}"),
                &means,
                want,
            ));
        }
    }
    test.assert();
}

/// Image-mean luminance of one GPU frame, by a renderer that keeps its pipelines between the
/// test's frames (compiling them per frame was most of these tests' time).
fn gpu_mean(
    r: &mut envis_wgpu::GpuRenderer,
    map: &CubeMap,
    gbuf: &[Option<GPixel>],
    size: usize,
    s: &Settings,
) -> f64 {
    mean_lum(&r.render(map, gbuf, size, size, s).unwrap().0.image.data)
}

/// Integer counts on the GPU carry the bias they carry on the CPU, and the test sees it: two
/// equally bright faces, N_L = 1 (N_f near 0.5 rounds to 0 or 1), light samples only. Fractional
/// counts on the same setup are unbiased.
#[test]
fn gpu_integer_counts_bias_is_detected() {
    let Some(ctx) = gpu() else { return };
    let mut renderer = envis_wgpu::GpuRenderer::new(ctx);
    let (n, size, k) = (8usize, 16usize, 64u32);
    let mut map = CubeMap::new(n);
    for f in [2usize, 4] {
        map.data[f * n * n..(f + 1) * n * n].fill(Vec3::ONE);
    }
    let gbuf = sphere_gbuffer(size, size, Material::diffuse(1.0));
    let (_, reference) = reference_image(&map, &gbuf, size, size, 1.0);
    let want = reference.iter().map(|c| luminance_f64(*c)).sum::<f64>() / reference.len() as f64;
    let mut run = |counts| {
        let means: Vec<f64> = (0..k)
            .map(|seed| {
                let s = Settings {
                    light_samples: 1,
                    brdf_samples: 0,
                    pool_size: 4,
                    counts,
                    seed: seed * 7919 + 1,
                    ..Default::default()
                };
                gpu_mean(&mut renderer, &map, &gbuf, size, &s)
            })
            .collect();
        MeanCheck::from_values(format!("{counts}"), &means, want)
    };
    let mut test = UnbiasedTest::new("gpu_integer_counts_bias_is_detected (fractional)");
    test.push(run(Counts::Fractional));
    test.assert();
    let int = run(Counts::Integer);
    assert!(
        int.z() > 6.0 && int.p_value() < 1e-6,
        "GPU integer bias not detected: {int:?}"
    );
}

/// A stream: the map changes every frame (the sun moves); one sampler is re-uploaded and rebuilt
/// each frame, and each frame's GPU image follows its own map — it equals the CPU render of that
/// frame, and not the previous frame's (no stale distribution, no frame-late sampling).
#[test]
fn gpu_stream_follows_the_map_every_frame() {
    let Some(ctx) = gpu() else { return };
    let (size, face) = (32usize, 16usize);
    let gbuf = sphere_gbuffer(size, size, Material::diffuse(0.8));
    let pixels: Vec<GpuGPixel> = gbuf.iter().map(GpuGPixel::from).collect();
    let s = Settings {
        light_samples: 8,
        brdf_samples: 8,
        seed: 3,
        ..Default::default()
    };
    let sampler = EnvSampler::for_settings(ctx, face, &s).unwrap();
    let shader = Shader::new(ctx);
    let mut prev_cpu: Option<Vec<Vec3>> = None;
    for frame in 0..6 {
        let map = load_env(
            &EnvSource::Sky {
                hours: 7.0 + 2.0 * frame as f32,
            },
            face,
        )
        .unwrap()
        .cube;
        sampler.upload(&ctx.queue, &map);
        sampler.set_seed(&ctx.queue, pool_seed(s.seed));
        // Build and shade in one submission, as a renderer does.
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        sampler.encode(&mut enc);
        ctx.queue.submit([enc.finish()]);
        let job = shader.shade(ctx, &sampler, &pixels, &s).unwrap();
        let img: Vec<Vec3> = job
            .color
            .iter()
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect();
        let cpu = render(&map, &gbuf, size, size, &s).unwrap().image.data;
        let diff = |a: &[Vec3], b: &[Vec3]| {
            a.iter()
                .zip(b)
                .map(|(x, y)| (*x - *y).abs().max_element() as f64)
                .sum::<f64>()
                / mean_lum(b).max(1e-9)
                / a.len() as f64
        };
        let now = diff(&img, &cpu);
        assert!(
            now < 1e-3,
            "frame {frame}: GPU image differs from this frame's CPU render ({now})"
        );
        if let Some(p) = &prev_cpu {
            let stale = diff(&img, p);
            assert!(
                stale > 100.0 * now.max(1e-6),
                "frame {frame}: the image is as close to the previous frame ({stale}) as to this one ({now})"
            );
        }
        prev_cpu = Some(cpu);
    }
}

/// The material-driven budget on the GPU: the same image as the CPU twin, and the work it skips
/// is skipped there too (no BRDF sample for a diffuse scene, no light sample for a near-mirror).
#[test]
fn gpu_material_budget_matches_cpu_and_skips_work() {
    let Some(ctx) = gpu() else { return };
    let map = load_env(&EnvSource::Sky { hours: 13.0 }, 16).unwrap().cube;
    let size = 32;
    for (name, mat) in [
        ("diffuse", Material::diffuse(0.8)),
        ("ggx 0.01", Material::ggx(0.8, 0.01)),
        ("ggx 0.3", Material::ggx(0.8, 0.3)),
    ] {
        let gbuf = sphere_gbuffer(size, size, mat);
        let s = Settings {
            light_samples: 8,
            brdf_samples: 8,
            material_budget: true,
            seed: 4,
            ..Default::default()
        };
        let (g, _) = render_gpu(ctx, &map, &gbuf, size, size, &s).unwrap();
        let c = render(&map, &gbuf, size, size, &s).unwrap();
        assert!(
            rel(mean_lum(&g.image.data), mean_lum(&c.image.data)) < 1e-3,
            "{name}: image mean"
        );
        assert_eq!(
            g.stats.brdf_samples_drawn, c.stats.brdf_samples_drawn,
            "{name}"
        );
        assert!((g.stats.green - c.stats.green).abs() < 1e-3, "{name}");
        match name {
            "diffuse" => assert_eq!(g.stats.brdf_samples_drawn, 0),
            "ggx 0.01" => assert!(
                g.stats.green + g.stats.yellow == 0.0
                    && g.stats.brdf_samples_drawn == 16 * g.stats.shaded_pixels
            ),
            _ => assert!(
                g.stats.brdf_samples_drawn == 8 * g.stats.shaded_pixels && g.stats.green > 0.0
            ),
        }
    }
}

/// Radiance from the map at its own resolution (`--radiance full`, the default of `envis
/// render`): the GPU reads the fine table by direction as the CPU does, the densities from the
/// coarse one, and the image differs from reading the coarse table (a near-mirror sphere shows
/// the coarse texels as blocks).
#[test]
fn gpu_full_resolution_radiance_matches_cpu() {
    let Some(ctx) = gpu() else { return };
    let size = 40;
    let env = envis::envmap::load::load_env_full(&EnvSource::Sky { hours: 15.0 }, 16).unwrap();
    let fine = env
        .fine
        .as_ref()
        .expect("the built-in sky is finer than 16^2 faces");
    assert_eq!(fine.size, envis::envmap::load::SKY_FACE);
    let lookup = |d: Vec3| fine.lookup(d);
    let mut renderer = envis_wgpu::GpuRenderer::new(ctx);
    for mat in [Material::diffuse(0.8), Material::ggx(0.8, 0.02)] {
        let gbuf = sphere_gbuffer(size, size, mat);
        let s = Settings {
            light_samples: 8,
            brdf_samples: 8,
            seed: 5,
            ..Default::default()
        };
        let extras = envis::render::Extras {
            fine: Some(&lookup),
            sub_texels: Some(fine),
            ..Default::default()
        };
        let cpu = envis::render::render_with(&env.cube, extras, &gbuf, size, size, &s).unwrap();
        let coarse = render(&env.cube, &gbuf, size, size, &s).unwrap();
        let gpu_extras = envis_wgpu::GpuExtras {
            fine: Some(fine),
            shadows: None,
        };
        let (gpu, _) = renderer
            .render_with(&env.cube, gpu_extras, &gbuf, size, size, &s)
            .unwrap();
        let differs = |a: &[Vec3], b: &[Vec3]| {
            a.iter()
                .zip(b)
                .filter(|(a, b)| (**a - **b).abs().max_element() > 1e-3 * b.max_element().max(1e-3))
                .count()
        };
        let off = differs(&gpu.image.data, &cpu.image.data);
        assert!(
            off * 200 <= size * size,
            "{mat:?}: {off} pixels differ from the CPU twin"
        );
        let changed = differs(&cpu.image.data, &coarse.image.data);
        assert!(
            changed * 4 > size * size / 2,
            "{mat:?}: the fine radiance changed only {changed} pixels"
        );
    }
}
