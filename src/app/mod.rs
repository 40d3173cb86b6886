//! The Bevy layer: one plugin per capability, resources as the interface between the main and the
//! render world, and the same WGSL stages as the headless backend ([`crate::gpu`]).
//!
//! - [`EnvMapStreamPlugin`] (main world): advances an [`crate::stream::EnvStream`] every update
//!   and publishes the current frame as the [`EnvFrame`] resource (extracted to the render world).
//! - [`EnvMapSamplingPlugin`] (render world): uploads a frame only when its generation changed and
//!   records the distribution build + light pool in the `RenderGraph` schedule, before
//!   `camera_driver`, so every camera of the frame shades with this frame's distribution.
//! - [`MisLightingPlugin`] (render world): replaces Bevy's deferred lighting with the face-weighted
//!   MIS pass (`Core3d`, main pass, before the opaque pass); the sky shows the environment map.
//!
//! [`EnvisSettings`] (main world, extracted) holds the sampling settings; [`EnvisCounters`] is
//! shared by both worlds and counts the work done (builds, uploads, lighting passes), which is how
//! tests prove that work is skipped when nothing changed.

#[cfg(feature = "demo")]
pub mod demo;
pub mod headless;
pub mod lighting;
pub mod sampling;
pub mod scene_objects;
pub mod stream;
pub mod timing;

pub use lighting::{EnvisCamera, EnvisMaterial, MisLightingPlugin};
pub use sampling::EnvMapSamplingPlugin;
pub use stream::{EnvFrame, EnvMapStream, EnvMapStreamPlugin};
pub use timing::{EnvisTimings, PassTimes};

use crate::render::Settings;
use bevy::prelude::*;
use bevy::render::extract_resource::ExtractResource;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// Sampling settings of the app (the core's [`Settings`]) plus display options.
#[derive(Resource, Clone, ExtractResource)]
pub struct EnvisSettings {
    pub sampling: Settings,
    /// Multiplier applied to the HDR radiance before tonemapping.
    pub exposure: f32,
    /// Draw the environment where there is no geometry (off: those pixels are 0, as in the CPU
    /// renderer's contract).
    pub show_sky: bool,
    /// Full-screen debug overlay (none costs nothing: the shader skips it).
    pub overlay: Overlay,
    /// Pixel (viewport coordinates) whose G-buffer texel and estimate are read back for the
    /// sample-debug view ([`EnvisProbe`]).
    pub probe: Option<UVec2>,
    /// Average frames while nothing changes: every frame draws a new pool and new per-pixel
    /// streams (seeds mixed with [`Self::frame`]), so the running mean converges to the integral.
    pub accumulate: bool,
    /// Frames accumulated so far (0 = this frame starts a new average). Kept by
    /// [`track_accumulation`]; bump [`Self::scene_revision`] when the scene changes.
    pub frame: u32,
    /// Changes whenever something the image depends on changed outside the settings (materials).
    pub scene_revision: u32,
    /// Rebuild the distribution and pool every frame even when nothing changed (the always-on
    /// path the skipping is tested against; off in normal use).
    pub always_rebuild: bool,
}

impl EnvisSettings {
    /// The seed of this frame: the user's seed, mixed with the accumulation frame when accumulating.
    pub fn frame_seed(&self) -> u32 {
        if self.accumulate && self.frame > 0 {
            crate::sampling::rng::hash_combine(&[self.sampling.seed, self.frame])
        } else {
            self.sampling.seed
        }
    }
}

/// Restart the running mean when the camera, the environment frame, the settings or the scene
/// changed; otherwise count one more frame.
pub fn track_accumulation(
    mut settings: ResMut<EnvisSettings>,
    cams: Query<&GlobalTransform, With<EnvisCamera>>,
    frame: Res<EnvFrame>,
    mut last: Local<Option<String>>,
) {
    if !settings.accumulate {
        if settings.frame != 0 {
            settings.frame = 0;
        }
        *last = None;
        return;
    }
    let s = &*settings;
    let key = format!(
        "{:?}|{}|{}|{:?}|{}|{}|{}",
        s.sampling,
        s.exposure,
        s.show_sky,
        s.overlay,
        s.scene_revision,
        frame.generation,
        cams.iter()
            .map(|t| format!("{:?}", t.to_matrix().to_cols_array()))
            .collect::<String>()
    );
    if last.as_deref() == Some(key.as_str()) {
        settings.frame += 1;
    } else {
        settings.frame = 0;
        *last = Some(key);
    }
}

impl Default for EnvisSettings {
    fn default() -> Self {
        EnvisSettings {
            sampling: Settings::default(),
            exposure: 1.0,
            show_sky: true,
            overlay: Overlay::None,
            probe: None,
            accumulate: false,
            frame: 0,
            scene_revision: 0,
            always_rebuild: false,
        }
    }
}

/// Full-screen debug overlays of the lighting pass.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Overlay {
    #[default]
    None,
    /// Samples each pixel evaluated (used light + BRDF) over its budget, as a heat map.
    EffectiveSamples,
    /// Fraction of the used light samples with a negative cosine (the seed's yellow).
    Wasted,
    /// |fractional - integer| / fractional: where integer counts pop.
    CountsDifference,
}

impl Overlay {
    pub const ALL: [Overlay; 4] = [
        Overlay::None,
        Overlay::EffectiveSamples,
        Overlay::Wasted,
        Overlay::CountsDifference,
    ];
    pub fn name(self) -> &'static str {
        match self {
            Overlay::None => "none",
            Overlay::EffectiveSamples => "effective samples",
            Overlay::Wasted => "wasted (yellow) fraction",
            Overlay::CountsDifference => "fractional - integer",
        }
    }

    /// What the overlay's colour scale means: the value at the red end (blue is 0), its unit, and
    /// what is measured. `budget` is the pixel's `N_L + N_B`. `None` for no overlay.
    pub fn legend(self, budget: usize) -> Option<OverlayLegend> {
        let (full_scale, unit, measures) = match self {
            Overlay::None => return None,
            Overlay::EffectiveSamples => (
                budget.max(1) as f32,
                "samples",
                "samples each pixel evaluated (used light + BRDF samples; red = the full budget)",
            ),
            Overlay::Wasted => (
                100.0,
                "%",
                "share of the used light samples below the horizon (the seed's yellow)",
            ),
            // The shader draws heat(4 d): red at a 25% relative difference.
            Overlay::CountsDifference => (
                25.0,
                "%",
                "|fractional - integer| / |fractional|: where integer counts pop",
            ),
        };
        Some(OverlayLegend {
            full_scale,
            unit,
            measures,
        })
    }
}

/// The colour scale of an overlay (see [`Overlay::legend`]).
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
    pub gpixel: crate::render::GPixel,
    /// The GPU's estimate for the pixel (before exposure).
    pub estimate: Vec3,
    /// Its random-stream index (the CPU twin needs it to reproduce the estimate).
    pub pixel_index: u32,
}

/// The latest probe result, shared by both worlds.
#[derive(Resource, Clone, Default, Deref)]
pub struct EnvisProbe(pub Arc<std::sync::Mutex<Option<ProbeResult>>>);

/// Work counters, shared by the main and the render world.
#[derive(Default, Debug)]
pub struct Counters {
    /// Distribution + pool builds recorded.
    pub builds: AtomicU64,
    /// Frames uploaded to the GPU.
    pub uploads: AtomicU64,
    /// GPU sampler (re)allocations (face size or pool size changed).
    pub allocations: AtomicU64,
    /// Lighting passes recorded (one per camera per frame).
    pub lighting_passes: AtomicU64,
    /// Lighting passes that ran an overlay (the overlay is a branch of the lighting pass: with
    /// overlays off this stays 0 and no overlay code runs).
    pub overlay_passes: AtomicU64,
}

/// Handle to the shared [`Counters`] (present in both worlds).
#[derive(Resource, Clone, Default, Deref)]
pub struct EnvisCounters(pub Arc<Counters>);

impl EnvisCounters {
    pub fn get(&self, c: impl Fn(&Counters) -> &AtomicU64) -> u64 {
        c(&self.0).load(Ordering::Relaxed)
    }
    pub(crate) fn bump(&self, c: impl Fn(&Counters) -> &AtomicU64) {
        c(&self.0).fetch_add(1, Ordering::Relaxed);
    }
}

/// The three envis plugins with default settings: the built-in sky, faces of 64^2.
pub struct EnvisPlugins;

impl Plugin for EnvisPlugins {
    fn build(&self, app: &mut App) {
        app.add_plugins((
            EnvMapStreamPlugin::default(),
            EnvMapSamplingPlugin,
            MisLightingPlugin,
        ));
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
            assert_eq!(o.legend(64).is_some(), o != Overlay::None, "{o:?}");
        }
        assert_eq!(
            Overlay::EffectiveSamples.legend(64).unwrap().full_scale,
            64.0
        );
    }
}
