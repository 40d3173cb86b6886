//! `envis bench`: speed measured as ratios against baselines run in the same process.
//!
//! Suite `speed`:
//! - shading throughput (samples evaluated per second) of the sphere at `--size`, `N_L + N_B`
//!   samples, for each strategy, as a ratio to the `brdf` strategy at the same budget;
//! - per-frame build time (CDF tables + face energies + pool) for face sizes 16..=`--max-face`,
//!   as a ratio to one plain streaming pass (sum of luminance) over the same texels, the
//!   memory-bound limit.
//! Each figure is the median of `--repeat` runs. Results go to `DIR/bench-speed.json`.

use crate::envmap::{load::load_env, luminance, CubeMap};
use crate::error::{Error, Result};
use crate::render::{self, Settings, Strategy};
use crate::sampling::{CubeDistribution, LightPool, Material};
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args, Clone, Debug)]
pub struct BenchArgs {
    /// Which benchmark suite to run.
    #[arg(long, default_value = "speed")]
    pub suite: String,
    /// Environment for the shading benchmark.
    #[arg(long, default_value = "builtin:sky")]
    pub env: String,
    #[arg(long, default_value_t = 64)]
    pub face_size: usize,
    /// Image width and height of the sphere.
    #[arg(long, default_value_t = 256)]
    pub size: usize,
    #[arg(long, default_value_t = 32)]
    pub light_samples: usize,
    #[arg(long, default_value_t = 32)]
    pub brdf_samples: usize,
    /// Largest face size in the build-time scaling sweep.
    #[arg(long, default_value_t = 512)]
    pub max_face: usize,
    /// Runs per figure (the median is reported).
    #[arg(long, default_value_t = 5)]
    pub repeat: usize,
    /// Output directory (default: current directory).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

/// One plain pass over the texels (the memory-bound limit the build is compared with).
pub fn streaming_pass(map: &CubeMap) -> f64 {
    use rayon::prelude::*;
    map.data.par_iter().map(|&c| luminance(c) as f64).sum()
}

pub fn run(a: BenchArgs) -> Result<()> {
    if a.suite != "speed" {
        return Err(Error::invalid(format!("unknown bench suite '{}' (available: speed)", a.suite)));
    }
    let dir = a.out.clone().unwrap_or_else(|| PathBuf::from("."));
    std::fs::create_dir_all(&dir).map_err(|e| Error::file(&dir, format!("cannot create: {e}")))?;
    let repeat = a.repeat.max(1);
    let env = load_env(&a.env.parse()?, a.face_size)?;
    let gbuf = render::sphere_gbuffer(a.size, a.size, Material::diffuse(0.8));
    let threads = rayon::current_num_threads();
    eprintln!("envis bench speed: {} threads, sphere {}^2, {}+{} samples, {} face {}^2", threads, a.size, a.light_samples, a.brdf_samples, a.env, a.face_size);

    let mut shading = Vec::new();
    let mut base_sps = 0.0;
    for strategy in [Strategy::Brdf, Strategy::Paper, Strategy::Global, Strategy::Light] {
        let s = Settings { light_samples: a.light_samples, brdf_samples: a.brdf_samples, strategy, ..Default::default() };
        let mut sps = Vec::new();
        let mut build = Vec::new();
        let mut shade = Vec::new();
        let mut samples = 0;
        for r in 0..repeat {
            let out = render::render(&env.cube, &gbuf, a.size, a.size, &Settings { seed: r as u32, ..s })?;
            sps.push(out.stats.samples_per_second);
            build.push(out.stats.build_ms);
            shade.push(out.stats.shade_ms);
            samples = out.stats.samples_evaluated;
        }
        let m = median(sps);
        if strategy == Strategy::Brdf {
            base_sps = m;
        }
        let row = serde_json::json!({
            "strategy": strategy.name(), "samples_per_second": m, "ratio_to_brdf": m / base_sps,
            "build_ms": median(build), "shade_ms": median(shade), "samples_evaluated": samples,
        });
        eprintln!("  shade {:>6}: {:>12.0} samples/s  ({:.2}x brdf)  build {:.2} ms  shade {:.1} ms", strategy.name(), m, m / base_sps, row["build_ms"].as_f64().unwrap(), row["shade_ms"].as_f64().unwrap());
        shading.push(row);
    }

    let mut scaling = Vec::new();
    let mut n = 16;
    while n <= a.max_face {
        let map = crate::envmap::sky::sky_cube(n, 10.0);
        let texels = 6 * n * n;
        let mut tb = Vec::new();
        let mut tp = Vec::new();
        let mut ts = Vec::new();
        for r in 0..repeat {
            let t = Instant::now();
            let d = CubeDistribution::build(&map);
            tb.push(t.elapsed().as_secs_f64() * 1e3);
            let t = Instant::now();
            let p = LightPool::build(&map, &d, a.light_samples.max(1), r as u32);
            tp.push(t.elapsed().as_secs_f64() * 1e3);
            std::hint::black_box(p);
            let t = Instant::now();
            std::hint::black_box(streaming_pass(&map));
            ts.push(t.elapsed().as_secs_f64() * 1e3);
        }
        let (b, p, s) = (median(tb), median(tp), median(ts));
        eprintln!("  build face {n:>4}^2: cdf {b:8.3} ms  pool {p:7.3} ms  stream {s:7.3} ms  cdf/stream {:6.1}x  ns/texel {:.2}", b / s, b * 1e6 / texels as f64);
        scaling.push(serde_json::json!({
            "face_size": n, "texels": texels, "cdf_ms": b, "pool_ms": p, "pool_per_face": a.light_samples.max(1),
            "stream_ms": s, "cdf_over_stream": b / s, "cdf_ns_per_texel": b * 1e6 / texels as f64,
        }));
        n *= 2;
    }
    let report = serde_json::json!({
        "suite": "speed", "threads": threads, "env": a.env, "face_size": a.face_size, "size": a.size,
        "light_samples": a.light_samples, "brdf_samples": a.brdf_samples, "repeat": repeat,
        "shading": shading, "build_scaling": scaling,
    });
    let path = dir.join("bench-speed.json");
    std::fs::write(&path, serde_json::to_string_pretty(&report).unwrap() + "\n").map_err(|e| Error::file(&path, format!("cannot write: {e}")))?;
    eprintln!("wrote {}", path.display());
    Ok(())
}
