//! # envis
//!
//! Real-time, unbiased importance sampling of dynamic HDR environment maps, after Lu, Pacanowski
//! & Granier, "Real-Time Importance Sampling of Dynamic Environment Maps" (Eurographics 2013).
//!
//! Data flows one way: environment map ([`envmap`]) -> per-face distributions and the light-sample
//! pool ([`sampling`]) -> per-pixel face weighting and MIS shading ([`render`]). This core needs
//! no Bevy and no GPU; it is the oracle that the GPU pipeline is tested against.

#[cfg(feature = "app")]
pub mod app;
pub mod bench;
pub mod cpu;
pub mod envmap;
pub mod error;
#[cfg(feature = "gpu")]
pub mod gpu;
#[cfg(feature = "app")]
pub mod prelude;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod sequence;
pub mod stats;
pub mod stream;
pub mod visibility;
mod vocab;

pub use error::{Error, Result};

/// The README, whose Bevy snippet `cargo test` compiles (a doc test), so the set-up it shows
/// cannot go stale; its other blocks are shell or text.
#[cfg(all(doctest, feature = "app"))]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;

/// docs/bevy.md, whose Bevy snippets `cargo test` compiles (doc tests).
#[cfg(all(doctest, feature = "app"))]
#[doc = include_str!("../docs/bevy.md")]
pub struct BevyDocDoctests;
