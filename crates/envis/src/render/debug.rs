//! The paper's sample-debug view on the CPU: how each pool sample serves one pixel (red:
//! discarded by face weighting, green: used, yellow: used but below the horizon, blue: used but
//! blocked by the scene).

use super::{FrameData, GPixel, Settings, Strategy};
use crate::sampling::rng::Rng;
use crate::sampling::tiles::draw_tile;
use crate::sampling::{MAX_REGIONS, TileCounts, face_count};
use glam::Vec3;

/// How one pool sample serves a pixel (the paper's sample-debug colours).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum SampleKind {
    /// Red: not taken, discarded by face weighting (beyond the face's (or tile's) `ceil(N_f)`, or
    /// an empty slot).
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
    /// The sample's region: its face, or with tiles its tile ([`crate::sampling::TileGrid`]).
    pub region: usize,
    pub dir: Vec3,
    pub kind: SampleKind,
}

/// The sample-debug view of one pixel: face weights, counts, every pool sample classified, and
/// the estimate.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PixelDebug {
    /// `mu_f`, summed over each face's tiles.
    pub mu: [f32; 6],
    /// `N_f = mu_f N_L` (before clamping to the pool), summed over each face's tiles.
    pub n_f: [f32; 6],
    /// Tiles per side `K` (1: whole faces) of faces of `face_size` texels.
    pub tiles: usize,
    pub face_size: usize,
    /// `N_t = mu_t N_L` per region (face-major, [`crate::sampling::TileGrid::region`]).
    pub n_t: Vec<f32>,
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
    let mut mass = [0.0f32; MAX_REGIONS];
    let total = fd.tiles.masses(n, s.strategy != Strategy::Light, &mut mass);
    let regions = fd.tiles.len();
    let mu: Vec<f32> = mass[..regions]
        .iter()
        .map(|&m| if total > 0.0 { m / total } else { 0.0 })
        .collect();
    let mut rng = Rng::new(s.seed, pixel_index);
    let window = super::estimator::pool_window(&mut rng, s, &fd.pool);
    let live = matches!(s.strategy, Strategy::Paper | Strategy::Light)
        && super::estimator::shading_directions(px).is_some();
    let k2 = fd.dist.grid.per_face();
    let taken = if live {
        taken_positions(s, nl, &mass[..regions], total, window.len, k2, &mut rng)
    } else {
        vec![false; regions * window.len]
    };
    let samples = pool_debug_samples(fd, &window, &taken, n, shadow);
    let per_face = |f: usize| mu[f * k2..(f + 1) * k2].iter().sum::<f32>();
    PixelDebug {
        mu: std::array::from_fn(per_face),
        n_f: std::array::from_fn(|f| per_face(f) * nl as f32),
        tiles: fd.dist.grid.k,
        face_size: fd.dist.size,
        n_t: mu.iter().map(|m| m * nl as f32).collect(),
        samples,
        estimate,
    }
}

/// The pixel's own part of the pool (one block with `PoolLayout::Blocks`): the slots it can
/// take, as the paper's view shows them, each classified. `taken` as [`taken_positions`] gives
/// it; with `shadow` (occluder, point) taken samples are shadow-tested.
fn pool_debug_samples(
    fd: &FrameData,
    window: &super::estimator::PoolWindow,
    taken: &[bool],
    n: Vec3,
    shadow: Option<(&dyn crate::visibility::Occluder, Vec3)>,
) -> Vec<DebugSample> {
    let (regions, k2) = (fd.tiles.len(), fd.dist.grid.per_face());
    let mut samples = Vec::with_capacity(regions * window.len);
    for r in 0..regions {
        for j in window.base..window.base + window.len {
            let ls = fd.pool.get(r, j);
            // Where slot j comes in this pixel's order.
            let taken = window
                .position(j)
                .is_some_and(|k| taken[r * window.len + k]);
            let kind = if !taken || ls.pdf <= 0.0 {
                SampleKind::Discarded
            } else if n.dot(ls.dir) <= 0.0 {
                SampleKind::Wasted
            } else if shadow.is_some_and(|(occ, p)| occ.occluded(p, n, ls.dir)) {
                SampleKind::Blocked
            } else {
                SampleKind::Used
            };
            samples.push(DebugSample {
                face: r / k2,
                region: r,
                dir: ls.dir,
                kind,
            });
        }
    }
    samples
}

/// Which positions of each region's window (`region * len + position`) the estimator's light
/// loop takes, from the regions' masses `C_t I_t` (sum `total`), drawing from `rng` as it does:
/// the first `N_t` per region, or with [`TileCounts::Face`] the face's `N_f`, each drawing a tile.
fn taken_positions(
    s: &Settings,
    nl: usize,
    mass: &[f32],
    total: f32,
    len: usize,
    k2: usize,
    rng: &mut Rng,
) -> Vec<bool> {
    let mut taken = vec![false; mass.len() * len];
    let share = |m: f32| if total > 0.0 { m / total } else { 0.0 };
    if k2 > 1 && s.tile_counts == TileCounts::Face {
        for (f, tiles) in mass.chunks(k2).enumerate() {
            let face_mass: f32 = tiles.iter().sum();
            let c = face_count(share(face_mass) * nl as f32, len, s.counts);
            for k in 0..c.taken {
                if let Some(t) = draw_tile(tiles, face_mass, rng.next_f32()) {
                    taken[(f * k2 + t) * len + k] = true;
                }
            }
        }
    } else {
        for (r, &m) in mass.iter().enumerate() {
            let c = face_count(share(m) * nl as f32, len, s.counts);
            taken[r * len..][..c.taken].fill(true);
        }
    }
    taken
}
