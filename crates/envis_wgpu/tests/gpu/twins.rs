//! Each WGSL build stage against its CPU twin on a real Vulkan device: the resample of an
//! environment image, the per-face distributions (with tiles), the global distribution, the pool,
//! its sub-texel refinement.

use super::*;

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
    let view = envis_wgpu::resample::source_view(texture);
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let source = envis_wgpu::resample::Source {
        view: &view,
        layout,
        width,
    };
    envis_wgpu::ImageResampler::new(&ctx.device).encode(&ctx.device, &mut enc, source, &s, None);
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
        assert_eq!(g.len(), envis_wgpu::sampler::global_len(map.size));
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
/// The paper's pool and a pool of independent blocks (`PoolLayout::Blocks`).
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
                assert_same_sample(&format!("{name} M={m}: sample {k}"), a, b);
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

/// The sub-texel pass alone (`shaders/subtexel.wgsl`, `refine_pool`): the GPU's pool refined on
/// the GPU into the texels of the sky at 32², against the same pool refined by the CPU twin
/// (`SubTexels::refine`) from the GPU's own tables. Per face and per tile.
#[test]
fn gpu_sub_texel_refine_matches_cpu_twin() {
    use envis_wgpu::subtexel::{FineRadiance, PoolRefine};
    let Some(ctx) = gpu() else { return };
    let fine = envis::envmap::sky::sky_cube(32, 15.0);
    let coarse = envis::envmap::sky::sky_cube(8, 15.0);
    let sub = SubTexels::new(&fine, 8).unwrap();
    let refine = PoolRefine::new(&ctx.device);
    let gpu_fine = FineRadiance::new(ctx, &fine, 8).unwrap();
    assert_eq!(gpu_fine.ratio, 4);
    for (m, tiles) in [(64usize, 1usize), (9, 2)] {
        let s = Settings {
            light_samples: m,
            tiles,
            ..Default::default()
        };
        let sampler = EnvSampler::for_settings(ctx, 8, &s).unwrap();
        sampler.upload(&ctx.queue, &coarse);
        ctx.wait(sampler.run(ctx, pool_seed(3))).unwrap();
        let drawn = sampler.read_tables(ctx).unwrap();
        ctx.wait(refine.run(ctx, &sampler, &gpu_fine).unwrap())
            .unwrap();
        let g = sampler.read_tables(ctx).unwrap();
        let dist = drawn.to_distribution();
        let mut moved = 0;
        for (k, (a, before)) in g.pool.iter().zip(&drawn.pool).enumerate() {
            let b = sub.refine(&dist, before);
            assert_same_sample(&format!("M={m} K={tiles} sample {k}"), a, &b);
            moved += ((a.dir - before.dir).length() > 1e-4) as usize;
        }
        assert!(
            moved * 2 > g.pool.len(),
            "M={m}: only {moved} samples moved"
        );
    }
}

/// A GPU pool sample `a` equals its CPU twin's `b` but for float rounding: direction within
/// 2e-6, pdf within 1e-5 relative, radiance exact.
fn assert_same_sample(what: &str, a: &PoolSample, b: &PoolSample) {
    let d = (a.dir - b.dir).length();
    assert!(d < 2e-6, "{what}: dir gpu {} cpu {}", a.dir, b.dir);
    let p = rel(a.pdf as f64, b.pdf as f64);
    assert!(p < 1e-5, "{what}: pdf gpu {} cpu {}", a.pdf, b.pdf);
    assert_eq!(a.radiance, b.radiance, "{what}: radiance");
}
