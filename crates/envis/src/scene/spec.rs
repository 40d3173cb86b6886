//! The scene file as written: one struct per TOML table, every field as the file names it
//! (`docs/scenes.md`). `Scene::load` turns them into objects and settings.

use super::AnimationSpec;
use crate::render::Strategy;
use crate::sampling::{Counts, Heuristic};
use glam::Vec3;
use serde::Deserialize;

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    pub environment: EnvironmentSpec,
    #[serde(default)]
    pub camera: CameraSpec,
    #[serde(default)]
    pub sampling: SamplingSpec,
    #[serde(rename = "object", default)]
    pub objects: Vec<ObjectSpec>,
    /// The sequence clock, camera orbit (`envis sequence`, `--time`).
    #[serde(default)]
    pub animation: AnimationSpec,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentSpec {
    /// `builtin:sky[:HOURS]`, an `.exr` / `.hdr` file or a frame directory (relative to the scene file).
    pub source: String,
    #[serde(default = "default_face")]
    pub face_size: usize,
    /// Sky animation speed, hours per second (the demo).
    #[serde(default)]
    pub speed: f32,
}

fn default_face() -> usize {
    64
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    pub position: [f32; 3],
    pub target: [f32; 3],
    /// Vertical field of view in degrees.
    pub fov: f32,
}

impl Default for CameraSpec {
    fn default() -> Self {
        CameraSpec {
            position: [0.0, 1.5, 6.0],
            target: [0.0, 0.8, 0.0],
            fov: 40.0,
        }
    }
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SamplingSpec {
    pub light_samples: Option<usize>,
    pub brdf_samples: Option<usize>,
    pub strategy: Option<Strategy>,
    pub counts: Option<Counts>,
    /// The MIS heuristic (`mis` in files written before it was named as the settings name it).
    #[serde(alias = "mis")]
    pub heuristic: Option<Heuristic>,
    pub seed: Option<u32>,
    /// Light samples per face per frame, `M` (`pool` in files written before it was named as
    /// the settings name it).
    #[serde(alias = "pool")]
    pub pool_size: Option<usize>,
    /// `shared`, `offset` or `blocks` (`--pool-layout`).
    pub pool_layout: Option<crate::render::PoolLayout>,
    /// K of `pool_layout = "blocks"`.
    pub pool_blocks: Option<usize>,
    /// `true`: the same as `pool_layout = "offset"` (files written before `pool_layout`).
    pub pixel_offset: Option<bool>,
    pub material_budget: Option<bool>,
    /// K x K tiles per cube face (`--tiles`).
    pub tiles: Option<usize>,
    /// `face` or `tile` (`--tile-counts`).
    pub tile_counts: Option<crate::sampling::TileCounts>,
    /// Shadow rays: `auto` (default), `on` or `off` (`--visibility` overrides it; the key is also
    /// read as `visibility`, its name before it was named as the settings name it).
    #[serde(alias = "visibility")]
    pub shadows: Option<crate::visibility::ShadowRays>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectSpec {
    #[serde(default)]
    pub name: Option<String>,
    pub shape: String,
    /// Sphere radius (default 1).
    #[serde(default)]
    pub radius: Option<f32>,
    /// Plane side length (default 10).
    #[serde(default)]
    pub size: Option<f32>,
    /// Torus radii (default 0.9 and 0.45).
    #[serde(default)]
    pub major_radius: Option<f32>,
    #[serde(default)]
    pub minor_radius: Option<f32>,
    /// glTF / GLB path (relative to the scene file): the first mesh primitive is used.
    #[serde(default)]
    pub path: Option<String>,
    #[serde(default)]
    pub position: [f32; 3],
    /// Rotation, degrees about X, then Y, then Z.
    #[serde(default)]
    pub rotation: [f32; 3],
    #[serde(default = "one")]
    pub scale: f32,
    pub material: MaterialSpec,
    /// Whether the object blocks shadow rays (default true).
    #[serde(default = "yes")]
    pub cast_shadows: bool,
    /// Units per second (`[animation]`: the object translates on the sequence clock).
    #[serde(default)]
    pub velocity: [f32; 3],
}

fn one() -> f32 {
    1.0
}

fn yes() -> bool {
    true
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// diffuse | phong | ggx | mix
    #[serde(rename = "type")]
    pub kind: String,
    /// Albedo: one number or `[r, g, b]`.
    #[serde(default = "default_albedo")]
    pub albedo: Albedo,
    #[serde(default)]
    pub exponent: Option<f32>,
    #[serde(default)]
    pub alpha: Option<f32>,
    /// `mix`: the specular share of the albedo.
    #[serde(default)]
    pub specular: Option<f32>,
}

#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(untagged)]
pub enum Albedo {
    Grey(f32),
    Rgb([f32; 3]),
}

fn default_albedo() -> Albedo {
    Albedo::Grey(0.8)
}

impl Albedo {
    pub fn rgb(self) -> Vec3 {
        match self {
            Albedo::Grey(a) => Vec3::splat(a),
            Albedo::Rgb(c) => Vec3::from(c),
        }
    }
}
