//! What a render is asked to do: the estimator ([`Strategy`]), the sample budget and how it is
//! split, and the seeds. Shared by the CPU renderer, the GPU stages and the Bevy plugins.

use crate::error::{Error, Result};
use crate::sampling::rng::hash;
use crate::sampling::{Counts, Heuristic};
#[cfg(feature = "bevy")]
use bevy_ecs::reflect::ReflectComponent;
#[cfg(feature = "bevy")]
use bevy_reflect::std_traits::ReflectDefault;

/// Which estimator shades the pixels. The same lowercase names serve the command line
/// (`--strategy`), scene files (`strategy = "paper"`), JSON output and the demo panel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
// Reflected for the Bevy camera component (`bevy_envis::EnvironmentSampling`, feature `bevy`).
#[cfg_attr(feature = "bevy", derive(bevy_reflect::Reflect))]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Strategy {
    /// The paper's method: per-pixel face weighting (light energy x pseudo form factor) of the
    /// shared pool, N_L light + N_B BRDF samples combined by MIS.
    Paper,
    /// pbrt-style: one lat-long distribution for the whole sphere, N_L samples per pixel, MIS
    /// with N_B BRDF samples.
    Global,
    /// Light only: N_L + N_B pool samples spread over faces by face energy alone (no cosine).
    Light,
    /// BRDF only: N_L + N_B BRDF samples.
    Brdf,
}

crate::display_as_serde_name!(Strategy);

/// How pixels share the per-frame light pool (`--pool-layout`, `pool_layout` in scene files and
/// on the Bevy camera). Every layout is unbiased: each pixel's light samples are, one by one,
/// distributed as the face pdfs. They differ in how the error is shared between pixels
/// (`docs/benchmarks.md`, "Pool layouts").
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "bevy", derive(bevy_reflect::Reflect))]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum PoolLayout {
    /// The paper's: one pool of `M` samples per face, every pixel takes its first `N_f`. The
    /// error is the same pattern in every pixel (whole-image flicker from frame to frame).
    Shared,
    /// One pool; each pixel starts at a random slot and wraps. With `M > N_L` pixels decorrelate,
    /// but a window of a larger stratified pool is not itself stratified.
    Offset,
    /// `K` independent stratified pools ("blocks", `--pool-blocks K`) of `M` samples per face;
    /// each pixel takes one block at random and reads it as the seed reads its pool. A pixel sees
    /// exactly a paper pool, so its own error is the paper's, while the image averages `K` pools.
    Blocks,
}

crate::display_as_serde_name!(PoolLayout);

impl PoolLayout {
    pub const ALL: [PoolLayout; 3] = [PoolLayout::Shared, PoolLayout::Offset, PoolLayout::Blocks];
}

/// Blocks of the `blocks` layout unless told otherwise: the fewest that bring the furnace's
/// image-mean flicker under 1% (`envis bench --suite flicker`).
pub const DEFAULT_POOL_BLOCKS: usize = 16;

/// How a render, or a Bevy camera, samples the environment: the one settings type of envis.
///
/// The CPU renderer, the GPU stages, the command line (`envis render`'s flags), scene files
/// (`[sampling]`) and the Bevy camera component read these fields under these names (the core
/// calls it [`Settings`]; with the `bevy` feature it *is* the camera component
/// `bevy_envis::prelude::EnvironmentSampling`, reflected and extracted). Every pixel with geometry gets
/// `light_samples` face-weighted light samples and `brdf_samples` BRDF samples, combined by
/// multiple importance sampling (Lu, Pacanowski & Granier 2013).
///
/// As a camera component it requires the deferred prepasses, an HDR target and no MSAA
/// (deferred rendering has none), and needs an `EnvisEnvironment` on the same camera to do
/// anything; removing it gives the camera back to Bevy's lighting alone. The last five fields
/// (`accumulate`, `overlay`, `face_size`, `probe`, `shadows`) are a view's: the CPU renderer takes
/// the map, the shadow geometry and the pixels from its caller instead.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
// A Bevy camera component with the `bevy` feature (bevy_envis extracts it and adds the
// prepasses, HDR and no MSAA it needs as required components); the core stays engine-free.
#[cfg_attr(
    feature = "bevy",
    derive(bevy_ecs::component::Component, bevy_reflect::Reflect),
    reflect(Component, Default, Clone)
)]
pub struct EnvironmentSampling {
    /// Light samples per pixel, `N_L` (shared between the cube faces by their face weights).
    pub light_samples: usize,
    /// BRDF samples per pixel, `N_B`.
    pub brdf_samples: usize,
    /// `paper` (the method: cosine face weights), `light` (energy only), `brdf`, or `global`
    /// (one lat-long distribution: the baseline).
    pub strategy: Strategy,
    /// `fractional` counts are unbiased and do not pop; `integer` counts are the paper's toggle.
    pub counts: Counts,
    /// The MIS heuristic (balance or power); `--mis` on the command line.
    pub heuristic: Heuristic,
    /// Light samples drawn per cube face (or tile) per frame, `M` (0: `light_samples`); `--pool`.
    pub pool_size: usize,
    /// How pixels share the pool: `shared` (the paper's: the same samples everywhere, coherent
    /// error), `offset` (a random start per pixel) or `blocks` (one of `pool_blocks`
    /// independent pools per pixel: the error becomes noise; `docs/benchmarks.md`).
    pub pool_layout: PoolLayout,
    /// `K`, the pool's blocks with [`PoolLayout::Blocks`] (ignored otherwise).
    pub pool_blocks: usize,
    /// Let each pixel's material choose the split of the `N_L + N_B` budget (`paper` only): see
    /// [`budget_for`].
    pub material_budget: bool,
    /// `K`: each face cut into `K x K` tiles, each weighted and sampled on its own
    /// (`--tiles`; `1` is the paper's whole faces; [`crate::sampling::tiles`]).
    pub tiles: usize,
    /// How the light samples are spread over tiles (`--tile-counts`; no effect with one tile).
    pub tile_counts: crate::sampling::TileCounts,
    /// Random seed of the pool and the per-pixel streams.
    pub seed: u32,
    /// A view's: average frames while nothing changes (camera, settings, map, viewport size).
    #[serde(skip)]
    pub accumulate: bool,
    /// A view's: a full-screen debug view instead of the image.
    #[serde(skip)]
    pub overlay: super::Overlay,
    /// Face size of the sampling distribution (a sampling choice: radiance comes from the
    /// full-resolution image; `--face-size` on the command line, whose map the caller loads).
    pub face_size: usize,
    /// A view's: the pixel (viewport coordinates) whose G-buffer texel and estimate are read
    /// back into `EnvisProbe` (the demo's sample-debug view).
    #[serde(skip)]
    pub probe: Option<glam::UVec2>,
    /// Shadow rays for every light and BRDF sample: `auto` (on when something can cast a
    /// shadow), `on` or `off` (`--visibility`, a scene file's `shadows`). In a Bevy view,
    /// `NotShadowCaster` meshes cast none; the CPU renderer casts them where its caller gives
    /// it the scene (`Extras::shadows`).
    pub shadows: crate::visibility::ShadowRays,
}

/// The core's name of [`EnvironmentSampling`]: what a render is asked to do.
pub type Settings = EnvironmentSampling;

/// Phong exponents from here up, and GGX roughness from here down, count as near-mirror lobes.
pub const NEAR_MIRROR_EXPONENT: f32 = 1000.0;
pub const NEAR_MIRROR_ALPHA: f32 = 0.02;

/// The material-driven split of a pixel's budget `(N_L, N_B)` (the `paper` strategy with
/// [`Settings::material_budget`]):
/// - diffuse only (no glossy lobe): all `N_L + N_B` samples from the light pool. Light sampling
///   with face weighting covers every direction the cosine lobe reaches, so it is unbiased alone,
///   and the accuracy sweep shows light samples beat BRDF samples on diffuse at every budget.
/// - a near-mirror lobe with no diffuse part: all samples from the BRDF. Light samples almost never
///   land in the lobe, and the BRDF pdf covers its whole support.
/// - otherwise the user's split, combined by MIS.
///
/// Each choice is an unbiased estimator on its own, so mixing them per pixel stays unbiased.
#[inline]
pub fn budget_for(m: &crate::sampling::Material, nl: usize, nb: usize) -> (usize, usize) {
    use crate::sampling::Lobe;
    let near_mirror = match m.lobe {
        Lobe::None => false,
        Lobe::Phong { exponent } => exponent >= NEAR_MIRROR_EXPONENT,
        Lobe::Ggx { alpha } | Lobe::GgxSchlick { alpha } => alpha <= NEAR_MIRROR_ALPHA,
    };
    if m.lobe == Lobe::None || m.ks.max_element() <= 0.0 {
        (nl + nb, 0)
    } else if near_mirror && m.kd.max_element() <= 0.0 {
        (0, nl + nb)
    } else {
        (nl, nb)
    }
}

impl Default for EnvironmentSampling {
    fn default() -> Self {
        EnvironmentSampling {
            light_samples: 32,
            brdf_samples: 32,
            pool_size: 0,
            strategy: Strategy::Paper,
            counts: Counts::Fractional,
            heuristic: Heuristic::Balance,
            seed: 0,
            // Not the paper's shared pool: blocks meet the FLIP and flicker targets at the paper's
            // per-pixel error (`docs/benchmarks.md`, "Pool layouts"); `Shared` keeps the paper's.
            pool_layout: PoolLayout::Blocks,
            pool_blocks: DEFAULT_POOL_BLOCKS,
            material_budget: false,
            tiles: 1,
            tile_counts: crate::sampling::TileCounts::Face,
            accumulate: false,
            overlay: super::Overlay::None,
            face_size: 64,
            probe: None,
            shadows: crate::visibility::ShadowRays::Auto,
        }
    }
}

impl Settings {
    /// Refuse settings that cannot produce an estimate. The messages name the fields (as the
    /// Bevy component and scene files spell them; the CLI's flags are the same words with `-`).
    pub fn validate(&self) -> Result<()> {
        if self.light_samples == 0 && self.brdf_samples == 0 {
            return Err(Error::invalid(
                "light_samples and brdf_samples are both 0: nothing to estimate with",
            ));
        }
        if self.light_samples > 1 << 16 || self.brdf_samples > 1 << 16 || self.pool_size > 1 << 20 {
            return Err(Error::invalid(
                "sample counts above 65536 per pixel (or a pool above 2^20 per face) are refused",
            ));
        }
        if self.pool_layout == PoolLayout::Blocks && !(1..=1024).contains(&self.pool_blocks) {
            return Err(Error::invalid(format!(
                "pool_blocks {} is out of range (1 to 1024)",
                self.pool_blocks
            )));
        }
        if !(1..=crate::sampling::MAX_TILES).contains(&self.tiles) {
            return Err(Error::invalid(format!(
                "tiles {} is out of range (1 to {})",
                self.tiles,
                crate::sampling::MAX_TILES
            )));
        }
        if self.pool_slots() > 1 << 20 {
            return Err(Error::invalid(
                "a pool above 2^20 samples per face or tile (M x blocks) is refused",
            ));
        }
        Ok(())
    }

    /// [`Self::validate`] against a map of face size `n`: a tile must hold a texel.
    pub fn validate_for(&self, n: usize) -> Result<()> {
        self.validate()?;
        if self.tiles > n {
            return Err(Error::invalid(format!(
                "tiles {} needs faces of at least {} texels (these have {n})",
                self.tiles, self.tiles
            )));
        }
        Ok(())
    }

    /// `N_L + N_B`, the samples a pixel is given (its material or strategy splits them:
    /// [`Settings::budget`]).
    pub fn samples_per_pixel(&self) -> usize {
        self.light_samples + self.brdf_samples
    }

    /// `(N_L, N_B)` for a pixel of material `m`: the strategy's split of the budget (and the
    /// material's, with [`Settings::material_budget`]).
    pub fn budget(&self, m: &crate::sampling::Material) -> (usize, usize) {
        match self.strategy {
            Strategy::Paper if self.material_budget => {
                budget_for(m, self.light_samples, self.brdf_samples)
            }
            _ => self.strategy_budget(),
        }
    }

    /// `(N_L, N_B)` as the strategy alone splits the budget: light-only and BRDF-only strategies
    /// spend all of `light_samples + brdf_samples` on their one technique.
    pub fn strategy_budget(&self) -> (usize, usize) {
        let all = self.light_samples + self.brdf_samples;
        match self.strategy {
            Strategy::Paper | Strategy::Global => (self.light_samples, self.brdf_samples),
            Strategy::Light => (all, 0),
            Strategy::Brdf => (0, all),
        }
    }

    /// M, the pool samples per region (face, or tile) a pixel can draw from (one block's, with
    /// [`PoolLayout::Blocks`]).
    pub fn pool_per_face(&self) -> usize {
        let all = self.strategy == Strategy::Light
            || (self.strategy == Strategy::Paper && self.material_budget);
        if self.pool_size > 0 {
            self.pool_size
        } else {
            self.light_samples.max(1) + if all { self.brdf_samples } else { 0 }
        }
    }

    /// Blocks in the pool: [`Settings::pool_blocks`] with [`PoolLayout::Blocks`], else 1.
    pub fn pool_block_count(&self) -> usize {
        match self.pool_layout {
            PoolLayout::Blocks => self.pool_blocks.max(1),
            PoolLayout::Shared | PoolLayout::Offset => 1,
        }
    }

    /// Slots per region (face, or tile) in the whole pool: `M` x blocks.
    pub fn pool_slots(&self) -> usize {
        self.pool_per_face() * self.pool_block_count()
    }
}

/// The light pool's seed for a render seed (shared with the GPU backend, so both draw one pool).
pub fn pool_seed(seed: u32) -> u32 {
    hash(seed ^ 0xA511_E9B3)
}
