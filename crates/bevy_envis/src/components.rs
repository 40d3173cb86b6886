//! The camera components a Bevy user adds: [`EnvironmentSampling`] (how to sample) and
//! [`EnvisEnvironment`] (what to sample), and [`EnvironmentResampling`] (reuse across pixels and
//! frames). All live on the camera, as Bevy's own `EnvironmentMapLight` does, so two cameras can
//! sample differently in one app. They are leaf data: the plugins read them, they depend on none.

use crate::EnvisSamplingPlugin;
use bevy::core_pipeline::prepass::{DeferredPrepass, DepthPrepass, MotionVectorPrepass};
use bevy::prelude::*;
use bevy::render::extract_component::ExtractComponent;
use bevy::render::sync_component::SyncComponent;

pub use envis::render::EnvironmentSampling;

/// The camera component is the core's settings type (a `Component` with the core's `bevy`
/// feature); the plugin marker lets this crate extract it to the render world.
impl SyncComponent<EnvisSamplingPlugin> for EnvironmentSampling {
    type Target = Self;
}

impl ExtractComponent<EnvisSamplingPlugin> for EnvironmentSampling {
    type QueryData = &'static Self;
    type QueryFilter = ();
    type Out = Self;

    fn extract_component(settings: &Self) -> Option<Self> {
        Some(*settings)
    }
}

/// What a sampling camera needs from Bevy, added with it as required components: the depth
/// and deferred prepasses (envis lights the G-buffer), HDR, and no MSAA (deferred has none).
/// Registered when the plugin is built, before any camera is spawned; a camera given
/// `EnvironmentSampling` before that would miss them, which is said once.
pub(crate) fn require_camera_set_up(app: &mut App) {
    use bevy::ecs::component::RequiredComponentsError;
    let results = [
        app.try_register_required_components::<EnvironmentSampling, DepthPrepass>(),
        app.try_register_required_components::<EnvironmentSampling, DeferredPrepass>(),
        app.try_register_required_components::<EnvironmentSampling, bevy::camera::Hdr>(),
        app.try_register_required_components_with::<EnvironmentSampling, Msaa>(|| Msaa::Off),
    ];
    for r in results {
        match r {
            // Registered already (the plugin's set-up run again on the same app): as wanted.
            Ok(()) | Err(RequiredComponentsError::DuplicateRegistration(..)) => {}
            Err(e) => warn!(
                "envis: EnvironmentSampling's camera set-up (prepasses, HDR, no MSAA) could not \
                 be required ({e}): add EnvisPlugin before spawning sampling cameras"
            ),
        }
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

/// Reservoir resampling of the environment light on this camera: with it,
/// [`EnvironmentSampling`]'s `light_samples` / `brdf_samples` are the candidates each pixel
/// draws per frame, and the image reuses the previous frame's and the neighbours' samples.
/// Removing it gives the plain estimator back.
#[derive(Component, Clone, Copy, Debug, PartialEq, Reflect)]
#[reflect(Component, Default, Clone)]
#[require(MotionVectorPrepass, DepthPrepass, DeferredPrepass)]
pub struct EnvironmentResampling {
    /// Reuse the previous frame's reservoirs (found through the motion vectors).
    pub temporal: bool,
    /// Spatial neighbours reused per pixel (at most 8: more are clamped), drawn where the
    /// pixel's history is short (under [`SPATIAL_UNTIL_HISTORY`] frames: a disocclusion, the
    /// first frames after a reset, `temporal: false`).
    ///
    /// [`SPATIAL_UNTIL_HISTORY`]: envis::render::resampling::SPATIAL_UNTIL_HISTORY
    pub spatial: u32,
    /// The cap on a reservoir's confidence from its history (frames' worth of candidates).
    pub max_history: u32,
    /// Pairwise MIS with visibility in the reuse (unbiased, a few more shadow rays); `false`:
    /// 1/M weights, no visibility reuse (faster, biased: measured in `docs/temporal.md`).
    pub unbiased: bool,
    /// Clear the history this frame (a camera cut), as TAA's `reset`; set back to `false`
    /// after the frame is extracted.
    pub reset: bool,
}

impl Default for EnvironmentResampling {
    fn default() -> Self {
        EnvironmentResampling {
            temporal: true,
            spatial: 3,
            max_history: 20,
            unbiased: true,
            reset: false,
        }
    }
}
