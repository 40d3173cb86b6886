//! Hard cases stay numerically stable (CPU twin). Each test asserts finite, non-negative output,
//! a positive pdf for every sample drawn, and unbiasedness or an energy bound.
//! `docs/numerical-stability.md` maps each case to its guard and to the test here.

use super::*;

/// Shade one pixel `k` times with different seeds; returns per-seed luminance.
fn shade_seeds(map: &CubeMap, px: &GPixel, s: Settings, k: u32) -> Vec<f64> {
    (0..k)
        .map(|seed| {
            let s = Settings {
                seed: seed * 104_729 + 17,
                ..s
            };
            let fd = envis::render::FrameData::prepare(map, &s);
            let (c, _) = envis::render::shade_pixel(&fd, &s, px, seed);
            assert!(
                c.is_finite() && c.min_element() >= 0.0,
                "pixel value {c} for {px:?}"
            );
            luminance_f64(c.as_dvec3())
        })
        .collect()
}

/// Directional albedo `int f cos` of `m` seen from `o`, by BRDF sampling: mean and standard
/// error over `k` samples. In the shading frame, as the renderer evaluates BRDF samples: a round
/// trip through world space moves a direction by ~1e-7, which a Phong lobe of exponent 1e5 turns
/// into a 1% error (found by this test: `cos^e` amplifies it `e` times).
fn directional_albedo(m: &Material, fr: &Frame, o: Vec3, k: u32) -> (f64, f64) {
    let mut r = Rng::new(77, 5);
    let ol = fr.to_local(o);
    let xs: Vec<f64> = (0..k)
        .map(|_| match m.sample_local(ol, rng_vec2(&mut r)) {
            Some((il, p)) => luminance_f64((m.eval_local(ol, il) * il.z.max(0.0) / p).as_dvec3()),
            None => 0.0,
        })
        .collect();
    mean_se(&xs)
}

fn single_texel_map(
    n: usize,
    face: usize,
    col: usize,
    row: usize,
    value: f32,
    background: f32,
) -> CubeMap {
    let mut m = CubeMap::from_fn(n, |_| Vec3::splat(background));
    let i = m.index(face, col, row);
    m.data[i] = Vec3::splat(value);
    m
}

#[test]
fn hard_single_bright_texel_centre_edge_corner() {
    let mut test = UnbiasedTest::new("hard_single_bright_texel_centre_edge_corner");
    let n = 16;
    for (label, col, row) in [
        ("centre", 8usize, 8usize),
        ("edge", 0, 7),
        ("corner", 15, 15),
    ] {
        let map = single_texel_map(n, 4, col, row, 1e6, 1e-3);
        let dist = CubeDistribution::build(&map);
        let fd = &dist.faces[4];
        // The bright texel is found with its exact probability and a positive, consistent pdf.
        let p = fd.texel_pmf(col, row) as f64;
        let want = 1e6 * texel_solid_angle(col, row, n) / fd.energy;
        assert!((p - want).abs() < 1e-4, "{label}: pmf {p} vs {want}");
        // Its hit rate, as a two-bin chi-square test (one of three positions).
        let mut r = Rng::new(1, 1);
        let hit_rate = Chi2Test::new(
            format!("bright texel at the {label}"),
            Discrete(2),
            20_000,
            3,
        );
        hit_rate
            .run(
                || {
                    let s = fd.sample(4, 0, rng_vec2(&mut r)).unwrap();
                    assert!(s.pdf > 0.0 && s.pdf.is_finite(), "{label}: pdf {}", s.pdf);
                    Some((s.col == col && s.row == row) as usize)
                },
                |hit| if hit == 1 { p } else { 1.0 - p },
            )
            .assert();
        // Unbiased renders of a normal facing the texel.
        let px = GPixel {
            n: face_uv_to_dir(
                4,
                (col as f32 + 0.5) / n as f32,
                (row as f32 + 0.5) / n as f32,
            ),
            o: Vec3::Z,
            material: Material::diffuse(0.8),
        };
        let reference = luminance_f64(reference_pixel(&map, &px, 1.0));
        for (name, s) in [
            (
                "paper",
                Settings {
                    light_samples: 4,
                    brdf_samples: 4,
                    ..Default::default()
                },
            ),
            (
                "paper light-only",
                Settings {
                    light_samples: 4,
                    brdf_samples: 0,
                    ..Default::default()
                },
            ),
        ] {
            test.push(MeanCheck::from_values(
                format!("{label} {name}"),
                &shade_seeds(&map, &px, s, 64),
                reference,
            ));
        }
    }
    test.assert();
}

#[test]
fn hard_dynamic_range_1e_minus6_to_1e6() {
    let mut test = UnbiasedTest::new("hard_dynamic_range_1e_minus6_to_1e6");
    let n = 8;
    let mut r = Rng::new(9, 9);
    let map = CubeMap::from_fn(n, |_| Vec3::ZERO);
    let map = CubeMap {
        data: map
            .data
            .iter()
            .map(|_| Vec3::splat(10f32.powf(-6.0 + 12.0 * r.next_f32())))
            .collect(),
        ..map
    };
    let dist = CubeDistribution::build(&map);
    for f in 0..6 {
        let s: f64 = (0..n * n)
            .map(|i| dist.faces[f].texel_pmf(i % n, i / n) as f64)
            .sum();
        assert!((s - 1.0).abs() < 1e-5, "face {f}: pmf sums to {s}");
        assert!(
            (0..n * n)
                .map(|t| dist.faces[f].pdf_area(t % n, t / n))
                .all(|p| p > 0.0 && p.is_finite()),
            "face {f}: a texel of 1e-6 must keep a positive pdf"
        );
    }
    let px = GPixel {
        n: Vec3::new(0.3, 0.5, 0.8).normalize(),
        o: Vec3::new(0.0, 0.2, 1.0).normalize(),
        material: Material::ggx(0.8, 0.3),
    };
    let reference = luminance_f64(reference_pixel(&map, &px, 1.0));
    test.push(MeanCheck::from_values(
        "dynamic range",
        &shade_seeds(
            &map,
            &px,
            Settings {
                light_samples: 8,
                brdf_samples: 8,
                ..Default::default()
            },
            128,
        ),
        reference,
    ));
    test.assert();
}

#[test]
fn hard_bad_texels_are_clamped_counted_and_never_sampled() {
    let (w, h) = (64usize, 32usize);
    let mut img = Image::new(w, h);
    for (i, t) in img.data.iter_mut().enumerate() {
        *t = Vec3::splat(1.0 + (i % 7) as f32);
    }
    let bad = [
        (0usize, f32::NAN),
        (100, f32::INFINITY),
        (200, f32::NEG_INFINITY),
        (300, -5.0),
        (400, -0.0),
    ];
    for &(i, v) in &bad {
        img.data[i] = Vec3::new(v, 1.0, 1.0);
    }
    let dir = tempdir();
    let p = dir.join("bad.exr");
    envis::render::output::write_exr(&p, &img).unwrap();
    let env = load_env(&EnvSource::File(p), 8).unwrap();
    assert_eq!(
        (env.report.nan, env.report.inf, env.report.negative),
        (1, 2, 1),
        "{}",
        env.report
    );
    assert!(
        env.cube
            .data
            .iter()
            .all(|c| c.is_finite() && c.min_element() >= 0.0)
    );
    let dist = CubeDistribution::build(&env.cube);
    assert!(dist.faces.iter().all(|f| {
        f.energy.is_finite()
            && (0..f.size * f.size).all(|t| f.pdf_area(t % f.size, t / f.size).is_finite())
    }));
    // In-memory sanitizer counts the same classes.
    let mut m = CubeMap::from_fn(2, |_| Vec3::ONE);
    m.data[0] = Vec3::new(f32::NAN, f32::INFINITY, -1.0);
    m.data[1] = Vec3::new(1.0, f32::NEG_INFINITY, 0.0);
    m.data[2] = Vec3::new(-1e-30, 0.0, 0.0);
    m.data[3] = Vec3::new(3e38, 1.0, 1.0); // finite, but would overflow f32 luminance
    let rep = m.sanitize();
    assert_eq!((rep.nan, rep.inf, rep.negative, rep.huge), (1, 1, 1, 1));
    assert_eq!(m.data[3].x, envis::envmap::MAX_RADIANCE);
    assert!(envis::envmap::luminance(m.data[3]).is_finite());
    assert_eq!(m.data[0], Vec3::ZERO);
    assert_eq!(m.data[1], Vec3::new(1.0, 0.0, 0.0));
}

#[test]
fn hard_2048_faces_single_bright_texel_keeps_its_pdf() {
    // 6 x 2048^2 = 25M texels: f32 prefix sums would lose a lone texel; f64 sums + normalised
    // f32 CDFs must find it with the right probability and the right pdf.
    let n = 2048;
    let (col, row) = (1234usize, 567usize);
    let mut map = CubeMap::from_fn(n, |_| Vec3::splat(1e-3));
    let i = map.index(2, col, row);
    map.data[i] = Vec3::splat(1e3);
    let dist = CubeDistribution::build(&map);
    let fd = &dist.faces[2];
    let p = fd.texel_pmf(col, row) as f64;
    let w = 1e3 * texel_solid_angle(col, row, n);
    let want = w / fd.energy; // I_f includes the texel itself
    assert!((p - want).abs() < 1e-4 * want, "pmf {p} vs {want}");
    // The marginal CDF gives that column exactly its share.
    let marginal = &fd.tiles[0].marginal;
    let col_share = (marginal.cdf[col + 1] - marginal.cdf[col]) as f64;
    let col_want = fd.conditional.total(0, col) / marginal.total;
    assert!(
        (col_share - col_want).abs() < 1e-5,
        "column share {col_share} vs {col_want}"
    );
    let mut r = Rng::new(4, 4);
    let hit_rate = Chi2Test::new("bright texel on a 2048^2 face", Discrete(2), 4000, 1);
    hit_rate
        .run(
            || {
                let s = fd.sample(2, 0, rng_vec2(&mut r)).unwrap();
                assert!(s.pdf > 0.0 && s.pdf.is_finite());
                let hit = s.col == col && s.row == row;
                if hit {
                    let q = texel_solid_angle(col, row, n) as f32;
                    // pdf x texel solid angle ~= pmf (the Jacobian varies by < 1e-3 across one
                    // texel).
                    assert!(
                        ((s.pdf * q) as f64 - p).abs() < 2e-3 * p,
                        "pdf {} x omega {q} vs pmf {p}",
                        s.pdf
                    );
                }
                Some(hit as usize)
            },
            |hit| if hit == 1 { p } else { 1.0 - p },
        )
        .assert();
}

#[test]
fn hard_normals_axes_diagonals_corners_grazing_backfacing_nonunit() {
    let mut test =
        UnbiasedTest::new("hard_normals_axes_diagonals_corners_grazing_backfacing_nonunit");
    let map = load_env(&EnvSource::Sky { hours: 10.0 }, 8).unwrap().cube;
    let s3 = 1.0 / 3f32.sqrt();
    let normals = [
        Vec3::X,
        -Vec3::X,
        Vec3::Y,
        -Vec3::Y,
        Vec3::Z,
        -Vec3::Z, // axes
        Vec3::new(1.0, 1.0, 0.0).normalize(),
        Vec3::new(0.0, -1.0, 1.0).normalize(), // face diagonals (edges)
        Vec3::new(s3, s3, s3),
        Vec3::new(-s3, s3, -s3), // through cube corners: some corner cosines are exactly 0
    ];
    for (k, &n) in normals.iter().enumerate() {
        // A view 30 degrees off the normal.
        let o = (n + 0.6 * Frame::new(n).t).normalize();
        for mat in [Material::diffuse(0.8), Material::ggx(0.8, 0.3)] {
            let px = GPixel {
                n,
                o,
                material: mat,
            };
            let reference = luminance_f64(reference_pixel(&map, &px, 1.0));
            let xs = shade_seeds(
                &map,
                &px,
                Settings {
                    light_samples: 8,
                    brdf_samples: 8,
                    ..Default::default()
                },
                96,
            );
            test.push(MeanCheck::from_values(
                format!("normal {k} {n} {mat:?}"),
                &xs,
                reference,
            ));
            // Non-unit normals and views give the same estimate as unit ones.
            let scaled = GPixel {
                n: n * 7.0,
                o: o * 0.001,
                material: mat,
            };
            let s = Settings {
                light_samples: 8,
                brdf_samples: 8,
                seed: 5,
                ..Default::default()
            };
            let fd = envis::render::FrameData::prepare(&map, &s);
            let (a, _) = envis::render::shade_pixel(&fd, &s, &px, 3);
            let (b, _) = envis::render::shade_pixel(&fd, &s, &scaled, 3);
            assert!(
                (a - b).length() <= 1e-4 * a.length().max(1e-6),
                "non-unit normal {n}: {a} vs {b}"
            );
        }
    }
    // Grazing views: finite and bounded; back-facing views and a zero normal: exactly 0.
    let n = Vec3::new(0.2, 0.9, 0.1).normalize();
    let t = Frame::new(n).t;
    for eps in [1e-2f32, 1e-4, 1e-6, 1e-7] {
        let o = (t + eps * n).normalize();
        for mat in [
            Material::diffuse(1.0),
            Material::phong(1.0, 150.0),
            Material::ggx(1.0, 0.05),
        ] {
            let xs = shade_seeds(
                &map,
                &GPixel {
                    n,
                    o,
                    material: mat,
                },
                Settings {
                    light_samples: 4,
                    brdf_samples: 4,
                    ..Default::default()
                },
                8,
            );
            assert!(
                xs.iter().all(|x| x.is_finite() && *x >= 0.0),
                "grazing {eps} {mat:?}: {xs:?}"
            );
        }
    }
    for px in [
        GPixel {
            n,
            o: -n,
            material: Material::diffuse(1.0),
        },
        GPixel {
            n: Vec3::ZERO,
            o: Vec3::Z,
            material: Material::diffuse(1.0),
        },
    ] {
        assert!(
            shade_seeds(&map, &px, Settings::default(), 2)
                .iter()
                .all(|&x| x == 0.0)
        );
    }
    test.assert();
}

#[test]
fn hard_brdf_parameter_extremes() {
    let mut test = UnbiasedTest::new("hard_brdf_parameter_extremes");
    // Phong exponent 0 .. 1e5, GGX alpha 1e-4 .. 1, albedo 0: every drawn sample has a positive
    // finite pdf, renders are finite and non-negative, and under a white furnace (L = 1) the
    // estimate never exceeds 1 (energy bound) beyond noise.
    let furnace = CubeMap::from_fn(8, |_| Vec3::ONE);
    let n = Vec3::new(0.1, 0.2, 0.97).normalize();
    let fr = Frame::new(n);
    let o = Vec3::new(0.3, 0.0, 0.95).normalize();
    let mut mats: Vec<Material> = [0.0f32, 1.0, 150.0, 1e4, 1e5]
        .iter()
        .map(|&e| Material::phong(1.0, e))
        .collect();
    mats.extend(
        [1e-4f32, 1e-3, 0.05, 0.5, 1.0]
            .iter()
            .map(|&a| Material::ggx(1.0, a)),
    );
    mats.push(Material::diffuse(0.0));
    mats.push(Material::ggx(0.0, 0.3));
    for m in &mats {
        let mut r = Rng::new(2, 2);
        for _ in 0..20_000 {
            if let Some((d, p)) = m.sample(&fr, o, rng_vec2(&mut r)) {
                assert!(
                    p > 0.0 && p.is_finite() && d.is_finite(),
                    "{m:?}: sample {d} pdf {p}"
                );
                assert!(m.eval(&fr, o, d).is_finite());
            }
        }
        let xs = shade_seeds(
            &furnace,
            &GPixel { n, o, material: *m },
            Settings {
                light_samples: 8,
                brdf_samples: 8,
                ..Default::default()
            },
            64,
        );
        // Both bounds: the estimate's mean is the directional albedo (a BRDF-only estimate with
        // 200,000 samples, no light pool, no MIS) within noise, and never above 1.
        let (albedo, albedo_se) = directional_albedo(m, &fr, o, 200_000);
        assert!(
            albedo <= 1.0 + 3.0 * albedo_se + 1e-3,
            "{m:?}: albedo {albedo} > 1"
        );
        let mut c = MeanCheck::from_values(format!("furnace {m:?}"), &xs, albedo);
        c.se = c.se.hypot(albedo_se);
        test.push(c);
        if m.is_black() {
            assert!(xs.iter().all(|&x| x == 0.0));
        }
    }
    test.assert();
}

#[test]
fn hard_tiny_mu_and_pool_requests() {
    let mut test = UnbiasedTest::new("hard_tiny_mu_and_pool_requests");
    // One face carries 1e-12 of the energy: its N_f is ~1e-11, one sample of weight frac.
    let n = 4;
    let mut map = CubeMap::from_fn(n, |_| Vec3::ZERO);
    for i in 0..n * n {
        map.data[2 * n * n + i] = Vec3::ONE; // +Y
        map.data[4 * n * n + i] = Vec3::splat(1e-12); // +Z
    }
    let px = GPixel {
        n: Vec3::new(0.0, 1.0, 1.0).normalize(),
        o: Vec3::new(0.0, 1.0, 1.0).normalize(),
        material: Material::diffuse(1.0),
    };
    let reference = luminance_f64(reference_pixel(&map, &px, 1.0));
    for s in [
        Settings {
            light_samples: 3,
            brdf_samples: 0,
            ..Default::default()
        },
        Settings {
            light_samples: 64,
            brdf_samples: 0,
            pool_size: 8,
            ..Default::default()
        }, // N_f > M: clamped
        Settings {
            light_samples: 64,
            brdf_samples: 4,
            pool_size: 8,
            pool_layout: envis::render::PoolLayout::Offset,
            ..Default::default()
        },
    ] {
        test.push(MeanCheck::from_values(
            format!("{s:?}"),
            &shade_seeds(&map, &px, s, 64),
            reference,
        ));
    }
    test.assert();
}

// ---------------------------------------------------------------------------------------------
// Loaders: bounded fuzzing of the parsers, seeded from the corpus in tests/corpus/.

fn corpus(name: &str) -> Vec<u8> {
    std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/corpus")
            .join(name),
    )
    .unwrap()
}

/// Mutations: bit flips, byte overwrites, truncation and duplication, from a deterministic RNG.
fn mutate(base: &[u8], r: &mut Rng) -> Vec<u8> {
    let mut v = base.to_vec();
    match r.next_u32() % 4 {
        0 => {
            for _ in 0..1 + r.next_u32() % 8 {
                let i = r.next_u32() as usize % v.len();
                v[i] ^= 1 << (r.next_u32() % 8);
            }
        }
        1 => {
            for _ in 0..1 + r.next_u32() % 4 {
                let i = r.next_u32() as usize % v.len();
                v[i] = r.next_u32() as u8;
            }
        }
        2 => v.truncate(r.next_u32() as usize % v.len()),
        _ => {
            let i = r.next_u32() as usize % v.len();
            let chunk = v[i..].to_vec();
            v.extend_from_slice(&chunk);
        }
    }
    v
}

/// Write `iters` mutations of `base` to `dir/m.EXT` and give each to `load`: none may panic; a
/// success must pass `ok`; an error must be one line naming the file.
fn fuzz<T>(
    name: &str,
    iters: u32,
    r: &mut Rng,
    load: impl Fn(&Path) -> envis::Result<T> + std::panic::RefUnwindSafe,
    ok: impl Fn(&T) -> bool,
) {
    let dir = tempdir();
    let base = corpus(name);
    let ext = name.rsplit('.').next().unwrap();
    // The corpus file itself loads.
    let p0 = dir.join(format!("base.{ext}"));
    std::fs::write(&p0, &base).unwrap();
    load(&p0).unwrap_or_else(|e| panic!("corpus {name} must load: {e}"));
    let p = dir.join(format!("m.{ext}"));
    for k in 0..iters {
        std::fs::write(&p, mutate(&base, r)).unwrap();
        match std::panic::catch_unwind(|| load(&p)) {
            Err(_) => panic!("{name}: mutation {k} panicked the loader"),
            Ok(Ok(v)) => assert!(ok(&v), "{name}: mutation {k} loaded bad data"),
            Ok(Err(e)) => {
                let msg = e.to_string();
                assert!(
                    msg.contains(&format!("m.{ext}")) && !msg.contains('\n'),
                    "{name}: mutation {k}: unclear error '{msg}'"
                );
            }
        }
    }
}

#[test]
fn hard_fuzz_loaders_never_panic() {
    let mut r = Rng::new(2024, 1);
    for (name, iters) in [
        ("latlong_8x4.exr", 600u32),
        ("latlong_8x4.hdr", 3000),
        ("cross_8x6_rle.hdr", 3000),
    ] {
        fuzz(
            name,
            iters,
            &mut r,
            |p| load_env(&EnvSource::File(p.to_path_buf()), 4),
            |env| {
                env.cube
                    .data
                    .iter()
                    .all(|c| c.is_finite() && c.min_element() >= 0.0)
            },
        );
    }
}

/// The glTF reader under the same mutations: every mutated file loads a consistent mesh or gives
/// a one-line error naming the file; none panics, and none allocates past the caps.
#[test]
fn hard_fuzz_glb_never_panics() {
    let mut r = Rng::new(2025, 3);
    for (name, iters) in [("tetra_nodes.glb", 3000u32), ("tetra_no_normals.glb", 1500)] {
        fuzz(name, iters, &mut r, envis::scene::load_glb, |m| {
            m.indices
                .iter()
                .flatten()
                .all(|&i| (i as usize) < m.positions.len())
                && m.normals.len() == m.positions.len()
        });
    }
}

/// glTF files: node transforms apply, missing normals are computed (outward), a crafted
/// accessor count is refused before allocation, the shipped bunny loads whole.
#[test]
fn glb_loader_nodes_normals_and_caps() {
    use envis::scene::load_glb;
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let m = load_glb(&root.join("tests/corpus/tetra_nodes.glb")).unwrap();
    assert_eq!((m.positions.len(), m.indices.len()), (8, 8));
    // The child node: translate (3, 0, 0), scale 2: vertex (1, 0, 0) lands at (5, 0, 0).
    let max_x = m.positions.iter().map(|p| p.x).fold(f32::MIN, f32::max);
    assert_eq!(max_x, 5.0);
    let m = load_glb(&root.join("tests/corpus/tetra_no_normals.glb")).unwrap();
    let centroid = m.positions.iter().sum::<Vec3>() / m.positions.len() as f32;
    for (p, n) in m.positions.iter().zip(&m.normals) {
        assert!(
            (n.length() - 1.0).abs() < 1e-5 && n.dot(*p - centroid) > 0.0,
            "{p} {n}"
        );
    }
    let e = load_glb(&root.join("tests/corpus/huge_count.glb"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("huge_count.glb") && e.contains("count"), "{e}");
    let bunny = load_glb(&support::repo().join("assets/models/bunny_plain.glb")).unwrap();
    assert_eq!((bunny.positions.len(), bunny.indices.len()), (2826, 5648));
}
