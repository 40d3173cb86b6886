//! GPU stages against their CPU twins, on a real Vulkan device (Mesa lavapipe in CI:
//! `WGPU_ADAPTER_NAME=llvmpipe`). Each stage is compared in isolation — the CPU twin of a stage
//! runs on exactly the GPU's input — and then the whole frame against the CPU renderer and the
//! f64 reference. A missing device fails the tests, unless `ENVIS_SKIP_GPU=1` (outside CI).

use envis::envmap::load::{EnvSource, load_env};
use envis::envmap::*;
use envis::gpu::{EnvSampler, GpuContext, GpuGPixel, Shader, render_gpu};
use envis::render::reference::reference_image;
use envis::render::{
    FrameData, GPixel, PoolLayout, Settings, Strategy, pool_seed, render, sphere_gbuffer,
};
use envis::sampling::*;
use envis::stats::{MeanCheck, UnbiasedTest};
use glam::Vec3;
use std::path::{Path, PathBuf};

mod support;
use std::sync::OnceLock;

/// One device for the whole binary (device creation on lavapipe costs ~100 ms; tests run in
/// parallel on it). `None` only when `ENVIS_SKIP_GPU=1` asked to skip (see `support`).
fn gpu() -> Option<&'static GpuContext> {
    static CTX: OnceLock<Option<GpuContext>> = OnceLock::new();
    CTX.get_or_init(|| match GpuContext::new() {
        Ok(c) => {
            eprintln!(
                "GPU tests on: {} ({:?}, timestamps: {})",
                c.info.name, c.info.backend, c.timestamps
            );
            Some(c)
        }
        Err(e) => {
            support::skip_gpu_or_fail(
                "the GPU tests",
                &format!("no Vulkan device ({e})"),
                support::INSTALL_LAVAPIPE,
            );
            None
        }
    })
    .as_ref()
}

fn real_map_paths() -> Vec<PathBuf> {
    support::real_maps().unwrap_or_default()
}

/// A map that is zero but for one texel of 1e6 (plus a dim floor so other faces are not empty).
fn single_texel_map(n: usize, face: usize, col: usize, row: usize) -> CubeMap {
    let mut m = CubeMap::new(n);
    for t in &mut m.data {
        *t = Vec3::splat(1e-3);
    }
    let i = m.index(face, col, row);
    m.data[i] = Vec3::splat(1e6);
    m
}

/// Test maps for the stage comparisons: the built-in sky, two real maps, a lone 1e6 texel.
fn stage_maps(n: usize) -> Vec<(String, CubeMap)> {
    let mut v = vec![(
        "builtin:sky:9".to_string(),
        load_env(&EnvSource::Sky { hours: 9.0 }, n).unwrap().cube,
    )];
    let real = real_map_paths();
    for p in real.iter().step_by(real.len().max(2) / 2).take(2) {
        v.push((
            p.display().to_string(),
            load_env(&EnvSource::File(p.clone()), n).unwrap().cube,
        ));
    }
    v.push((
        "single 1e6 texel".into(),
        single_texel_map(n, 4, n / 3, n - 2),
    ));
    v
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / a.abs().max(b.abs()).max(1e-30)
}

/// Build on the GPU (a pool of `blocks` blocks of `m` per face) and read every table back.
fn gpu_build(
    ctx: &GpuContext,
    map: &CubeMap,
    m: usize,
    blocks: usize,
    seed: u32,
) -> envis::gpu::GpuTables {
    gpu_build_tiled(ctx, map, 1, m, blocks, seed)
}

/// [`gpu_build`] with `tiles x tiles` tiles per face.
fn gpu_build_tiled(
    ctx: &GpuContext,
    map: &CubeMap,
    tiles: usize,
    m: usize,
    blocks: usize,
    seed: u32,
) -> envis::gpu::GpuTables {
    let s = Settings {
        light_samples: m,
        brdf_samples: 0,
        tiles,
        pool_layout: PoolLayout::Blocks,
        pool_blocks: blocks,
        ..Default::default()
    };
    let mut s = EnvSampler::for_settings(ctx, map.size, &s).unwrap();
    s.set_blocks(blocks).unwrap();
    s.upload(&ctx.queue, map);
    ctx.wait(s.run(ctx, seed)).unwrap();
    s.read_tables(ctx).unwrap()
}

/// Upload `layers` (each `w x h`, RGB) as an Rgba32Float 2D texture with that many layers.
fn upload_texture(ctx: &GpuContext, w: u32, h: u32, layers: &[&[Vec3]]) -> wgpu::Texture {
    use wgpu::util::DeviceExt;
    let data: Vec<f32> = layers
        .iter()
        .flat_map(|l| l.iter().flat_map(|c| [c.x, c.y, c.z, 1.0]))
        .collect();
    ctx.device.create_texture_with_data(
        &ctx.queue,
        &wgpu::TextureDescriptor {
            label: Some("test environment"),
            size: wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: layers.len() as u32,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba32Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        },
        wgpu::util::TextureDataOrder::LayerMajor,
        bytemuck::cast_slice(&data),
    )
}

/// Resample `texture` into a sampler of face `n` on the GPU and build; the texel table read back.
fn gpu_resample(ctx: &GpuContext, texture: &wgpu::Texture, width: u32, n: usize) -> CubeMap {
    use envis::envmap::resample::SourceLayout;
    let size = texture.size();
    let layout = SourceLayout::detect(size.width, size.height, size.depth_or_array_layers).unwrap();
    let s = EnvSampler::new(ctx, n, 4).unwrap();
    let view = envis::gpu::resample::source_view(texture);
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let source = envis::gpu::resample::Source {
        view: &view,
        layout,
        width,
    };
    envis::gpu::ImageResampler::new(&ctx.device).encode(&ctx.device, &mut enc, source, &s, None);
    ctx.wait(ctx.queue.submit([enc.finish()])).unwrap();
    ctx.wait(s.run(ctx, 1)).unwrap();
    s.read_tables(ctx).unwrap().to_map()
}

/// The resample stage (a Bevy `Image` texture -> the cube texel table, on the GPU) equals its CPU
/// twin for a lat-long and a cube source, bad texels included (read as 0 by both), and a cube
/// image is read in Bevy's left-handed convention (world +Z is layer 5, -Z).
#[test]
fn gpu_resample_matches_cpu() {
    use envis::envmap::resample::SourceImage;
    let Some(ctx) = gpu() else { return };
    let n = 16;
    let (w, h) = (96usize, 48usize);
    let mut ll = Image::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let (u, v) = (x as f32 / w as f32, y as f32 / h as f32);
            ll.data[y * w + x] = Vec3::new(1.0 + u, 0.5 + (6.0 * v).sin().abs(), 2.0 - v);
        }
    }
    ll.data[10 * w + 30] = Vec3::splat(5e3); // a sun
    ll.data[20 * w + 5] = Vec3::new(f32::NAN, -3.0, f32::INFINITY);
    let tex = upload_texture(ctx, w as u32, h as u32, &[&ll.data]);
    let got = gpu_resample(ctx, &tex, w as u32, n);
    let want = SourceImage::new_latlong(ll).to_cube(n);
    assert_cubes_close("lat-long", &got, &want);

    let c = 12usize;
    let mut layers = CubeMap::new(c);
    for (i, t) in layers.data.iter_mut().enumerate() {
        let (f, r) = (i / (c * c), (i % (c * c)) as f32 / (c * c) as f32);
        *t = Vec3::new(f as f32 + 1.0, r, 1.0 - r);
    }
    let slices: Vec<&[Vec3]> = layers.data.chunks(c * c).collect();
    let tex = upload_texture(ctx, c as u32, c as u32, &slices);
    let got = gpu_resample(ctx, &tex, c as u32, n);
    let want = SourceImage::new_cube(layers).to_cube(n);
    assert_cubes_close("cube", &got, &want);
    let centre = |f: usize| got.texel(f, n / 2, n / 2).x;
    assert_eq!(centre(2), 3.0, "+Y reads layer 2");
    assert_eq!(
        centre(4),
        6.0,
        "+Z reads layer 5 (Bevy's cubes are left-handed)"
    );
    assert_eq!(centre(5), 5.0, "-Z reads layer 4");
}

/// Texel tables equal up to the GPU's trigonometry: Vulkan lets `acos` / `atan2` be off by
/// thousands of ulps (~1e-4 rad), which moves a lat-long tap by that much. So: at most 1% of the
/// texels may differ by more than 1e-3 relative (next to the sun), none by more than 1e-2, and each
/// face's sum agrees to 5e-4 (the +Y face, where the azimuth turns fastest, is worst).
fn assert_cubes_close(what: &str, got: &CubeMap, want: &CubeMap) {
    assert_eq!(got.size, want.size);
    let (mut worst, mut off) = (0.0f64, 0usize);
    for (g, w) in got.data.iter().zip(&want.data) {
        let r = (0..3)
            .map(|k| rel(g[k] as f64, w[k] as f64))
            .fold(0.0, f64::max);
        worst = worst.max(r);
        off += (r > 1e-3) as usize;
    }
    let n2 = got.size * got.size;
    assert!(
        worst < 1e-2 && off * 100 <= got.data.len(),
        "{what}: worst relative texel difference {worst}, {off} texels above 1e-3"
    );
    for f in 0..6 {
        let sum = |c: &CubeMap| {
            c.data[f * n2..(f + 1) * n2]
                .iter()
                .map(|t| t.x as f64)
                .sum::<f64>()
        };
        assert!(
            rel(sum(got), sum(want)) < 5e-4,
            "{what}: face {f} sums differ: {} vs {}",
            sum(got),
            sum(want)
        );
    }
}

#[test]
fn gpu_distribution_matches_cpu() {
    let Some(ctx) = gpu() else { return };
    for n in [1usize, 7, 64] {
        for (name, map) in stage_maps(n.max(2)).into_iter().map(|(nm, m)| {
            (
                nm,
                if n == 1 {
                    envis::envmap::resample::resize_cube(&m, 1)
                } else {
                    m
                },
            )
        }) {
            for tiles in [1, 3].into_iter().filter(|&k| k <= map.size) {
                check_distribution_twin(ctx, &format!("{name} K={tiles}"), &map, tiles);
            }
        }
    }
}

/// The GPU's distribution of `map` with `tiles x tiles` tiles per face against the CPU's: the
/// weights, every region's energy, corners and CDF over its columns, every column band's CDF,
/// and the pdf table.
fn check_distribution_twin(ctx: &GpuContext, name: &str, map: &CubeMap, tiles: usize) {
    let cpu = CubeDistribution::build_tiled(map, tiles);
    let w_cpu = envis::sampling::distribution::texel_weights(map);
    let g = gpu_build_tiled(ctx, map, tiles, 8, 1, 1);
    let (n, grid) = (map.size, cpu.grid);
    let nn = n * n;
    for (i, (&a, &b)) in g.weights.iter().zip(&w_cpu).enumerate() {
        assert!(
            rel(a as f64, b as f64) < 1e-6,
            "{name} n={n}: weight {i}: gpu {a} cpu {b}"
        );
    }
    for r in 0..grid.regions() {
        let (f, t) = (r / grid.per_face(), r % grid.per_face());
        let tile = &cpu.faces[f].tiles[t];
        assert!(
            rel(g.energies[r] as f64, tile.energy) < 2e-5,
            "{name}: I_{r}: gpu {} cpu {}",
            g.energies[r],
            tile.energy
        );
        for (j, c) in grid.corners(r).iter().enumerate() {
            assert!(
                (g.corners[r][j] - *c).length() < 1e-6,
                "{name}: region {r} corner {j}: gpu {} cpu {c}",
                g.corners[r][j]
            );
        }
        for (c, &want) in tile.marginal.cdf.iter().enumerate() {
            let v = g.marg_cdf[r * (n + 1) + c];
            assert!(
                (v - want).abs() < 2e-6,
                "{name}: region {r} CDF(u)[{c}]: gpu {v} cpu {want}"
            );
        }
    }
    for f in 0..6 {
        let fd = &cpu.faces[f];
        for col in 0..n {
            let base = (f * n + col) * (n + grid.k);
            for (r, &v) in g.cond_cdf[base..base + n + grid.k].iter().enumerate() {
                let want = fd.conditional.cdf(col, r);
                assert!(
                    (v - want).abs() < 2e-6,
                    "{name}: face {f} CDF(v|u={col})[{r}]: gpu {v} cpu {want}"
                );
            }
        }
        for t in 0..nn {
            let (a, b) = (
                g.pdf_area[f * nn + t] as f64,
                fd.pdf_area(t % n, t / n) as f64,
            );
            assert!(
                rel(a, b) < 2e-5 || (a - b).abs() < 1e-30,
                "{name}: face {f} pdf_area[{t}]: gpu {a} cpu {b}"
            );
        }
    }
}

/// The `global` baseline's build: the GPU's lat-long CDFs and pdf table equal the CPU twin's.
#[test]
fn gpu_global_distribution_matches_cpu() {
    let Some(ctx) = gpu() else { return };
    for (name, map) in stage_maps(16) {
        let mut s = EnvSampler::new(ctx, map.size, 4).unwrap();
        s.enable_global(&ctx.device, &ctx.queue).unwrap();
        s.upload(&ctx.queue, &map);
        ctx.wait(s.run(ctx, 1)).unwrap();
        let g = s.read_global(ctx).unwrap();
        let cpu = GlobalDistribution::build(&map);
        let (w, h) = (cpu.width, cpu.height);
        assert_eq!(g.len(), envis::gpu::sampler::global_len(map.size));
        for (y, &v) in g[..h + 1].iter().enumerate() {
            assert!(
                (v - cpu.marginal.cdf[y]).abs() < 1e-5,
                "{name}: marginal[{y}] gpu {v} cpu {}",
                cpu.marginal.cdf[y]
            );
        }
        let rows = h + 1;
        for y in 0..h {
            for x in 0..=w {
                let (a, b) = (g[rows + y * (w + 1) + x], cpu.conditional[y].cdf[x]);
                assert!(
                    (a - b).abs() < 1e-5,
                    "{name}: row {y} cdf[{x}] gpu {a} cpu {b}"
                );
            }
        }
        let pdf = rows + h * (w + 1);
        for y in 0..h {
            for x in 0..w {
                let want = cpu.marginal.bin_pmf(y) as f64
                    * cpu.conditional[y].bin_pmf(x) as f64
                    * (w * h) as f64;
                let got = g[pdf + y * w + x] as f64;
                assert!(
                    rel(got, want) < 1e-4,
                    "{name}: p(u,v) cell ({x},{y}) gpu {got} cpu {want}"
                );
            }
        }
    }
}

/// The pool stage alone: the CPU twin draws the pool from the GPU's own tables, so every sample
/// must match (same hashes, same binary search); the only allowed difference is float rounding.
/// The seed's pool and a pool of independent blocks (`PoolLayout::Blocks`).
#[test]
fn gpu_pool_matches_cpu_twin() {
    let Some(ctx) = gpu() else { return };
    for (name, map) in stage_maps(32) {
        for (m, blocks, tiles) in [
            (1usize, 1usize, 1usize),
            (37, 1, 1),
            (256, 1, 1),
            (12, 5, 1),
            (9, 2, 3),
        ] {
            let seed = pool_seed(5);
            let g = gpu_build_tiled(ctx, &map, tiles, m, blocks, seed);
            let cpu = LightPool::build_blocks(&g.to_map(), &g.to_distribution(), m, blocks, seed);
            assert_eq!(cpu.samples.len(), g.pool.len());
            let mut worst_dir = 0.0f32;
            for (k, (a, b)) in g.pool.iter().zip(&cpu.samples).enumerate() {
                worst_dir = worst_dir.max((a.dir - b.dir).length());
                assert!(
                    (a.dir - b.dir).length() < 2e-6,
                    "{name} M={m}: sample {k} dir gpu {} cpu {}",
                    a.dir,
                    b.dir
                );
                assert!(
                    rel(a.pdf as f64, b.pdf as f64) < 1e-5,
                    "{name} M={m}: sample {k} pdf gpu {} cpu {}",
                    a.pdf,
                    b.pdf
                );
                assert_eq!(a.radiance, b.radiance, "{name} M={m}: sample {k} radiance");
                assert!(
                    a.pdf > 0.0 || g.energies[k / (m * blocks)] == 0.0,
                    "{name}: a sample with pdf 0 on a lit face"
                );
            }
            // And against the pool drawn from the CPU's own tables: same texels but where a CDF
            // value differs by rounding right at a sample's bin boundary.
            let own = FrameData::prepare(
                &map,
                &Settings {
                    light_samples: m,
                    brdf_samples: 0,
                    seed: 5,
                    pool_layout: PoolLayout::Blocks,
                    pool_blocks: blocks,
                    tiles,
                    ..Default::default()
                },
            );
            let differ = g
                .pool
                .iter()
                .zip(&own.pool.samples)
                .filter(|(a, b)| (a.dir - b.dir).length() > 1e-4)
                .count();
            assert!(
                differ * 1000 <= g.pool.len(),
                "{name} M={m}: {differ} of {} samples differ from the CPU-built pool",
                g.pool.len()
            );
        }
    }
}

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
                mis,
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

fn mean_lum(d: &[Vec3]) -> f64 {
    d.iter().map(|c| luminance(*c) as f64).sum::<f64>() / d.len() as f64
}

/// Different seeds: the mean of GPU renders is within statistical tolerance of the f64 reference
/// (diffuse, Phong 150, GGX 0.2), on the sky and a real map.
#[test]
fn gpu_render_is_unbiased() {
    let Some(ctx) = gpu() else { return };
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
                    gpu_mean(ctx, map, &gbuf, size, &s)
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

/// Image-mean luminance of one GPU frame.
fn gpu_mean(
    ctx: &GpuContext,
    map: &CubeMap,
    gbuf: &[Option<GPixel>],
    size: usize,
    s: &Settings,
) -> f64 {
    mean_lum(
        &render_gpu(ctx, map, gbuf, size, size, s)
            .unwrap()
            .0
            .image
            .data,
    )
}

/// Integer counts on the GPU carry the bias they carry on the CPU, and the test sees it: two
/// equally bright faces, N_L = 1 (N_f near 0.5 rounds to 0 or 1), light samples only. Fractional
/// counts on the same setup are unbiased.
#[test]
fn gpu_integer_counts_bias_is_detected() {
    let Some(ctx) = gpu() else { return };
    let (n, size, k) = (8usize, 16usize, 64u32);
    let mut map = CubeMap::new(n);
    for f in [2usize, 4] {
        map.data[f * n * n..(f + 1) * n * n].fill(Vec3::ONE);
    }
    let gbuf = sphere_gbuffer(size, size, Material::diffuse(1.0));
    let (_, reference) = reference_image(&map, &gbuf, size, size, 1.0);
    let want = reference.iter().map(|c| luminance_f64(*c)).sum::<f64>() / reference.len() as f64;
    let run = |counts| {
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
                gpu_mean(ctx, &map, &gbuf, size, &s)
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

#[path = "gpu/stability.rs"]
mod stability;

#[cfg(feature = "app")]
#[path = "gpu/bevy_app.rs"]
mod bevy_app;

#[cfg(feature = "app")]
#[path = "gpu/bevy_plugin.rs"]
mod bevy_plugin;

#[cfg(feature = "app")]
#[path = "gpu/examples.rs"]
mod examples;

#[path = "gpu/visibility.rs"]
mod visibility;

/// `envis ARGS --out OUT --stats STATS`, which must succeed (`what` names the run if not).
fn render_ok(args: &[&str], out: &Path, stats: &Path, what: &str) {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_envis"))
        .args(args)
        .arg("--out")
        .arg(out)
        .arg("--stats")
        .arg(stats)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "{what}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

fn read_exr_mean(path: &Path) -> f64 {
    let img = envis::envmap::load::read_exr(path).unwrap();
    mean_lum(&img.data)
}

/// The command line: `--backend wgpu` (the stages on the analytic G-buffer) equals the CPU image
/// to float rounding; `--backend gpu` (the Bevy pipeline offscreen) agrees statistically; both
/// write the device and pass times into `--stats`.
#[test]
fn cli_gpu_backends() {
    let Some(_) = gpu() else { return };
    let dir = support::TempDir::new("gpu-cli");
    let mut backends = vec!["cpu", "wgpu"];
    if cfg!(feature = "app") {
        backends.push("gpu");
    }
    let mut means = Vec::new();
    for b in &backends {
        let out = dir.join(format!("{b}.exr"));
        let stats = dir.join(format!("{b}.json"));
        let args = [
            "render",
            "--env",
            "builtin:sky:14",
            "--brdf",
            "ggx",
            "--alpha",
            "0.3",
            "--size",
            "48",
            "--face-size",
            "32",
            "--backend",
            b,
        ];
        render_ok(&args, &out, &stats, &format!("--backend {b}"));
        let j: serde_json::Value = support::read_json(&stats);
        assert_eq!(j["backend"], *b, "{j}");
        means.push(read_exr_mean(&out));
    }
    assert!(
        rel(means[1], means[0]) < 1e-3,
        "wgpu {} vs cpu {}",
        means[1],
        means[0]
    );
    if means.len() > 2 {
        assert!(
            rel(means[2], means[0]) < 0.03,
            "gpu (bevy) {} vs cpu {}",
            means[2],
            means[0]
        );
    }
    // A scene file (perspective camera, sphere / glTF bunny / torus / plane) on each backend,
    // without and with shadow rays. With them the GPUs trace triangles (a tessellated sphere,
    // as Bevy draws it) where the CPU has the analytic sphere: the image means agree within 1%,
    // the ray counts (cast before the geometry is asked) within 0.1%.
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/showcase.toml");
    for vis in ["off", "auto"] {
        let mut scene_means = Vec::new();
        let mut rays = Vec::new();
        for b in &backends {
            let out = dir.join(format!("scene-{b}-{vis}.exr"));
            let stats = dir.join(format!("scene-{b}-{vis}.json"));
            let scene = scene.to_str().unwrap();
            let args = [
                "render",
                "--size",
                "48",
                "--visibility",
                vis,
                "--backend",
                b,
            ];
            let args = [&args[..], &["--scene", scene]].concat();
            render_ok(&args, &out, &stats, &format!("scene on {b}"));
            scene_means.push(read_exr_mean(&out));
            let j = support::read_json(&stats);
            rays.push(j["shadow_rays"].as_f64().unwrap_or(0.0));
        }
        let tol = if vis == "off" { 1e-3 } else { 0.01 };
        assert!(
            rel(scene_means[1], scene_means[0]) < tol,
            "scene, visibility {vis}: wgpu {} vs cpu {}",
            scene_means[1],
            scene_means[0]
        );
        if vis == "off" {
            assert_eq!(rays[..2], [0.0, 0.0]);
        } else {
            assert!(
                rays[0] > 0.0 && rel(rays[1], rays[0]) < 1e-3,
                "shadow rays: {rays:?}"
            );
        }
        if scene_means.len() > 2 {
            // Meshes and 8-bit materials in the G-buffer, and silhouettes rasterised rather than ray cast.
            assert!(
                rel(scene_means[2], scene_means[0]) < 0.05,
                "scene, visibility {vis}: gpu (bevy) {} vs cpu {}",
                scene_means[2],
                scene_means[0]
            );
        }
    }
    // `global` runs on the GPU too.
    let (a, b) = (dir.join("g-cpu.exr"), dir.join("g-wgpu.exr"));
    for (be, out) in [("cpu", &a), ("wgpu", &b)] {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_envis"))
            .args([
                "render",
                "--size",
                "32",
                "--face-size",
                "16",
                "--strategy",
                "global",
                "--backend",
                be,
            ])
            .arg("--out")
            .arg(out)
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "global on {be}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    assert!(rel(read_exr_mean(&a), read_exr_mean(&b)) < 1e-3);
}

#[cfg(feature = "demo")]
#[path = "gpu/demo.rs"]
mod demo;

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
