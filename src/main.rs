//! `envis` command line. The names of `render` and `reference` and their options are a contract
//! (outside checks call them): keep them stable.

use clap::{Args, Parser, Subcommand, ValueEnum};
use envis::envmap::load::{EnvSource, LoadedEnv, load_env};
use envis::error::{Error, Result};
use envis::render::{self, Settings, Strategy, output, reference};
use envis::sampling::{Counts, Heuristic, Material};
use std::path::PathBuf;

#[derive(Parser)]
#[command(
    name = "envis",
    version,
    about = "Real-time, unbiased importance sampling of dynamic HDR environment maps",
    args_conflicts_with_subcommands = true
)]
struct Cli {
    #[command(subcommand)]
    cmd: Option<Cmd>,
    /// Without a subcommand: the interactive demo.
    #[command(flatten)]
    demo: DemoArgs,
}

/// Options of the interactive demo (`envis` with no subcommand).
#[derive(Args, Clone)]
struct DemoArgs {
    /// Environment: builtin:sky[:HOURS] (animated), an .exr/.hdr file, or a directory of frames.
    #[arg(long, default_value = "builtin:sky:9")]
    env: String,
    /// A directory of .exr/.hdr frames, played in name order, looping.
    #[arg(long)]
    sequence: Option<PathBuf>,
    /// Frame rate of --sequence.
    #[arg(long, default_value_t = 24.0)]
    fps: f32,
    /// Maps to rotate and cross-fade (comma-separated files).
    #[arg(long, value_delimiter = ',')]
    carousel: Vec<PathBuf>,
    /// Cube face size in texels.
    #[arg(long, default_value_t = 128)]
    face_size: usize,
    /// Window size, WIDTHxHEIGHT.
    #[arg(long, default_value = "1280x720")]
    window: String,
    #[arg(long, default_value_t = 32)]
    light_samples: usize,
    #[arg(long, default_value_t = 32)]
    brdf_samples: usize,
    /// Scripted run for CI: take screenshots into DIR, write DIR/report.json, exit.
    #[arg(long)]
    script: Option<PathBuf>,
    /// A TOML scene file (objects, camera, environment, sampling; see assets/scenes/).
    #[arg(long)]
    scene: Option<PathBuf>,
}

#[derive(Subcommand)]
enum Cmd {
    /// Render a scene with Monte Carlo light + BRDF sampling and write a linear float32 EXR.
    Render(RenderArgs),
    /// Write the converged reference image (exact quadrature over every cube texel, f64).
    Reference(ReferenceArgs),
    /// Write an environment as an unfolded horizontal cube cross (EXR, or PNG preview).
    Cross(CrossArgs),
    /// Benchmarks (ratios against baselines run in the same process).
    Bench(envis::bench::BenchArgs),
}

#[derive(Args, Clone)]
struct SceneArgs {
    /// Environment: an .exr/.hdr file (2:1 lat-long or 4:3/3:4 cube cross), or builtin:sky[:HOURS].
    #[arg(long, default_value = "builtin:sky")]
    env: String,
    /// Cube face size in texels.
    #[arg(long, default_value_t = 64)]
    face_size: usize,
    /// Scene: `sphere` (the unit sphere, orthographic), or a TOML scene file (which then supplies
    /// the environment, camera, objects, materials and sampling settings; see assets/scenes/).
    #[arg(long, default_value = "sphere")]
    scene: String,
    /// Image width and height in pixels.
    #[arg(long, default_value_t = 256)]
    size: usize,
    #[arg(long, value_enum, default_value_t = BrdfArg::Diffuse)]
    brdf: BrdfArg,
    /// Albedo (diffuse albedo, or specular tint of phong / ggx).
    #[arg(long, default_value_t = 0.8)]
    albedo: f32,
    /// Phong exponent.
    #[arg(long, default_value_t = 150.0)]
    exponent: f32,
    /// GGX roughness alpha.
    #[arg(long, default_value_t = 0.2)]
    alpha: f32,
}

#[derive(Clone, Copy, ValueEnum)]
enum BrdfArg {
    Diffuse,
    Phong,
    Ggx,
}

#[derive(Clone, Copy, ValueEnum)]
enum BackendArg {
    /// The CPU renderer (the oracle).
    Cpu,
    /// The Bevy pipeline offscreen (no window): a sphere mesh -> Bevy's deferred G-buffer (24-bit
    /// normals, 8-bit materials) -> the envis GPU build and lighting pass.
    Gpu,
    /// The WGSL stages alone on a headless wgpu device, shading the same analytic G-buffer as
    /// `cpu` (same seed: the same image to float rounding).
    Wgpu,
}

#[derive(Args)]
struct RenderArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// N_L, light samples per pixel.
    #[arg(long, default_value_t = 32)]
    light_samples: usize,
    /// N_B, BRDF samples per pixel.
    #[arg(long, default_value_t = 32)]
    brdf_samples: usize,
    #[arg(long, value_enum, default_value_t = Strategy::Paper)]
    strategy: Strategy,
    #[arg(long, value_enum, default_value_t = Counts::Fractional)]
    counts: Counts,
    #[arg(long, value_enum, default_value_t = Heuristic::Balance)]
    mis: Heuristic,
    #[arg(long, default_value_t = 0)]
    seed: u32,
    /// M, pool samples per face (default: N_L).
    #[arg(long, default_value_t = 0)]
    pool: usize,
    /// Start each pixel at a random offset into the pool (decorrelates pixels).
    #[arg(long)]
    pixel_offset: bool,
    /// Let each pixel's material choose the light / BRDF split of the budget (`paper` only):
    /// diffuse -> light samples only, near-mirror -> BRDF samples only.
    #[arg(long)]
    material_budget: bool,
    #[arg(long, value_enum, default_value_t = BackendArg::Cpu)]
    backend: BackendArg,
    /// Output image (linear RGB float32 EXR).
    #[arg(long)]
    out: PathBuf,
    /// Write statistics (timings, samples, red/green/yellow/wasted) as JSON.
    #[arg(long)]
    stats: Option<PathBuf>,
    /// Also write a tone-mapped sRGB PNG preview.
    #[arg(long)]
    png: Option<PathBuf>,
}

#[derive(Args)]
struct ReferenceArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Quadrature refinement factor (sub-texel points scale with it).
    #[arg(long, default_value_t = 1.0)]
    refine: f64,
    #[arg(long)]
    out: PathBuf,
    #[arg(long)]
    stats: Option<PathBuf>,
    #[arg(long)]
    png: Option<PathBuf>,
}

#[derive(Args)]
struct CrossArgs {
    #[arg(long, default_value = "builtin:sky")]
    env: String,
    #[arg(long, default_value_t = 64)]
    face_size: usize,
    /// Output: .exr (linear) or .png (tone-mapped preview).
    #[arg(long)]
    out: PathBuf,
    /// Exposure for the PNG preview.
    #[arg(long, default_value_t = 1.0)]
    exposure: f32,
}

fn material(a: &SceneArgs) -> Result<Material> {
    if !(a.albedo.is_finite() && a.albedo >= 0.0) {
        return Err(Error::invalid(format!(
            "--albedo {} must be finite and >= 0",
            a.albedo
        )));
    }
    Ok(match a.brdf {
        BrdfArg::Diffuse => Material::diffuse(a.albedo),
        BrdfArg::Phong => {
            if !(a.exponent.is_finite() && a.exponent >= 0.0) {
                return Err(Error::invalid(format!(
                    "--exponent {} must be finite and >= 0",
                    a.exponent
                )));
            }
            Material::phong(a.albedo, a.exponent)
        }
        BrdfArg::Ggx => {
            if !(a.alpha.is_finite() && a.alpha > 0.0 && a.alpha <= 1.0) {
                return Err(Error::invalid(format!(
                    "--alpha {} must be in (0, 1]",
                    a.alpha
                )));
            }
            Material::ggx(a.albedo, a.alpha)
        }
    })
}

/// The environment, G-buffer and material of `--scene`: `sphere` (with the command-line
/// environment and material), or a TOML scene file, which supplies everything but the size.
/// What [`setup`] returns: the environment, the G-buffer, the material and the scene file.
type Setup = (
    LoadedEnv,
    Vec<Option<render::GPixel>>,
    Material,
    Option<envis::scene::Scene>,
);

fn setup(a: &SceneArgs) -> Result<Setup> {
    if a.size == 0 || a.size > 16384 {
        return Err(Error::invalid(format!(
            "--size {} out of range 1..=16384",
            a.size
        )));
    }
    if a.scene != "sphere" {
        if !a.scene.ends_with(".toml") {
            return Err(Error::invalid(format!(
                "unknown scene '{}' (expected: sphere, or a .toml scene file)",
                a.scene
            )));
        }
        let sc = envis::scene::Scene::load(std::path::Path::new(&a.scene))?;
        let src: EnvSource = sc.environment.parse()?;
        let env = load_env(&src, sc.file.environment.face_size)?;
        if env.report.total() > 0 {
            eprintln!("envis: {}: {}", sc.environment, env.report);
        }
        let gbuf = sc.gbuffer(a.size, a.size);
        return Ok((env, gbuf, sc.objects[0].material, Some(sc)));
    }
    let mat = material(a)?;
    let src: EnvSource = a.env.parse()?;
    let env = load_env(&src, a.face_size)?;
    if env.report.total() > 0 {
        eprintln!("envis: {}: {}", a.env, env.report);
    }
    Ok((env, render::sphere_gbuffer(a.size, a.size, mat), mat, None))
}

fn check_exr_path(p: &std::path::Path) -> Result<()> {
    match p.extension().and_then(|e| e.to_str()) {
        Some(e) if e.eq_ignore_ascii_case("exr") => Ok(()),
        _ => Err(Error::invalid(format!(
            "--out {}: output must be an .exr file",
            p.display()
        ))),
    }
}

fn write_json(path: &std::path::Path, v: &impl serde::Serialize) -> Result<()> {
    let s = serde_json::to_string_pretty(v).expect("stats serialise");
    std::fs::write(path, s + "\n").map_err(|e| Error::file(path, format!("cannot write: {e}")))
}

/// `--backend wgpu`: the WGSL stages on a headless wgpu device (the same shaders the Bevy app runs).
#[cfg(feature = "gpu")]
fn render_wgpu(
    map: &envis::envmap::CubeMap,
    gbuf: &[Option<render::GPixel>],
    size: usize,
    s: &Settings,
) -> Result<(render::Rendered, serde_json::Value)> {
    let ctx = envis::gpu::GpuContext::new()?;
    let (out, t) = envis::gpu::render_gpu(&ctx, map, gbuf, size, size, s)?;
    let extra = serde_json::json!({ "backend": "wgpu", "device": ctx.info.name, "device_backend": format!("{:?}", ctx.info.backend), "gpu_timings": t });
    Ok((out, extra))
}

#[cfg(not(feature = "gpu"))]
fn render_wgpu(
    _: &envis::envmap::CubeMap,
    _: &[Option<render::GPixel>],
    _: usize,
    _: &Settings,
) -> Result<(render::Rendered, serde_json::Value)> {
    Err(Error::invalid(
        "--backend wgpu: this envis was built without the `gpu` feature (cargo build --features gpu)",
    ))
}

/// `--backend gpu`: the Bevy app headless (no window), sphere mesh + deferred G-buffer. Pixels
/// off the sphere are 0, as in the CPU contract (the app's sky pass is off).
#[cfg(feature = "app")]
fn render_bevy(
    a: &SceneArgs,
    s: &Settings,
    scene: Option<&envis::scene::Scene>,
) -> Result<(render::Rendered, serde_json::Value)> {
    use envis::app::{EnvisMaterial, EnvisSettings, headless::HeadlessSphere};
    use envis::sampling::Lobe;
    use envis::stream::{EnvStream, StreamSource};
    let settings = EnvisSettings {
        sampling: *s,
        show_sky: false,
        ..Default::default()
    };
    if let Some(sc) = scene {
        let t0 = std::time::Instant::now();
        let mut app = HeadlessSphere::from_scene(sc, settings, a.size as u32)?;
        let data = app.capture();
        let mut stats = render::RenderStats::for_settings(a.size, a.size, s, s.pool_per_face());
        stats.shade_ms = t0.elapsed().as_secs_f64() * 1e3;
        let extra = serde_json::json!({ "backend": "gpu", "pipeline": "bevy (offscreen)", "scene": sc.path });
        return Ok((
            render::Rendered {
                image: envis::envmap::Image {
                    width: a.size,
                    height: a.size,
                    data,
                },
                stats,
            },
            extra,
        ));
    }
    let mat = material(a)?;
    let em = match mat.lobe {
        Lobe::None => EnvisMaterial::Lambert { albedo: mat.kd },
        Lobe::Phong { exponent } => EnvisMaterial::Phong {
            albedo: mat.ks,
            exponent,
        },
        Lobe::Ggx { alpha } => EnvisMaterial::Ggx {
            albedo: mat.ks,
            alpha,
        },
    };
    let source = match a.env.parse::<EnvSource>()? {
        EnvSource::Sky { hours } => StreamSource::Sky { hours, speed: 0.0 },
        EnvSource::File(p) => StreamSource::File(p),
    };
    EnvStream::open(source.clone(), a.face_size)?; // refuse a bad source here, with its error
    let t0 = std::time::Instant::now();
    let mut app = HeadlessSphere::new(source, a.face_size, em, settings, a.size as u32);
    let data = app.capture();
    let mut stats = render::RenderStats::for_settings(a.size, a.size, s, s.pool_per_face());
    stats.shade_ms = t0.elapsed().as_secs_f64() * 1e3;
    let c = app.counters();
    let t = app.app.world().resource::<envis::app::EnvisTimings>().get();
    let extra = serde_json::json!({
        "backend": "gpu",
        "pipeline": "bevy (offscreen)",
        "pass_times_ms": t,
        "note": "shade_ms is the wall time of the whole headless app (start-up, pipelines, frames); per-pixel sample counts are not read back",
        "distribution_builds": c.get(|c| &c.builds),
        "lighting_passes": c.get(|c| &c.lighting_passes),
    });
    let image = envis::envmap::Image {
        width: a.size,
        height: a.size,
        data,
    };
    Ok((render::Rendered { image, stats }, extra))
}

#[cfg(not(feature = "app"))]
fn render_bevy(
    _: &SceneArgs,
    _: &Settings,
    _: Option<&envis::scene::Scene>,
) -> Result<(render::Rendered, serde_json::Value)> {
    Err(Error::invalid(
        "--backend gpu: this envis was built without the `app` feature (cargo build --features app)",
    ))
}

#[cfg(feature = "app")]
fn run_demo(a: DemoArgs) -> Result<()> {
    use envis::stream::StreamSource;
    let scene = a
        .scene
        .as_deref()
        .map(envis::scene::Scene::load)
        .transpose()?;
    let source = if let Some(sc) = &scene {
        match StreamSource::parse(&sc.environment)? {
            StreamSource::Sky { hours, .. } => StreamSource::Sky {
                hours,
                speed: sc.file.environment.speed,
            },
            other => other,
        }
    } else if let Some(dir) = a.sequence {
        StreamSource::Sequence { dir, fps: a.fps }
    } else if !a.carousel.is_empty() {
        StreamSource::Carousel {
            paths: a.carousel,
            period: 8.0,
            fade: 2.0,
            spin: 0.05,
        }
    } else {
        StreamSource::parse(&a.env)?
    };
    // Refuse a bad source before opening a window, with its error.
    envis::stream::EnvStream::open(
        source.clone(),
        scene
            .as_ref()
            .map_or(a.face_size, |s| s.file.environment.face_size),
    )?;
    let (w, h) = a
        .window
        .split_once('x')
        .and_then(|(w, h)| Some((w.parse::<u32>().ok()?, h.parse::<u32>().ok()?)))
        .filter(|(w, h)| (64..=8192).contains(w) && (64..=8192).contains(h))
        .ok_or_else(|| {
            Error::invalid(format!(
                "--window {}: expected WIDTHxHEIGHT, e.g. 1280x720",
                a.window
            ))
        })?;
    let sampling = scene.as_ref().map_or(
        Settings {
            light_samples: a.light_samples,
            brdf_samples: a.brdf_samples,
            ..Default::default()
        },
        |s| s.settings,
    );
    sampling.validate()?;
    let face_size = scene
        .as_ref()
        .map_or(a.face_size, |s| s.file.environment.face_size);
    if let Some(d) = &a.script {
        std::fs::create_dir_all(d).map_err(|e| Error::file(d, format!("cannot create: {e}")))?;
    }
    let exit = envis::app::demo::run(envis::app::demo::DemoOptions {
        source,
        face_size,
        script: a.script,
        window: (w, h),
        sampling,
        scene,
    });
    match exit {
        bevy::app::AppExit::Success => Ok(()),
        bevy::app::AppExit::Error(c) => {
            Err(Error::invalid(format!("the demo exited with code {c}")))
        }
    }
}

#[cfg(not(feature = "app"))]
fn run_demo(_: DemoArgs) -> Result<()> {
    Err(Error::invalid(
        "the interactive demo needs the `app` feature (cargo run --release --features app); see `envis --help` for the commands",
    ))
}

fn run(cli: Cli) -> Result<()> {
    let Some(cmd) = cli.cmd else {
        return run_demo(cli.demo);
    };
    match cmd {
        Cmd::Render(r) => {
            check_exr_path(&r.out)?;
            let settings = Settings {
                light_samples: r.light_samples,
                brdf_samples: r.brdf_samples,
                pool_size: r.pool,
                strategy: r.strategy,
                counts: r.counts,
                mis: r.mis,
                seed: r.seed,
                pixel_offset: r.pixel_offset,
                material_budget: r.material_budget,
            };
            settings.validate()?;
            let (env, gbuf, _, scene) = setup(&r.scene)?;
            // A scene file supplies the sampling settings too.
            let settings = scene.as_ref().map_or(settings, |sc| sc.settings);
            let size = r.scene.size;
            let (mut out, extra) = match r.backend {
                BackendArg::Cpu => (
                    render::render(&env.cube, &gbuf, size, size, &settings)?,
                    serde_json::json!({ "backend": "cpu" }),
                ),
                BackendArg::Wgpu => render_wgpu(&env.cube, &gbuf, size, &settings)?,
                BackendArg::Gpu => render_bevy(&r.scene, &settings, scene.as_ref())?,
            };
            // What the loader clamped, plus anything the GPU's own sanitise pass found.
            out.stats.clamped_texels.add(env.report);
            output::write_exr(&r.out, &out.image)?;
            if let Some(p) = &r.png {
                output::write_png(p, &out.image, 1.0)?;
            }
            if let Some(p) = &r.stats {
                let mut v = serde_json::to_value(&out.stats).expect("stats serialise");
                if let (Some(o), Some(e)) = (v.as_object_mut(), extra.as_object()) {
                    o.extend(e.clone());
                }
                write_json(p, &v)?;
            }
            Ok(())
        }
        Cmd::Reference(r) => {
            check_exr_path(&r.out)?;
            if !(r.refine.is_finite() && r.refine > 0.0) {
                return Err(Error::invalid("--refine must be > 0"));
            }
            let (env, gbuf, mat, _) = setup(&r.scene)?;
            let t = std::time::Instant::now();
            let (img, _) =
                reference::reference_image(&env.cube, &gbuf, r.scene.size, r.scene.size, r.refine);
            let ms = t.elapsed().as_secs_f64() * 1e3;
            output::write_exr(&r.out, &img)?;
            if let Some(p) = &r.png {
                output::write_png(p, &img, 1.0)?;
            }
            if let Some(p) = &r.stats {
                let k = reference::subdivision(r.scene.size, &mat, r.refine);
                write_json(
                    p,
                    &serde_json::json!({ "reference_ms": ms, "subtexel_points_per_axis": k, "clamped_texels": env.report }),
                )?;
            }
            Ok(())
        }
        Cmd::Cross(c) => {
            let env = load_env(&c.env.parse()?, c.face_size)?;
            if env.report.total() > 0 {
                eprintln!("envis: {}: {}", c.env, env.report);
            }
            let img = envis::envmap::cube_to_cross(&env.cube);
            match c
                .out
                .extension()
                .and_then(|e| e.to_str())
                .map(|e| e.to_ascii_lowercase())
                .as_deref()
            {
                Some("exr") => output::write_exr(&c.out, &img),
                Some("png") => output::write_png(&c.out, &img, c.exposure),
                _ => Err(Error::invalid(format!(
                    "--out {}: expected .exr or .png",
                    c.out.display()
                ))),
            }
        }
        Cmd::Bench(b) => envis::bench::run(b),
    }
}

fn main() {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            use clap::error::ErrorKind;
            if matches!(
                e.kind(),
                ErrorKind::DisplayHelp
                    | ErrorKind::DisplayVersion
                    | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
            ) {
                e.exit();
            }
            // One line: clap's first line names the problem.
            let text = e.render().to_string();
            let first = text
                .lines()
                .find(|l| !l.trim().is_empty())
                .unwrap_or("invalid arguments");
            eprintln!("envis: {}", first.trim_start_matches("error: "));
            std::process::exit(2);
        }
    };
    if let Err(e) = run(cli) {
        eprintln!("envis: error: {e}");
        std::process::exit(1);
    }
}
