//! Suite `gpu`: the GPU stages' per-pass times, each next to its CPU twin run in the same process.
//!
//! - distribution build + light pool for 6 x N^2 faces (N = 16 .. 1024, or what the device binds);
//! - a full frame (`--size` / `--height`, default 1920 x 1080) of the sphere G-buffer at
//!   `N_L + N_B` samples (default 32 + 32).
//!
//! GPU figures are timestamp queries around each compute pass (when the device has them) and wall
//! time from submission to completion; each is the median of `--repeat` runs after one warm-up.

use super::{BenchArgs, median};
use envis::envmap::load::{EnvSource, load_env};
use envis::error::Result;
use envis::render::{self, Settings, pool_seed};
use envis::sampling::{CubeDistribution, LightPool, Material};
use envis::stream::EnvStream;
use envis_wgpu::{EnvSampler, GpuContext, GpuGPixel, Shader};
use std::path::PathBuf;
use std::time::Instant;

#[derive(serde::Serialize)]
struct BuildRow {
    face: usize,
    texels: usize,
    pool_per_face: usize,
    gpu_ms: Option<f64>,
    gpu_wall_ms: f64,
    cpu_ms: f64,
    cpu_over_gpu: Option<f64>,
}

#[derive(serde::Serialize)]
struct FrameRow {
    width: usize,
    height: usize,
    shaded_pixels: usize,
    light_samples: usize,
    brdf_samples: usize,
    material: String,
    gpu_build_ms: Option<f64>,
    gpu_shade_ms: Option<f64>,
    gpu_shade_wall_ms: f64,
    cpu_shade_ms: f64,
    cpu_over_gpu: Option<f64>,
}

pub fn run(a: BenchArgs, dir: PathBuf) -> Result<()> {
    let ctx = GpuContext::new()?;
    let repeat = a.repeat.max(1);
    eprintln!(
        "gpu bench on {} ({:?}), timestamps: {}",
        ctx.info.name, ctx.info.backend, ctx.timestamps
    );
    let builds = build_rows(&ctx, &a, repeat)?;
    let frames = frame_rows(&ctx, &a, repeat)?;
    let out = serde_json::json!({
        "device": ctx.info.name,
        "backend": format!("{:?}", ctx.info.backend),
        "driver": ctx.info.driver_info,
        "timestamps": ctx.timestamps,
        "repeat": repeat,
        "build": builds,
        "frame": frames,
    });
    let path = dir.join("bench-gpu.json");
    envis::render::output::write_json(&path, &out)?;
    eprintln!("wrote {}", path.display());
    Ok(())
}

/// The build rows over the face sizes (those the device cannot bind left out).
fn build_rows(ctx: &GpuContext, a: &BenchArgs, repeat: usize) -> Result<Vec<BuildRow>> {
    let m = a.light_samples.max(1);
    let faces: Vec<usize> = if a.quick {
        vec![16, 64, 256]
    } else {
        vec![16, 64, 256, 1024]
    };
    let mut builds = Vec::new();
    for &n in &faces {
        builds.extend(build_row(ctx, n, m, repeat)?);
    }
    Ok(builds)
}

/// A full frame of the sphere, diffuse and glossy, under `--env`.
fn frame_rows(ctx: &GpuContext, a: &BenchArgs, repeat: usize) -> Result<Vec<FrameRow>> {
    let (width, height) = if a.quick {
        (480, 270)
    } else {
        (a.size.max(1), a.height.unwrap_or(a.size * 9 / 16).max(1))
    };
    let map = load_env(&a.env.parse::<EnvSource>()?, a.face_size)?.cube;
    let s = Settings {
        light_samples: a.light_samples,
        brdf_samples: a.brdf_samples,
        ..Default::default()
    };
    s.validate()?;
    let mut frames = Vec::new();
    for (name, mat) in [
        ("diffuse", Material::diffuse(0.8)),
        ("ggx 0.2", Material::ggx(0.8, 0.2)),
    ] {
        let gbuf = render::sphere_gbuffer(width, height, mat);
        frames.push(frame_row(
            ctx,
            &map,
            &gbuf,
            (width, height),
            name,
            &s,
            repeat,
        )?);
    }
    Ok(frames)
}

/// The distribution build + pool of `M = m` per face on 6 x `n`^2 faces on the GPU and on the
/// CPU, medians of `repeat` after a warm-up; `None` where the device cannot bind the tables.
fn build_row(ctx: &GpuContext, n: usize, m: usize, repeat: usize) -> Result<Option<BuildRow>> {
    let sampler = match EnvSampler::new(ctx, n, m) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("  {n}^2: skipped on this device: {e}");
            return Ok(None);
        }
    };
    let map = load_env(&EnvSource::Sky { hours: 10.0 }, n)?.cube;
    sampler.upload(&ctx.queue, &map);
    let (mut g, mut w, mut c) = (Vec::new(), Vec::new(), Vec::new());
    for k in 0..=repeat {
        let t = Instant::now();
        ctx.wait(sampler.run(ctx, pool_seed(k as u32)))?;
        let wall = t.elapsed().as_secs_f64() * 1e3;
        let gms = sampler.last_gpu_ms(ctx);
        let t = Instant::now();
        let dist = CubeDistribution::build(&map);
        let pool = LightPool::build(&map, &dist, m, pool_seed(k as u32));
        let cpu = t.elapsed().as_secs_f64() * 1e3;
        std::hint::black_box(pool.samples.len());
        if k > 0 {
            w.push(wall);
            c.push(cpu);
            g.extend(gms);
        }
    }
    let gpu_ms = (!g.is_empty()).then(|| median(g));
    let (gpu_wall_ms, cpu_ms) = (median(w), median(c));
    eprintln!(
        "  build+pool 6x{n}^2, M={m}: GPU {} ms (wall {gpu_wall_ms:.3} ms), CPU {cpu_ms:.3} ms",
        fmt(gpu_ms)
    );
    Ok(Some(BuildRow {
        face: n,
        texels: 6 * n * n,
        pool_per_face: m,
        gpu_ms,
        gpu_wall_ms,
        cpu_ms,
        cpu_over_gpu: gpu_ms.map(|g| cpu_ms / g),
    }))
}

/// One frame of G-buffer `gbuf` (`size`, material `name`) shaded on the GPU and on the CPU,
/// medians of up to 3 runs after a warm-up.
fn frame_row(
    ctx: &GpuContext,
    map: &envis::envmap::CubeMap,
    gbuf: &[Option<render::GPixel>],
    (width, height): (usize, usize),
    name: &str,
    s: &Settings,
    repeat: usize,
) -> Result<FrameRow> {
    let pixels: Vec<GpuGPixel> = gbuf.iter().map(GpuGPixel::from).collect();
    let sampler = EnvSampler::for_settings(ctx, map.size, s)?;
    sampler.upload(&ctx.queue, map);
    let shader = Shader::new(ctx);
    let (mut gb, mut gs, mut gw, mut cs) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for k in 0..=repeat.min(3) {
        ctx.wait(sampler.run(ctx, pool_seed(s.seed)))?;
        let b = sampler.last_gpu_ms(ctx);
        let t = Instant::now();
        let job = shader.shade(ctx, &sampler, &pixels, s)?;
        let wall = t.elapsed().as_secs_f64() * 1e3;
        let cpu = render::render(map, gbuf, width, height, s)?.stats.shade_ms;
        if k > 0 {
            gb.extend(b);
            gs.extend(job.gpu_ms);
            gw.push(wall);
            cs.push(cpu);
        }
    }
    let gpu_shade_ms = (!gs.is_empty()).then(|| median(gs));
    let cpu_shade_ms = median(cs);
    let row = FrameRow {
        width,
        height,
        shaded_pixels: gbuf.iter().filter(|p| p.is_some()).count(),
        light_samples: s.light_samples,
        brdf_samples: s.brdf_samples,
        material: name.into(),
        gpu_build_ms: (!gb.is_empty()).then(|| median(gb)),
        gpu_shade_ms,
        gpu_shade_wall_ms: median(gw),
        cpu_shade_ms,
        cpu_over_gpu: gpu_shade_ms.map(|g| cpu_shade_ms / g),
    };
    eprintln!(
        "  frame {width}x{height} {name}, {}+{}: GPU shade {} ms (wall incl. upload/readback {:.1} ms), CPU {cpu_shade_ms:.1} ms",
        s.light_samples,
        s.brdf_samples,
        fmt(row.gpu_shade_ms),
        row.gpu_shade_wall_ms
    );
    Ok(row)
}

fn fmt(x: Option<f64>) -> String {
    x.map_or("n/a".into(), |v| format!("{v:.3}"))
}

#[derive(serde::Serialize)]
struct SceneRow {
    scene: String,
    /// Shadow rays cast: `on` or `off`.
    visibility: &'static str,
    frames: usize,
    builds: usize,
    mean_frame_ms: f64,
    mean_build_ms: f64,
    mean_shade_ms: f64,
    shade_gpu_ms: Option<f64>,
    brdf_samples_per_frame: u64,
    light_samples_per_frame: f64,
    shadow_rays_per_frame: u64,
}

/// The scene suite's numbers for one scene: its frame cost with and without shadow rays.
#[derive(serde::Serialize)]
struct VisibilityCost {
    scene: String,
    /// Triangles the GPU traces (meshes once per placement, a sphere as 4,096).
    triangles_traced: usize,
    shade_on_over_off: f64,
    /// Shadow rays per second, counting all the extra shading time as ray time.
    shadow_rays_per_second: f64,
}

/// Suite `scene`: what a scene costs per frame when only the work it needs is done. Each scene
/// file is played for `--repeat` x 10 frames at 30 fps (3 with `--quick`), once without shadow
/// rays and once with: its environment stream advances, the distribution is rebuilt only when
/// the frame changed, and the G-buffer is shaded.
pub fn scenes(a: BenchArgs, dir: PathBuf) -> Result<()> {
    use envis::scene::Scene;
    let ctx = GpuContext::new()?;
    let root = crate::repo_path("assets/scenes");
    let names = [
        "diffuse-static.toml",
        "glossy-dynamic.toml",
        "showcase.toml",
    ];
    let frames = if a.quick { 3 } else { 10 * a.repeat.max(1) };
    let (w, h) = if a.quick {
        (160, 100)
    } else {
        (a.size, a.height.unwrap_or(a.size * 10 / 16))
    };
    let (mut rows, mut costs) = (Vec::new(), Vec::new());
    for name in names {
        let sc = Scene::load(&root.join(name))?;
        let flat = sc.shadow_bvh().map_err(envis::error::Error::invalid)?;
        let (gbuf, points) = sc.gbuffer_points(w, h);
        let bvh = envis_wgpu::visibility::GpuBvh::new(&ctx, &flat);
        let off = play(&ctx, name, &sc, &gbuf, None, frames)?;
        let on = play(&ctx, name, &sc, &gbuf, Some((&bvh, &points)), frames)?;
        let extra_s = (on.mean_shade_ms - off.mean_shade_ms).max(1e-6) / 1e3;
        costs.push(VisibilityCost {
            scene: name.into(),
            triangles_traced: flat.meshes.triangles.len(),
            shade_on_over_off: on.mean_shade_ms / off.mean_shade_ms.max(1e-9),
            shadow_rays_per_second: on.shadow_rays_per_frame as f64 / extra_s,
        });
        rows.extend([off, on]);
    }
    let ratio = rows[2].mean_frame_ms / rows[0].mean_frame_ms.max(1e-9);
    eprintln!("  glossy-dynamic / diffuse-static frame time (no shadow rays): {ratio:.2}x");
    let out = serde_json::json!({ "device": ctx.info.name, "width": w, "height": h, "scenes": rows, "visibility": costs, "dynamic_glossy_over_static_diffuse": ratio });
    let path = dir.join("bench-scene.json");
    envis::render::output::write_json(&path, &out)?;
    eprintln!("wrote {}", path.display());
    Ok(())
}

/// Play `sc` for `frames` frames, with shadow rays through `shadows` (the GPU geometry and each
/// pixel's surface point) or without.
fn play(
    ctx: &GpuContext,
    name: &str,
    sc: &envis::scene::Scene,
    gbuf: &[Option<envis::render::GPixel>],
    shadows: Option<(&envis_wgpu::visibility::GpuBvh, &[glam::Vec3])>,
    frames: usize,
) -> Result<SceneRow> {
    let mut stream = scene_stream(sc)?;
    let pixels: Vec<GpuGPixel> = gbuf.iter().map(GpuGPixel::from).collect();
    let s = sc.settings;
    let sampler = EnvSampler::for_settings(ctx, stream.face_size(), &s)?;
    let shader = Shader::new(ctx);
    let player = Player {
        ctx,
        pixels,
        s,
        sampler,
        shader,
        shadows,
    };
    // Some drivers (lavapipe among them) compile a pipeline at its first dispatch: one untimed
    // frame first, so that the timings are steady-state frames.
    player.rebuild(&stream)?;
    player.shade()?;
    let played = player.time_frames(&mut stream, frames)?;
    Ok(played.row(name, frames, shadows.is_some()))
}

/// The scene's environment stream (a sky moving at the scene's speed).
fn scene_stream(sc: &envis::scene::Scene) -> Result<EnvStream> {
    let env = &sc.file.environment;
    EnvStream::open(sc.stream_source(env.speed)?, env.face_size)
}

/// What one scene is played with: its G-buffer on the GPU, settings, sampler, shader and shadow
/// geometry.
struct Player<'a> {
    ctx: &'a GpuContext,
    pixels: Vec<GpuGPixel>,
    s: Settings,
    sampler: EnvSampler,
    shader: Shader,
    shadows: Option<(&'a envis_wgpu::visibility::GpuBvh, &'a [glam::Vec3])>,
}

/// What playing a scene measured: the builds, each frame's times, and the last frame's counts.
#[derive(Default)]
struct Played {
    builds: usize,
    frame_ms: Vec<f64>,
    build_ms: Vec<f64>,
    shade_ms: Vec<f64>,
    gpu: Vec<f64>,
    brdf: u64,
    light: f64,
    rays: u64,
}

impl Player<'_> {
    /// Upload the stream's current frame and rebuild the distribution and pool from it.
    fn rebuild(&self, stream: &EnvStream) -> Result<()> {
        self.sampler.upload(&self.ctx.queue, stream.frame());
        self.ctx
            .wait(self.sampler.run(self.ctx, pool_seed(self.s.seed)))
    }

    /// Shade the G-buffer once (with shadow rays if any).
    fn shade(&self) -> Result<envis_wgpu::shading::ShadeJob> {
        self.shader
            .shade_with_shadows(self.ctx, &self.sampler, &self.pixels, &self.s, self.shadows)
    }

    /// `frames` frames at 30 fps: the stream advances, the distribution is rebuilt only when
    /// its frame changed, and the G-buffer is shaded.
    fn time_frames(&self, stream: &mut EnvStream, frames: usize) -> Result<Played> {
        let mut p = Played::default();
        let mut uploaded = None;
        for f in 0..frames {
            let t0 = Instant::now();
            if f > 0 {
                stream.advance(1.0 / 30.0);
            }
            if uploaded != Some(stream.generation()) {
                self.rebuild(stream)?;
                uploaded = Some(stream.generation());
                p.builds += 1;
            }
            let t1 = Instant::now();
            let job = self.shade()?;
            let t2 = Instant::now();
            p.frame_ms.push((t2 - t0).as_secs_f64() * 1e3);
            p.build_ms.push((t1 - t0).as_secs_f64() * 1e3);
            p.shade_ms.push((t2 - t1).as_secs_f64() * 1e3);
            if let Some(g) = job.gpu_ms {
                p.gpu.push(g);
            }
            p.brdf = job.stats.iter().map(|q| q[3] as u64).sum();
            p.light = job.stats.iter().map(|q| (q[1] + q[2]) as f64).sum();
            p.rays = job.rays.iter().map(|r| r[0] as u64).sum();
        }
        Ok(p)
    }
}

impl Played {
    /// The scene's row (means over the frames), printed.
    fn row(self, name: &str, frames: usize, shadows: bool) -> SceneRow {
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
        let (builds, brdf, light, rays) = (self.builds, self.brdf, self.light, self.rays);
        let row = SceneRow {
            scene: name.into(),
            visibility: if shadows { "on" } else { "off" },
            frames,
            builds,
            mean_frame_ms: mean(&self.frame_ms),
            mean_build_ms: mean(&self.build_ms),
            mean_shade_ms: mean(&self.shade_ms),
            shade_gpu_ms: (!self.gpu.is_empty()).then(|| mean(&self.gpu)),
            brdf_samples_per_frame: brdf,
            light_samples_per_frame: light,
            shadow_rays_per_frame: rays,
        };
        eprintln!(
            "  {name} (shadows {}): {frames} frames, {builds} builds, frame {:.2} ms (build {:.2} + shade {:.2}), BRDF samples/frame {brdf}, light samples/frame {light:.0}, shadow rays/frame {rays}",
            row.visibility, row.mean_frame_ms, row.mean_build_ms, row.mean_shade_ms
        );
        row
    }
}
