//! The seed's sample-debug view on the CPU: how each pool sample serves one pixel (red:
//! discarded by face weighting, green: used, yellow: used but below the horizon, blue: used but
//! blocked by the scene).

use super::{FrameData, GPixel, Settings, Strategy};
use crate::sampling::rng::Rng;
use crate::sampling::{face_count, face_weights};
use glam::Vec3;

/// How one pool sample serves a pixel (the seed's sample-debug colours).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum SampleKind {
    /// Red: not taken, discarded by face weighting (beyond the face's `ceil(N_f)`, or an empty slot).
    Discarded,
    /// Green: taken, positive cosine.
    Used,
    /// Yellow: taken, non-positive cosine (wasted).
    Wasted,
    /// Blue: taken, positive cosine, but its shadow ray is blocked.
    Blocked,
}

/// One pool sample as the pixel sees it.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct DebugSample {
    pub face: usize,
    pub dir: Vec3,
    pub kind: SampleKind,
}

/// The sample-debug view of one pixel: face weights, counts, every pool sample classified, and
/// the estimate.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PixelDebug {
    pub mu: [f32; 6],
    /// `N_f = mu_f N_L` (before clamping to the pool).
    pub n_f: [f32; 6],
    pub samples: Vec<DebugSample>,
    pub estimate: Vec3,
}

/// Classify every pool sample for pixel `px` exactly as [`shade_pixel`](super::shade_pixel)'s light loop uses them
/// (same face weights, counts, offset), for the `paper` and `light` strategies.
pub fn debug_pixel(fd: &FrameData, s: &Settings, px: &GPixel, pixel_index: u32) -> PixelDebug {
    debug_pixel_at(fd, s, px, None, pixel_index)
}

/// [`debug_pixel`] for a pixel whose surface point is `at`: with `fd.occluder`, used samples
/// whose shadow ray is blocked are [`SampleKind::Blocked`] (as `shade_pixel_at` shades them).
pub fn debug_pixel_at(
    fd: &FrameData,
    s: &Settings,
    px: &GPixel,
    at: Option<Vec3>,
    pixel_index: u32,
) -> PixelDebug {
    let (estimate, _) = super::estimator::shade_pixel_at(fd, s, px, at, pixel_index);
    let shadow = fd.occluder.zip(at);
    let n = px.n.normalize_or_zero();
    let (nl, _) = s.budget(&px.material);
    let fw = face_weights(n, &fd.energies, s.strategy != Strategy::Light);
    let mut rng = Rng::new(s.seed, pixel_index);
    let window = super::estimator::pool_window(&mut rng, s, &fd.pool);
    // The pixel's own part of the pool (one block with `PoolLayout::Blocks`): the slots it can
    // take, as the seed's view shows them.
    let mut samples = Vec::with_capacity(6 * window.len);
    let live = matches!(s.strategy, Strategy::Paper | Strategy::Light)
        && super::estimator::shading_directions(px).is_some();
    for f in 0..6 {
        let c = face_count(fw.mu[f] * nl as f32, window.len, s.counts);
        for j in window.base..window.base + window.len {
            let ls = fd.pool.get(f, j);
            // Where slot j comes in this pixel's order.
            let taken = window.position(j).is_some_and(|k| k < c.taken);
            let kind = if !live || !taken || ls.pdf <= 0.0 {
                SampleKind::Discarded
            } else if n.dot(ls.dir) <= 0.0 {
                SampleKind::Wasted
            } else if shadow.is_some_and(|(occ, p)| occ.occluded(p, n, ls.dir)) {
                SampleKind::Blocked
            } else {
                SampleKind::Used
            };
            samples.push(DebugSample {
                face: f,
                dir: ls.dir,
                kind,
            });
        }
    }
    PixelDebug {
        mu: fw.mu,
        n_f: std::array::from_fn(|f| fw.mu[f] * nl as f32),
        samples,
        estimate,
    }
}
