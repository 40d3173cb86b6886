//! Suite `speed`: shading throughput per strategy against the `brdf` strategy, and the per-frame
//! build against one streaming pass over the same texels.

use super::*;

/// One plain pass over the texels (the memory-bound limit the build is compared with).
pub fn streaming_pass(map: &CubeMap) -> f64 {
    use rayon::prelude::*;
    map.data.par_iter().map(|&c| luminance(c) as f64).sum()
}

pub(super) fn speed(a: BenchArgs, dir: PathBuf) -> Result<()> {
    let repeat = a.repeat.max(1);
    let env = load_env(&a.env.parse()?, a.face_size)?;
    let gbuf = render::sphere_gbuffer(a.size, a.size, Material::diffuse(0.8));
    let threads = rayon::current_num_threads();
    eprintln!(
        "envis bench speed: {} threads, sphere {}^2, {}+{} samples, {} face {}^2",
        threads, a.size, a.light_samples, a.brdf_samples, a.env, a.face_size
    );

    let shading = shading_rows(&a, &env.cube, &gbuf, repeat)?;
    let scaling = build_scaling(&a, repeat);
    let pool_scaling = pool_scaling(repeat);
    let report = serde_json::json!({
        "suite": "speed", "threads": threads, "env": a.env, "face_size": a.face_size, "size": a.size,
        "light_samples": a.light_samples, "brdf_samples": a.brdf_samples, "repeat": repeat,
        "shading": shading, "build_scaling": scaling, "pool_scaling": pool_scaling,
    });
    let path = dir.join("bench-speed.json");
    envis::render::output::write_json(&path, &report)?;
    let (svg, png) = scaling_plot(&scaling).write(&dir, "build-scaling")?;
    let (psvg, ppng) = pool_chart(&pool_scaling).write(&dir, "pool-scaling")?;
    eprintln!("wrote {}, {svg}, {png}, {psvg} and {ppng}", path.display());
    Ok(())
}

/// Samples per second of each strategy shading the sphere (median of `repeat` seeds), and each
/// one's ratio to BRDF sampling alone.
fn shading_rows(
    a: &BenchArgs,
    map: &CubeMap,
    gbuf: &[Option<render::GPixel>],
    repeat: usize,
) -> Result<Vec<serde_json::Value>> {
    let mut shading = Vec::new();
    let mut base_sps = 0.0;
    for strategy in [
        Strategy::Brdf,
        Strategy::Paper,
        Strategy::Global,
        Strategy::Light,
    ] {
        let s = Settings {
            light_samples: a.light_samples,
            brdf_samples: a.brdf_samples,
            strategy,
            ..Default::default()
        };
        let runs = ShadingRuns::measure(a, map, gbuf, repeat, s)?;
        let m = median(runs.sps);
        if strategy == Strategy::Brdf {
            base_sps = m;
        }
        let row = serde_json::json!({
            "strategy": strategy.to_string(), "samples_per_second": m, "ratio_to_brdf": m / base_sps,
            "build_ms": median(runs.build), "shade_ms": median(runs.shade), "samples_evaluated": runs.samples,
        });
        eprintln!(
            "  shade {:>6}: {:>12.0} samples/s  ({:.2}x brdf)  build {:.2} ms  shade {:.1} ms",
            strategy.to_string(),
            m,
            m / base_sps,
            row["build_ms"].as_f64().unwrap(),
            row["shade_ms"].as_f64().unwrap()
        );
        shading.push(row);
    }

    Ok(shading)
}

/// One strategy's figures from each of `repeat` seeds shading the sphere.
struct ShadingRuns {
    sps: Vec<f64>,
    build: Vec<f64>,
    shade: Vec<f64>,
    /// Samples evaluated by the last run.
    samples: u64,
}

impl ShadingRuns {
    /// Renders the sphere `gbuf` in `map` with settings `s` and seeds `0..repeat`.
    fn measure(
        a: &BenchArgs,
        map: &CubeMap,
        gbuf: &[Option<render::GPixel>],
        repeat: usize,
        s: Settings,
    ) -> Result<Self> {
        let mut runs = ShadingRuns {
            sps: Vec::new(),
            build: Vec::new(),
            shade: Vec::new(),
            samples: 0,
        };
        for r in 0..repeat {
            let out = render::render(
                map,
                gbuf,
                a.size,
                a.size,
                &Settings {
                    seed: r as u32,
                    ..s
                },
            )?;
            runs.sps.push(out.stats.samples_per_second);
            runs.build.push(out.stats.build_ms);
            runs.shade.push(out.stats.shade_ms);
            runs.samples = out.stats.samples_evaluated;
        }
        Ok(runs)
    }
}

/// Per face size from 16² to `--max-face`: the CDF build fresh and per frame, the pool, and one
/// plain streaming pass over the same texels (medians of `repeat`).
fn build_scaling(a: &BenchArgs, repeat: usize) -> Vec<serde_json::Value> {
    let mut scaling = Vec::new();
    let mut n = 16;
    while n <= a.max_face {
        let map = envis::envmap::sky::sky_cube(n, 10.0);
        let texels = 6 * n * n;
        let mut tb = Vec::new();
        let mut tr = Vec::new();
        let mut tp = Vec::new();
        let mut ts = Vec::new();
        let mut frame = CubeDistribution::build(&map);
        for r in 0..repeat {
            let t = Instant::now();
            let d = CubeDistribution::build(&map);
            tb.push(t.elapsed().as_secs_f64() * 1e3);
            // A stream's frame: the same build into the last frame's memory.
            let t = Instant::now();
            frame.rebuild(&map);
            tr.push(t.elapsed().as_secs_f64() * 1e3);
            let t = Instant::now();
            let p = LightPool::build(&map, &d, a.light_samples.max(1), r as u32);
            tp.push(t.elapsed().as_secs_f64() * 1e3);
            std::hint::black_box(p);
            let t = Instant::now();
            std::hint::black_box(streaming_pass(&map));
            ts.push(t.elapsed().as_secs_f64() * 1e3);
        }
        let (b, rb, p, s) = (median(tb), median(tr), median(tp), median(ts));
        eprintln!(
            "  build face {n:>4}^2: cdf {b:8.3} ms (per frame, reusing memory: {rb:8.3})  pool {p:7.3} ms  stream {s:7.3} ms  cdf/stream {:6.1}x (per frame {:5.1}x)  ns/texel {:.2}",
            b / s,
            rb / s,
            b * 1e6 / texels as f64
        );
        scaling.push(serde_json::json!({
            "face_size": n, "texels": texels, "cdf_ms": b, "rebuild_ms": rb, "pool_ms": p, "pool_per_face": a.light_samples.max(1),
            "stream_ms": s, "cdf_over_stream": b / s, "rebuild_over_stream": rb / s, "cdf_ns_per_texel": b * 1e6 / texels as f64,
        }));
        n *= 2;
    }
    scaling
}

/// The pool against M (samples per face) on a fixed 64^2 map: linear in 6 M once M passes the
/// per-face setup.
fn pool_scaling(repeat: usize) -> Vec<serde_json::Value> {
    let map = envis::envmap::sky::sky_cube(64, 10.0);
    let dist = CubeDistribution::build(&map);
    let mut pool_scaling = Vec::new();
    for m in [8usize, 32, 128, 512, 2048, 8192] {
        let times: Vec<f64> = (0..repeat)
            .map(|r| {
                let t = Instant::now();
                std::hint::black_box(LightPool::build(&map, &dist, m, r as u32));
                t.elapsed().as_secs_f64() * 1e3
            })
            .collect();
        let ms = median(times);
        eprintln!(
            "  pool M = {m:>5} per face (64^2 faces): {ms:8.3} ms  {:.1} ns/sample",
            ms * 1e6 / (6 * m) as f64
        );
        pool_scaling.push(serde_json::json!({ "pool_per_face": m, "samples": 6 * m, "pool_ms": ms, "ns_per_sample": ms * 1e6 / (6 * m) as f64 }));
    }
    pool_scaling
}

/// The pool's build time against its size (log-log), from [`pool_scaling`]'s rows.
fn pool_chart(pool_scaling: &[serde_json::Value]) -> accuracy::Chart {
    let pool_points = pool_scaling
        .iter()
        .map(|r| {
            (
                r["samples"].as_f64().unwrap_or(0.0),
                r["pool_ms"].as_f64().unwrap_or(0.0),
            )
        })
        .collect();
    accuracy::Chart {
        title: "Light-sample pool build vs pool size (CPU, 64^2 faces)".into(),
        xlabel: "pool samples (6 M)",
        ylabel: "ms (median)",
        xlog: true,
        ylog: true,
        series: vec![accuracy::Series {
            name: "pool build".into(),
            color: "#2ca02c",
            points: pool_points,
            dashed: false,
        }],
    }
}

/// Build time against texel count (log-log): the CDF build (into fresh memory, and into the
/// last frame's as a stream does), the pool and one plain streaming pass over the same texels
/// (the memory-bound limit), from the speed suite's scaling rows.
fn scaling_plot(rows: &[serde_json::Value]) -> accuracy::Chart {
    use accuracy::{Chart, Series};
    let col = |k: &str| -> Vec<(f64, f64)> {
        rows.iter()
            .map(|r| {
                (
                    r["texels"].as_f64().unwrap_or(0.0),
                    r[k].as_f64().unwrap_or(0.0),
                )
            })
            .collect()
    };
    let series = vec![
        Series {
            name: "CDF build (fresh memory)".into(),
            color: "#d62728",
            points: col("cdf_ms"),
            dashed: true,
        },
        Series {
            name: "CDF build (a stream's frame)".into(),
            color: "#9467bd",
            points: col("rebuild_ms"),
            dashed: false,
        },
        Series {
            name: "light pool".into(),
            color: "#2ca02c",
            points: col("pool_ms"),
            dashed: false,
        },
        Series {
            name: "streaming pass".into(),
            color: "#1f77b4",
            points: col("stream_ms"),
            dashed: false,
        },
    ];
    Chart {
        title: "Per-frame build time vs texels (CPU)".into(),
        xlabel: "texels (6 N^2)",
        ylabel: "ms (median)",
        xlog: true,
        ylog: true,
        series,
    }
}
