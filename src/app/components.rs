//! The two camera components a Bevy user adds: [`EnvironmentSampling`] (how to sample) and
//! [`EnvisEnvironment`] (what to sample). Both live on the camera, as Bevy's own
//! `EnvironmentMapLight` does, so two cameras can sample differently in one app.

use super::Overlay;
use crate::render::{PoolLayout, Settings, Strategy};
use crate::sampling::{Counts, Heuristic};
use bevy::core_pipeline::prepass::{DeferredPrepass, DepthPrepass};
use bevy::prelude::*;
use bevy::render::extract_component::ExtractComponent;

/// Unbiased, per-frame importance-sampled environment lighting for this camera (Lu, Pacanowski &
/// Granier 2013): every pixel with geometry gets `light_samples` face-weighted light samples and
/// `brdf_samples` BRDF samples, combined by multiple importance sampling.
///
/// Requires the deferred prepasses, an HDR target and no MSAA (deferred rendering has none).
/// Needs an [`EnvisEnvironment`] on the same camera to do anything. Removing it gives the camera
/// back to Bevy's lighting alone.
#[derive(Component, Clone, Debug, PartialEq, Reflect, ExtractComponent)]
#[reflect(Component, Default, Clone)]
#[require(DepthPrepass, DeferredPrepass, bevy::camera::Hdr, Msaa::Off)]
pub struct EnvironmentSampling {
    /// Light samples per pixel, `N_L` (shared between the cube faces by their face weights).
    pub light_samples: u32,
    /// BRDF samples per pixel, `N_B`.
    pub brdf_samples: u32,
    /// `paper` (the method: cosine face weights), `light` (energy only), `brdf`, or `global`
    /// (one lat-long distribution: the baseline).
    pub strategy: Strategy,
    /// `fractional` counts are unbiased and do not pop; `integer` counts are the paper's toggle.
    pub counts: Counts,
    /// The MIS heuristic (balance or power).
    pub heuristic: Heuristic,
    /// Light samples drawn per cube face per frame, `M` (0: `light_samples`).
    pub pool_size: u32,
    /// How pixels share the pool: `shared` (the paper's: the same samples everywhere, coherent
    /// error), `offset` (a random start per pixel) or `blocks` (one of `pool_blocks`
    /// independent pools per pixel: the error becomes noise; `docs/benchmarks.md`).
    pub pool_layout: PoolLayout,
    /// Independent pools with `blocks`, `K`.
    pub pool_blocks: u32,
    /// Let each pixel's material split the budget (diffuse: all light samples; near-mirror: all
    /// BRDF samples); `paper` only.
    pub material_budget: bool,
    /// `K`: each cube face cut into `K x K` tiles, each weighted and sampled on its own (1: the
    /// paper's whole faces; at most [`crate::sampling::MAX_TILES`]).
    pub tiles: u32,
    /// With tiles: `Face` (the paper's counts per face, each sample drawing its tile) or `Tile`
    /// (counts per tile).
    pub tile_counts: crate::sampling::TileCounts,
    /// Random seed of the pool and the per-pixel streams.
    pub seed: u32,
    /// Average frames while nothing changes (camera, settings, map, viewport size).
    pub accumulate: bool,
    /// A full-screen debug view instead of the image.
    pub overlay: Overlay,
    /// Face size of the sampling distribution (a sampling choice: radiance seen in the
    /// background comes from the full-resolution image).
    pub face_size: u32,
    /// Pixel (viewport coordinates) whose G-buffer texel and estimate are read back into
    /// [`super::EnvisProbe`] (the demo's sample-debug view).
    pub probe: Option<UVec2>,
    /// Shadow rays against the scene's meshes for every light and BRDF sample: `auto` (on
    /// when some mesh casts shadows), `on` or `off`. `NotShadowCaster` meshes cast none.
    pub shadows: crate::visibility::ShadowRays,
}

impl Default for EnvironmentSampling {
    fn default() -> Self {
        EnvironmentSampling {
            light_samples: 32,
            brdf_samples: 32,
            strategy: Strategy::Paper,
            counts: Counts::Fractional,
            heuristic: Heuristic::Balance,
            pool_size: 0,
            pool_layout: PoolLayout::Blocks,
            pool_blocks: crate::render::DEFAULT_POOL_BLOCKS as u32,
            material_budget: false,
            tiles: Settings::default().tiles as u32,
            tile_counts: Settings::default().tile_counts,
            seed: 0,
            accumulate: false,
            overlay: Overlay::None,
            face_size: 64,
            probe: None,
            shadows: crate::visibility::ShadowRays::Auto,
        }
    }
}

impl EnvironmentSampling {
    /// The core's settings (what the CPU renderer takes for the same image).
    pub fn settings(&self) -> Settings {
        Settings {
            light_samples: self.light_samples as usize,
            brdf_samples: self.brdf_samples as usize,
            pool_size: self.pool_size as usize,
            strategy: self.strategy,
            counts: self.counts,
            mis: self.heuristic,
            seed: self.seed,
            pool_layout: self.pool_layout,
            pool_blocks: self.pool_blocks as usize,
            material_budget: self.material_budget,
            tiles: self.tiles as usize,
            tile_counts: self.tile_counts,
        }
    }

    /// Copy the core's settings in (the demo's panel edits a [`Settings`]).
    pub fn set_settings(&mut self, s: &Settings) {
        self.light_samples = s.light_samples as u32;
        self.brdf_samples = s.brdf_samples as u32;
        self.pool_size = s.pool_size as u32;
        self.strategy = s.strategy;
        self.counts = s.counts;
        self.heuristic = s.mis;
        self.seed = s.seed;
        self.pool_layout = s.pool_layout;
        self.pool_blocks = s.pool_blocks as u32;
        self.material_budget = s.material_budget;
        self.tiles = s.tiles as u32;
        self.tile_counts = s.tile_counts;
    }

    /// `N_L + N_B`.
    pub fn budget(&self) -> u32 {
        self.light_samples + self.brdf_samples
    }
}

/// The environment this camera is lit by: an `Image` asset, read on the GPU.
///
/// `image` is a 2:1 lat-long image (Bevy's `.exr` / `.hdr` loaders give `Rgba32Float`; render
/// targets are usually `Rgba16Float`) or a 6-layer cube image in Bevy's convention. The sampling
/// distribution is rebuilt on the GPU from the texture when the asset changes, and every frame
/// when `dynamic` is set.
#[derive(Component, Clone, Debug, Reflect, ExtractComponent)]
#[reflect(Component, Clone)]
pub struct EnvisEnvironment {
    pub image: Handle<Image>,
    /// Multiplies the map, as `EnvironmentMapLight::intensity` does: the result is in cd/m²,
    /// and the camera's `Exposure` then applies as it does to every Bevy light.
    pub intensity: f32,
    /// World-space rotation of the map.
    pub rotation: Quat,
    /// Rebuild the distribution every frame: for images written on the GPU (a compute shader,
    /// a render target), which change detection cannot see.
    pub dynamic: bool,
    /// Draw the map where there is no geometry (off: Bevy's clear colour). A camera with a
    /// `Skybox` (with an image) has Bevy's skybox there instead, whatever this says: one
    /// background, with one brightness (`Skybox::brightness`).
    pub show_background: bool,
}

impl EnvisEnvironment {
    /// The environment `image` at intensity 1, unrotated, static, shown in the background.
    pub fn new(image: Handle<Image>) -> Self {
        EnvisEnvironment {
            image,
            intensity: 1.0,
            rotation: Quat::IDENTITY,
            dynamic: false,
            show_background: true,
        }
    }
}

/// The `Exposure` that multiplies radiance by `m` (Bevy's exposure is `1 / (1.2 * 2^ev100)`):
/// `exposure_multiplier(1.0)` shows the map's values as they are.
pub fn exposure_multiplier(m: f32) -> bevy::camera::Exposure {
    bevy::camera::Exposure {
        ev100: -(1.2 * m.max(1e-30)).log2(),
    }
}
