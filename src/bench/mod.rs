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
//! Suite `accuracy`: error vs time over strategies, budgets, materials and maps (see [`accuracy`]).

pub mod accuracy;
pub mod chart;
pub mod flicker;
pub mod flip;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod tiles;
pub mod visibility;

use crate::envmap::{CubeMap, load::load_env, luminance};
use crate::error::{Error, Result};
use crate::render::{self, Settings, Strategy};
use crate::sampling::{CubeDistribution, LightPool, Material};
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
    /// GPU pass times of the WGSL stages and the Bevy pipeline (feature `gpu`).
    Gpu,
    /// Static diffuse vs dynamic glossy frame cost on the scene files (feature `gpu`).
    Scene,
    /// Shadow rays on the CPU: frame cost with and without, rays per second, BVH builds.
    Visibility,
}
crate::vocab::display_as_value_enum!(Suite);

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
    /// Accuracy suite: do not also time each point on the GPU backend.
    #[arg(long)]
    pub cpu_only: bool,
}

pub(crate) fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

/// One plain pass over the texels (the memory-bound limit the build is compared with).
pub fn streaming_pass(map: &CubeMap) -> f64 {
    use rayon::prelude::*;
    map.data.par_iter().map(|&c| luminance(c) as f64).sum()
}

pub fn run(a: BenchArgs) -> Result<()> {
    let dir = a.out.clone().unwrap_or_else(|| PathBuf::from("."));
    std::fs::create_dir_all(&dir).map_err(|e| Error::file(&dir, format!("cannot create: {e}")))?;
    match a.suite {
        Suite::Speed => speed(a, dir),
        Suite::Offset => offset(a, dir),
        Suite::Accuracy => accuracy_suite(a, dir),
        Suite::Flicker => flicker::run(a, &dir),
        Suite::Popping => popping(a, dir),
        Suite::Visibility => visibility::run(a, dir),
        #[cfg(feature = "gpu")]
        Suite::Gpu => gpu::run(a, dir),
        #[cfg(feature = "gpu")]
        Suite::Scene => gpu::scenes(a, dir),
        #[cfg(not(feature = "gpu"))]
        s @ (Suite::Gpu | Suite::Scene) => Err(Error::invalid(format!(
            "bench suite '{s}': this envis was built without the `gpu` feature"
        ))),
    }
}

/// Suite `popping`: temporal stability of integer vs fractional counts (the seed's "smooth
/// transitions"). The built-in sun moves from 9h to 11h over `frames` frames; every frame uses the
/// same seed, so frame-to-frame change comes only from the environment and the counts. For each
/// mode: mean |change| per pixel relative to the reference's own mean |change| (1 = as smooth as
/// the truth), and the fraction of (pixel, frame) pairs that jump by more than 10% of the pixel
/// while the reference moves by less than 1% (discontinuities). Writes `popping.json`, a plot of
/// the change per frame (`popping.svg` / `.png`) and PNG strips of 6 frames per mode.
fn popping(a: BenchArgs, dir: PathBuf) -> Result<()> {
    let frames = if a.quick { 8 } else { 48 };
    let (size, face) = (a.size.min(64), a.face_size.min(32));
    let mat = Material::diffuse(0.8);
    let gbuf = render::sphere_gbuffer(size, size, mat);
    let idx: Vec<usize> = (0..gbuf.len()).filter(|&i| gbuf[i].is_some()).collect();
    let lum = |c: glam::Vec3| crate::envmap::luminance(c) as f64;
    let hours = |t: usize| 9.0 + 2.0 * t as f32 / (frames - 1) as f32;
    let maps: Vec<crate::envmap::CubeMap> = (0..frames)
        .map(|t| crate::envmap::sky::sky_cube(face, hours(t)))
        .collect();
    let refs: Vec<Vec<f64>> = maps
        .iter()
        .map(|m| {
            crate::render::reference::reference_image(m, &gbuf, size, size, 1.0)
                .1
                .iter()
                .map(|&c| crate::envmap::luminance_f64(c))
                .collect()
        })
        .collect();
    let ref_change: f64 = (1..frames)
        .map(|t| {
            idx.iter()
                .map(|&i| (refs[t][i] - refs[t - 1][i]).abs())
                .sum::<f64>()
        })
        .sum::<f64>();
    let np = idx.len().max(1) as f64;
    let per_frame = |f: &dyn Fn(usize) -> f64| -> Vec<(f64, f64)> {
        (1..frames).map(|t| (t as f64, f(t) / np)).collect()
    };
    let mut series = vec![accuracy::Series {
        name: "reference".into(),
        color: "#000000",
        points: per_frame(&|t| {
            idx.iter()
                .map(|&i| (refs[t][i] - refs[t - 1][i]).abs())
                .sum()
        }),
        dashed: true,
    }];
    let mut rows = Vec::new();
    for (name, counts, color) in [
        ("fractional", crate::sampling::Counts::Fractional, "#d62728"),
        ("integer", crate::sampling::Counts::Integer, "#ff7f0e"),
    ] {
        let s = Settings {
            light_samples: a.light_samples,
            brdf_samples: a.brdf_samples,
            counts,
            seed: 1,
            ..Default::default()
        };
        let imgs: Vec<crate::envmap::Image> = maps
            .iter()
            .map(|m| render::render(m, &gbuf, size, size, &s).map(|o| o.image))
            .collect::<Result<_>>()?;
        let (mut change, mut jumps, mut pairs) = (0.0, 0usize, 0usize);
        for t in 1..frames {
            for &i in &idx {
                let (x0, x1) = (lum(imgs[t - 1].data[i]), lum(imgs[t].data[i]));
                let d = (x1 - x0).abs();
                change += d;
                pairs += 1;
                let r = (refs[t][i] - refs[t - 1][i]).abs();
                if d > 0.1 * x0.max(x1).max(1e-6) && r < 0.01 * refs[t][i].max(1e-6) {
                    jumps += 1;
                }
            }
        }
        series.push(accuracy::Series {
            name: format!("{name} counts"),
            color,
            points: per_frame(&|t| {
                idx.iter()
                    .map(|&i| (lum(imgs[t].data[i]) - lum(imgs[t - 1].data[i])).abs())
                    .sum()
            }),
            dashed: false,
        });
        let ratio = change / ref_change.max(1e-12);
        let jump_frac = jumps as f64 / pairs.max(1) as f64;
        eprintln!(
            "  {name:10}: mean |frame change| = {ratio:.2} x the reference's; discontinuities {:.3}% of pixel-frames",
            100.0 * jump_frac
        );
        // Strip of 6 frames, spread over the animation.
        let picks: Vec<usize> = (0..6).map(|k| k * (frames - 1) / 5).collect();
        let mut strip = crate::envmap::Image::new(6 * size, size);
        for (k, &t) in picks.iter().enumerate() {
            for y in 0..size {
                for x in 0..size {
                    strip.data[y * 6 * size + k * size + x] = imgs[t].get(x, y);
                }
            }
        }
        crate::render::output::write_png(
            &dir.join(format!("popping-strip-{name}.png")),
            &strip,
            1.0,
        )?;
        rows.push(serde_json::json!({ "counts": name, "change_over_reference": ratio, "discontinuity_fraction": jump_frac, "strip_frames": picks }));
    }
    let report = serde_json::json!({ "suite": "popping", "frames": frames, "hours": [9.0, 11.0], "size": size, "face_size": face, "light_samples": a.light_samples, "brdf_samples": a.brdf_samples, "seed": "1 for every frame", "rows": rows });
    let path = dir.join("popping.json");
    crate::render::output::write_json(&path, &report)?;
    let chart = accuracy::Chart {
        title: "Frame-to-frame change, sun moving 9h -> 11h (same seed every frame)".into(),
        xlabel: "frame",
        ylabel: "mean |luminance change| per pixel",
        xlog: false,
        ylog: false,
        series,
    };
    let (svg, png) = chart.write(&dir, "popping")?;
    eprintln!(
        "wrote {}, {svg}, {png} and popping-strip-*.png",
        path.display()
    );
    Ok(())
}

/// The sweep's progress on stderr (indicatif): on a terminal a bar redrawn in place, with the
/// count, the time so far, the time left and the rate; elsewhere (logs, CI) the same figures as a
/// plain line every 5%.
struct Progress {
    bar: indicatif::ProgressBar,
    tty: bool,
}

impl Progress {
    fn new(total: usize) -> Self {
        use std::io::IsTerminal;
        let tty = std::io::stderr().is_terminal();
        let bar = if tty {
            indicatif::ProgressBar::new(total as u64)
        } else {
            indicatif::ProgressBar::hidden()
        };
        bar.set_length(total as u64);
        let style = indicatif::ProgressStyle::with_template(
            "[{bar:30}] {pos}/{len} {percent:>3}%  {elapsed}, ~{eta} left, {per_sec}  {msg}",
        )
        .map(|s| s.progress_chars("#>."))
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar());
        bar.set_style(style);
        Progress { bar, tty }
    }

    /// `done` points of the total finished, the last one described by `what`.
    fn update(&self, done: usize, what: &str) {
        self.bar.set_position(done as u64);
        self.bar.set_message(what.to_string());
        let total = self.bar.length().unwrap_or(0) as usize;
        if !self.tty && (done.is_multiple_of((total / 20).max(1)) || done == total) {
            eprintln!(
                "{done}/{total} {:3.0}%  {:.1} s, ~{:.1} s left, {:.1} points/s  {what}",
                100.0 * done as f64 / total.max(1) as f64,
                self.bar.elapsed().as_secs_f64(),
                self.bar.eta().as_secs_f64(),
                self.bar.per_sec()
            );
        }
        if done == total {
            self.bar.finish();
        }
    }
}

/// Suite `accuracy`: writes `accuracy.csv`, `accuracy.json` and `accuracy-vs-time.md` to `dir`.
fn accuracy_suite(a: BenchArgs, dir: PathBuf) -> Result<()> {
    let cfg = accuracy::Config::new(a.quick, a.maps.as_deref())?;
    let start = Instant::now();
    let total = accuracy::point_count(&cfg);
    eprintln!(
        "envis bench accuracy: {} environments x {} materials, {total} points",
        cfg.envs.len(),
        cfg.materials.len()
    );
    // The GPU backend, when this build has it and a device is there (`--cpu-only` skips it).
    #[cfg(feature = "gpu")]
    let gpu_ctx = if a.cpu_only {
        None
    } else {
        crate::gpu::GpuContext::new()
            .map_err(|e| eprintln!("accuracy: no GPU backend ({e}); CPU only"))
            .ok()
    };
    #[cfg(feature = "gpu")]
    let gpu_device = gpu_ctx
        .as_ref()
        .map(|c| format!("{} ({:?})", c.info.name, c.info.backend));
    #[cfg(not(feature = "gpu"))]
    let gpu_device: Option<String> = None;

    // Resumable: every finished point is appended to `accuracy.partial.jsonl` (first line: the
    // sweep's fingerprint). A rerun with the same configuration takes those points and measures
    // only the rest; the file is removed once the outputs are written.
    let fingerprint = accuracy::fingerprint(&cfg, gpu_device.as_deref());
    let partial = dir.join("accuracy.partial.jsonl");
    let resume: Vec<accuracy::Point> = match std::fs::read_to_string(&partial) {
        Ok(text) => {
            let mut lines = text.lines();
            if lines.next() == Some(serde_json::to_string(&fingerprint).unwrap().as_str()) {
                // A line cut short by the interruption is dropped (and measured again).
                let pts: Vec<accuracy::Point> =
                    lines.filter_map(|l| serde_json::from_str(l).ok()).collect();
                eprintln!(
                    "accuracy: resuming {} of {total} points from {}",
                    pts.len(),
                    partial.display()
                );
                pts
            } else {
                eprintln!(
                    "accuracy: {} is from a different configuration; starting over",
                    partial.display()
                );
                Vec::new()
            }
        }
        Err(_) => Vec::new(),
    };
    let mut journal = {
        let mut text = serde_json::to_string(&fingerprint).unwrap() + "\n";
        for p in &resume {
            text += &(serde_json::to_string(p).unwrap() + "\n");
        }
        std::fs::write(&partial, text)
            .map_err(|e| Error::file(&partial, format!("cannot write: {e}")))?;
        std::fs::OpenOptions::new()
            .append(true)
            .open(&partial)
            .map_err(|e| Error::file(&partial, format!("cannot append: {e}")))?
    };
    let resumed = resume.len();
    let mut journal_error = None;
    let mut progress: Option<Progress> = None;
    let report_progress = |done: usize, total: usize, p: &accuracy::Point, was_resumed: bool| {
        use std::io::Write as _;
        if !was_resumed && let Err(e) = writeln!(journal, "{}", serde_json::to_string(p).unwrap()) {
            journal_error.get_or_insert(e);
        }
        // Made on the first point: the sweep knows the total only then.
        let bar = progress.get_or_insert_with(|| Progress::new(total));
        bar.update(
            done,
            &format!("{} / {} / {} N={}", p.env, p.material, p.strategy, p.budget),
        );
    };
    #[cfg(feature = "gpu")]
    let points = match &gpu_ctx {
        Some(ctx) => {
            let mut renderer = crate::gpu::GpuRenderer::new(ctx);
            let mut time = |map: &CubeMap,
                            gbuf: &[Option<render::GPixel>],
                            size: usize,
                            s: &Settings|
             -> Result<(f64, f64)> {
                let (_, t) = renderer.render(map, gbuf, size, size, s)?;
                Ok((
                    t.build_gpu_ms.unwrap_or(t.build_wall_ms),
                    t.shade_gpu_ms.unwrap_or(t.shade_wall_ms),
                ))
            };
            accuracy::sweep(&cfg, &resume, Some(&mut time), report_progress)?
        }
        None => accuracy::sweep(&cfg, &resume, None, report_progress)?,
    };
    #[cfg(not(feature = "gpu"))]
    let points = accuracy::sweep(&cfg, &resume, None, report_progress)?;
    if let Some(e) = journal_error {
        eprintln!(
            "accuracy: could not append to {} ({e}); this run is not resumable",
            partial.display()
        );
    }
    let mut command = String::from("envis bench --suite accuracy");
    if a.quick {
        command.push_str(" --quick");
    }
    if let Some(m) = &a.maps {
        command.push_str(&format!(" --maps {}", m.display()));
    }
    let write = |name: &str, text: String| -> Result<()> {
        let p = dir.join(name);
        std::fs::write(&p, text).map_err(|e| Error::file(&p, format!("cannot write: {e}")))
    };
    write("accuracy.csv", accuracy::csv(&points))?;
    crate::render::output::write_json(
        &dir.join("accuracy.json"),
        &serde_json::json!({ "command": command, "points": points }),
    )?;
    let mut md = accuracy::report(&cfg, &points, &command, gpu_device.as_deref());
    md.push_str("## Plots\n\n");
    md.push_str("Each plot is written as SVG and PNG (plotters); the PNGs are shown here.\n\n");
    for (mname, _) in &cfg.materials {
        let stem = accuracy::plot_stem(mname);
        let (_, time_png) = accuracy::plot_error_vs_time(&points, mname).write(&dir, &stem)?;
        let (_, samples_png) = accuracy::plot_error_vs_samples(&points, mname)
            .write(&dir, &format!("{stem}-samples"))?;
        md.push_str(&format!(
            "![{mname}: error vs time]({time_png}) ![{mname}: error vs samples]({samples_png})\n\n"
        ));
    }
    let (_, wasted_png) = accuracy::plot_wasted(&points).write(&dir, "accuracy-wasted")?;
    md.push_str(&format!("![wasted light samples]({wasted_png})\n\n"));
    md.push_str(&format!(
        "Sweep time: {:.0} s{}.\n",
        start.elapsed().as_secs_f64(),
        if resumed > 0 {
            format!(
                " ({resumed} of {} points resumed from an interrupted run)",
                points.len()
            )
        } else {
            String::new()
        }
    ));
    write("accuracy-vs-time.md", md)?;
    let _ = std::fs::remove_file(&partial);
    eprintln!(
        "wrote accuracy.csv, accuracy.json, accuracy-vs-time.md to {} in {:.0} s",
        dir.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Suite `offset`: what the per-pixel random start offset into the pool does. For a pool of
/// M = N_L and M = 4 N_L samples per face, with and without the offset, over `--repeat` seeds:
/// per-pixel relative MSE against the reference (noise a viewer sees per pixel), and the spread
/// across seeds of the image-mean error (error shared by all pixels, i.e. correlated).
fn offset(a: BenchArgs, dir: PathBuf) -> Result<()> {
    let env = load_env(&a.env.parse()?, a.face_size)?;
    let size = a.size;
    let k = a.repeat.max(4);
    let mut rows = Vec::new();
    for (mname, mat) in [
        ("diffuse", Material::diffuse(0.8)),
        ("ggx 0.2", Material::ggx(0.8, 0.2)),
    ] {
        let gbuf = render::sphere_gbuffer(size, size, mat);
        let (_, reference) =
            crate::render::reference::reference_image(&env.cube, &gbuf, size, size, 1.0);
        let lum = crate::envmap::luminance_f64;
        let idx: Vec<usize> = (0..gbuf.len()).filter(|&i| gbuf[i].is_some()).collect();
        let ref_mean = idx.iter().map(|&i| lum(reference[i])).sum::<f64>() / idx.len() as f64;
        for pool_mult in [1usize, 4] {
            for pool_layout in crate::render::PoolLayout::ALL {
                let s = Settings {
                    light_samples: a.light_samples,
                    brdf_samples: a.brdf_samples,
                    pool_size: a.light_samples * pool_mult,
                    pool_layout,
                    ..Default::default()
                };
                let (mut relmse, mut means) = (0.0, Vec::new());
                for seed in 0..k {
                    let out = render::render(
                        &env.cube,
                        &gbuf,
                        size,
                        size,
                        &Settings {
                            seed: seed as u32,
                            ..s
                        },
                    )?;
                    let mut m = 0.0;
                    for &i in &idx {
                        let (x, r) = (lum(out.image.data[i].as_dvec3()), lum(reference[i]));
                        relmse += (x - r) * (x - r) / (r * r + 1e-2);
                        m += x;
                    }
                    means.push(m / idx.len() as f64);
                }
                relmse /= (k * idx.len()) as f64;
                let (_, se) = crate::stats::mean_se(&means);
                let mean_sd = se * (k as f64).sqrt() / ref_mean;
                eprintln!(
                    "  {mname:8} pool {:>3}/face {:6}: per-pixel relMSE {relmse:.4e}  image-mean rel. SD {mean_sd:.4e}",
                    s.pool_size, pool_layout
                );
                rows.push(serde_json::json!({ "material": mname, "pool_per_face": s.pool_size, "pool_layout": pool_layout, "pool_blocks": s.pool_block_count(), "relmse": relmse, "image_mean_rel_sd": mean_sd }));
            }
        }
    }
    let report = serde_json::json!({ "suite": "offset", "env": a.env, "face_size": a.face_size, "size": size, "light_samples": a.light_samples, "brdf_samples": a.brdf_samples, "seeds": k, "rows": rows });
    let path = dir.join("bench-offset.json");
    crate::render::output::write_json(&path, &report)?;
    eprintln!("wrote {}", path.display());
    Ok(())
}

fn speed(a: BenchArgs, dir: PathBuf) -> Result<()> {
    let repeat = a.repeat.max(1);
    let env = load_env(&a.env.parse()?, a.face_size)?;
    let gbuf = render::sphere_gbuffer(a.size, a.size, Material::diffuse(0.8));
    let threads = rayon::current_num_threads();
    eprintln!(
        "envis bench speed: {} threads, sphere {}^2, {}+{} samples, {} face {}^2",
        threads, a.size, a.light_samples, a.brdf_samples, a.env, a.face_size
    );

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
        let mut sps = Vec::new();
        let mut build = Vec::new();
        let mut shade = Vec::new();
        let mut samples = 0;
        for r in 0..repeat {
            let out = render::render(
                &env.cube,
                &gbuf,
                a.size,
                a.size,
                &Settings {
                    seed: r as u32,
                    ..s
                },
            )?;
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
            "strategy": strategy.to_string(), "samples_per_second": m, "ratio_to_brdf": m / base_sps,
            "build_ms": median(build), "shade_ms": median(shade), "samples_evaluated": samples,
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

    let mut scaling = Vec::new();
    let mut n = 16;
    while n <= a.max_face {
        let map = crate::envmap::sky::sky_cube(n, 10.0);
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
    // The pool against M (samples per face) on a fixed 64^2 map: linear in 6 M once M passes the
    // per-face setup.
    let map = crate::envmap::sky::sky_cube(64, 10.0);
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
    let report = serde_json::json!({
        "suite": "speed", "threads": threads, "env": a.env, "face_size": a.face_size, "size": a.size,
        "light_samples": a.light_samples, "brdf_samples": a.brdf_samples, "repeat": repeat,
        "shading": shading, "build_scaling": scaling, "pool_scaling": pool_scaling,
    });
    let path = dir.join("bench-speed.json");
    crate::render::output::write_json(&path, &report)?;
    let (svg, png) = scaling_plot(&scaling).write(&dir, "build-scaling")?;
    let pool_points = pool_scaling
        .iter()
        .map(|r| {
            (
                r["samples"].as_f64().unwrap_or(0.0),
                r["pool_ms"].as_f64().unwrap_or(0.0),
            )
        })
        .collect();
    let pool_chart = accuracy::Chart {
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
    };
    let (psvg, ppng) = pool_chart.write(&dir, "pool-scaling")?;
    eprintln!("wrote {}, {svg}, {png}, {psvg} and {ppng}", path.display());
    Ok(())
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
