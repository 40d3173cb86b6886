//! The CPU renderer (the oracle for the GPU pipeline): per-frame distribution + pool build, then
//! deferred shading of a G-buffer with one of four estimators, in parallel and deterministic for a
//! given seed (every pixel has its own random stream).
//!
//! - [`settings`]: what a render is asked to do (strategy, budget, seeds);
//! - [`estimator`]: one pixel's estimate (light pool / global / BRDF samples, MIS);
//! - [`stats`]: sample accounting and `--stats`;
//! - [`debug`]: the paper's red / green / yellow classification of one pixel's pool samples;
//! - [`reference`](mod@reference): the exact f64 quadrature the estimators are tested against.

pub mod debug;
pub mod estimator;
pub mod output;
mod overlay;
pub mod reference;
pub mod resampling;
pub mod scene;
pub mod settings;
pub mod stats;

use crate::envmap::CubeMap;
use crate::error::Result;
use glam::Vec3;
use rayon::prelude::*;

pub use debug::{DebugSample, PixelDebug, SampleKind, debug_pixel, debug_pixel_at};
pub use estimator::{FrameData, shade_pixel};
pub use overlay::Overlay;
pub use scene::{GPixel, sphere_gbuffer};
pub use settings::{
    DEFAULT_POOL_BLOCKS, EnvironmentSampling, NEAR_MIRROR_ALPHA, NEAR_MIRROR_EXPONENT, PoolLayout,
    Settings, Strategy, budget_for, pool_seed,
};
pub use stats::{PixelStats, RenderStats};

/// A rendered image and its statistics.
pub struct Rendered {
    pub image: crate::envmap::Image,
    pub stats: RenderStats,
}

/// Render a G-buffer of `width x height` pixels (row-major, `None` = no geometry).
pub fn render(
    map: &CubeMap,
    gbuf: &[Option<GPixel>],
    width: usize,
    height: usize,
    s: &Settings,
) -> Result<Rendered> {
    render_with(map, Extras::default(), gbuf, width, height, s)
}

/// What a frame can add to the map and the G-buffer.
#[derive(Clone, Copy, Default)]
pub struct Extras<'a> {
    /// Radiance from the full-resolution environment while `map` gives the sampling densities:
    /// the CPU twin of the Bevy pass ([`FrameData::fine`]).
    pub fine: Option<estimator::FineRadiance<'a>>,
    /// The map at its own resolution, to sample the light inside the distribution's texels by
    /// its luminance ([`FrameData::with_sub_texels`]); the CLI passes the map `fine` reads.
    /// Every sample then reads its radiance from it (`fine` is not needed; a BRDF sample's
    /// radiance and its light density's factor come from one lookup).
    /// `None`: uniform inside them, as the Bevy pass samples.
    pub sub_texels: Option<&'a CubeMap>,
    /// Shadow rays: the scene, and each pixel's surface point (laid out as the G-buffer).
    pub shadows: Option<(&'a dyn crate::visibility::Occluder, &'a [Vec3])>,
}

/// [`render`] with [`Extras`].
pub fn render_with(
    map: &CubeMap,
    extras: Extras<'_>,
    gbuf: &[Option<GPixel>],
    width: usize,
    height: usize,
    s: &Settings,
) -> Result<Rendered> {
    s.validate_for(map.size)?;
    assert_eq!(gbuf.len(), width * height);
    if let Some((_, points)) = extras.shadows {
        assert_eq!(
            points.len(),
            gbuf.len(),
            "one surface point per G-buffer pixel"
        );
    }
    let t0 = std::time::Instant::now();
    let mut fd = FrameData::prepare(map, s);
    if let Some(fine) = extras.sub_texels {
        fd = fd.with_sub_texels(fine);
    }
    fd.fine = extras.fine;
    fd.occluder = extras.shadows.map(|(o, _)| o);
    let points = extras.shadows.map(|(_, p)| p);
    let build_ms = t0.elapsed().as_secs_f64() * 1e3;
    let t1 = std::time::Instant::now();
    let out: Vec<(Vec3, Option<PixelStats>)> = gbuf
        .par_iter()
        .enumerate()
        .map(|(i, px)| match px {
            Some(p) => {
                let at = points.map(|pts| pts[i]);
                let (c, st) = estimator::shade_pixel_at(&fd, s, p, at, i as u32);
                (c, Some(st))
            }
            None => (Vec3::ZERO, None),
        })
        .collect();
    let shade_ms = t1.elapsed().as_secs_f64() * 1e3;

    let mut stats = RenderStats::for_settings(width, height, s, fd.pool.block);
    stats.build_ms = build_ms;
    stats.shade_ms = shade_ms;
    let per_pixel: Vec<Option<PixelStats>> = out.iter().map(|(_, st)| *st).collect();
    stats.accumulate(&per_pixel);
    let image = crate::envmap::Image {
        width,
        height,
        data: out.into_iter().map(|(c, _)| c).collect(),
    };
    Ok(Rendered { image, stats })
}
