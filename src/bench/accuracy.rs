//! `envis bench --suite accuracy`: what accuracy costs in time (CPU backend).
//!
//! Sweep: strategies {paper-fractional, paper-offset (a random per-pixel start into the pool),
//! paper-blocks (one of 16 independent pools per pixel, `PoolLayout::Blocks`), the same with the
//! power heuristic (paper-blocks-power), paper-blocks with 2 x 2 and 4 x 4 tiles per face
//! (paper-blocks-tiles2, paper-blocks-tiles4),
//! paper-integer, global (power MIS), light, brdf} x total
//! sample budgets N = N_L + N_B (4..512; paper and global also at light fractions 1/4 and 3/4) x
//! materials {diffuse, Phong 150, GGX 0.3, GGX 0.05} x environments (built-in sky at 8h, 12h, 17h,
//! plus every .exr/.hdr in `--maps DIR`). Each point: relMSE and RMSE of the sphere against the
//! f64 reference (mean over seeds), build and shade time, wasted-sample fraction.
//! Output: `accuracy.csv`, `accuracy.json` and `accuracy-vs-time.md` (tables, Pareto fronts, the
//! exact command) in the output directory.

use crate::envmap::load::{EnvSource, load_env};
use crate::envmap::luminance_f64;
use crate::error::{Error, Result};
use crate::render::{self, Settings, Strategy, reference};
use crate::sampling::{Counts, Heuristic, Material};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// One measured point of the sweep.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Point {
    pub env: String,
    pub material: String,
    pub strategy: String,
    pub light_samples: usize,
    pub brdf_samples: usize,
    pub budget: usize,
    pub relmse: f64,
    pub rmse: f64,
    pub build_ms: f64,
    pub shade_ms: f64,
    pub wasted: f64,
    /// Mean HDR-FLIP of the render against the reference (mean over seeds).
    pub flip: f64,
    /// The same point on the GPU backend (seed 0): distribution + pool build and shading, ms
    /// (timestamp queries, or wall time where the device has none). `None` without a GPU.
    pub gpu_build_ms: Option<f64>,
    pub gpu_shade_ms: Option<f64>,
}

/// Renders one point on a GPU backend and returns `(build_ms, shade_ms)`.
pub type GpuTimer<'a> = dyn FnMut(
        &crate::envmap::CubeMap,
        &[Option<render::GPixel>],
        usize,
        &Settings,
    ) -> Result<(f64, f64)>
    + 'a;

/// Sweep configuration.
pub struct Config {
    pub envs: Vec<String>,
    pub materials: Vec<(String, Material)>,
    pub budgets: Vec<usize>,
    pub size: usize,
    pub face_size: usize,
    pub seeds: u32,
}

impl Config {
    pub fn new(quick: bool, maps: Option<&Path>) -> Result<Self> {
        let mut envs: Vec<String> = if quick {
            vec!["builtin:sky:10".into()]
        } else {
            ["builtin:sky:8", "builtin:sky:12", "builtin:sky:17"]
                .iter()
                .map(|s| s.to_string())
                .collect()
        };
        if let Some(dir) = maps {
            let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
                .map_err(|e| Error::file(dir, format!("cannot list: {e}")))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e == "exr" || e == "hdr"))
                .collect();
            files.sort();
            if quick {
                files.truncate(1);
            }
            envs.extend(files.iter().map(|p| p.display().to_string()));
        }
        let materials = if quick {
            vec![
                ("diffuse".into(), Material::diffuse(0.8)),
                ("ggx 0.3".into(), Material::ggx(0.8, 0.3)),
            ]
        } else {
            vec![
                ("diffuse".into(), Material::diffuse(0.8)),
                ("phong 150".into(), Material::phong(0.8, 150.0)),
                ("ggx 0.3".into(), Material::ggx(0.8, 0.3)),
                ("ggx 0.05".into(), Material::ggx(0.8, 0.05)),
            ]
        };
        let budgets = if quick {
            vec![4, 16, 64]
        } else {
            vec![4, 8, 16, 32, 64, 128, 256, 512]
        };
        Ok(Config {
            envs,
            materials,
            budgets,
            size: if quick { 16 } else { 32 },
            face_size: if quick { 16 } else { 32 },
            seeds: if quick { 1 } else { 2 },
        })
    }
}

/// The (label, settings) pairs swept at total budget `n`. The `paper-*` rows but `paper-offset`
/// and `paper-blocks` are the seed's method exactly: one shared pool.
fn strategies(n: usize) -> Vec<(String, Settings)> {
    let half = Settings {
        light_samples: n / 2,
        brdf_samples: n - n / 2,
        pool_layout: crate::render::PoolLayout::Shared,
        ..Default::default()
    };
    let mut v = vec![
        ("paper-fractional".to_string(), half),
        (
            "paper-offset".to_string(),
            Settings {
                pool_layout: crate::render::PoolLayout::Offset,
                ..half
            },
        ),
        (
            "paper-blocks".to_string(),
            Settings {
                pool_layout: crate::render::PoolLayout::Blocks,
                ..half
            },
        ),
        (
            "paper-blocks-power".to_string(),
            Settings {
                pool_layout: crate::render::PoolLayout::Blocks,
                mis: Heuristic::Power,
                ..half
            },
        ),
        (
            "paper-integer".to_string(),
            Settings {
                counts: Counts::Integer,
                ..half
            },
        ),
    ];
    // Sub-face tiles on the default pool layout (`--tiles K`): against paper-blocks (K = 1).
    for k in super::tiles::SWEPT {
        v.push((
            super::tiles::label(k),
            Settings {
                pool_layout: crate::render::PoolLayout::Blocks,
                tiles: k,
                ..half
            },
        ));
    }
    v.extend([
        (
            "global".to_string(),
            Settings {
                strategy: Strategy::Global,
                mis: Heuristic::Power,
                ..half
            },
        ),
        (
            "light".to_string(),
            Settings {
                strategy: Strategy::Light,
                ..half
            },
        ),
        (
            "brdf".to_string(),
            Settings {
                strategy: Strategy::Brdf,
                ..half
            },
        ),
    ]);
    if n >= 8 {
        for (tag, nl) in [("L1/4", n / 4), ("L3/4", 3 * n / 4)] {
            let s = Settings {
                light_samples: nl,
                brdf_samples: n - nl,
                ..half
            };
            v.push((format!("paper-fractional {tag}"), s));
            v.push((
                format!("global {tag}"),
                Settings {
                    strategy: Strategy::Global,
                    mis: Heuristic::Power,
                    ..s
                },
            ));
        }
    }
    v
}

/// Number of points [`sweep`] will measure.
pub fn point_count(cfg: &Config) -> usize {
    cfg.envs.len()
        * cfg.materials.len()
        * cfg
            .budgets
            .iter()
            .map(|&n| strategies(n).len())
            .sum::<usize>()
}

/// A fingerprint of everything that decides the sweep's points: a resumed sweep must match it.
pub fn fingerprint(cfg: &Config, gpu_device: Option<&str>) -> String {
    let mats: Vec<String> = cfg
        .materials
        .iter()
        .map(|(n, m)| format!("{n}={m:?}"))
        .collect();
    format!(
        "envs={:?} materials={:?} budgets={:?} size={} face={} seeds={} gpu={gpu_device:?} version={}",
        cfg.envs,
        mats,
        cfg.budgets,
        cfg.size,
        cfg.face_size,
        cfg.seeds,
        env!("CARGO_PKG_VERSION")
    )
}

/// Key of a point within a sweep.
fn key(
    env: &str,
    material: &str,
    strategy: &str,
    budget: usize,
) -> (String, String, String, usize) {
    (
        env.to_string(),
        material.to_string(),
        strategy.to_string(),
        budget,
    )
}

/// Run the sweep, calling `progress(done, total, point, resumed)` after each point. Points found
/// in `resume` (from an interrupted run with the same [`fingerprint`]) are taken as they are,
/// not measured again. With `gpu`, each measured point is also rendered (seed 0) and timed on
/// the GPU backend.
pub fn sweep(
    cfg: &Config,
    resume: &[Point],
    mut gpu: Option<&mut GpuTimer>,
    mut progress: impl FnMut(usize, usize, &Point, bool),
) -> Result<Vec<Point>> {
    let total = point_count(cfg);
    let mut points = Vec::with_capacity(total);
    let saved: std::collections::HashMap<_, &Point> = resume
        .iter()
        .map(|p| (key(&p.env, &p.material, &p.strategy, p.budget), p))
        .collect();
    for env_name in &cfg.envs {
        let todo = |mname: &str| {
            cfg.budgets.iter().any(|&n| {
                strategies(n)
                    .iter()
                    .any(|(label, _)| !saved.contains_key(&key(env_name, mname, label, n)))
            })
        };
        // An environment whose points were all resumed is not even loaded.
        let env = if cfg.materials.iter().any(|(m, _)| todo(m)) {
            Some(load_env(&env_name.parse::<EnvSource>()?, cfg.face_size)?)
        } else {
            None
        };
        for (mname, mat) in &cfg.materials {
            let gbuf = render::sphere_gbuffer(cfg.size, cfg.size, *mat);
            let refimg = match &env {
                Some(env) if todo(mname) => {
                    reference::reference_image(&env.cube, &gbuf, cfg.size, cfg.size, 1.0).1
                }
                _ => Vec::new(),
            };
            let ref_rgb: Vec<glam::Vec3> = refimg.iter().map(|c| c.as_vec3()).collect();
            let idx: Vec<usize> = (0..gbuf.len()).filter(|&i| gbuf[i].is_some()).collect();
            for &n in &cfg.budgets {
                for (label, s) in strategies(n) {
                    if let Some(p) = saved.get(&key(env_name, mname, &label, n)) {
                        progress(points.len() + 1, total, p, true);
                        points.push((*p).clone());
                        continue;
                    }
                    let Some(env) = &env else {
                        unreachable!("a point to measure means its environment was loaded")
                    };
                    let (mut relmse, mut mse, mut build, mut shade, mut wasted, mut flip) =
                        (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
                    for seed in 0..cfg.seeds {
                        let out = render::render(
                            &env.cube,
                            &gbuf,
                            cfg.size,
                            cfg.size,
                            &Settings { seed, ..s },
                        )?;
                        for &i in &idx {
                            let (x, r) = (
                                luminance_f64(out.image.data[i].as_dvec3()),
                                luminance_f64(refimg[i]),
                            );
                            relmse += (x - r) * (x - r) / (r * r + 1e-2);
                            mse += (x - r) * (x - r);
                        }
                        build += out.stats.build_ms;
                        shade += out.stats.shade_ms;
                        wasted += out.stats.wasted;
                        flip += super::flip::hdr_flip(&ref_rgb, &out.image.data, cfg.size, cfg.size)
                            .1 as f64;
                    }
                    let (gpu_build_ms, gpu_shade_ms) = match gpu.as_deref_mut() {
                        Some(time) => {
                            let (b, s) = time(&env.cube, &gbuf, cfg.size, &s)?;
                            (Some(b), Some(s))
                        }
                        None => (None, None),
                    };
                    let k = cfg.seeds as f64;
                    let np = (idx.len() as f64 * k).max(1.0);
                    // The samples each technique actually draws (the baselines spend all N on one).
                    let (nl, nb) = match s.strategy {
                        Strategy::Light => (n, 0),
                        Strategy::Brdf => (0, n),
                        _ => (s.light_samples, s.brdf_samples),
                    };
                    let p = Point {
                        env: env_name.clone(),
                        material: mname.clone(),
                        strategy: label,
                        light_samples: nl,
                        brdf_samples: nb,
                        budget: n,
                        relmse: relmse / np,
                        rmse: (mse / np).sqrt(),
                        build_ms: build / k,
                        shade_ms: shade / k,
                        wasted: wasted / k,
                        flip: flip / k,
                        gpu_build_ms,
                        gpu_shade_ms,
                    };
                    progress(points.len() + 1, total, &p, false);
                    points.push(p);
                }
            }
        }
    }
    Ok(points)
}

/// Indices of the points not dominated in (time, relMSE): in order of time, each with a lower
/// error than every faster point.
pub fn pareto_front(pts: &[Point]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..pts.len()).collect();
    order.sort_by(|&a, &b| {
        (pts[a].build_ms + pts[a].shade_ms).total_cmp(&(pts[b].build_ms + pts[b].shade_ms))
    });
    let mut best = f64::INFINITY;
    order
        .into_iter()
        .filter(|&i| {
            let better = pts[i].relmse < best;
            best = best.min(pts[i].relmse);
            better
        })
        .collect()
}

fn geomean(xs: impl Iterator<Item = f64>) -> f64 {
    let (mut s, mut n) = (0.0, 0.0);
    for x in xs {
        s += x.max(1e-30).ln();
        n += 1.0;
    }
    if n > 0.0 { (s / n).exp() } else { f64::NAN }
}

pub(super) fn mean(xs: impl Iterator<Item = f64>) -> f64 {
    let (mut s, mut n) = (0.0, 0.0);
    for x in xs {
        s += x;
        n += 1.0;
    }
    if n > 0.0 { s / n } else { f64::NAN }
}

/// Points of one material pooled over environments (geometric means), one per (strategy, N).
pub(super) fn pooled(pts: &[Point], material: &str) -> Vec<Point> {
    let keys: std::collections::BTreeSet<(String, usize)> = pts
        .iter()
        .filter(|p| p.material == material)
        .map(|p| (p.strategy.clone(), p.budget))
        .collect();
    keys.into_iter()
        .map(|(s, n)| {
            let sel: Vec<&Point> = pts
                .iter()
                .filter(|p| p.material == material && p.strategy == s && p.budget == n)
                .collect();
            Point {
                env: "geomean".into(),
                material: material.into(),
                strategy: s,
                light_samples: sel[0].light_samples,
                brdf_samples: sel[0].brdf_samples,
                budget: n,
                relmse: geomean(sel.iter().map(|p| p.relmse)),
                rmse: geomean(sel.iter().map(|p| p.rmse)),
                build_ms: geomean(sel.iter().map(|p| p.build_ms)),
                shade_ms: geomean(sel.iter().map(|p| p.shade_ms)),
                wasted: mean(sel.iter().map(|p| p.wasted)),
                flip: mean(sel.iter().map(|p| p.flip)),
                gpu_build_ms: sel
                    .iter()
                    .all(|p| p.gpu_build_ms.is_some())
                    .then(|| geomean(sel.iter().filter_map(|p| p.gpu_build_ms))),
                gpu_shade_ms: sel
                    .iter()
                    .all(|p| p.gpu_shade_ms.is_some())
                    .then(|| geomean(sel.iter().filter_map(|p| p.gpu_shade_ms))),
            }
        })
        .collect()
}

/// A Markdown table: one row per budget, one column per strategy, `cell` for each pooled point.
fn strategy_table(
    md: &mut String,
    budgets: &[usize],
    pool: &[Point],
    strategies: &[&str],
    cell: impl Fn(&Point) -> String,
) {
    let _ = writeln!(
        md,
        "| N | {} |\n|---:|{}",
        strategies.join(" | "),
        "---:|".repeat(strategies.len())
    );
    for &n in budgets {
        let _ = write!(md, "| {n} |");
        for s in strategies {
            match pool.iter().find(|p| p.strategy == *s && p.budget == n) {
                Some(p) => {
                    let _ = write!(md, " {} |", cell(p));
                }
                None => md.push_str(" — |"),
            }
        }
        md.push('\n');
    }
}

/// The generated report: tables per material, the paper-vs-global comparison, Pareto fronts.
pub fn report(cfg: &Config, pts: &[Point], command: &str, gpu_device: Option<&str>) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "# Accuracy vs time\n\nGenerated by `{command}`.\n");
    let _ = writeln!(
        md,
        "Sphere {s}x{s}, cube faces {f}^2, {k} seed(s) per point, CPU backend, {t} threads. relMSE is the mean over pixels of (x-r)^2/(r^2+0.01) on luminance, against the f64 reference. Time is build + shade in milliseconds. Environments: {e}.\n",
        s = cfg.size,
        f = cfg.face_size,
        k = cfg.seeds,
        t = rayon::current_num_threads(),
        e = cfg.envs.join(", ")
    );
    let _ = writeln!(
        md,
        "FLIP is the mean HDR-FLIP (Andersson et al. 2021, `src/bench/flip.rs`, checked against NVIDIA's flip-evaluator) of the image against the reference, 67 pixels per degree. GPU: {}.\n",
        gpu_device.map_or("not run (no GPU backend in this build, or no adapter)".to_string(), |d| format!("each point also rendered once (seed 0) on {d}; build and shade times are timestamp queries, or wall time where the device has none"))
    );
    let main = [
        "paper-fractional",
        "paper-offset",
        "paper-blocks",
        "paper-blocks-power",
        "paper-integer",
        "global",
        "light",
        "brdf",
    ];
    for (mname, _) in &cfg.materials {
        let pool = pooled(pts, mname);
        let _ = writeln!(
            md,
            "## {mname}\n\nGeometric mean over environments of relMSE (time in ms). N_L = N_B = N/2 where both are used:\n"
        );
        strategy_table(&mut md, &cfg.budgets, &pool, &main, |p| {
            format!("{:.3e} ({:.2})", p.relmse, p.build_ms + p.shade_ms)
        });
        let _ = writeln!(
            md,
            "\nMean HDR-FLIP{}:\n",
            if gpu_device.is_some() {
                " (GPU build + shade ms)"
            } else {
                ""
            }
        );
        strategy_table(&mut md, &cfg.budgets, &pool, &main, |p| {
            match (p.gpu_build_ms, p.gpu_shade_ms) {
                (Some(b), Some(t)) => format!("{:.4} ({:.2})", p.flip, b + t),
                _ => format!("{:.4}", p.flip),
            }
        });
        let (mut wins, mut cases) = (0, 0);
        // Issue 14's FLIP target: mean FLIP <= 0.8 x global's at N >= 16, per pool layout.
        let layouts = [
            "paper-fractional",
            "paper-offset",
            "paper-blocks",
            "paper-blocks-power",
        ];
        let (mut flip_met, mut flip_cases) = ([0usize; 4], 0);
        for env in &cfg.envs {
            for &n in &cfg.budgets {
                let get = |s: &str| {
                    pts.iter().find(|p| {
                        &p.env == env && &p.material == mname && p.strategy == s && p.budget == n
                    })
                };
                let (shared, global) = (get("paper-fractional"), get("global"));
                if let (Some(a), Some(b)) = (shared, global) {
                    cases += 1;
                    wins += (a.relmse < b.relmse) as usize;
                }
                if let (Some(g), true) = (global, n >= 16) {
                    flip_cases += 1;
                    for (met, s) in flip_met.iter_mut().zip(layouts) {
                        *met += get(s).is_some_and(|p| p.flip <= 0.8 * g.flip) as usize;
                    }
                }
            }
        }
        let _ = writeln!(
            md,
            "\nMean FLIP at most 0.8 x global's, N >= 16: paper-fractional (shared pool) in **{} of {flip_cases}** cases, paper-offset in **{} of {flip_cases}**, paper-blocks (16 pools) in **{} of {flip_cases}**, paper-blocks-power (power MIS) in **{} of {flip_cases}**.",
            flip_met[0], flip_met[1], flip_met[2], flip_met[3]
        );
        let wasted = |s: &str| {
            100.0
                * mean(
                    pts.iter()
                        .filter(|p| &p.material == mname && p.strategy == s)
                        .map(|p| p.wasted),
                )
        };
        let _ = writeln!(
            md,
            "\npaper-fractional has lower relMSE than global in **{wins} of {cases}** (environment, N) cases at equal samples. Mean wasted (negative-cosine) light-sample fraction: paper-fractional {:.1}%, global {:.1}%, light {:.1}%.\n",
            wasted("paper-fractional"),
            wasted("global"),
            wasted("light")
        );
        let _ = writeln!(
            md,
            "Pareto front (error vs time, pooled over environments):\n\n| strategy | N_L + N_B | time (ms) | relMSE |\n|---|---:|---:|---:|"
        );
        for i in pareto_front(&pool) {
            let p = &pool[i];
            let _ = writeln!(
                md,
                "| {} | {} + {} | {:.2} | {:.3e} |",
                p.strategy,
                p.light_samples,
                p.brdf_samples,
                p.build_ms + p.shade_ms,
                p.relmse
            );
        }
        md.push('\n');
    }
    super::tiles::report(&mut md, cfg, pts);
    md
}

/// CSV of all points (one header line).
pub fn csv(pts: &[Point]) -> String {
    let mut s = String::from(
        "env,material,strategy,light_samples,brdf_samples,budget,relmse,rmse,build_ms,shade_ms,wasted,flip,gpu_build_ms,gpu_shade_ms\n",
    );
    let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.4}"));
    for p in pts {
        let _ = writeln!(
            s,
            "\"{}\",\"{}\",\"{}\",{},{},{},{:.6e},{:.6e},{:.4},{:.4},{:.4},{:.5},{},{}",
            p.env,
            p.material,
            p.strategy,
            p.light_samples,
            p.brdf_samples,
            p.budget,
            p.relmse,
            p.rmse,
            p.build_ms,
            p.shade_ms,
            p.wasted,
            p.flip,
            opt(p.gpu_build_ms),
            opt(p.gpu_shade_ms)
        );
    }
    s
}

pub use super::chart::{Chart, Series};

const MAIN: [(&str, &str); 10] = [
    ("paper-fractional", "#d62728"),
    ("paper-offset", "#8c564b"),
    ("paper-blocks", "#17becf"),
    ("paper-blocks-power", "#bcbd22"),
    ("paper-blocks-tiles2", "#e377c2"),
    ("paper-blocks-tiles4", "#7f7f7f"),
    ("paper-integer", "#ff9896"),
    ("global", "#1f77b4"),
    ("light", "#2ca02c"),
    ("brdf", "#9467bd"),
];

/// One series per main strategy through its budgets, `(x, y)` picked from the pooled points.
fn strategy_series(
    pool: &[Point],
    x: impl Fn(&Point) -> f64,
    y: impl Fn(&Point) -> f64,
) -> Vec<Series> {
    MAIN.iter()
        .map(|(name, color)| {
            let mut line: Vec<&Point> = pool.iter().filter(|p| p.strategy == *name).collect();
            line.sort_by_key(|p| p.budget);
            Series {
                name: name.to_string(),
                color,
                points: line.iter().map(|p| (x(p), y(p))).collect(),
                dashed: false,
            }
        })
        .collect()
}

/// An error-vs-time plot (log-log) of one material: one line per main strategy through its
/// budgets (geometric means over environments), the Pareto front dashed.
pub fn plot_error_vs_time(pts: &[Point], material: &str) -> Chart {
    let pool = pooled(pts, material);
    let t = |p: &Point| p.build_ms + p.shade_ms;
    let mut series = strategy_series(&pool, t, |p| p.relmse);
    let front = pareto_front(&pool)
        .into_iter()
        .map(|i| (t(&pool[i]), pool[i].relmse))
        .collect();
    series.push(Series {
        name: "Pareto front (all)".into(),
        color: "#000000",
        points: front,
        dashed: true,
    });
    let title = format!("{material}: relMSE vs time (geometric mean over environments)");
    Chart {
        title,
        xlabel: "time per frame, ms (build + shade, CPU)",
        ylabel: "relMSE",
        xlog: true,
        ylog: true,
        series,
    }
}

/// Error against the sample budget N = N_L + N_B (log-log) for one material.
pub fn plot_error_vs_samples(pts: &[Point], material: &str) -> Chart {
    let pool = pooled(pts, material);
    let title = format!("{material}: relMSE vs samples per pixel");
    Chart {
        title,
        xlabel: "samples per pixel, N = N_L + N_B",
        ylabel: "relMSE",
        xlog: true,
        ylog: true,
        series: strategy_series(&pool, |p| p.budget as f64, |p| p.relmse),
    }
}

/// The fraction of light samples wasted on negative cosines, against the budget, per strategy
/// (mean over materials and environments).
pub fn plot_wasted(pts: &[Point]) -> Chart {
    let keys: std::collections::BTreeSet<(String, usize)> =
        pts.iter().map(|p| (p.strategy.clone(), p.budget)).collect();
    let pool: Vec<Point> = keys
        .into_iter()
        .map(|(st, n)| {
            let sel: Vec<&Point> = pts
                .iter()
                .filter(|p| p.strategy == st && p.budget == n)
                .collect();
            Point {
                wasted: mean(sel.iter().map(|p| p.wasted)),
                ..sel[0].clone()
            }
        })
        .filter(|p| p.strategy != "brdf")
        .collect();
    let series = strategy_series(&pool, |p| p.budget as f64, |p| 100.0 * p.wasted)
        .into_iter()
        .filter(|s| !s.points.is_empty())
        .collect();
    Chart {
        title: "Light samples wasted on negative cosines (mean over materials and maps)".into(),
        xlabel: "samples per pixel, N = N_L + N_B",
        ylabel: "wasted light samples, %",
        xlog: true,
        ylog: false,
        series,
    }
}

/// File stem of a material's plots: `accuracy-<material>` with spaces and dots made dashes.
pub fn plot_stem(material: &str) -> String {
    format!("accuracy-{}", material.replace([' ', '.'], "-"))
}
