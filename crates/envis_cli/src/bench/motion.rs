//! Suite `motion`: reservoir resampling on an animated scene (`assets/scenes/motion.toml`:
//! orbiting camera, a moving sphere, contact shadows, a moving sun), each measured frame against
//! its own converged reference. Configurations, run in one sitting:
//! - `single 32+32`: today's estimator, every sample shadow-tested, no reuse;
//! - `single 4+4`: the same at the candidates' budget;
//! - `restir 4+4`: spatiotemporal reuse of 4 + 4 candidates, unbiased (the default);
//! - `restir 4+4 biased`;
//! - `temporal 4+4`: temporal reuse only;
//! - `restir 4+4 shadowed candidates`: every candidate shadow-tested (`candidate_visibility`);
//! - `restir 4+4 unsplit`: the map's bright part resampled with the rest (`split_bright` off).
//!
//! With a device (a machine without an adapter gets the CPU rows and a message) and without
//! `--cpu-only`, the first four again on the WGSL passes
//! (`wgpu ...`, a headless device: lavapipe in CI), each timed against `wgpu single 32+32` in the
//! same sitting; and the first four once more through Bevy (`bevy ...`:
//! `envis sequence --backend gpu`, the `EnvironmentResampling` pass on the stream's map split as
//! the oracle splits it, its counts read back; the plain rows' rays are not counted, `null`;
//! its cost is the GPU timestamps').
//!
//! Per configuration over the measured frames (and `--seeds` seeds): mean relMSE and HDR-FLIP
//! against the reference, lighting cost (build + shading, wall clock) and shadow rays per
//! pixel, and each as a ratio to `single 32+32` on the same backend; where the scene switches
//! its environment among the measured frames (`[[animation.switch]]`), the frames reuse needs
//! to follow (`frames_to_follow`). The reference of a frame is today's estimator at
//! `REF_SAMPLES` + `REF_SAMPLES` samples (unbiased; its own relMSE is printed, so the floor is
//! known). Writes `DIR/bench-motion.json`.

use super::BenchArgs;
use crate::sequence::{self, Posed, SequenceBackend, SequenceOptions};
use envis::envmap::{Image, luminance};
use envis::error::{Error, Result};
use envis::render::resampling::{Resampling, ResamplingMode};
use envis::render::{Extras, Settings};
use envis::scene::Scene;
use std::path::PathBuf;

/// The suite's scene, relative to the crate root (`--scene` replaces it).
const DEFAULT_SCENE: &str = "assets/scenes/motion.toml";

/// Samples of each kind per pixel in the reference frames.
const REF_SAMPLES: usize = 1024;

/// One configuration's figures over the measured frames.
#[derive(Clone, Debug, serde::Serialize)]
pub struct MotionRow {
    pub name: String,
    pub backend: &'static str,
    pub relmse: f64,
    pub flip: f64,
    /// Build + shading per frame, milliseconds.
    pub frame_ms: f64,
    pub shadow_rays_per_pixel: f64,
    /// Each as a ratio to the `single 32+32` row.
    pub relmse_ratio: f64,
    pub flip_ratio: f64,
    pub cost_ratio: f64,
    /// Per measured frame: (frame, relMSE), the relMSE a mean over seeds.
    pub per_frame: Vec<(u32, f64)>,
    /// Where the scene switches its environment among the measured frames
    /// (`[[animation.switch]]`): frames after the switch until the relMSE is back within 2x its
    /// steady value (`frames_to_follow` below); `None` without a switch, or if it never gets
    /// back.
    pub frames_to_follow: Option<u32>,
}

/// The relMSE of `img` against `rf` (luminance; `1e-2` keeps dark pixels from dominating, as
/// in the accuracy sweep).
pub(super) fn relmse(img: &Image, rf: &Image) -> f64 {
    let n = img.data.len().max(1) as f64;
    img.data
        .iter()
        .zip(&rf.data)
        .map(|(x, r)| {
            let (x, r) = (luminance(*x) as f64, luminance(*r) as f64);
            (x - r) * (x - r) / (r * r + 1e-2)
        })
        .sum::<f64>()
        / n
}

pub fn run(a: BenchArgs, dir: PathBuf) -> Result<()> {
    let m = Motion::new(&a)?;
    let mut rows: Vec<MotionRow> = Vec::new();
    for (name, r, n, backend) in configs(&a) {
        let mut row = m.measure(&name, r, n, backend)?;
        let base = rows.iter().find(|b| b.backend == row.backend);
        if let Some(base) = base {
            row.relmse_ratio = row.relmse / base.relmse;
            row.flip_ratio = row.flip / base.flip;
            row.cost_ratio = row.frame_ms / base.frame_ms;
        }
        let base = base.map_or(row.per_frame.as_slice(), |b| b.per_frame.as_slice());
        row.frames_to_follow = m
            .switch_frame()
            .and_then(|k| frames_to_follow(&row.per_frame, base, k));
        let follow = m.switch_frame().map_or(String::new(), |k| {
            let n = row
                .frames_to_follow
                .map_or("never".into(), |n| n.to_string());
            format!("  back within 2x {n} frames after the switch at frame {k}")
        });
        eprintln!(
            "  {name:30} relMSE {:.4} ({:.2}x)  FLIP {:.4} ({:.2}x)  {:.1} ms ({:.2}x)  {:.2} rays/px{follow}",
            row.relmse,
            row.relmse_ratio,
            row.flip,
            row.flip_ratio,
            row.frame_ms,
            row.cost_ratio,
            row.shadow_rays_per_pixel
        );
        rows.push(row);
    }
    let out = dir.join("bench-motion.json");
    let v = serde_json::json!({
        "suite": "motion",
        "scene": a.scene.as_ref().map_or(DEFAULT_SCENE.into(), |p| p.display().to_string()),
        "size": m.size,
        "frames": [m.first, m.frames],
        "reference_samples": REF_SAMPLES,
        "seeds": m.seeds,
        "threads": rayon::current_num_threads(),
        "rows": rows,
    });
    envis::render::output::write_json(&out, &v)?;
    eprintln!("wrote {}", out.display());
    Ok(())
}

/// A configuration: its name, resampling, samples of each kind per pixel, backend.
type Config = (String, Option<Resampling>, usize, SequenceBackend);

/// The configurations compared: [`cpu_configs`] on the CPU, and the first four of them on the
/// WGSL passes and through Bevy where this build has them (each backend's first is its
/// baseline).
fn configs(a: &BenchArgs) -> Vec<Config> {
    let cpu = cpu_configs();
    let mut v: Vec<Config> = (cpu.iter())
        .map(|&(name, r, n)| (name.to_string(), r, n, SequenceBackend::Cpu))
        .collect();
    if !a.cpu_only && wgpu_available() {
        v.extend(
            (cpu.iter().take(4))
                .map(|&(name, r, n)| (format!("wgpu {name}"), r, n, SequenceBackend::Wgpu)),
        );
        v.extend(
            (cpu.iter().take(4))
                .map(|&(name, r, n)| (format!("bevy {name}"), r, n, SequenceBackend::Bevy)),
        );
    }
    v
}

/// Whether there is a device to run the WGSL passes on; says why not once, so a machine without
/// a GPU adapter still gets the CPU rows.
fn wgpu_available() -> bool {
    envis_wgpu::GpuContext::new()
        .map_err(|e| eprintln!("motion: no GPU backend ({e}); CPU rows only"))
        .is_ok()
}

/// The CPU's configurations, as (name, resampling, samples of each kind per pixel); the first
/// is the baseline of the ratios.
fn cpu_configs() -> [(&'static str, Option<Resampling>, usize); 7] {
    let shadowed = Resampling {
        candidate_visibility: true,
        ..Default::default()
    };
    let unsplit = Resampling {
        split_bright: false,
        ..Default::default()
    };
    [
        ("single 32+32", None, 32),
        ("single 4+4", None, 4),
        (
            "restir 4+4",
            Resampling::for_mode(ResamplingMode::Spatiotemporal, true),
            4,
        ),
        (
            "restir 4+4 biased",
            Resampling::for_mode(ResamplingMode::Spatiotemporal, false),
            4,
        ),
        (
            "temporal 4+4",
            Resampling::for_mode(ResamplingMode::Temporal, true),
            4,
        ),
        ("restir 4+4 shadowed candidates", Some(shadowed), 4),
        ("restir 4+4 unsplit", Some(unsplit), 4),
    ]
}

/// The animated scene, the image size, and the measured frames `first..frames` with their
/// references.
struct Motion {
    scene: Scene,
    size: usize,
    first: u32,
    frames: u32,
    refs: Vec<Image>,
    /// Seeds per configuration (`--seeds`).
    seeds: u32,
}

impl Motion {
    /// The first frame of the scene's first environment switch that falls among the measured
    /// frames, after the first of them.
    fn switch_frame(&self) -> Option<u32> {
        let a = &self.scene.file.animation;
        (self.first + 1..self.frames).find(|&k| {
            let (t, before) = (self.scene.frame_time(k), self.scene.frame_time(k - 1));
            a.switch.iter().any(|s| before < s.at && s.at <= t)
        })
    }

    /// Loads the scene (`--scene` or [`DEFAULT_SCENE`]) and renders the references.
    fn new(a: &BenchArgs) -> Result<Self> {
        let default = crate::repo_path(DEFAULT_SCENE);
        let path = a.scene.clone().unwrap_or(default);
        let scene = Scene::load(&path)?;
        let (size, frames, first) = if a.quick {
            (48, 6, 3)
        } else {
            (a.size, 32, 16)
        };
        eprintln!(
            "motion: {size}^2, frames {first}..{frames}, reference {REF_SAMPLES}+{REF_SAMPLES}"
        );
        let refs = references(&scene, size, first, frames)?;
        Ok(Motion {
            scene,
            size,
            first,
            frames,
            refs,
            seeds: a.seeds,
        })
    }

    /// Configuration `name` (resampling `r`, `n` + `n` samples, on `backend`) over the sequence:
    /// its means over the measured frames, ratios still 1.
    fn measure(
        &self,
        name: &str,
        r: Option<Resampling>,
        n: usize,
        backend: SequenceBackend,
    ) -> Result<MotionRow> {
        let o = SequenceOptions {
            size: self.size,
            frames: self.frames,
            settings: Settings {
                light_samples: n,
                brdf_samples: n,
                ..self.scene.settings
            },
            resampling: r,
            visibility: None,
            backend,
        };
        let mut row = MotionRow {
            name: name.into(),
            backend: backend.name(),
            relmse: 0.0,
            flip: 0.0,
            frame_ms: 0.0,
            shadow_rays_per_pixel: 0.0,
            relmse_ratio: 1.0,
            flip_ratio: 1.0,
            cost_ratio: 1.0,
            per_frame: Vec::new(),
            frames_to_follow: None,
        };
        let mut per_frame = vec![0.0; (self.frames - self.first) as usize];
        for s in 0..self.seeds {
            let o = SequenceOptions {
                settings: Settings {
                    seed: o.settings.seed.wrapping_add(s),
                    ..o.settings
                },
                ..o
            };
            sequence::run(&self.scene, &o, |f| {
                let k = f.stats.frame;
                if k < self.first {
                    return Ok(());
                }
                let rf = &self.refs[(k - self.first) as usize];
                let e = relmse(&f.image, rf);
                per_frame[(k - self.first) as usize] += e;
                row.relmse += e;
                row.flip +=
                    super::flip::hdr_flip(&rf.data, &f.image.data, self.size, self.size).1 as f64;
                row.frame_ms += f.stats.build_ms + f.stats.shade_ms;
                row.shadow_rays_per_pixel += f.stats.shadow_rays_per_pixel.unwrap_or(f64::NAN);
                Ok(())
            })?;
        }
        let n = self.seeds as f64;
        row.per_frame = (self.first..self.frames)
            .zip(per_frame)
            .map(|(k, e)| (k, e / n))
            .collect();
        let m = (self.frames - self.first) as f64 * n;
        row.relmse /= m;
        row.flip /= m;
        row.frame_ms /= m;
        row.shadow_rays_per_pixel /= m;
        Ok(row)
    }
}

/// Frames from `switch` until a frame's relMSE is within 2x the steady value; `None` if none
/// is. Each frame's relMSE is taken relative to the baseline's in the same frame (`base`, of
/// the same frames): the maps before and after a switch differ in difficulty, and the baseline,
/// which reuses nothing, is as hard as each frame is. The steady value is the mean ratio over
/// the measured frames before the switch (the last four frames where there are none: those
/// after a switch are steady only if reuse has followed it, which a slow recovery never shows).
fn frames_to_follow(per_frame: &[(u32, f64)], base: &[(u32, f64)], switch: u32) -> Option<u32> {
    let ratio: Vec<(u32, f64)> = (per_frame.iter().zip(base))
        .map(|(&(k, e), &(_, b))| (k, e / b.max(f64::MIN_POSITIVE)))
        .collect();
    let before: Vec<f64> = (ratio.iter())
        .filter(|f| f.0 < switch)
        .map(|f| f.1)
        .collect();
    let steady = match before.is_empty() {
        false => before.iter().sum::<f64>() / before.len() as f64,
        true => {
            let tail = &ratio[ratio.len().saturating_sub(4)..];
            tail.iter().map(|f| f.1).sum::<f64>() / tail.len().max(1) as f64
        }
    };
    (ratio.iter())
        .find(|&&(k, e)| k >= switch && e <= 2.0 * steady)
        .map(|&(k, _)| k - switch)
}

/// The converged reference of frames `first..frames`.
fn references(scene: &Scene, size: usize, first: u32, frames: u32) -> Result<Vec<Image>> {
    let (shadows, _) = scene.shadows(None);
    (first..frames)
        .map(|k| {
            let p = Posed::new(scene, scene.frame_time(k), size)?;
            let occ = p.scene.occluders();
            let extras = Extras {
                shadows: shadows.then_some((&occ as _, p.screen.points.as_slice())),
                ..Default::default()
            };
            let s = Settings {
                light_samples: REF_SAMPLES,
                brdf_samples: REF_SAMPLES,
                seed: 0x5eed + k,
                ..scene.settings
            };
            let r = envis::render::render_with(&p.map, extras, &p.screen.gbuf, size, size, &s)
                .map_err(|e| Error::invalid(format!("motion reference: {e}")))?;
            Ok(r.image)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::frames_to_follow;

    /// Counted from the switch to the first frame within 2x the steady ratio to the baseline
    /// (before the switch; the last four frames without frames before it); `None` where none
    /// after the switch is.
    #[test]
    fn frames_to_follow_counts_from_the_switch() {
        let run = |e: &[f64]| -> Vec<(u32, f64)> { (10..).zip(e.iter().copied()).collect() };
        let flat = run(&[1.0; 10]);
        let settled = run(&[1.0, 1.0, 9.0, 5.0, 2.5, 1.5, 1.0, 1.0, 1.0, 1.0]);
        assert_eq!(frames_to_follow(&settled, &flat, 12), Some(3));
        // No frames before the switch: the last four's mean.
        assert_eq!(frames_to_follow(&settled, &flat, 10), Some(0));
        // A slow recovery is not steady: still 4x the value before the switch at the end.
        let slow = run(&[1.0, 1.0, 30.0, 20.0, 14.0, 10.0, 8.0, 6.0, 5.0, 4.0]);
        assert_eq!(frames_to_follow(&slow, &flat, 12), None);
        // A harder map after the switch (the baseline's error doubles) is not a lag.
        let harder = run(&[1.0, 1.0, 6.0, 4.0, 4.0, 4.0, 4.0, 4.0, 4.0, 4.0]);
        let base = run(&[1.0, 1.0, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0]);
        assert_eq!(frames_to_follow(&harder, &base, 12), Some(1));
    }
}
