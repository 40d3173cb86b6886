//! The per-frame distributions (Mitsuba-style chi-square tests, pdf integrated per bin): face
//! CDFs, the face- and tile-weighted mixtures, the global baseline and the light pool.

use super::*;

#[test]
fn face_distribution_chi2_texel_domain() {
    let n = 8;
    let map = structured_cube(n);
    let dist = CubeDistribution::build(&map);
    for f in 0..6 {
        let fd = &dist.faces[f];
        let mut r = Rng::new(5, f as u32);
        let name = format!("face_distribution_chi2_texel_domain face {f}");
        Chi2Test::new(name, Discrete(n * n), 100_000, 6)
            .run(
                || {
                    let s = fd.sample(f, 0, rng_vec2(&mut r)).unwrap();
                    assert!(s.pdf > 0.0 && s.pdf.is_finite());
                    assert!(s.row != 1 && s.col != 2, "sampled a zero texel");
                    Some(s.row * n + s.col)
                },
                |i| fd.texel_pmf(i % n, i / n) as f64,
            )
            .assert();
    }
}

/// The per-frame build lays the conditionals out in strips of columns, row by row. On a face of
/// 100 (a full strip of 64 and a partial one of 36), with zero rows, a zero column and a hot
/// texel, every column's CDF, total and samples match a plain 1D distribution over that column;
/// and a rebuild into the last frame's memory, from another map, equals a fresh build bit for bit.
#[test]
fn face_distribution_strips_match_column_distributions() {
    use envis::sampling::distribution::{STRIP, face_solid_angles};
    let n = 100;
    assert!(n > STRIP && n % STRIP != 0);
    let map = structured_cube(n);
    let dist = CubeDistribution::build(&map);
    let omega = face_solid_angles(n);
    let mut r = Rng::new(8, 1);
    for f in [2, 3] {
        let fd = &dist.faces[f];
        for c in 0..n {
            let w: Vec<f32> = (0..n)
                .map(|row| luminance(map.data[map.index(f, c, row)]).max(0.0) * omega[row * n + c])
                .collect();
            let want = Distribution1D::new(w);
            let got = &fd.conditional;
            let (ta, tb) = (got.total(0, c), want.total);
            assert!(
                (ta - tb).abs() <= 1e-12 * tb,
                "face {f} column {c} total {ta} vs {tb}"
            );
            for row in 0..=n {
                let (a, b) = (got.cdf(c, row), want.cdf[row]);
                assert!(
                    (a - b).abs() < 1e-6,
                    "face {f} column {c} cdf[{row}]: {a} vs {b}"
                );
            }
            for row in 0..n {
                assert_eq!(got.bin_pmf(c, row), want.bin_pmf(row));
            }
            for _ in 0..20 {
                let u = r.next_f32();
                let (a, b) = (got.sample(c, 0, u), want.sample(u));
                // The same row, unless u sits within rounding of a boundary.
                let near = (0..=n).any(|k| (want.cdf[k] - u).abs() < 1e-6);
                assert!(
                    a.0 == b.0 || near,
                    "face {f} column {c} u {u}: {a:?} vs {b:?}"
                );
            }
        }
    }
    let mut frame = CubeDistribution::build(&smooth_cube(n));
    frame.rebuild(&map);
    for (a, b) in frame.faces.iter().zip(&dist.faces) {
        assert_eq!(a.energy, b.energy);
        assert_eq!(a.tiles[0].area_scale, b.tiles[0].area_scale);
        assert_eq!(a.tiles[0].marginal.cdf, b.tiles[0].marginal.cdf);
        for c in 0..n {
            for row in 0..=n {
                assert_eq!(a.conditional.cdf(c, row), b.conditional.cdf(c, row));
            }
        }
    }
}

#[test]
fn face_distribution_invert_round_trips() {
    let map = structured_cube(8);
    let dist = CubeDistribution::build(&map);
    let mut r = Rng::new(21, 0);
    for f in 0..6 {
        for _ in 0..1000 {
            let u = rng_vec2(&mut r);
            let s = dist.faces[f].sample(f, 0, u).unwrap();
            let (g, a, b) = dir_to_face_ab(s.dir);
            assert_eq!(g, f);
            let back = dist.faces[f].invert(a, b);
            assert!(
                (back - u).abs().max_element() < 1e-3,
                "face {f}: {u} -> {back}"
            );
        }
    }
}

#[test]
fn face_distribution_solid_angle_pdf_chi2() {
    // Histogram of sampled directions in 24x24 bins of face coordinates; expected counts from the
    // returned *solid-angle* pdf times exact sub-rect solid angles (8x8 per bin): this only fits
    // if the cube-face Jacobian in the pdf is right.
    let map = smooth_cube(8);
    let dist = CubeDistribution::build(&map);
    for f in 0..6 {
        let mut r = Rng::new(17, f as u32);
        let name = format!("face_distribution_solid_angle_pdf_chi2 face {f}");
        let domain = FacePlane {
            face: f,
            n: 24,
            q: 8,
        };
        Chi2Test::new(name, domain, 200_000, 6)
            .run(
                || dist.faces[f].sample(f, 0, rng_vec2(&mut r)).map(|s| s.dir),
                |d| {
                    let (g, p) = dist.face_pdf(d);
                    assert_eq!(g, f);
                    p as f64
                },
            )
            .assert();
    }
}

#[test]
fn face_weighted_mixture_chi2_for_several_normals() {
    let n = 8;
    let map = structured_cube(n);
    let dist = CubeDistribution::build(&map);
    let e = dist.energies();
    let smooth = CubeDistribution::build(&smooth_cube(8));
    let normals = [
        Vec3::Y,
        Vec3::new(1.0, 1.0, 1.0),
        Vec3::new(0.3, -0.8, 0.2),
        -Vec3::Z,
        Vec3::new(1.0, 0.0, 0.0),
    ];
    for (k, &nrm) in normals.iter().enumerate() {
        let fw = face_weights(nrm.normalize(), &e, true);
        let mix = Distribution1D::new(fw.mu.to_vec());
        // Exact test in the (face, texel) domain; with the sphere test below, two checks per
        // normal.
        let checks = 2 * normals.len();
        let mut r = Rng::new(11, k as u32);
        Chi2Test::new(
            format!("mixture texels normal {nrm}"),
            Discrete(6 * n * n),
            100_000,
            checks,
        )
        .run(
            || {
                let (f, _) = mix.sample(r.next_f32());
                let s = dist.faces[f].sample(f, 0, rng_vec2(&mut r)).unwrap();
                Some((f * n + s.row) * n + s.col)
            },
            |i| {
                fw.mu[i / (n * n)] as f64
                    * dist.faces[i / (n * n)].texel_pmf(i % n, (i / n) % n) as f64
            },
        )
        .assert();
        // Faces entirely below the horizon are never used (exact skip), others are.
        for (f, corners) in envis::sampling::faceweights::FACE_CORNERS
            .iter()
            .enumerate()
        {
            let corners_up = corners
                .iter()
                .any(|&c| nrm.dot(envis::sampling::faceweights::corner(c)) > 0.0);
            assert_eq!(
                fw.mu[f] > 0.0,
                corners_up && e[f] > 0.0,
                "normal {nrm} face {f}"
            );
        }
        // And over the sphere, with the solid-angle pdf mu_f p_f(w), on the smooth map.
        let dist = &smooth;
        let fw = face_weights(nrm.normalize(), &smooth.energies(), true);
        let mix = Distribution1D::new(fw.mu.to_vec());
        chi2_sphere(
            format!("mixture sphere normal {nrm}"),
            checks,
            nrm,
            200_000,
            |r| {
                let (f, _) = mix.sample(r.next_f32());
                dist.faces[f].sample(f, 0, rng_vec2(r)).map(|s| s.dir)
            },
            |d| {
                let (f, p) = dist.face_pdf(d);
                fw.mu[f] * p
            },
            100 + k as u32,
        );
    }
}

/// Sub-face tiles (`--tiles K`): the per-pixel mixture over `6 K^2` tiles, each sampled from its
/// own CDFs, has the pmf `mu_t P(texel | t)` in the (face, texel) domain and the solid-angle pdf
/// `mu_t p_t(w)` over the sphere; a tile wholly below the horizon gets no weight, and every
/// other lit tile some. `K = 3` on faces of 8 does not divide them (tiles of 3, 3 and 2 texels).
#[test]
fn tile_mixture_chi2_for_several_normals() {
    use envis::sampling::{MAX_REGIONS, TileWeights};
    let (n, k) = (8, 3);
    let normals = [
        Vec3::Y,
        Vec3::new(1.0, 1.0, 1.0),
        Vec3::new(0.3, -0.8, 0.2),
        Vec3::new(1.0, 0.0, 0.0),
    ];
    let checks = 2 * normals.len();
    for (map, sphere) in [(structured_cube(n), false), (smooth_cube(n), true)] {
        let dist = CubeDistribution::build_tiled(&map, k);
        let (grid, e) = (dist.grid, dist.region_energies());
        assert_eq!(grid.regions(), 6 * k * k);
        let tiles = TileWeights::new(grid, &e);
        for (j, &nrm) in normals.iter().enumerate() {
            let nrm = nrm.normalize();
            let mut mass = [0.0f32; MAX_REGIONS];
            let total = tiles.masses(nrm, true, &mut mass);
            let mu: Vec<f32> = mass[..grid.regions()].iter().map(|m| m / total).collect();
            for (r, &m) in mu.iter().enumerate() {
                let up = grid.corners(r).iter().any(|c| nrm.dot(*c) > 0.0);
                assert_eq!(m > 0.0, up && e[r] > 0.0, "normal {nrm} region {r}");
            }
            let mix = Distribution1D::new(mu.clone());
            let draw = |r: &mut Rng| {
                let (t, _) = mix.sample(r.next_f32());
                dist.sample_region(t, rng_vec2(r))
            };
            if sphere {
                chi2_sphere(
                    format!("tiles K={k} sphere normal {nrm}"),
                    checks,
                    nrm,
                    200_000,
                    |r| draw(r).map(|s| s.dir),
                    |d| {
                        let t = envis::envmap::dir_to_texel(d, n);
                        let (f, p) = dist.face_pdf(d);
                        mu[grid.region(f, t.col, t.row)] * p
                    },
                    300 + j as u32,
                );
                continue;
            }
            let mut r = Rng::new(31, j as u32);
            Chi2Test::new(
                format!("tiles K={k} texels normal {nrm}"),
                Discrete(6 * n * n),
                100_000,
                checks,
            )
            .run(
                || {
                    let s = draw(&mut r)?;
                    let (f, _, _) = envis::envmap::dir_to_face_ab(s.dir);
                    Some((f * n + s.row) * n + s.col)
                },
                |i| {
                    let (f, col, row) = (i / (n * n), i % n, (i / n) % n);
                    mu[grid.region(f, col, row)] as f64 * dist.faces[f].texel_pmf(col, row) as f64
                },
            )
            .assert();
        }
    }
}

#[test]
fn global_sampler_chi2() {
    // The pbrt-style lat-long baseline: directions against its solid-angle pdf, on a smooth map
    // and on one with zero rows and columns and lone bright texels.
    let maps = [
        ("smooth", smooth_cube(8)),
        ("structured", structured_cube(8)),
    ];
    for (k, (name, map)) in maps.iter().enumerate() {
        let g = GlobalDistribution::build(map);
        let mut r = Rng::new(31, k as u32);
        Chi2Test::new(
            format!("global sampler {name}"),
            Sphere::new(Vec3::Y),
            200_000,
            2,
        )
        .run(
            || g.sample(rng_vec2(&mut r)).map(|(d, _)| d),
            |d| g.pdf(d) as f64,
        )
        .assert();
    }
}

#[test]
fn light_pool_chi2_per_slot() {
    // Each slot of the pool, taken alone over seeds, is distributed as its face's pdf (the
    // stratification only correlates slots within one pool): the property that lets a pixel use
    // any k slots, or start at a random offset, and stay unbiased.
    let map = smooth_cube(8);
    let dist = CubeDistribution::build(&map);
    let (m, seeds, faces) = (4usize, 40_000u32, [2usize, 4]);
    let mut slots = vec![Vec::with_capacity(seeds as usize); faces.len() * m];
    for seed in 0..seeds {
        let pool = LightPool::build(&map, &dist, m, seed);
        for (j, &f) in faces.iter().enumerate() {
            for i in 0..m {
                let s = pool.get(f, i);
                let (g, p) = dist.face_pdf(s.dir);
                assert!(g == f && (s.pdf - p).abs() <= 1e-4 * p, "{s:?} vs pdf {p}");
                slots[j * m + i].push(s.dir);
            }
        }
    }
    for (j, &f) in faces.iter().enumerate() {
        for i in 0..m {
            let mut dirs = slots[j * m + i].iter();
            let domain = FacePlane {
                face: f,
                n: 16,
                q: 8,
            };
            let name = format!("light pool face {f} slot {i}");
            Chi2Test::new(name, domain, seeds as usize, faces.len() * m)
                .run(|| dirs.next().copied(), |d| dist.face_pdf(d).1 as f64)
                .assert();
        }
    }
}

/// A pool of blocks (`PoolLayout::Blocks`) is `K` paper pools side by side: block 0 is the paper's
/// pool of the same seed, block `b` the paper's pool drawn with `block_seed(seed, b)`, and the
/// blocks differ (independent draws), so a pixel that takes one whole block takes a stratified
/// pool whose every slot is distributed as the face pdf (`light_pool_chi2_per_slot`).
#[test]
fn pool_blocks_are_independent_seed_pools() {
    use envis::sampling::pool::block_seed;
    let map = smooth_cube(8);
    let dist = CubeDistribution::build(&map);
    let (m, k, seed) = (6usize, 4usize, 77u32);
    let blocks = LightPool::build_blocks(&map, &dist, m, k, seed);
    assert_eq!((blocks.per_region, blocks.block), (k * m, m));
    for b in 0..k {
        let one = LightPool::build(&map, &dist, m, block_seed(seed, b as u32));
        for f in 0..6 {
            for i in 0..m {
                assert_eq!(
                    blocks.get(f, b * m + i),
                    one.get(f, i),
                    "block {b} face {f} slot {i}"
                );
            }
        }
    }
    let seeds_pool = LightPool::build(&map, &dist, m, seed);
    assert_eq!(&blocks.samples[..m], &seeds_pool.samples[..m]);
    let same = (0..m)
        .filter(|&i| blocks.get(0, i) == blocks.get(0, m + i))
        .count();
    assert_eq!(same, 0, "blocks 0 and 1 share {same} samples");
}
