//! The Bevy layer: [`EnvisPlugin`] and two camera components give a Bevy app unbiased,
//! per-frame importance-sampled environment lighting (`docs/bevy.md`):
//!
//! ```ignore
//! // The same set-up, compiled and run headless by the tests: examples/gltf_scene.rs.
//! use bevy::prelude::*;
//! use bevy_envis::prelude::*;
//!
//! fn setup(mut commands: Commands, assets: Res<AssetServer>) {
//!     commands.spawn((
//!         Camera3d::default(),
//!         EnvironmentSampling { light_samples: 32, brdf_samples: 32, ..default() },
//!         EnvisEnvironment { intensity: 0.5, ..EnvisEnvironment::new(assets.load("sky.exr")) },
//!     ));
//! }
//! App::new().add_plugins((DefaultPlugins, EnvisPlugin)).add_systems(Startup, setup).run();
//! ```
//!
//! One plugin per capability, all added by [`EnvisPlugin`]:
//! - [`EnvisMaterialPlugin`]: the [`EnvisMaterial`] deferred material.
//! - [`EnvisSamplingPlugin`] (render world): per environment image, the resample, distribution
//!   and light pool on the GPU, in the `RenderGraph` schedule before `camera_driver`.
//! - [`EnvisShadowsPlugin`] (both worlds): the scene's shadow geometry (a two-level BVH of the
//!   shadow-casting meshes) for envis's shadow rays.
//! - [`EnvisLightingPlugin`] (render world): per camera, the face-weighted MIS pass after Bevy's
//!   deferred lighting (`Core3d`, main pass, before the opaque pass), and [`EnvisLightReady`] on
//!   each camera from the first frame it lit.
//!
//! envis's GPU programs are compiled on a thread of its own from start-up
//! ([`programs::EnvisPrograms`]): a camera is lit from the first frame they, its distribution
//! and Bevy's passes under it are ready, and shows Bevy's own image until then.
//! - [`EnvisResamplingPlugin`] (both worlds): per camera with [`EnvironmentResampling`],
//!   reservoir resampling of the environment light across pixels and frames, before the
//!   lighting pass, which then shows its image.
//!
//! [`EnvisStreamPlugin`] (not in [`EnvisPlugin`]) plays envis's own streams (file sequences,
//! the carousel, the built-in sky) into an `Image` for [`EnvisEnvironment`].
//!
//! [`EnvisCounters`] is shared by both worlds and counts the work done (builds, lighting passes,
//! bytes uploaded), which is how tests prove that work is skipped when nothing changed.

/// The engine-free core (maps, sampling, the CPU oracle, streams), for the types the plugins
/// take (`envis::stream::StreamSource`, `envis::render::Strategy`).
pub use envis;
/// The WGSL stages the plugins run.
pub use envis_wgpu;

pub mod components;
pub mod coverage;
pub mod lighting;
mod lighting_uniforms;
pub mod material;
pub mod pose;
pub mod prelude;
pub mod programs;
pub mod ready;
pub mod resampling;
pub mod sampling;
pub mod scene_objects;
mod scene_revision;
pub mod setup;
pub mod shader_reload;
pub mod shadows;
pub mod stream;
pub mod tagged;
pub mod timing;

pub use components::{
    EnvironmentResampling, EnvironmentSampling, EnvisEnvironment, exposure_multiplier,
};
pub use envis::render::Overlay;
pub use lighting::EnvisLightingPlugin;
pub use material::{
    ENVIS_LIGHTING_PASS_ID, EnvisBrdf, EnvisMaterial, EnvisMaterialPlugin,
    standard_material_decoded,
};
pub use ready::{EnvisLightReady, ReadyReport};
pub use resampling::EnvisResamplingPlugin;
pub use sampling::EnvisSamplingPlugin;
pub use shader_reload::EnvisShaderReloadPlugin;
pub use shadows::EnvisShadowsPlugin;
pub use stream::{EnvFrame, EnvMapStream, EnvisStreamPlugin};
pub use timing::{EnvisTimings, PassTimes};

use bevy::prelude::*;
use bevy::render::diagnostic::RenderDiagnosticsPlugin;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// Everything envis needs (and nothing from egui or the demo): add it next to `DefaultPlugins`.
/// Cameras without [`EnvironmentSampling`] + [`EnvisEnvironment`] are not affected.
///
/// It sets itself up ([`setup`]): `DefaultOpaqueRendererMethod::deferred()` becomes the default
/// (so `StandardMaterial`s write the G-buffer envis lights), and a camera set up so that envis
/// lights nothing, or with Bevy's environment light as well, gets a one-time warning.
pub struct EnvisPlugin;

impl Plugin for EnvisPlugin {
    fn build(&self, app: &mut App) {
        setup::default_to_deferred(app);
        // GPU times of envis's passes go through Bevy's render diagnostics (`EnvisTimings` and
        // the demo read them): added here unless the app has it (add yours before this plugin).
        if app.get_sub_app(bevy::render::RenderApp).is_some()
            && !app.is_plugin_added::<RenderDiagnosticsPlugin>()
        {
            app.init_resource::<bevy::diagnostic::DiagnosticsStore>()
                .add_plugins(RenderDiagnosticsPlugin);
        }
        app.add_systems(PreUpdate, timing::read_pass_diagnostics);
        app.register_type::<EnvironmentSampling>()
            .register_type::<EnvisEnvironment>()
            .register_type::<EnvisLightReady>()
            .add_systems(PostUpdate, setup::warn_camera_setup)
            .add_plugins((
                EnvisMaterialPlugin,
                EnvisSamplingPlugin,
                shadows::EnvisShadowsPlugin,
                EnvisLightingPlugin,
                EnvisResamplingPlugin,
            ));
    }
}

/// Insert the resources both worlds share ([`EnvisCounters`], [`EnvisTimings`], [`EnvisProbe`],
/// [`AccumulatedFrames`])
/// once, the same `Arc`s in each world.
pub(crate) fn share_resources(app: &mut App) {
    let counters = app
        .world_mut()
        .get_resource_or_insert_with(EnvisCounters::default)
        .clone();
    let timings = app
        .world_mut()
        .get_resource_or_insert_with(EnvisTimings::default)
        .clone();
    let probe = app
        .world_mut()
        .get_resource_or_insert_with(EnvisProbe::default)
        .clone();
    let frames = app
        .world_mut()
        .get_resource_or_insert_with(AccumulatedFrames::default)
        .clone();
    if let Some(render_app) = app.get_sub_app_mut(bevy::render::RenderApp) {
        render_app
            .insert_resource(counters)
            .insert_resource(timings)
            .insert_resource(probe)
            .insert_resource(frames);
    }
}

/// What an overlay's colour scale means: the value at the red end (blue is 0), its unit, and
/// what is measured. `budget` is the pixel's `N_L + N_B`. `None` for no overlay.
pub fn overlay_legend(overlay: Overlay, budget: usize) -> Option<OverlayLegend> {
    {
        let (full_scale, unit, measures) = match overlay {
            Overlay::None => return None,
            Overlay::EffectiveSamples => (
                budget.max(1) as f32,
                "samples",
                "samples each pixel evaluated (used light + BRDF samples; red = the full budget)",
            ),
            Overlay::Wasted => (
                100.0,
                "%",
                "share of the used light samples below the horizon (the paper's yellow)",
            ),
            // The shader draws heat(4 d): red at a 25% relative difference.
            Overlay::CountsDifference => (
                25.0,
                "%",
                "|fractional - integer| / |fractional|: where integer counts pop",
            ),
            Overlay::History => (
                envis_wgpu::resampling::HISTORY_FULL_SCALE,
                "M",
                "each resampled pixel's confidence: frames of candidates reused plus the spatial \
                 neighbours' share (blue: no history, as after a disocclusion)",
            ),
        };
        Some(OverlayLegend {
            full_scale,
            unit,
            measures,
        })
    }
}

/// The colour scale of an overlay (see [`overlay_legend`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OverlayLegend {
    /// The value drawn red; 0 is drawn blue, and the scale is linear between.
    pub full_scale: f32,
    pub unit: &'static str,
    pub measures: &'static str,
}

/// The overlays' colour ramp for `t` in `[0, 1]`: blue, cyan, green, yellow, red (linear RGB).
/// Twin of `heat` in `shaders/lighting.wgsl`.
pub fn heat(t: f32) -> Vec3 {
    let x = t.clamp(0.0, 1.0) * 4.0;
    let g = if x > 2.0 { 4.0 - x } else { x };
    Vec3::new(x - 2.0, g, 2.0 - x).clamp(Vec3::ZERO, Vec3::ONE)
}

/// What the lighting pass read back for the probed pixel.
#[derive(Clone, Copy, Debug)]
pub struct ProbeResult {
    pub pixel: UVec2,
    /// The decoded G-buffer texel (normal, view, material) exactly as the shader saw it.
    pub gpixel: envis::render::GPixel,
    /// The GPU's estimate for the pixel (before exposure).
    pub estimate: Vec3,
    /// Its random-stream index (the CPU twin needs it to reproduce the estimate).
    pub pixel_index: u32,
    /// The seed of the frame it was read in (per frame while accumulating).
    pub seed: u32,
    /// Its world position when the pass cast shadow rays (the CPU twin then casts them too).
    pub point: Option<Vec3>,
}

/// The latest probe result, shared by both worlds.
#[derive(Resource, Clone, Default, Deref)]
pub struct EnvisProbe(pub Arc<std::sync::Mutex<Option<ProbeResult>>>);

/// Work counters, shared by the main and the render world.
#[derive(Default, Debug)]
pub struct Counters {
    /// Distribution + pool builds recorded (resample, distribution, pool).
    pub builds: AtomicU64,
    /// Bytes of environment images that Bevy uploaded from the CPU (an `Image` added or modified
    /// on the CPU); an image written on the GPU adds nothing.
    pub image_bytes_uploaded: AtomicU64,
    /// GPU sampler (re)allocations (face size or pool size changed).
    pub allocations: AtomicU64,
    /// Distributions alive in the render world after the last frame (a gauge, not a count):
    /// those no camera uses are dropped.
    pub live_distributions: AtomicU64,
    /// Opaque `StandardMaterial` meshes that render forward (envis cannot light them) and
    /// transparent ones, at the last look ([`coverage::warn_forward_meshes`]; gauges).
    pub forward_meshes: AtomicU64,
    pub transparent_meshes: AtomicU64,
    /// Camera set-up warnings given (once per camera and problem: [`setup::warn_camera_setup`]).
    pub setup_warnings: AtomicU64,
    /// Shadow-ray BVHs built from mesh assets (once per mesh asset, however often it is
    /// placed; again only when the asset changes).
    pub shadow_bvh_builds: AtomicU64,
    /// Top levels over the placed meshes built anew (meshes came, went or changed; once for a
    /// static scene) and refitted (meshes only moved).
    pub shadow_tlas_builds: AtomicU64,
    pub shadow_tlas_refits: AtomicU64,
    /// Deformed casters' BVHs refitted to a new pose (one per skinned or morphed mesh whose
    /// joints moved or morph weights changed).
    pub shadow_deformed_refits: AtomicU64,
    /// Lighting passes recorded (one per camera per frame).
    pub lighting_passes: AtomicU64,
    /// Lighting passes that ran an overlay (the overlay is a branch of the lighting pass: with
    /// overlays off this stays 0 and no overlay code runs).
    pub overlay_passes: AtomicU64,
    /// Frames resampled by `EnvironmentResampling` cameras (one per camera per frame), and of
    /// those, the frames that had a history to reuse (not the first, not after a reset).
    pub resampling_passes: AtomicU64,
    pub resampling_histories: AtomicU64,
    /// Of those, the frames that resampled the map's bright part apart (a map on the CPU: the
    /// envis stream's, or an image with its texels in the main world; and a bright part in it).
    pub resampling_bright: AtomicU64,
    /// Cameras whose resampling buffers the render world keeps (a gauge): those gone or no
    /// longer resampling are dropped.
    pub resampling_views: AtomicU64,
}

/// Frames each accumulating camera (main-world entity) has averaged so far, written by the
/// render world; shared by both worlds.
#[derive(Resource, Clone, Default)]
pub struct AccumulatedFrames(pub Arc<std::sync::Mutex<std::collections::HashMap<Entity, u32>>>);

impl AccumulatedFrames {
    /// Frames averaged by `camera` before its last frame (0: the last frame started the mean).
    pub fn get(&self, camera: Entity) -> Option<u32> {
        self.0.lock().ok()?.get(&camera).copied()
    }
}

/// Handle to the shared [`Counters`] (present in both worlds).
#[derive(Resource, Clone, Default, Deref)]
pub struct EnvisCounters(pub Arc<Counters>);

impl EnvisCounters {
    pub fn get(&self, c: impl Fn(&Counters) -> &AtomicU64) -> u64 {
        c(&self.0).load(Ordering::Relaxed)
    }
    pub(crate) fn bump(&self, c: impl Fn(&Counters) -> &AtomicU64) {
        self.add(c, 1);
    }
    pub(crate) fn add(&self, c: impl Fn(&Counters) -> &AtomicU64, n: u64) {
        c(&self.0).fetch_add(n, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The ramp's stops, as the WGSL computes them.
    #[test]
    fn heat_ramp_stops() {
        let stops = [
            (0.0, Vec3::new(0.0, 0.0, 1.0)),
            (0.25, Vec3::new(0.0, 1.0, 1.0)),
            (0.5, Vec3::new(0.0, 1.0, 0.0)),
            (0.75, Vec3::new(1.0, 1.0, 0.0)),
            (1.0, Vec3::new(1.0, 0.0, 0.0)),
        ];
        for (t, c) in stops {
            assert_eq!(heat(t), c, "t = {t}");
        }
        assert_eq!(heat(-1.0), heat(0.0));
        assert_eq!(heat(7.0), heat(1.0));
    }

    #[test]
    fn every_overlay_but_none_has_a_legend() {
        for o in Overlay::ALL {
            assert_eq!(overlay_legend(o, 64).is_some(), o != Overlay::None, "{o:?}");
        }
        assert_eq!(
            overlay_legend(Overlay::EffectiveSamples, 64)
                .unwrap()
                .full_scale,
            64.0
        );
    }
}

/// The README, whose Bevy snippet `cargo test` compiles (a doc test), so the set-up it shows
/// cannot go stale; its other blocks are shell or text.
#[cfg(doctest)]
#[doc = include_str!("../../../README.md")]
pub struct ReadmeDoctests;

/// docs/bevy.md, whose Bevy snippets `cargo test` compiles (doc tests).
#[cfg(doctest)]
#[doc = include_str!("../../../docs/bevy.md")]
pub struct BevyDocDoctests;
