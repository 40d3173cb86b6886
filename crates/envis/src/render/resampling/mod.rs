//! Reservoir resampling (ReSTIR) of the paper's samples across pixels and frames: the CPU oracle.
//!
//! The map is split into its bright part (a sun) and the rest ([`Split`]); each part has a
//! reservoir per pixel ([`Part`]), and per frame, for every pixel and part:
//! 1. **Candidates**: for the rest, the paper's face-weighted light samples (fractional counts,
//!    on a distribution built from the rest) and the BRDF samples, exactly as the estimator
//!    draws them but without shadow rays, streamed into one reservoir ([`CandidateSink`]); the
//!    target `p̂` is the luminance of the rest's unshadowed integrand (BRDF x cosine x its
//!    radiance), and the selected sample gets one shadow ray (blocked, the reservoir is culled:
//!    `W = 0`). For the bright part, [`BRIGHT_LIGHT_SAMPLES`] samples of its own table and one
//!    BRDF sample, each shadow-tested ([`bright_reservoir`]): its target is the shadowed
//!    integrand. Where the previous frame's candidates found the bright part partly blocked at
//!    the pixel's place or beside it (a penumbra), [`BRIGHT_PENUMBRA_SAMPLES`] of them.
//! 2. **Temporal reuse**: the previous frame's reservoir at the reprojected pixel (the
//!    caller's `reproject`), rejected on disocclusion ([`similar`]), its confidence capped at
//!    `max_history` and scaled by how far the two pixels' targets agree ([`lobe_agreement`])
//!    and, for the rest, by how far the two frames' maps do ([`map_agreement`]: a carousel
//!    step drops the history), its sample's target re-evaluated under this frame's map and
//!    geometry, and combined with
//!    the candidates ([`combine`](combine::combine)). The bright part's history only where the
//!    bright light has not changed ([`BrightLight::same_light`]). The result is the next
//!    frame's history.
//! 3. **Spatial reuse** (the rest only, where the pixel's history is short: its confidence
//!    under [`SPATIAL_UNTIL_HISTORY`]): `spatial` neighbours' temporal reservoirs in a disc of
//!    [`SPATIAL_RADIUS`] pixels, passing the same geometric tests, their confidence capped at
//!    [`SPATIAL_CONFIDENCE`] of the pixel's and scaled by [`lobe_agreement`], combined the same
//!    way. Shading only: fed back as history, a neighbour's sample (made for another normal)
//!    stays at full confidence for frames (measured on the still motion scene: 3.6x against
//!    1.7x the error of today's 32 + 32 with the temporal result as history, before the cap).
//! 4. The estimate: `f(Y) V(Y) W` summed over the parts.
//!
//! Unbiased by default (pairwise MIS, [`combine`](combine::combine)): shadow rays are the
//! candidates' (one for the rest, up to `BRIGHT_LIGHT_SAMPLES + 1` for the bright part, or
//! `BRIGHT_PENUMBRA_SAMPLES + 1` in a penumbra), one per reused sample (the canonical pixel
//! must see what it selects), and one per other domain for the canonical sample's MIS weight:
//! at most `1 + 2 (1 + spatial)` for the rest and `BRIGHT_PENUMBRA_SAMPLES + 3` for the bright
//! part per pixel (18 at the defaults; 5.0 on average on the motion scene, docs/temporal.md).
//! The biased option spends at most `BRIGHT_LIGHT_SAMPLES_BIASED + 4` (the candidates', and a
//! final sample's from elsewhere, but for the rest's history, whose visibility it trusts).
//! Deterministic: every pass draws from its own per-pixel stream.

mod agreement;
mod bright;
mod bright_light;
mod combine;
mod passes;
mod reservoir;
mod settings;

pub use agreement::{
    AGREEMENT_SCALE, DIFFUSE_WIDTH, MAP_AGREEMENT_SCALE, MIN_AGREEMENT_WIDTH, lobe_agreement,
    map_agreement,
};
pub use bright::{
    BRIGHT_LIGHT_SAMPLES, BRIGHT_LIGHT_SAMPLES_BIASED, BRIGHT_MAX_AREA, BRIGHT_OVER_MEAN,
    BRIGHT_PENUMBRA_SAMPLES, BrightLight, Part, Split, bright_light_samples, bright_reservoir,
    bright_threshold,
};
pub use combine::{Domain, DomainSurface, combine};
pub use reservoir::{CandidateSink, Reservoir};
pub use settings::{Mutation, Resampling, ResamplingMode};

pub use passes::{BRIGHT_SAME_POINT, same_point};
use passes::{Candidates, candidates, penumbra_before, spatial, temporal};

use super::estimator::{FrameData, shading_directions};
use super::{GPixel, PixelStats, RenderStats, Settings};
use crate::envmap::Image;
use crate::sampling::rng::{Rng, hash_combine};
use crate::sampling::warp::Frame;
use crate::visibility::Occluder;
use glam::Vec3;
use rayon::prelude::*;

/// Spatial neighbours are drawn uniformly in a disc of this radius, in pixels.
pub const SPATIAL_RADIUS: f32 = 8.0;
/// A spatial neighbour's confidence is capped at this fraction of the pixel's own. Its
/// integrand differs (another normal, another view), so where the pixel's history has
/// converged, mixing neighbours in at equal confidence adds the variance of that difference:
/// on the motion scene held still, restir measured 3.6x the error of today's 32 + 32 at equal
/// confidence, 0.79x capped at 1/4 (temporal reuse alone: 0.66x). Any confidences keep the
/// pairwise weights summing to 1: unbiased either way.
pub const SPATIAL_CONFIDENCE: f32 = 0.25;
/// Spatial neighbours are drawn only for a pixel whose confidence after temporal reuse is
/// under this many frames: where its history is short (a disocclusion, the first frames, a
/// reset, `temporal: false`). Where the history holds more, the neighbours' samples changed the
/// error little and cost two shadow rays each: on the motion scene (4 seeds, frames 16..31 at
/// 48²) drawing them everywhere measured 5.41x the relMSE of today's 32 + 32 at 6.45 rays a
/// pixel, only under 8 frames 5.72x at 4.57 (the same at 4 and 12; before the penumbra
/// samples); held still 0.79x against 0.71x (neighbours at a converged pixel add their
/// integrands' difference). 4 rather than 8: the same error in frames 16..31 (4.34x against
/// 4.33x), but at 192² 4.95 rays a pixel against 5.32 (more of the 8-pixel disc's neighbours
/// pass the geometric tests at a finer resolution); in frames 3..5, 4.64x at 5.62 rays against
/// 4.40x at 6.86. The threshold reads the confidences only, never the samples: unbiased.
pub const SPATIAL_UNTIL_HISTORY: f32 = 4.0;
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

/// One frame's screen: the map (split), the G-buffer, each pixel's surface point and [`Surface`], and
/// the scene's shadow-casting geometry (`None`: no shadows).
#[derive(Clone, Copy)]
pub struct Screen<'a> {
    pub split: &'a Split,
    pub gbuf: &'a [Option<GPixel>],
    pub points: &'a [Vec3],
    pub surfaces: &'a [Surface],
    pub width: usize,
    pub height: usize,
    pub occluder: Option<&'a dyn Occluder>,
}

impl<'a> Screen<'a> {
    /// Pixel `i`'s surface, as the reservoirs of `part` see it.
    fn surface(&self, i: usize, part: Part) -> Option<DomainSurface<'a>> {
        self.gbuf[i].as_ref().map(|px| DomainSurface {
            split: self.split,
            part,
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
    pub reservoirs: &'a [Reservoirs],
    /// Nothing that casts shadows moved since that frame: where a pixel's point is its history
    /// pixel's too ([`same_point`]), the two see the same directions, so the unbiased
    /// combination's visibility rays between them are known without casting (`passes::temporal`).
    pub still_geometry: bool,
}

/// A pixel's reservoirs, one per [`Part`] of the map (indexed by `Part as usize`).
pub type Reservoirs = [Reservoir; 2];

/// Where pixel `i` of this frame was in the previous one: the pixel, and the distance from the
/// previous camera its point had then (for the depth test). `None`: off screen.
pub type Reproject<'a> = &'a (dyn Fn(usize) -> Option<(usize, f32)> + Sync);

/// A resampled frame.
pub struct Resampled {
    pub image: Image,
    /// The history for the next frame.
    pub reservoirs: Vec<Reservoirs>,
    pub stats: RenderStats,
    pub reuse: ReuseStats,
}

/// What reuse did in a frame.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct ReuseStats {
    /// Pixels whose previous reservoir passed the tests.
    pub temporal_accepted: u64,
    /// Pixels whose previous reservoir of the bright part did (the same light, and in the
    /// unbiased mode the same point: [`BRIGHT_SAME_POINT`]).
    pub bright_temporal_accepted: u64,
    /// Neighbours that passed the tests, over all pixels.
    pub spatial_accepted: u64,
    /// Mean confidence `M` of the final reservoirs over shaded pixels.
    pub mean_history: f64,
}

/// The unshadowed integrand `f(o, d) L(d) <n, d>+` at a pixel (the target's colour), `L` the
/// radiance of the map's `part` (zero outside it).
pub fn target_rgb(split: &Split, part: Part, px: &GPixel, d: Vec3) -> Vec3 {
    let Some((n, o)) = shading_directions(px) else {
        return Vec3::ZERO;
    };
    let cos = n.dot(d);
    if cos <= 0.0 {
        return Vec3::ZERO;
    }
    let frame = Frame::new(n);
    px.material.eval_local(frame.to_local(o), frame.to_local(d)) * split.radiance(part, d) * cos
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
    s.validate_for(cur.split.rest.size)?;
    assert_eq!(cur.gbuf.len(), cur.width * cur.height);
    let s = Settings {
        seed: frame_seed(s.seed, frame),
        ..*s
    };
    let t0 = std::time::Instant::now();
    let mut fd = FrameData::prepare(&cur.split.rest, &s);
    if r.candidate_visibility {
        fd.occluder = cur.occluder;
    }
    let build_ms = t0.elapsed().as_secs_f64() * 1e3;
    let t1 = std::time::Instant::now();
    let stream = |pass: u32, i: usize| Rng::new(hash_combine(&[s.seed, pass, 0x5e57]), i as u32);
    // 1. Candidates, and the selected ones' shadow rays.
    let (mut res, mut rays, per_pixel) = candidate_pass(cur, history, &fd, &s, r, stream);
    let mut reuse = ReuseStats::default();
    // The next frame's history: the temporal pass's reservoirs, not the spatial pass's (below).
    let mut next = res.clone();
    for part in Part::ALL {
        if part == Part::Bright && cur.split.bright.is_empty() {
            continue; // its target is 0 everywhere: nothing to reuse
        }
        let stream = |pass: u32, i: usize| stream(pass + 4 * part as u32, i);
        let (t, sp) = reuse_part(
            cur,
            history,
            r,
            part,
            (&mut res, &mut next, &mut rays),
            stream,
        );
        match part {
            Part::Rest => (reuse.temporal_accepted, reuse.spatial_accepted) = (t, sp),
            Part::Bright => reuse.bright_temporal_accepted = t,
        }
    }
    // 4. Shade.
    let (image, shade_rays) = shade(cur, &mut res);
    let shade_ms = t1.elapsed().as_secs_f64() * 1e3;
    let mut stats = RenderStats::for_settings(cur.width, cur.height, &s, fd.pool.block);
    (stats.build_ms, stats.shade_ms) = (build_ms, shade_ms);
    stats.accumulate(&per_pixel);
    // The candidates' own rays (`candidate_visibility`) are in `accumulate`'s count already.
    stats.shadow_rays += rays.iter().map(|&n| n as u64).sum::<u64>() + shade_rays;
    reuse.mean_history = mean_history(cur, &res);
    Ok(Resampled {
        image,
        reservoirs: next,
        stats,
        reuse,
    })
}

/// Pass 1 over every pixel: its reservoirs, its shadow rays so far and its sample counts.
fn candidate_pass(
    cur: &Screen,
    history: Option<(History, Reproject)>,
    fd: &FrameData,
    s: &Settings,
    r: &Resampling,
    stream: impl Fn(u32, usize) -> Rng + Sync,
) -> (Vec<Reservoirs>, Vec<u32>, Vec<Option<PixelStats>>) {
    let first: Vec<Candidates> = (0..cur.width * cur.height)
        .into_par_iter()
        .map(|i| {
            let penumbra = (history.filter(|_| r.temporal))
                .is_some_and(|(h, reproject)| penumbra_before(&h, reproject, i));
            candidates(cur, fd, s, (r, penumbra), i, stream(1, i))
        })
        .collect();
    let rays: Vec<u32> = first.iter().map(|f| f.rays).collect();
    let per_pixel: Vec<Option<PixelStats>> = first.iter().map(|f| f.stats).collect();
    let res: Vec<Reservoirs> = first.into_iter().map(|f| f.res).collect();
    (res, rays, per_pixel)
}

/// Temporal (2.) and spatial (3.) reuse of the reservoirs of `part`, in place, their rays added
/// to `rays`; the domains each accepted. The bright part's history is reused only where the
/// bright light is the one it was made under ([`BrightLight::same_light`]), the rest's at the
/// confidence its map's light keeps ([`map_agreement`]).
fn reuse_part(
    cur: &Screen,
    history: Option<(History, Reproject)>,
    r: &Resampling,
    part: Part,
    (res, next, rays): (&mut Vec<Reservoirs>, &mut [Reservoirs], &mut [u32]),
    stream: impl Fn(u32, usize) -> Rng + Sync,
) -> (u64, u64) {
    let n_px = res.len();
    let history = history
        .filter(|(h, _)| part == Part::Rest || h.screen.split.bright.same_light(&cur.split.bright));
    let mut accepted = (0, 0);
    if let (true, Some((h, reproject))) = (r.temporal, history) {
        // (The bright part's history is of the same light, above.)
        let maps = match part {
            Part::Rest => map_agreement(&h.screen.split.rest, &cur.split.rest),
            Part::Bright => 1.0,
        };
        let out = per_pixel_pass(n_px, |i| {
            temporal(cur, &h, (reproject, maps), r, (res, part), i, stream(2, i))
        });
        accepted.0 = replace(res, part, rays, out);
    }
    for (n, q) in next.iter_mut().zip(res.iter()) {
        n[part as usize] = q[part as usize];
    }
    // The bright part is not reused across pixels: its candidates already see its visibility
    // (two rays), and a neighbour's penumbra is not this pixel's (docs/temporal.md).
    if r.spatial > 0 && part == Part::Rest {
        let out = per_pixel_pass(n_px, |i| spatial(cur, r, (res, part), i, stream(3, i)));
        accepted.1 = replace(res, part, rays, out);
    }
    accepted
}

/// A reuse pass over every pixel, in parallel: `pass(i)` gives pixel `i`'s new reservoir, the
/// rays it cast and the domains it accepted.
fn per_pixel_pass(
    n_px: usize,
    pass: impl Fn(usize) -> (Reservoir, u32, u32) + Sync,
) -> Vec<(Reservoir, u32, u32)> {
    (0..n_px).into_par_iter().map(&pass).collect()
}

/// Take a pass's reservoirs of `part`, add its rays; the domains it accepted, summed.
fn replace(
    res: &mut [Reservoirs],
    part: Part,
    rays: &mut [u32],
    out: Vec<(Reservoir, u32, u32)>,
) -> u64 {
    let mut accepted = 0;
    for (i, (q, n, a)) in out.into_iter().enumerate() {
        res[i][part as usize] = q;
        rays[i] += n;
        accepted += a as u64;
    }
    accepted
}

/// The image: per pixel, `f(Y) V(Y) W` summed over the parts' reservoirs, testing a final
/// sample's visibility where it is not known yet (the biased mode); and the rays that cast.
fn shade(cur: &Screen, res: &mut [Reservoirs]) -> (Image, u64) {
    let data: Vec<(Vec3, u32)> = res
        .par_iter_mut()
        .enumerate()
        .map(|(i, qs)| {
            let (mut sum, mut n) = (Vec3::ZERO, 0);
            for (q, part) in qs.iter_mut().zip(Part::ALL) {
                if let (Some(at), true) = (cur.surface(i, part), q.is_live() && !q.visible) {
                    q.visible = at.visible(q.dir, &mut n);
                    if !q.visible {
                        q.ucw = 0.0;
                    }
                }
                if q.is_live() {
                    sum += q.estimate();
                }
            }
            (sum, n)
        })
        .collect();
    let rays = data.iter().map(|d| d.1 as u64).sum();
    let image = Image {
        width: cur.width,
        height: cur.height,
        data: data.into_iter().map(|d| d.0).collect(),
    };
    (image, rays)
}

/// The mean confidence of the final reservoirs (of the rest) over shaded pixels.
fn mean_history(cur: &Screen, res: &[Reservoirs]) -> f64 {
    let shaded = cur.gbuf.iter().filter(|p| p.is_some()).count().max(1);
    cur.gbuf
        .iter()
        .zip(res)
        .filter(|(p, _)| p.is_some())
        .map(|(_, q)| q[Part::Rest as usize].m as f64)
        .sum::<f64>()
        / shaded as f64
}
