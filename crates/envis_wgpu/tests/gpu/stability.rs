//! Hard cases on the GPU (issue: hard cases stay numerically stable). The same catalogue as
//! `envis/tests/core/stability.rs`, where it applies to the GPU stages: every case asserts finite,
//! non-negative output and a positive pdf for every pool sample on a lit face, and compares with
//! the CPU twin (same seed) or the exact value.

use super::*;
use envis::render::GPixel;

/// GPU and CPU renders of an arbitrary G-buffer with the same settings; asserts the GPU output is
/// finite and non-negative, and returns both images.
fn both(
    ctx: &GpuContext,
    map: &CubeMap,
    gbuf: &[Option<GPixel>],
    s: &Settings,
) -> (Vec<Vec3>, Vec<Vec3>) {
    let (g, _) = render_gpu(ctx, map, gbuf, gbuf.len(), 1, s).unwrap();
    let c = render(map, gbuf, gbuf.len(), 1, s).unwrap();
    for (i, p) in g.image.data.iter().enumerate() {
        assert!(
            p.is_finite() && p.min_element() >= 0.0,
            "GPU pixel {i} = {p} for {:?}",
            gbuf[i]
        );
    }
    (g.image.data, c.image.data)
}

/// Per pixel, GPU within `tol` (relative to max(|cpu|, floor)) of the CPU twin.
fn assert_twins(label: &str, gpu: &[Vec3], cpu: &[Vec3], tol: f32, floor: f32) {
    for (i, (a, b)) in gpu.iter().zip(cpu).enumerate() {
        let d = (*a - *b).abs().max_element() / b.max_element().max(floor);
        assert!(d <= tol, "{label}: pixel {i}: gpu {a} cpu {b}");
    }
}

fn px(n: Vec3, o: Vec3, material: Material) -> Option<GPixel> {
    Some(GPixel { n, o, material })
}

#[test]
fn gpu_hard_maps_all_zero_one_face_single_texel_constant() {
    let Some(ctx) = gpu() else { return };
    let n = 16;
    let normals = [
        Vec3::X,
        -Vec3::Y,
        Vec3::new(1.0, 1.0, 1.0),
        Vec3::new(0.3, -0.2, 0.9),
        -Vec3::Z,
    ];
    let gbuf: Vec<Option<GPixel>> = normals
        .iter()
        .map(|&nn| {
            px(
                nn,
                (nn + Vec3::new(0.2, 0.1, 0.0)).normalize(),
                Material::ggx(0.8, 0.3),
            )
        })
        .collect();
    let s = Settings {
        light_samples: 16,
        brdf_samples: 8,
        seed: 2,
        ..Default::default()
    };

    // All zero: a defined, all-black result; every pool slot empty.
    let zero = CubeMap::new(n);
    let (g, _) = both(ctx, &zero, &gbuf, &s);
    assert!(
        g.iter().all(|c| *c == Vec3::ZERO),
        "all-zero map must render black"
    );
    let t = gpu_build(ctx, &zero, 8, 1, 1);
    assert!(t.pool.iter().all(|p| p.pdf == 0.0) && t.energies.iter().all(|&e| e == 0.0));

    // One face lit, five black; a single 1e6 texel at a face centre, on an edge, at a corner.
    let mut one_face = CubeMap::new(n);
    for i in 0..n * n {
        one_face.data[2 * n * n + i] = Vec3::splat(2.0);
    }
    let mut cases = vec![("one face lit".to_string(), one_face)];
    for (label, col, row) in [
        ("centre", 8usize, 8usize),
        ("edge", 0, 7),
        ("corner", 15, 15),
    ] {
        let mut m = CubeMap::new(n);
        let i = m.index(4, col, row);
        m.data[i] = Vec3::splat(1e6);
        cases.push((format!("1e6 texel at {label}"), m));
    }
    for (label, map) in &cases {
        let t = gpu_build(ctx, map, 64, 1, 9);
        for (k, p) in t.pool.iter().enumerate() {
            let lit = t.energies[k / 64] > 0.0;
            assert!(
                p.pdf.is_finite() && p.pdf >= 0.0 && (p.pdf > 0.0) == lit,
                "{label}: pool sample {k} pdf {}",
                p.pdf
            );
            if lit {
                assert!(
                    p.radiance.max_element() > 0.0,
                    "{label}: a lit face sampled a black texel"
                );
            }
        }
        let (g, c) = both(ctx, map, &gbuf, &s);
        assert_twins(label, &g, &c, 2e-3, 1e-3);
    }

    // Constant map (white furnace): diffuse albedo 1 returns 1 up to noise, GGX with F = 1 <= 1.
    let white = CubeMap::from_fn(n, |_| Vec3::ONE);
    let furnace: Vec<Option<GPixel>> = (0..256)
        .map(|i| {
            let nn = Vec3::new((i as f32 * 0.37).sin(), (i as f32 * 0.71).cos(), 0.5).normalize();
            px(
                nn,
                nn,
                if i % 2 == 0 {
                    Material::diffuse(1.0)
                } else {
                    Material::ggx(1.0, 0.05 + (i % 7) as f32 * 0.1)
                },
            )
        })
        .collect();
    let (g, c) = both(ctx, &white, &furnace, &s);
    assert_twins("furnace", &g, &c, 2e-3, 1e-3);
    for (i, c) in g.iter().enumerate().skip(1).step_by(2) {
        assert!(
            c.max_element() <= 1.0 + 0.35,
            "furnace: GGX pixel {i} = {c} (energy bound 1 + noise)"
        );
    }
    // The pool is shared by all pixels, so average over seeds for the diffuse mean.
    let means: Vec<f64> = (0..8)
        .map(|seed| {
            let (g, _) = render_gpu(
                ctx,
                &white,
                &furnace,
                furnace.len(),
                1,
                &Settings {
                    seed,
                    pool_layout: envis::render::PoolLayout::Offset,
                    pool_size: 64,
                    ..s
                },
            )
            .unwrap();
            g.image
                .data
                .iter()
                .step_by(2)
                .map(|c| c.x as f64)
                .sum::<f64>()
                / 128.0
        })
        .collect();
    // A white furnace with albedo 1 reflects exactly 1: two-sided, so a lost sample shows as
    // well as a gained one (these pixels have exact normals: no G-buffer quantisation).
    let mut test = UnbiasedTest::new("gpu furnace");
    test.push(MeanCheck::from_values("diffuse", &means, 1.0));
    test.assert();
}

/// NaN, +Inf, -Inf and negative texels uploaded raw: the GPU's own sanitise pass clamps and counts
/// them exactly as the CPU does, and none is ever sampled.
#[test]
fn gpu_hard_bad_texels_are_clamped_counted_and_never_sampled() {
    let Some(ctx) = gpu() else { return };
    let n = 8;
    let mut raw = CubeMap::from_fn(n, |d| Vec3::splat(1.0 + d.y.max(0.0)));
    let bad = [
        Vec3::new(f32::NAN, 1.0, 1.0),
        Vec3::new(f32::INFINITY, 1.0, 1.0),
        Vec3::new(1.0, f32::NEG_INFINITY, 1.0),
        Vec3::new(-3.0, 1.0, 1.0),
        Vec3::new(1.0, 3e38, 1.0),
        Vec3::new(f32::NAN, f32::INFINITY, -1.0),
    ];
    for (k, b) in bad.iter().enumerate() {
        raw.data[k * 37] = *b;
    }
    let mut clean = raw.clone();
    let cpu_report = clean.sanitize();
    let s = EnvSampler::new(ctx, n, 512).unwrap();
    s.upload(&ctx.queue, &raw);
    ctx.wait(s.run(ctx, 4)).unwrap();
    let gpu_report = s.read_problems(ctx).unwrap();
    assert_eq!(gpu_report, cpu_report, "GPU sanitise counts");
    let t = s.read_tables(ctx).unwrap();
    assert_eq!(
        t.radiance, clean.data,
        "GPU-sanitised radiance equals the CPU's"
    );
    for p in &t.pool {
        assert!(
            p.radiance.is_finite()
                && p.radiance.min_element() >= 0.0
                && p.radiance.max_element() <= MAX_RADIANCE
        );
        assert!(p.pdf.is_finite() && p.pdf > 0.0);
    }
    let cpu = CubeDistribution::build(&clean);
    for f in 0..6 {
        assert!(
            rel(t.energies[f] as f64, cpu.faces[f].energy) < 2e-5,
            "face {f} energy"
        );
    }
}

/// 2048^2 faces (25M texels), or the largest the device binds: the lone bright texel is still found, with the CPU's probability and
/// pdf, by the GPU's hierarchical f32 prefix sums.
#[test]
fn gpu_hard_2048_faces_single_bright_texel_keeps_its_pdf() {
    let Some(ctx) = gpu() else { return };
    // 16 bytes per texel: 2048^2 faces need a 384 MiB storage binding. Where the device cannot
    // bind that (lavapipe's limit is 128 MiB), the sampler must refuse with a clear error, and the
    // case runs at the largest face size the device can bind.
    let mut n = 2048;
    if let Err(e) = EnvSampler::new(ctx, n, 16) {
        let msg = e.to_string();
        assert!(
            msg.contains("storage-binding limit") && msg.contains("texel table"),
            "unclear refusal: {msg}"
        );
        while EnvSampler::new(ctx, n, 16).is_err() {
            n /= 2;
        }
        eprintln!(
            "note: {} binds at most {n}^2 faces ({msg}); the 2048^2 case runs at {n}^2 here",
            ctx.info.name
        );
    }
    assert!(n >= 1024);
    let (col, row) = (n * 3 / 5, 77usize);
    let mut map = CubeMap::from_fn(n, |_| Vec3::splat(1e-3));
    let i = map.index(3, col, row);
    map.data[i] = Vec3::splat(1e6);
    let m = 4096;
    let t = gpu_build(ctx, &map, m, 1, 12);
    let cpu = CubeDistribution::build(&map);
    let fd = &cpu.faces[3];
    let p_cpu = fd.texel_pmf(col, row) as f64;
    let p_gpu = (t.marg_cdf[3 * (n + 1) + col + 1] - t.marg_cdf[3 * (n + 1) + col]) as f64 * {
        let base = (3 * n + col) * (n + 1);
        (t.cond_cdf[base + row + 1] - t.cond_cdf[base + row]) as f64
    };
    assert!(
        rel(p_gpu, p_cpu) < 1e-3,
        "texel probability gpu {p_gpu} cpu {p_cpu}"
    );
    assert!(
        rel(t.energies[3] as f64, fd.energy) < 1e-4,
        "I_f gpu {} cpu {}",
        t.energies[3],
        fd.energy
    );
    // The pool finds it: the fraction of face-3 samples in the bright texel matches its probability.
    let hits = t.pool[3 * m..4 * m]
        .iter()
        .filter(|p| p.radiance.x > 1e5)
        .count() as f64;
    let expect = p_cpu * m as f64;
    assert!(
        (hits - expect).abs() <= 4.0 * expect.sqrt().max(1.0) + 1.0,
        "{hits} hits, expected {expect}"
    );
    for p in t.pool[3 * m..4 * m].iter().filter(|p| p.radiance.x > 1e5) {
        let want = cpu.face_pdf(p.dir).1 as f64;
        assert!(
            rel(p.pdf as f64, want) < 1e-3,
            "bright-texel sample pdf gpu {} cpu {want}",
            p.pdf
        );
    }
}

/// Geometry, BRDF and count extremes, each against the CPU twin with the same seed.
#[test]
fn gpu_hard_geometry_brdf_and_count_extremes() {
    let Some(ctx) = gpu() else { return };
    let map = load_env(&EnvSource::Sky { hours: 11.0 }, 16).unwrap().cube;
    let d = 1.0 / 3f32.sqrt();
    let mut gbuf = Vec::new();
    // Normals along axes, face diagonals and exactly through cube corners; grazing, back-facing
    // and non-unit vectors.
    for nn in [
        Vec3::X,
        -Vec3::X,
        Vec3::Y,
        -Vec3::Y,
        Vec3::Z,
        -Vec3::Z,
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(0.0, -1.0, 1.0),
        Vec3::new(d, d, d),
        Vec3::new(-d, d, -d),
    ] {
        for o in [
            nn,
            (nn + Vec3::new(0.3, 0.2, 0.1)).normalize(),
            (nn.cross(Vec3::new(0.3, 0.5, 0.7)).normalize() + 1e-4 * nn).normalize(),
            -nn,
        ] {
            gbuf.push(px(nn, o, Material::phong(0.7, 150.0)));
        }
        gbuf.push(px(nn * 1e3, nn * 1e-3, Material::diffuse(0.5)));
    }
    // BRDF extremes: Phong 0 .. 1e5, GGX 1e-4 .. 1, albedo 0, mixes.
    for e in [0.0f32, 1.0, 150.0, 1e4, 1e5] {
        gbuf.push(px(
            Vec3::Y,
            Vec3::new(0.2, 0.9, 0.1).normalize(),
            Material::phong(0.8, e),
        ));
    }
    for a in [1e-4f32, 1e-3, 0.05, 0.5, 1.0] {
        gbuf.push(px(
            Vec3::Y,
            Vec3::new(0.2, 0.9, 0.1).normalize(),
            Material::ggx(0.8, a),
        ));
    }
    gbuf.push(px(Vec3::Y, Vec3::Y, Material::diffuse(0.0)));
    gbuf.push(px(
        Vec3::Y,
        Vec3::Y,
        Material {
            kd: Vec3::splat(0.3),
            ks: Vec3::splat(0.5),
            lobe: Lobe::Phong { exponent: 1e4 },
        },
    ));
    gbuf.push(None);
    let settings = [
        Settings {
            light_samples: 8,
            brdf_samples: 8,
            ..Default::default()
        },
        Settings {
            light_samples: 0,
            brdf_samples: 8,
            ..Default::default()
        },
        Settings {
            light_samples: 8,
            brdf_samples: 0,
            ..Default::default()
        },
        // Requests larger than the pool (N_f clamped to M), and integer counts.
        Settings {
            light_samples: 64,
            brdf_samples: 4,
            pool_size: 5,
            counts: Counts::Integer,
            ..Default::default()
        },
        Settings {
            light_samples: 7,
            brdf_samples: 3,
            heuristic: Heuristic::Power,
            pool_layout: envis::render::PoolLayout::Offset,
            seed: 99,
            ..Default::default()
        },
    ];
    for s in settings {
        let (g, c) = both(ctx, &map, &gbuf, &s);
        // Near-mirror lobes (Phong 1e5, GGX 1e-4) amplify f32 rounding of the direction; the
        // comparison floor is 1% of the image's brightest pixel there.
        let floor = 1e-2 * c.iter().map(|p| p.max_element()).fold(0.0, f32::max);
        assert_twins(&format!("{s:?}"), &g, &c, 5e-3, floor.max(1e-3));
    }
    // Both counts zero: a clear error, on the GPU backend too.
    let e = render_gpu(
        ctx,
        &map,
        &gbuf,
        gbuf.len(),
        1,
        &Settings {
            light_samples: 0,
            brdf_samples: 0,
            ..Default::default()
        },
    );
    assert!(e.is_err());
}
