//! `envis bench`: speed measured as ratios against baselines run in the same process.
//!
//! Suite `speed`:
//! - shading throughput (samples evaluated per second) of the sphere at `--size`, `N_L + N_B`
//!   samples, for each strategy, as a ratio to the `brdf` strategy at the same budget;
//! - per-frame build time (CDF tables + face energies + pool) for face sizes 16..=`--max-face`,
//!   as a ratio to one plain streaming pass (sum of luminance) over the same texels, the
//!   memory-bound limit.
//!
//! Each figure is the median of `--repeat` runs. Results go to `DIR/bench-speed.json`.
//!
//! Suite `offset`: the effect of the per-pixel random start offset into the pool (`DIR/bench-offset.json`).
//!
//! Suite `flicker`: seed-to-seed movement of the image mean on a white furnace, per pool layout
//! (see [`flicker`]).
//!
//! Suite `gpu`: per-pass GPU times next to their CPU twins (see [`gpu`]).
//! Suite `scene`: per-frame cost of a static diffuse scene vs a dynamic glossy one (see [`gpu::scenes`]).
//!
//! Suite `motion`: reservoir resampling on an animated scene (see [`motion`]).
//!
//! Suite `ready`: how long a game-like Bevy app waits for its first lit frame (`bench/ready.rs`).
//!
//! Suite `accuracy`: error vs time over strategies, budgets, materials and maps (see [`accuracy`]).

pub mod accuracy;
mod accuracy_suite;
mod bevy_ibl;
pub mod chart;
pub mod flicker;
pub mod flip;
pub mod gpu;
pub mod motion;
mod offset;
mod popping;
mod ready;
mod speed;
pub mod tiles;
pub mod visibility;

use envis::envmap::{CubeMap, load::load_env, luminance};
use envis::error::{Error, Result};
use envis::render::{self, Settings, Strategy};
use envis::sampling::{CubeDistribution, LightPool, Material};
use std::path::PathBuf;
use std::time::Instant;

/// The benchmark suites of `envis bench --suite`.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum Suite {
    /// CPU build and shading throughput per strategy, build scaling against face size.
    Speed,
    /// Pool offsets: how much shared error a per-pixel pool offset removes.
    Offset,
    /// The accuracy-vs-time sweep (strategies x budgets x materials x maps).
    Accuracy,
    /// Seed-to-seed flicker of the image mean on a white furnace, per pool layout.
    Flicker,
    /// Temporal stability of integer vs fractional counts.
    Popping,
    /// GPU pass times of the WGSL stages and the Bevy pipeline.
    Gpu,
    /// Static diffuse vs dynamic glossy frame cost on the scene files.
    Scene,
    /// Shadow rays on the CPU: frame cost with and without, rays per second, BVH builds.
    Visibility,
    /// Reservoir resampling on an animated scene: per-frame error against each frame's own
    /// reference, rays and time, on the CPU, the WGSL passes and Bevy.
    Motion,
    /// envis beside Bevy's `GeneratedEnvironmentMapLight`: error and frame cost.
    BevyIbl,
    /// Time to the first lit frame of a game-like app, and what it waits on.
    Ready,
}
/// Prints the suite's command-line name (`bevy-ibl`), as `--suite` takes it.
impl std::fmt::Display for Suite {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let v = clap::ValueEnum::to_possible_value(self)
            .expect("every suite has a name (none is skipped)");
        f.write_str(v.get_name())
    }
}

#[derive(clap::Args, Clone, Debug)]
pub struct BenchArgs {
    /// Which benchmark suite to run.
    #[arg(long, value_enum, default_value_t = Suite::Speed)]
    pub suite: Suite,
    /// Environment for the shading benchmark.
    #[arg(long, default_value = "builtin:sky")]
    pub env: String,
    #[arg(long, default_value_t = 64)]
    pub face_size: usize,
    /// Image width (and height, unless --height) of the sphere.
    #[arg(long, default_value_t = 256)]
    pub size: usize,
    /// Image height (suite `gpu`; default: 9/16 of --size).
    #[arg(long)]
    pub height: Option<usize>,
    #[arg(long, default_value_t = 32)]
    pub light_samples: usize,
    #[arg(long, default_value_t = 32)]
    pub brdf_samples: usize,
    /// Largest face size in the build-time scaling sweep.
    #[arg(long, default_value_t = 1024)]
    pub max_face: usize,
    /// Runs per figure (the median is reported).
    #[arg(long, default_value_t = 5)]
    pub repeat: usize,
    /// Output directory (default: current directory).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Accuracy suite: also sweep every .exr/.hdr map in this folder.
    #[arg(long)]
    pub maps: Option<PathBuf>,
    /// Accuracy suite: a small sweep (a smoke test, under a minute).
    #[arg(long)]
    pub quick: bool,
    /// Accuracy and motion suites: do not also run on the GPU backend.
    #[arg(long)]
    pub cpu_only: bool,
    /// Motion suite: the animated scene file (default: `assets/scenes/motion.toml`).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Motion suite: run every configuration with this many seeds (the scene's, then the next
    /// ones) and report the means: a few pixels far off their reference dominate a
    /// sequence's relMSE, so one seed's figure can be 30% off another's.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub seeds: u32,
}

pub(crate) fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

pub use speed::streaming_pass;

pub fn run(a: BenchArgs) -> Result<()> {
    let dir = a.out.clone().unwrap_or_else(|| PathBuf::from("."));
    std::fs::create_dir_all(&dir).map_err(|e| Error::file(&dir, format!("cannot create: {e}")))?;
    match a.suite {
        Suite::Speed => speed::speed(a, dir),
        Suite::Offset => offset::offset(a, dir),
        Suite::Accuracy => accuracy_suite::accuracy_suite(a, dir),
        Suite::Flicker => flicker::run(a, &dir),
        Suite::Popping => popping::popping(a, dir),
        Suite::Visibility => visibility::run(a, dir),
        Suite::Motion => motion::run(a, dir),
        Suite::Gpu => gpu::run(a, dir),
        Suite::Scene => gpu::scenes(a, dir),
        Suite::BevyIbl => bevy_ibl::run(a, dir),
        Suite::Ready => ready::run(a, dir),
    }
}
