//! What a Bevy user imports: `use bevy_envis::prelude::*;`.
//!
//! - [`EnvisPlugin`]: add it next to `DefaultPlugins`; [`EnvisShaderReloadPlugin`] recompiles
//!   the lighting pass when its WGSL changes (the examples add it).
//! - [`EnvironmentSampling`] and [`EnvisEnvironment`]: the two camera components;
//!   [`EnvironmentResampling`] adds reservoir resampling across pixels and frames;
//!   [`EnvisLightReady`] marks a camera from the first frame envis lit it (a loading screen
//!   waits for it).
//! - [`EnvisMaterial`] / [`EnvisBrdf`]: envis's own deferred material (plain `StandardMaterial`
//!   meshes are lit too).
//! - The sampling vocabulary: [`Strategy`], [`Counts`], [`Heuristic`], [`Overlay`],
//!   [`ShadowRays`] (`EnvironmentSampling::shadows`).

pub use crate::{
    EnvironmentResampling, EnvironmentSampling, EnvisBrdf, EnvisEnvironment, EnvisLightReady,
    EnvisMaterial, EnvisPlugin, EnvisShaderReloadPlugin, Overlay, exposure_multiplier,
};
pub use envis::render::Strategy;
pub use envis::sampling::{Counts, Heuristic};
pub use envis::visibility::ShadowRays;
