//! Sub-face tiles (`--tiles K`): each cube face cut into `K x K` tiles, each with its own energy,
//! CDFs and pool, weighted per pixel like the paper's faces (`docs/method.md`, "Tiles").
//!
//! A face weighted as a whole sends samples below the horizon of any normal its face straddles;
//! a tile straddles it over a smaller area. Per pixel, tile `t` gets
//! `C_t = sum over its 4 corners of max(0, <n, corner>)` and `mu_t = C_t I_t / sum(C_t I_t)`,
//! `N_t = mu_t N_L` (the paper's pseudo form factor and face energy, per tile). The paper's
//! argument for skipping a tile carries over: a tile is planar, so `<n, p>` is linear on it and a
//! tile whose four corners all have `cos <= 0` lies wholly below the horizon. `K = 1` is the
//! paper's method.
//!
//! Tile `i` of a row (or column) covers texels `ceil(i N / K) .. ceil((i + 1) N / K)`, so a texel's
//! tile is `floor(x K / N)`; when `K` does not divide `N` the tiles differ by one texel in width.
//! `K` must not exceed `N` (every tile holds a texel).

use crate::envmap::face_ab_to_vec;
use glam::Vec3;

/// How a pixel's `N_L` light samples are spread over the tiles (`--tile-counts`; no effect with
/// one tile per face). Both are unbiased: the light density in direction `w` of tile `t` is
/// `N_t p_t(w)` either way.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "bevy", derive(bevy_reflect::Reflect))]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum TileCounts {
    /// The paper's counts per tile: tile `t` takes `N_t = mu_t N_L` samples (fractional or integer,
    /// [`super::Counts`]). Every lit tile above the horizon costs at least one sample, so the
    /// samples evaluated grow with `K^2`.
    Tile,
    /// The paper's counts per face, `N_f = sum of its tiles' N_t`; each of the face's samples
    /// draws its tile with probability `N_t / N_f` (one random number) and takes that tile's
    /// next pool sample. The samples evaluated stay the paper's.
    Face,
}

crate::display_as_serde_name!(TileCounts);

/// The tile a face's sample draws ([`TileCounts::Face`]): the first of the face's tiles whose
/// running sum of `mass` exceeds `u * sum` (`u` in `[0, 1)`), never a tile of mass 0; `None` when
/// every mass is 0.
#[inline]
pub fn draw_tile(mass: &[f32], sum: f32, u: f32) -> Option<usize> {
    let x = u * sum;
    let mut acc = 0.0f32;
    let mut last = None;
    for (t, &m) in mass.iter().enumerate() {
        if m > 0.0 {
            acc += m;
            last = Some(t);
            if acc > x {
                return last;
            }
        }
    }
    // Rounding can leave `x` at the very top: the last tile with mass.
    last
}

/// The largest `K` (a per-pixel table of `6 K^2` densities lives on the stack).
pub const MAX_TILES: usize = 8;
/// The most regions (tiles over all faces) a distribution can have.
pub const MAX_REGIONS: usize = 6 * MAX_TILES * MAX_TILES;

/// How an `N x N` face is cut into `K x K` tiles. Regions (tiles over the cube) are numbered
/// face-major, then tile row, then tile column: `face K^2 + ty K + tx`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileGrid {
    /// Face size `N`.
    pub size: usize,
    /// Tiles per side `K`.
    pub k: usize,
}

impl TileGrid {
    /// `K` tiles per side of an `n`-texel face; `k` is clamped to `1..=min(n, MAX_TILES)`.
    pub fn new(n: usize, k: usize) -> Self {
        TileGrid {
            size: n,
            k: k.clamp(1, n.clamp(1, MAX_TILES)),
        }
    }

    /// First texel of tile `i` along a side (`i = K` gives `N`).
    #[inline]
    pub fn bound(&self, i: usize) -> usize {
        (i * self.size).div_ceil(self.k)
    }

    /// The tile holding texel `x` along a side.
    #[inline]
    pub fn of(&self, x: usize) -> usize {
        x * self.k / self.size
    }

    /// Tiles per face, `K^2`.
    #[inline]
    pub fn per_face(&self) -> usize {
        self.k * self.k
    }

    /// Regions over the cube, `6 K^2`.
    #[inline]
    pub fn regions(&self) -> usize {
        6 * self.per_face()
    }

    /// The region of texel (`col`, `row`) of face `face`.
    #[inline]
    pub fn region(&self, face: usize, col: usize, row: usize) -> usize {
        face * self.per_face() + self.of(row) * self.k + self.of(col)
    }

    /// Face, tile column and tile row of region `r`.
    #[inline]
    pub fn split(&self, r: usize) -> (usize, usize, usize) {
        let t = r % self.per_face();
        (r / self.per_face(), t % self.k, t / self.k)
    }

    /// Texel columns and rows of region `r`: `(c0, c1, r0, r1)`, half-open.
    #[inline]
    pub fn span(&self, r: usize) -> (usize, usize, usize, usize) {
        let (_, tx, ty) = self.split(r);
        (
            self.bound(tx),
            self.bound(tx + 1),
            self.bound(ty),
            self.bound(ty + 1),
        )
    }

    /// The four unit corner directions of region `r`, in the order
    /// (c0, r0), (c1, r0), (c0, r1), (c1, r1).
    pub fn corners(&self, r: usize) -> [Vec3; 4] {
        let (f, _, _) = self.split(r);
        let (c0, c1, r0, r1) = self.span(r);
        let h = 2.0 / self.size as f32;
        let at = |c: usize, r: usize| {
            face_ab_to_vec(f, -1.0 + c as f32 * h, -1.0 + r as f32 * h).normalize()
        };
        [at(c0, r0), at(c1, r0), at(c0, r1), at(c1, r1)]
    }
}

/// Per region, the four corners (structure of arrays, so the per-pixel loop vectorises across
/// regions) and the energy `I_t`: what a pixel needs to weight the tiles.
#[derive(Clone, Debug, Default)]
pub struct TileWeights {
    x: [Vec<f32>; 4],
    y: [Vec<f32>; 4],
    z: [Vec<f32>; 4],
    /// `I_t` per region.
    pub energy: Vec<f32>,
}

impl TileWeights {
    /// The tiles of `grid` with region energies `energy`.
    pub fn new(grid: TileGrid, energy: &[f64]) -> Self {
        let mut w = TileWeights {
            energy: energy.iter().map(|&e| e as f32).collect(),
            ..Default::default()
        };
        for r in 0..grid.regions() {
            for (k, c) in grid.corners(r).into_iter().enumerate() {
                w.x[k].push(c.x);
                w.y[k].push(c.y);
                w.z[k].push(c.z);
            }
        }
        w
    }

    /// Regions.
    pub fn len(&self) -> usize {
        self.energy.len()
    }

    pub fn is_empty(&self) -> bool {
        self.energy.is_empty()
    }

    /// `C_t I_t` for every region into `out` (`C_t = 1` without the cosine: the `light`
    /// strategy), and their sum, added in region order (as the WGSL does).
    #[inline(always)]
    pub fn masses(&self, n: Vec3, use_cosine: bool, out: &mut [f32]) -> f32 {
        let out = &mut out[..self.len()];
        if use_cosine {
            let [x0, x1, x2, x3] = &self.x;
            let [y0, y1, y2, y3] = &self.y;
            let [z0, z1, z2, z3] = &self.z;
            let cos = |x: &[f32], y: &[f32], z: &[f32], i: usize| {
                (n.x * x[i] + n.y * y[i] + n.z * z[i]).max(0.0)
            };
            for (i, m) in out.iter_mut().enumerate() {
                let c = cos(x0, y0, z0, i)
                    + cos(x1, y1, z1, i)
                    + cos(x2, y2, z2, i)
                    + cos(x3, y3, z3, i);
                *m = c * self.energy[i];
            }
        } else {
            out.copy_from_slice(&self.energy);
        }
        out.iter().sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::faceweights::face_weights;

    #[test]
    fn draw_tile_follows_the_masses_and_skips_empty_tiles() {
        let mass = [0.0, 1.0, 0.0, 3.0];
        let mut hits = [0usize; 4];
        for i in 0..4000 {
            hits[draw_tile(&mass, 4.0, (i as f32 + 0.5) / 4000.0).unwrap()] += 1;
        }
        assert_eq!(hits, [0, 1000, 0, 3000]);
        assert_eq!(draw_tile(&mass, 4.0, 0.999_999_9), Some(3));
        // A sum rounded above the masses' still lands on a tile with mass.
        assert_eq!(draw_tile(&mass, 4.5, 0.999), Some(3));
        assert_eq!(draw_tile(&[0.0, 0.0], 0.0, 0.5), None);
    }

    #[test]
    fn tiles_cover_the_face_once() {
        for (n, k) in [(32, 1), (32, 4), (33, 4), (7, 7), (5, 2), (64, 8)] {
            let g = TileGrid::new(n, k);
            assert_eq!((g.bound(0), g.bound(g.k)), (0, n));
            for x in 0..n {
                let t = g.of(x);
                assert!(g.bound(t) <= x && x < g.bound(t + 1), "n {n} k {k} x {x}");
            }
            for t in 0..g.k {
                let w = g.bound(t + 1) - g.bound(t);
                assert!(w == n / g.k || w == n / g.k + 1, "n {n} k {k}: width {w}");
            }
        }
        assert_eq!(TileGrid::new(4, 9).k, 4);
        assert_eq!(TileGrid::new(64, 20).k, MAX_TILES);
    }

    #[test]
    fn one_tile_per_face_gives_the_paper_face_weights() {
        let energy = [1.0, 2.0, 0.5, 3.0, 0.0, 1.5];
        let w = TileWeights::new(TileGrid::new(16, 1), &energy);
        let mut mass = [0.0; 6];
        for n in [
            Vec3::new(0.3, 0.9, -0.2),
            Vec3::X,
            Vec3::new(-0.5, -0.5, 0.7),
        ] {
            let n = n.normalize();
            let total = w.masses(n, true, &mut mass);
            let seed = face_weights(n, &energy, true);
            for (f, (m, mu)) in mass.iter().zip(seed.mu).enumerate() {
                assert!((m / total - mu).abs() < 1e-6, "{n} face {f}");
            }
        }
    }

    #[test]
    fn a_tile_below_the_horizon_gets_no_weight_and_one_above_does() {
        let g = TileGrid::new(32, 4);
        let w = TileWeights::new(g, &vec![1.0; g.regions()]);
        let mut mass = [0.0; MAX_REGIONS];
        let n = Vec3::new(0.2, 1.0, 0.1).normalize();
        w.masses(n, true, &mut mass);
        for (r, &m) in mass[..g.regions()].iter().enumerate() {
            let c = g.corners(r);
            let all_below = c.iter().all(|d| n.dot(*d) <= 0.0);
            assert_eq!(m == 0.0, all_below, "region {r}");
        }
    }
}
