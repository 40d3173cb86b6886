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
//!
//! Here the sweep; `strategies.rs` the strategies swept, `report.rs` the tables and summaries,
//! `plots.rs` the charts.

use envis::envmap::load::{EnvSource, load_env};
use envis::envmap::luminance_f64;
use envis::error::{Error, Result};
use envis::render::{self, Settings, Strategy, reference};
use envis::sampling::{Counts, Heuristic, Material};
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
        &envis::envmap::CubeMap,
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
    progress: impl FnMut(usize, usize, &Point, bool),
) -> Result<Vec<Point>> {
    let total = point_count(cfg);
    let mut run = Run {
        cfg,
        points: Vec::with_capacity(total),
        saved: resume
            .iter()
            .map(|p| (key(&p.env, &p.material, &p.strategy, p.budget), p))
            .collect(),
        total,
        progress,
    };
    for env_name in &cfg.envs {
        // An environment whose points were all resumed is not even loaded.
        let env = if cfg.materials.iter().any(|(m, _)| run.todo(env_name, m)) {
            Some(load_env(&env_name.parse::<EnvSource>()?, cfg.face_size)?)
        } else {
            None
        };
        for (mname, mat) in &cfg.materials {
            let cube = env.as_ref().map(|env| &env.cube);
            let sphere = Sphere::new(cfg, env_name, mname, *mat, cube, run.todo(env_name, mname));
            run.material(&sphere, gpu.as_deref_mut())?;
        }
    }
    Ok(run.points)
}

/// The sweep under way: the points so far, those resumed, and who hears of each.
struct Run<'a, P> {
    cfg: &'a Config,
    points: Vec<Point>,
    /// The points of an interrupted run, by [`key`].
    saved: std::collections::HashMap<(String, String, String, usize), &'a Point>,
    total: usize,
    progress: P,
}

impl<P: FnMut(usize, usize, &Point, bool)> Run<'_, P> {
    /// Whether material `mname` in `env_name` has a point left to measure.
    fn todo(&self, env_name: &str, mname: &str) -> bool {
        self.cfg.budgets.iter().any(|&n| {
            strategies(n)
                .iter()
                .any(|(label, _)| !self.saved.contains_key(&key(env_name, mname, label, n)))
        })
    }

    /// Every point of `sphere`'s environment and material: resumed where saved, else measured.
    fn material(&mut self, sphere: &Sphere, mut gpu: Option<&mut GpuTimer>) -> Result<()> {
        for &n in &self.cfg.budgets {
            for (label, s) in strategies(n) {
                if let Some(p) = self.saved.get(&key(sphere.env, sphere.material, &label, n)) {
                    (self.progress)(self.points.len() + 1, self.total, p, true);
                    self.points.push((*p).clone());
                    continue;
                }
                let p = sphere.measure(self.cfg, label, n, s, gpu.as_deref_mut())?;
                (self.progress)(self.points.len() + 1, self.total, &p, false);
                self.points.push(p);
            }
        }
        Ok(())
    }
}

/// The sphere of one material in one environment, with its reference where points need it.
struct Sphere<'a> {
    env: &'a str,
    material: &'a str,
    /// The environment; `None` where all its points were resumed and it was not loaded.
    cube: Option<&'a envis::envmap::CubeMap>,
    gbuf: Vec<Option<render::GPixel>>,
    /// The f64 reference; empty where none of the points is measured.
    refimg: Vec<glam::DVec3>,
    ref_rgb: Vec<glam::Vec3>,
    /// The pixels the sphere covers.
    idx: Vec<usize>,
}

impl<'a> Sphere<'a> {
    /// The sphere's G-buffer, and its reference where `cube` is loaded and a point is `needed`.
    fn new(
        cfg: &Config,
        env: &'a str,
        material: &'a str,
        mat: Material,
        cube: Option<&'a envis::envmap::CubeMap>,
        needed: bool,
    ) -> Self {
        let gbuf = render::sphere_gbuffer(cfg.size, cfg.size, mat);
        let refimg = match cube {
            Some(cube) if needed => {
                reference::reference_image(cube, &gbuf, cfg.size, cfg.size, 1.0).1
            }
            _ => Vec::new(),
        };
        let ref_rgb: Vec<glam::Vec3> = refimg.iter().map(|c| c.as_vec3()).collect();
        let idx: Vec<usize> = (0..gbuf.len()).filter(|&i| gbuf[i].is_some()).collect();
        Sphere {
            env,
            material,
            cube,
            gbuf,
            refimg,
            ref_rgb,
            idx,
        }
    }

    /// The point of strategy `label` (settings `s`) at total budget `n`: CPU figures averaged
    /// over the seeds, and the GPU's times where there is one.
    fn measure(
        &self,
        cfg: &Config,
        label: String,
        n: usize,
        s: Settings,
        gpu: Option<&mut GpuTimer>,
    ) -> Result<Point> {
        let Some(cube) = self.cube else {
            unreachable!("a point to measure means its environment was loaded")
        };
        let sums = self.seed_sums(cfg, cube, s)?;
        let (gpu_build_ms, gpu_shade_ms) = match gpu {
            Some(time) => {
                let (b, s) = time(cube, &self.gbuf, cfg.size, &s)?;
                (Some(b), Some(s))
            }
            None => (None, None),
        };
        let k = cfg.seeds as f64;
        let np = (self.idx.len() as f64 * k).max(1.0);
        // The samples each technique actually draws (the baselines spend all N on one).
        let (nl, nb) = match s.strategy {
            Strategy::Light => (n, 0),
            Strategy::Brdf => (0, n),
            _ => (s.light_samples, s.brdf_samples),
        };
        Ok(Point {
            env: self.env.to_string(),
            material: self.material.to_string(),
            strategy: label,
            light_samples: nl,
            brdf_samples: nb,
            budget: n,
            relmse: sums.relmse / np,
            rmse: (sums.mse / np).sqrt(),
            build_ms: sums.build / k,
            shade_ms: sums.shade / k,
            wasted: sums.wasted / k,
            flip: sums.flip / k,
            gpu_build_ms,
            gpu_shade_ms,
        })
    }

    /// Renders settings `s` once per seed: the sums over seeds (and pixels) a point averages.
    fn seed_sums(&self, cfg: &Config, cube: &envis::envmap::CubeMap, s: Settings) -> Result<Sums> {
        let mut t = Sums::default();
        for seed in 0..cfg.seeds {
            let out = render::render(
                cube,
                &self.gbuf,
                cfg.size,
                cfg.size,
                &Settings { seed, ..s },
            )?;
            for &i in &self.idx {
                let (x, r) = (
                    luminance_f64(out.image.data[i].as_dvec3()),
                    luminance_f64(self.refimg[i]),
                );
                t.relmse += (x - r) * (x - r) / (r * r + 1e-2);
                t.mse += (x - r) * (x - r);
            }
            t.build += out.stats.build_ms;
            t.shade += out.stats.shade_ms;
            t.wasted += out.stats.wasted;
            t.flip +=
                super::flip::hdr_flip(&self.ref_rgb, &out.image.data, cfg.size, cfg.size).1 as f64;
        }
        Ok(t)
    }
}

/// A point's figures summed over seeds (relMSE and MSE also over pixels).
#[derive(Default)]
struct Sums {
    relmse: f64,
    mse: f64,
    build: f64,
    shade: f64,
    wasted: f64,
    flip: f64,
}

mod plots;
mod report;
mod strategies;

pub use super::chart::{Chart, Series};
pub use plots::{plot_error_vs_samples, plot_error_vs_time, plot_stem, plot_wasted};
pub use report::{csv, pareto_front, report};
pub(super) use report::{mean, pooled};
use strategies::strategies;
