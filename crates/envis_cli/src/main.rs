//! `envis` command line. The names of `render` and `reference` and their options are a contract
//! (outside checks call them): keep them stable.

mod cli;

use clap::{Args, Parser, Subcommand, ValueEnum};
use envis::error::Result;
use envis::render::{PoolLayout, Settings, Strategy};
use envis::sampling::{Counts, Heuristic};
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
    /// Size of the panels relative to their normal size (egui's zoom factor): below 1 they leave
    /// a small window's scene visible (the scripted test runs a 512 x 320 window at 0.5).
    #[arg(long, default_value_t = 1.0)]
    ui_scale: f32,
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
    /// Render an animated scene file frame by frame, with reservoir resampling across pixels
    /// and frames: DIR/frame_0000.exr ... (linear), and per-frame statistics.
    Sequence(SequenceArgs),
    /// Benchmarks (ratios against baselines run in the same process).
    Bench(envis_cli::bench::BenchArgs),
}

#[derive(Args)]
struct SequenceArgs {
    /// The TOML scene file (its `[animation]` table moves it).
    #[arg(long)]
    scene: std::path::PathBuf,
    /// Frames to render (frame k is at k / fps seconds).
    #[arg(long)]
    frames: u32,
    /// Output directory (created if missing).
    #[arg(long)]
    out: std::path::PathBuf,
    /// `off` (today's estimator every frame), `temporal`, or `spatiotemporal` (the default).
    #[arg(long, value_enum, default_value_t = envis::render::resampling::ResamplingMode::Spatiotemporal)]
    resampling: envis::render::resampling::ResamplingMode,
    /// Biased reuse: 1/M MIS weights, no visibility in the weights (at most 2 shadow rays per pixel).
    #[arg(long)]
    biased: bool,
    /// `cpu`: the oracle; `wgpu`: the WGSL passes on a headless device, the same frames to float
    /// rounding; `gpu`: the scene's meshes in a headless Bevy app, resampled by the
    /// `EnvironmentResampling` pass (Bevy's G-buffer and motion vectors; its counts read back).
    #[arg(long, value_enum, default_value_t = BackendArg::Cpu)]
    backend: BackendArg,
    /// Image width and height in pixels.
    #[arg(long, default_value_t = 256)]
    size: usize,
    /// Overrides the scene file's seed.
    #[arg(long)]
    seed: Option<u32>,
    /// N_L (the candidates per pixel per frame with resampling); default: the scene file's.
    #[arg(long)]
    light_samples: Option<usize>,
    /// N_B; default: the scene file's.
    #[arg(long)]
    brdf_samples: Option<usize>,
    /// Shadow rays: overrides the scene file's `shadows` (`--shadows` is the same flag, under
    /// the settings' name).
    #[arg(long, value_enum, visible_alias = "shadows")]
    visibility: Option<envis::visibility::ShadowRays>,
    /// Write the settings and one object per frame as JSON.
    #[arg(long)]
    stats: Option<std::path::PathBuf>,
    /// Also write DIR/frame_0000.png ... (tone-mapped previews).
    #[arg(long)]
    png: bool,
}

#[derive(Args, Clone)]
struct SceneArgs {
    /// Environment: an .exr/.hdr file (2:1 lat-long or 4:3/3:4 cube cross), or builtin:sky[:HOURS].
    #[arg(long, default_value = "builtin:sky")]
    env: String,
    /// Face size of the sampling distribution, in texels (with `--radiance full`, a sampling
    /// choice only: radiance comes from the map at its own resolution).
    #[arg(long, default_value_t = 64)]
    face_size: usize,
    /// Where light and BRDF samples read radiance: `full`, the map at its own resolution (a
    /// lat-long's width / 4 per cube face, a cross's face, 128 for the built-in sky), as the Bevy
    /// pass reads the image; `distribution`, the `--face-size` map that gives the densities (what
    /// `render` and `reference` did before 2026-12-05).
    #[arg(long, value_enum, default_value_t = RadianceArg::Full)]
    radiance: RadianceArg,
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
    /// Shadow rays for every light and BRDF sample (CPU): `auto` (default, or the scene file's
    /// `shadows`) casts them when some object can shadow a visible point (`--shadows` is the
    /// same flag, under the settings' name).
    #[arg(long, value_enum, visible_alias = "shadows")]
    visibility: Option<envis::visibility::ShadowRays>,
    /// With a scene file: the pose at this time, in seconds on its `[animation]` clock (the
    /// camera orbited, objects moved, the sky's clock advanced).
    #[arg(long, default_value_t = 0.0)]
    time: f32,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum RadianceArg {
    Full,
    Distribution,
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
    /// The MIS heuristic (`--heuristic` is the same flag, under the settings' name).
    #[arg(long, value_enum, default_value_t = Heuristic::Balance, visible_alias = "heuristic")]
    mis: Heuristic,
    #[arg(long, default_value_t = 0)]
    seed: u32,
    /// M, pool samples per face (default: N_L; `--pool-size` is the same flag, under the
    /// settings' name).
    #[arg(long, default_value_t = 0, visible_alias = "pool-size")]
    pool: usize,
    /// How pixels share the pool: `shared` (the paper's), `offset` (a random start per pixel),
    /// `blocks` (one of K independent pools per pixel).
    #[arg(long, value_enum, default_value_t = Settings::default().pool_layout)]
    pool_layout: PoolLayout,
    /// K, the independent pools of `--pool-layout blocks`.
    #[arg(long, default_value_t = envis::render::DEFAULT_POOL_BLOCKS)]
    pool_blocks: usize,
    /// The same as `--pool-layout offset` (kept for scripts written before `--pool-layout`).
    #[arg(long, hide = true, conflicts_with = "pool_layout")]
    pixel_offset: bool,
    /// K: cut each cube face into K x K tiles, each weighted and sampled on its own (1: the
    /// paper's whole faces). Tiles differ by one texel when K does not divide the face size.
    #[arg(long, default_value_t = Settings::default().tiles)]
    tiles: usize,
    /// With tiles: `face` (the paper's counts per face, each sample drawing its tile) or `tile`
    /// (the paper's counts per tile: at least one sample per lit tile).
    #[arg(long, value_enum, default_value_t = Settings::default().tile_counts)]
    tile_counts: envis::sampling::TileCounts,
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

fn run(cli: Cli) -> Result<()> {
    let Some(cmd) = cli.cmd else {
        return cli::demo::run_demo(cli.demo);
    };
    match cmd {
        Cmd::Render(r) => cli::commands::render(r),
        Cmd::Reference(r) => cli::commands::reference(r),
        Cmd::Cross(c) => cli::commands::cross(c),
        Cmd::Sequence(q) => cli::sequence::sequence(q),
        Cmd::Bench(b) => envis_cli::bench::run(b),
    }
}

fn main() {
    cli::one_line_panics();
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
