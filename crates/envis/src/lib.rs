//! # envis
//!
//! Real-time, unbiased importance sampling of dynamic HDR environment maps, after Lu, Pacanowski
//! & Granier, "Real-Time Importance Sampling of Dynamic Environment Maps" (Eurographics 2013).
//!
//! Data flows one way: environment map ([`envmap`]) -> per-face distributions and the light-sample
//! pool ([`sampling`]) -> per-pixel face weighting and MIS shading ([`render`]). This core needs
//! no Bevy and no GPU; it is the oracle that the GPU stages (`envis_wgpu`) and the Bevy plugins
//! (`bevy_envis`) are tested against.
//!
//! Features: `clap` (`clap::ValueEnum` on the settings enums, for command lines), `bevy` (the
//! settings as Bevy data: `EnvironmentSampling` a component, the enums reflected; bevy_ecs and
//! bevy_reflect only), `bytemuck` (the flat BVH's nodes as plain GPU data).

pub mod cpu;
pub mod envmap;
pub mod error;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod stream;
pub mod visibility;
#[doc(hidden)]
pub mod vocab;

pub use error::{Error, Result};
