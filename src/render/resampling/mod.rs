//! Reservoir resampling (ReSTIR) of the paper's samples across pixels and frames: the CPU oracle.
//!
//! Per frame, for every pixel:
//! 1. **Candidates** ([`CandidateSink`]): the paper's face-weighted light samples (fractional
//!    counts) and the BRDF samples, exactly as the estimator draws them but without shadow rays,
//!    streamed into one reservoir. The target `p̂` is the luminance of the unshadowed integrand
//!    (BRDF x cosine x radiance). The selected sample gets one shadow ray; blocked, the
//!    reservoir is culled (`W = 0`).
//! 2. **Temporal reuse**: the previous frame's final reservoir at the reprojected pixel (the
//!    caller's `reproject`), rejected on disocclusion ([`similar`]), its confidence capped at
//!    `max_history`, its sample's target re-evaluated under this frame's map and geometry, and
//!    combined with the candidates ([`combine`](combine::combine)).
//! 3. **Spatial reuse**: `spatial` neighbours' temporal reservoirs in a disc of
//!    [`SPATIAL_RADIUS`] pixels, passing the same geometric tests, combined the same way.
//! 4. The estimate `f(Y) V(Y) W`; the final reservoirs are the next frame's history.
//!
//! Unbiased by default (pairwise MIS, [`combine`](combine::combine)): shadow rays are the
//! candidate's, one per reused sample (the canonical pixel must see what it selects), and one per
//! other domain for the canonical sample's MIS weight: at most `1 + 2 (1 + spatial)` per pixel
//! (9 at the defaults; 4.6 on average on the motion scene, docs/temporal.md). The biased option
//! spends at most 2. Deterministic: every pass draws from its own per-pixel stream.

mod combine;
mod passes;
mod reservoir;

pub use combine::{Domain, DomainSurface, combine};
pub use reservoir::{CandidateSink, Reservoir};

use passes::{candidates, spatial, temporal};

use super::estimator::{FrameData, shading_directions};
use super::{GPixel, PixelStats, RenderStats, Settings};
use crate::envmap::{CubeMap, Image};
use crate::sampling::rng::{Rng, hash_combine};
use crate::sampling::warp::Frame;
use crate::visibility::Occluder;
use glam::Vec3;
use rayon::prelude::*;

/// Which reuse a sequence does (`--resampling`).
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    serde::Serialize,
    serde::Deserialize,
    clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum ResamplingMode {
    /// No resampling: every frame is today's estimator (every sample shadow-tested).
    Off,
    /// Candidates and the previous frame's reservoir.
    Temporal,
    /// Temporal, then `spatial` neighbours.
    #[default]
    Spatiotemporal,
}
crate::vocab::display_as_value_enum!(ResamplingMode);

/// How a frame resamples. The defaults are `EnvironmentResampling`'s.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Resampling {
    pub temporal: bool,
    /// Neighbours of the spatial pass (0: none).
    pub spatial: u32,
    /// The history's confidence is capped at this many frames of candidates.
    pub max_history: u32,
    /// MIS weights with visibility (unbiased) or `1 / M` (biased, fewer rays).
    pub unbiased: bool,
    /// Shadow-test every candidate (one ray per light and BRDF sample), so that the target is
    /// the shadowed integrand from the start: no blocked sun can inflate a sky sample's weight
    /// (docs/temporal.md). Off by default: the budget is one ray per selected sample.
    pub candidate_visibility: bool,
    /// A deliberate fault, for the tests that must catch it (`None` in any real use).
    #[serde(skip)]
    pub mutation: Option<Mutation>,
}

impl Default for Resampling {
    fn default() -> Self {
        Resampling {
            temporal: true,
            spatial: 3,
            max_history: 20,
            unbiased: true,
            candidate_visibility: false,
            mutation: None,
        }
    }
}

impl Resampling {
    /// The settings of a `--resampling` mode (`None` for `off`).
    pub fn for_mode(mode: ResamplingMode, unbiased: bool) -> Option<Self> {
        let base = Resampling {
            unbiased,
            ..Default::default()
        };
        match mode {
            ResamplingMode::Off => None,
            ResamplingMode::Temporal => Some(Resampling { spatial: 0, ..base }),
            ResamplingMode::Spatiotemporal => Some(base),
        }
    }
}

/// Faults the mutation tests inject, each one a way reuse can be broken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mutation {
    /// A reused sample keeps its old target instead of being re-evaluated here and now.
    StaleTarget,
    /// The other domains' terms are left out of the MIS weight's denominator.
    DroppedMisTerm,
    /// Reprojection looks the point up with this frame's camera instead of the previous one
    /// (applied by the sequence driver, which owns the cameras).
    WrongReprojection,
}

/// Spatial neighbours are drawn uniformly in a disc of this radius, in pixels.
pub const SPATIAL_RADIUS: f32 = 8.0;
/// Two pixels' surfaces may share samples when their normals are within this cosine...
pub const NORMAL_COS: f32 = 0.9;
/// ...their camera distances within this fraction of each other, and they are the same object
/// (same material).
pub const DEPTH_REL: f32 = 0.1;

/// Per pixel, what the geometric tests read besides the G-buffer.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Surface {
    /// Distance from the camera.
    pub depth: f32,
    /// The object hit.
    pub id: u32,
}

/// Whether two surfaces (normal, surface) can share samples: same object, normals within
/// [`NORMAL_COS`], depths within [`DEPTH_REL`].
pub fn similar(n_a: Vec3, a: Surface, n_b: Vec3, b: Surface) -> bool {
    a.id == b.id
        && n_a.normalize_or_zero().dot(n_b.normalize_or_zero()) >= NORMAL_COS
        && (a.depth - b.depth).abs() <= DEPTH_REL * a.depth.max(b.depth)
}

/// One frame's screen: the map, the G-buffer, each pixel's surface point and [`Surface`], and
/// the scene's shadow-casting geometry (`None`: no shadows).
#[derive(Clone, Copy)]
pub struct Screen<'a> {
    pub map: &'a CubeMap,
    pub gbuf: &'a [Option<GPixel>],
    pub points: &'a [Vec3],
    pub surfaces: &'a [Surface],
    pub width: usize,
    pub height: usize,
    pub occluder: Option<&'a dyn Occluder>,
}

impl<'a> Screen<'a> {
    fn surface(&self, i: usize) -> Option<DomainSurface<'a>> {
        self.gbuf[i].as_ref().map(|px| DomainSurface {
            map: self.map,
            px,
            point: self.points[i],
            occluder: self.occluder,
        })
    }
}

/// The previous frame as temporal reuse reads it.
#[derive(Clone, Copy)]
pub struct History<'a> {
    pub screen: Screen<'a>,
    pub reservoirs: &'a [Reservoir],
}

/// Where pixel `i` of this frame was in the previous one: the pixel, and the distance from the
/// previous camera its point had then (for the depth test). `None`: off screen.
pub type Reproject<'a> = &'a (dyn Fn(usize) -> Option<(usize, f32)> + Sync);

/// A resampled frame.
pub struct Resampled {
    pub image: Image,
    /// The history for the next frame.
    pub reservoirs: Vec<Reservoir>,
    pub stats: RenderStats,
    pub reuse: ReuseStats,
}

/// What reuse did in a frame.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct ReuseStats {
    /// Pixels whose previous reservoir passed the tests.
    pub temporal_accepted: u64,
    /// Neighbours that passed the tests, over all pixels.
    pub spatial_accepted: u64,
    /// Mean confidence `M` of the final reservoirs over shaded pixels.
    pub mean_history: f64,
}

/// The unshadowed integrand `f(o, d) L(d) <n, d>+` at a pixel (the target's colour).
pub fn target_rgb(map: &CubeMap, px: &GPixel, d: Vec3) -> Vec3 {
    let Some((n, o)) = shading_directions(px) else {
        return Vec3::ZERO;
    };
    let cos = n.dot(d);
    if cos <= 0.0 {
        return Vec3::ZERO;
    }
    let frame = Frame::new(n);
    px.material.eval_local(frame.to_local(o), frame.to_local(d)) * map.lookup(d) * cos
}

/// The seed of frame `frame` of a sequence whose settings' seed is `seed`: frames draw new
/// samples (pool and per-pixel streams) so reuse averages them.
pub fn frame_seed(seed: u32, frame: u32) -> u32 {
    if frame == 0 {
        seed
    } else {
        hash_combine(&[seed, frame, 0x7e57])
    }
}

/// Resample frame `frame` of a sequence: candidates, temporal reuse against `history`, spatial
/// reuse, shading. `s` gives the candidates (`light_samples` + `brdf_samples` per pixel); its
/// seed is mixed with the frame index ([`frame_seed`]).
pub fn resample_frame(
    cur: &Screen,
    history: Option<(History, Reproject)>,
    s: &Settings,
    r: &Resampling,
    frame: u32,
) -> crate::error::Result<Resampled> {
    s.validate_for(cur.map.size)?;
    let n_px = cur.width * cur.height;
    assert_eq!(cur.gbuf.len(), n_px);
    let s = Settings {
        seed: frame_seed(s.seed, frame),
        ..*s
    };
    let t0 = std::time::Instant::now();
    let mut fd = FrameData::prepare(cur.map, &s);
    if r.candidate_visibility {
        fd.occluder = cur.occluder;
    }
    let build_ms = t0.elapsed().as_secs_f64() * 1e3;
    let t1 = std::time::Instant::now();
    let stream = |pass: u32, i: usize| Rng::new(hash_combine(&[s.seed, pass, 0x5e57]), i as u32);
    // 1. Candidates, and the selected one's shadow ray.
    let first: Vec<(Reservoir, Option<PixelStats>, u32)> = (0..n_px)
        .into_par_iter()
        .map(|i| candidates(cur, &fd, &s, r, i, stream(1, i)))
        .collect();
    let mut rays: Vec<u32> = first.iter().map(|f| f.2).collect();
    let per_pixel: Vec<Option<PixelStats>> = first.iter().map(|f| f.1).collect();
    let mut res: Vec<Reservoir> = first.into_iter().map(|f| f.0).collect();
    let mut reuse = ReuseStats::default();
    // 2. Temporal.
    if let (true, Some((h, reproject))) = (r.temporal, history) {
        let out: Vec<(Reservoir, u32, bool)> = (0..n_px)
            .into_par_iter()
            .map(|i| temporal(cur, &h, reproject, r, &res, i, stream(2, i)))
            .collect();
        reuse.temporal_accepted = out.iter().filter(|o| o.2).count() as u64;
        for (i, (t, n, _)) in out.into_iter().enumerate() {
            res[i] = t;
            rays[i] += n;
        }
    }
    // 3. Spatial.
    if r.spatial > 0 {
        let out: Vec<(Reservoir, u32, u32)> = (0..n_px)
            .into_par_iter()
            .map(|i| spatial(cur, r, &res, i, stream(3, i)))
            .collect();
        reuse.spatial_accepted = out.iter().map(|o| o.2 as u64).sum();
        for (i, (t, n, _)) in out.into_iter().enumerate() {
            res[i] = t;
            rays[i] += n;
        }
    }
    // 4. Shade: the final sample's visibility where it is not known yet (the biased mode).
    let data: Vec<(Vec3, u32)> = res
        .par_iter_mut()
        .enumerate()
        .map(|(i, q)| {
            let mut n = 0;
            if let (Some(at), true) = (cur.surface(i), q.is_live() && !q.visible) {
                q.visible = at.visible(q.dir, &mut n);
                if !q.visible {
                    q.ucw = 0.0;
                }
            }
            (
                if q.is_live() {
                    q.estimate()
                } else {
                    Vec3::ZERO
                },
                n,
            )
        })
        .collect();
    let shade_ms = t1.elapsed().as_secs_f64() * 1e3;
    let mut stats = RenderStats::for_settings(cur.width, cur.height, &s, fd.pool.block);
    (stats.build_ms, stats.shade_ms) = (build_ms, shade_ms);
    stats.accumulate(&per_pixel);
    // The candidates' own rays (`candidate_visibility`) are in `accumulate`'s count already.
    stats.shadow_rays += rays
        .iter()
        .zip(&data)
        .map(|(a, b)| (a + b.1) as u64)
        .sum::<u64>();
    let shaded = cur.gbuf.iter().filter(|p| p.is_some()).count().max(1);
    reuse.mean_history = cur
        .gbuf
        .iter()
        .zip(&res)
        .filter(|(p, _)| p.is_some())
        .map(|(_, q)| q.m as f64)
        .sum::<f64>()
        / shaded as f64;
    let image = Image {
        width: cur.width,
        height: cur.height,
        data: data.into_iter().map(|d| d.0).collect(),
    };
    Ok(Resampled {
        image,
        reservoirs: res,
        stats,
        reuse,
    })
}
