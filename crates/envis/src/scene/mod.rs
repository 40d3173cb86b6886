//! Scene files (TOML): objects (built-in shapes or glTF meshes, transforms, materials), the
//! environment source, the camera and the sampling settings. `envis render --scene FILE` and the
//! demo's `--scene FILE` read them; examples are in `assets/scenes/`.
//!
//! ```toml
//! [environment]
//! source = "builtin:sky:10"   # or a file, or a directory of frames
//! face_size = 64
//!
//! [camera]
//! position = [0.0, 1.5, 6.0]
//! target = [0.0, 0.8, 0.0]
//! fov = 40.0                  # vertical, degrees
//!
//! [sampling]                  # every field optional
//! light_samples = 32
//! brdf_samples = 32
//! material_budget = true
//!
//! [[object]]
//! shape = "sphere"            # sphere | plane | torus | gltf
//! radius = 1.0
//! position = [-1.5, 1.0, 0.0]
//! material = { type = "phong", albedo = 0.8, exponent = 150.0 }
//! ```
//!
//! Errors name the file, the line and the field. The CPU G-buffer of a scene is ray cast:
//! spheres and planes analytically, tori and glTF meshes as triangles.

mod animation;
mod camera;
mod convert;
mod glb;
mod objects;
pub mod shadows;
mod shapes;
mod spec;

use crate::error::{Error, Result};
use crate::render::{GPixel, Settings};
use crate::sampling::Material;
pub use animation::{AnimationSpec, SwitchSpec};
pub use camera::Camera;
pub use convert::material;
use convert::sampling_settings;
use glam::Vec3;
pub use glb::{load_glb, parse_glb};
use objects::{MeshCache, object_shape};
pub use shapes::{MeshInstance, Shape, TriMesh, sphere_mesh, square_mesh, torus_mesh};
pub use spec::*;
use std::path::{Path, PathBuf};

/// A built scene object: its material and geometry in world space.
#[derive(Clone, Debug)]
pub struct Object {
    pub name: String,
    pub material: Material,
    pub shape: Shape,
    pub spec: ObjectSpec,
}

/// A loaded scene.
#[derive(Clone, Debug)]
pub struct Scene {
    pub path: PathBuf,
    pub file: SceneFile,
    pub objects: Vec<Object>,
    pub settings: Settings,
    /// The environment source, resolved relative to the scene file.
    pub environment: String,
    /// The top level over every object, for the G-buffer's rays.
    tlas: crate::visibility::Tlas,
}

fn err(path: &Path, msg: impl Into<String>) -> Error {
    Error::file(path, msg)
}

/// Line (1-based) of a byte offset in `text`.
fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].matches('\n').count() + 1
}

impl Scene {
    pub fn load(path: &Path) -> Result<Scene> {
        let text =
            std::fs::read_to_string(path).map_err(|e| err(path, format!("cannot read: {e}")))?;
        let file: SceneFile = toml::from_str(&text).map_err(|e| {
            // The line number and the field the error is in (the key on that line, if any).
            let line = e
                .span()
                .map(|s| {
                    let n = line_of(&text, s.start);
                    let key = text
                        .lines()
                        .nth(n - 1)
                        .and_then(|l| l.split_once('='))
                        .map(|(k, _)| format!(", field `{}`", k.trim()))
                        .unwrap_or_default();
                    format!("line {n}{key}: ")
                })
                .unwrap_or_default();
            err(path, format!("{line}{}", e.message().trim()))
        })?;
        Scene::from_file(path, file)
    }

    /// The scene a parsed file describes (`path`: where relative paths start, and what errors
    /// name).
    pub fn from_file(path: &Path, file: SceneFile) -> Result<Scene> {
        check_animation(path, &file)?;
        let base = path.parent().unwrap_or(Path::new("."));
        let resolve = |p: &str| -> PathBuf {
            let p = PathBuf::from(p);
            if p.is_absolute() { p } else { base.join(p) }
        };
        let environment = if file.environment.source.starts_with("builtin:") {
            file.environment.source.clone()
        } else {
            resolve(&file.environment.source).display().to_string()
        };
        let settings = sampling_settings(path, &file.sampling, file.environment.face_size)?;
        let mut objects = Vec::new();
        // One mesh per asset (a glTF file, a torus's radii), however often it is placed.
        let mut meshes = MeshCache::default();
        for (i, o) in file.objects.iter().enumerate() {
            let at = |field: &str| {
                format!(
                    "object {} ({}), field `{field}`",
                    i + 1,
                    o.name.as_deref().unwrap_or(&o.shape)
                )
            };
            let material =
                material(&o.material).map_err(|m| err(path, format!("{}: {m}", at("material"))))?;
            let shape = object_shape(o, &at, path, &resolve, &mut meshes)?;
            objects.push(Object {
                name: o
                    .name
                    .clone()
                    .unwrap_or_else(|| format!("{} {}", o.shape, i + 1)),
                material,
                shape,
                spec: o.clone(),
            });
        }
        if objects.is_empty() {
            return Err(err(path, "no [[object]] in the scene"));
        }
        let bounds: Vec<_> = objects.iter().map(|o: &Object| o.shape.bounds()).collect();
        Ok(Scene {
            path: path.to_path_buf(),
            file,
            tlas: crate::visibility::Tlas::build(&bounds),
            objects,
            settings,
            environment,
        })
    }

    /// The stream of the scene's environment, a built-in sky's clock running at `speed` hours
    /// per second (the scene's own `environment.speed` for playback, 0 for a still frame).
    pub fn stream_source(&self, speed: f32) -> Result<crate::stream::StreamSource> {
        use crate::stream::StreamSource;
        Ok(match StreamSource::parse(&self.environment)? {
            StreamSource::Sky { hours, .. } => StreamSource::Sky { hours, speed },
            other => other,
        })
    }

    /// The scene's G-buffer seen by its camera (perspective), `width x height`, row-major.
    pub fn gbuffer(&self, width: usize, height: usize) -> Vec<Option<GPixel>> {
        self.gbuffer_points(width, height).0
    }

    /// [`Self::gbuffer`] and each pixel's surface point (the origin of its shadow rays; the
    /// camera's position where there is no geometry).
    pub fn gbuffer_points(&self, width: usize, height: usize) -> (Vec<Option<GPixel>>, Vec<Vec3>) {
        let sc = self.screen(width, height);
        (sc.gbuf, sc.points)
    }

    /// The camera of a `width x height` image.
    pub fn camera(&self, width: usize, height: usize) -> Camera {
        Camera::new(&self.file.camera, width, height)
    }

    /// What the camera sees: per pixel the G-buffer, the surface point, and its distance and
    /// object (what resampling's geometric tests read).
    pub fn screen(&self, width: usize, height: usize) -> SceneScreen {
        use rayon::prelude::*;
        let cam = self.camera(width, height);
        let eye = cam.eye;
        let px: Vec<_> = (0..width * height)
            .into_par_iter()
            .map(|i| {
                let d = cam.ray(i);
                match self.trace_object(eye, d) {
                    Some((id, t, n, m)) => {
                        let px = GPixel {
                            n,
                            o: -d,
                            material: m,
                        };
                        let surface = crate::render::resampling::Surface { depth: t, id };
                        (Some(px), eye + d * t, surface)
                    }
                    None => (None, eye, Default::default()),
                }
            })
            .collect();
        let mut out = SceneScreen {
            gbuf: Vec::with_capacity(px.len()),
            points: Vec::with_capacity(px.len()),
            surfaces: Vec::with_capacity(px.len()),
        };
        for (g, p, s) in px {
            out.gbuf.push(g);
            out.points.push(p);
            out.surfaces.push(s);
        }
        out
    }

    /// Closest hit along the ray: shading normal (facing the ray) and material.
    pub fn trace(&self, o: Vec3, d: Vec3) -> Option<(Vec3, Material)> {
        self.trace_hit(o, d).map(|(_, n, m)| (n, m))
    }

    /// [`Self::trace`] with the hit distance.
    pub fn trace_hit(&self, o: Vec3, d: Vec3) -> Option<(f32, Vec3, Material)> {
        self.trace_object(o, d).map(|(_, t, n, m)| (t, n, m))
    }

    /// [`Self::trace_hit`] with the index of the object hit.
    pub fn trace_object(&self, o: Vec3, d: Vec3) -> Option<(u32, f32, Vec3, Material)> {
        let (i, (t, n)) = self.tlas.closest(o, d, f32::INFINITY, |i, t_max| {
            let hit = self.objects[i].shape.intersect(o, d, t_max)?;
            Some((hit.0, hit))
        })?;
        Some((
            i as u32,
            t,
            if n.dot(d) > 0.0 { -n } else { n },
            self.objects[i].material,
        ))
    }
}

/// A scene seen by its camera ([`Scene::screen`]), row-major.
pub struct SceneScreen {
    pub gbuf: Vec<Option<GPixel>>,
    /// Surface points (the eye where there is no geometry).
    pub points: Vec<Vec3>,
    pub surfaces: Vec<crate::render::resampling::Surface>,
}

/// The animation's numbers are finite, the clock runs forward.
fn check_animation(path: &Path, f: &SceneFile) -> Result<()> {
    let a = &f.animation;
    if !(a.fps.is_finite() && a.fps > 0.0) {
        return Err(err(path, format!("[animation]: fps {} must be > 0", a.fps)));
    }
    if !a.orbit.is_finite() || !f.environment.speed.is_finite() {
        return Err(err(path, "[animation]: orbit and speed must be finite"));
    }
    if let Some(s) = a.switch.iter().find(|s| !(s.at.is_finite() && s.at > 0.0)) {
        return Err(err(
            path,
            format!("[[animation.switch]]: at {} must be > 0 seconds", s.at),
        ));
    }
    if let Some((i, _)) = f
        .objects
        .iter()
        .enumerate()
        .find(|(_, o)| !o.velocity.iter().all(|v| v.is_finite()))
    {
        return Err(err(
            path,
            format!("object {}, field `velocity`: must be finite", i + 1),
        ));
    }
    Ok(())
}
