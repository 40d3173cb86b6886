//! `envis bench --suite bevy-ibl`: envis beside Bevy's own dynamic environment
//! light, `GeneratedEnvironmentMapLight` (the map refiltered on the GPU every frame, then the
//! split-sum lookup per pixel), in the same headless Bevy app, on the same scenes, map and
//! exposure. Each image against the converged one (envis accumulating many frames, with its
//! shadow rays: the integral both approximate), relMSE and mean HDR-FLIP, and each one's frame
//! cost (median wall time of a frame, same sitting). Results in `bench-bevy-ibl.json`, each
//! image beside it as a PNG (`bevy-ibl-SCENE-LIGHT.png`).

use super::BenchArgs;
use super::motion::relmse;
use crate::headless::{HeadlessApp, radiance_camera, radiance_view};
use bevy::core_pipeline::prepass::{DeferredPrepass, DepthPrepass};
use bevy::light::GeneratedEnvironmentMapLight;
use bevy::prelude::*;
use bevy_envis::{EnvironmentSampling, EnvisEnvironment};
use envis::envmap::Image as EnvImage;
use envis::envmap::load::{EnvSource, load_env};
use envis::error::{Error, Result};
use envis::visibility::ShadowRays;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Who lights the scene.
#[derive(Clone, Copy, Debug)]
enum Light {
    /// envis with `light + brdf` samples per pixel, shadow rays on, averaging `frames` frames
    /// (1: a single frame, as a game shows it).
    Envis { light: u32, brdf: u32, frames: u32 },
    /// envis with `EnvironmentResampling` (its defaults), `light + brdf` candidates a pixel,
    /// shown after `frames` frames of a still camera (the history they built).
    Resampled { light: u32, brdf: u32, frames: u32 },
    /// Bevy's `GeneratedEnvironmentMapLight`.
    Bevy,
}

impl Light {
    fn name(self) -> String {
        match self {
            Light::Envis { light, brdf, .. } => format!("envis {light}+{brdf}"),
            Light::Resampled { light, brdf, .. } => format!("envis {light}+{brdf} resampled"),
            Light::Bevy => "bevy GeneratedEnvironmentMapLight".into(),
        }
    }
}

/// The two scenes: a row of spheres of roughness 0.05 to 1, and a sphere resting on a plane.
#[derive(Clone, Copy, Debug, serde::Serialize)]
enum SceneKind {
    Spheres,
    Contact,
}

const ROUGHNESS: [f32; 5] = [0.05, 0.25, 0.5, 0.75, 1.0];

#[derive(serde::Serialize)]
struct Row {
    scene: SceneKind,
    light: String,
    relmse: f64,
    mean_flip: f64,
    /// Mean luminance of the image, and of the converged one.
    mean: f64,
    reference_mean: f64,
    /// Median wall time of one frame of the whole headless app, ms.
    frame_ms: f64,
}

pub fn run(a: BenchArgs, dir: PathBuf) -> Result<()> {
    let src: EnvSource = a.env.parse()?;
    // A power-of-two cube (Bevy's generator needs one), read by both in Bevy's convention.
    let face = if a.quick { 32 } else { 128 };
    let map = load_env(&src, face)?.cube;
    let (scale, reference_frames, timed) = if a.quick { (1, 4, 2) } else { (4, 64, 8) };
    let mut rows = Vec::new();
    for scene in [SceneKind::Spheres, SceneKind::Contact] {
        let (w, h) = match scene {
            SceneKind::Spheres => (80 * scale, 16 * scale),
            SceneKind::Contact => (40 * scale, 30 * scale),
        };
        let shot = Shot {
            scene,
            w,
            h,
            map: &map,
        };
        rows.extend(shot.compare(&dir, reference_frames, timed)?);
    }
    let out = serde_json::json!({
        "env": a.env, "face_size": face, "reference_frames": reference_frames,
        "reference": "envis 32+32 with shadow rays, accumulated",
        "rows": rows,
    });
    let path = dir.join("bench-bevy-ibl.json");
    envis::render::output::write_json(&path, &out)?;
    eprintln!("wrote {}", path.display());
    Ok(())
}

/// The lights measured against the converged image: envis with few and with many samples (a
/// single frame each), envis resampling few candidates (after 8 frames), and Bevy's.
const LIGHTS: [Light; 4] = [
    Light::Envis {
        light: 4,
        brdf: 4,
        frames: 1,
    },
    Light::Resampled {
        light: 4,
        brdf: 4,
        frames: 8,
    },
    Light::Envis {
        light: 32,
        brdf: 32,
        frames: 1,
    },
    Light::Bevy,
];

fn mean_luminance(img: &EnvImage) -> f64 {
    let sum: f64 = img
        .data
        .iter()
        .map(|&c| envis::envmap::luminance(c) as f64)
        .sum();
    sum / img.data.len().max(1) as f64
}

/// One scene at one size under one map.
struct Shot<'a> {
    scene: SceneKind,
    w: u32,
    h: u32,
    map: &'a envis::envmap::CubeMap,
}

impl Shot<'_> {
    /// The converged image (envis 32+32 accumulating `reference_frames` frames), then a row per
    /// light of [`LIGHTS`] against it, each timed over `timed` frames; every image written to
    /// `dir`.
    fn compare(&self, dir: &Path, reference_frames: u32, timed: usize) -> Result<Vec<Row>> {
        let reference = self.render(Light::Envis {
            light: 32,
            brdf: 32,
            frames: reference_frames,
        })?;
        self.write_png(dir, "reference", &reference)?;
        let mut rows = Vec::new();
        for light in LIGHTS {
            rows.push(self.row(dir, light, &reference, timed)?);
        }
        Ok(rows)
    }

    /// The image under `light` against the converged `reference`: written to `dir`, measured
    /// and printed.
    fn row(&self, dir: &Path, light: Light, reference: &EnvImage, timed: usize) -> Result<Row> {
        let (img, frame_ms) = self.render_timed(light, timed)?;
        self.write_png(dir, &light.name().replace([' ', '+'], "-"), &img)?;
        let (_, mean_flip) =
            super::flip::hdr_flip(&reference.data, &img.data, self.w as usize, self.h as usize);
        let row = Row {
            scene: self.scene,
            light: light.name(),
            relmse: relmse(&img, reference),
            mean_flip: mean_flip as f64,
            mean: mean_luminance(&img),
            reference_mean: mean_luminance(reference),
            frame_ms,
        };
        eprintln!(
            "  {:?} / {}: relMSE {:.3e}, HDR-FLIP {:.4}, mean {:.4} (converged {:.4}), {:.1} ms a frame",
            self.scene,
            row.light,
            row.relmse,
            row.mean_flip,
            row.mean,
            row.reference_mean,
            row.frame_ms
        );
        Ok(row)
    }

    /// `img` as `bevy-ibl-SCENE-NAME.png` (lower case) in `dir`.
    fn write_png(&self, dir: &Path, name: &str, img: &EnvImage) -> Result<()> {
        let path = dir.join(format!("bevy-ibl-{:?}-{name}.png", self.scene).to_lowercase());
        envis::render::output::write_png(&path, img, 1.0)
    }

    /// The image under `light` (after `frames` accumulated frames for envis), and the median
    /// frame time of `timed` more frames (0: not timed).
    fn render_timed(&self, light: Light, timed: usize) -> Result<(EnvImage, f64)> {
        let (mut h, target) = self.app(light);
        let img = self.capture(&mut h, &target, light)?;
        let mut times = Vec::with_capacity(timed);
        for _ in 0..timed {
            let t0 = Instant::now();
            h.update();
            times.push(t0.elapsed().as_secs_f64() * 1e3);
        }
        let ms = if times.is_empty() {
            f64::NAN
        } else {
            super::median(times)
        };
        Ok((img, ms))
    }

    fn render(&self, light: Light) -> Result<EnvImage> {
        Ok(self.render_timed(light, 0)?.0)
    }

    fn capture(
        &self,
        h: &mut HeadlessApp,
        target: &Handle<Image>,
        light: Light,
    ) -> Result<EnvImage> {
        // Bevy's generator and envis's distribution are ready after a few frames; an
        // accumulating envis camera then averages its frames.
        let frames = match light {
            Light::Envis { frames, .. } | Light::Resampled { frames, .. } => frames as usize + 3,
            Light::Bevy => 4,
        };
        h.until_lit();
        for _ in 0..frames {
            h.update();
        }
        let data = h.capture_next(target)?;
        if data.len() != (self.w * self.h) as usize {
            return Err(Error::invalid("bevy-ibl: a capture of the wrong size"));
        }
        Ok(EnvImage {
            width: self.w as usize,
            height: self.h as usize,
            data,
        })
    }

    /// The headless app: the scene, the map as a Bevy cube image, the camera lit by `light`.
    fn app(&self, light: Light) -> (HeadlessApp, Handle<Image>) {
        let mut h = HeadlessApp::new();
        // Plugins finish on the first frame; Bevy's generator registers its component's hooks
        // then, which must come before any entity holds one.
        h.update();
        let env = h.add::<Image>(bevy_envis::stream::cube_image(self.map));
        self.spawn_scene(&mut h);
        let target = h.float_target(self.w, self.h);
        let (projection, transform) = self.view();
        let world = h.app.world_mut();
        let envis = |light: u32, brdf: u32, frames: u32| {
            let sampling = EnvironmentSampling {
                light_samples: light as usize,
                brdf_samples: brdf as usize,
                shadows: ShadowRays::On,
                accumulate: frames > 1,
                ..default()
            };
            let env = EnvisEnvironment {
                show_background: false,
                ..EnvisEnvironment::new(env.clone())
            };
            radiance_camera(target.clone(), projection.clone(), transform, sampling, env)
        };
        match light {
            Light::Envis {
                light,
                brdf,
                frames,
            } => {
                world.spawn(envis(light, brdf, frames));
            }
            Light::Resampled { light, brdf, .. } => {
                // Its frames build the history; they are not averaged.
                world.spawn((
                    envis(light, brdf, 1),
                    bevy_envis::EnvironmentResampling::default(),
                ));
            }
            Light::Bevy => {
                // The same deferred path as envis's cameras, Bevy's light instead of envis's.
                let prepasses = (DepthPrepass, DeferredPrepass, bevy::camera::Hdr, Msaa::Off);
                let generated = GeneratedEnvironmentMapLight {
                    environment_map: env,
                    intensity: 1.0,
                    ..default()
                };
                world.spawn((
                    radiance_view(target.clone(), projection, transform),
                    prepasses,
                    generated,
                ));
            }
        }
        (h, target)
    }

    fn spawn_scene(&self, h: &mut HeadlessApp) {
        let sphere = h.add::<Mesh>(Sphere::new(1.0).mesh().ico(5).expect("icosphere"));
        match self.scene {
            SceneKind::Spheres => {
                for (k, r) in ROUGHNESS.into_iter().enumerate() {
                    let mat = h.add::<StandardMaterial>(StandardMaterial {
                        base_color: Color::srgb(0.9, 0.9, 0.9),
                        metallic: 1.0,
                        perceptual_roughness: r,
                        ..default()
                    });
                    let x = 2.1 * (k as f32 - 2.0);
                    h.app.world_mut().spawn((
                        Mesh3d(sphere.clone()),
                        MeshMaterial3d(mat),
                        Transform::from_xyz(x, 0.0, 0.0),
                    ));
                }
            }
            SceneKind::Contact => {
                let mat = h.add::<StandardMaterial>(StandardMaterial {
                    base_color: Color::srgb(0.8, 0.8, 0.8),
                    perceptual_roughness: 0.6,
                    ..default()
                });
                let plane = h.add::<Mesh>(Plane3d::default().mesh().size(8.0, 8.0));
                let world = h.app.world_mut();
                world.spawn((
                    Mesh3d(sphere),
                    MeshMaterial3d(mat.clone()),
                    Transform::from_xyz(0.0, 1.0, 0.0),
                ));
                world.spawn((Mesh3d(plane), MeshMaterial3d(mat)));
            }
        }
    }

    fn view(&self) -> (Projection, Transform) {
        match self.scene {
            SceneKind::Spheres => (
                Projection::Orthographic(OrthographicProjection {
                    scaling_mode: bevy::camera::ScalingMode::Fixed {
                        width: 10.5,
                        height: 2.1,
                    },
                    ..OrthographicProjection::default_3d()
                }),
                Transform::from_xyz(0.0, 0.0, 5.0).looking_at(Vec3::ZERO, Vec3::Y),
            ),
            SceneKind::Contact => (
                Projection::Perspective(PerspectiveProjection::default()),
                Transform::from_xyz(0.0, 2.5, 5.0).looking_at(Vec3::new(0.0, 0.7, 0.0), Vec3::Y),
            ),
        }
    }
}
