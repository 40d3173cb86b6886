//! Tabulated distributions of light intensity, built every frame from the current cube map.
//!
//! Per face (or, with `--tiles K`, per tile of a face: [`super::tiles`]): texel weight
//! `w(c, r) = Y(c, r) * Omega(c, r)` (luminance x texel solid angle); marginal CDF over columns `u`
//! and, per column, a conditional CDF over rows `v` (the paper's CDF(u) and CDF(v|u)). Sums are accumulated in f64 and stored normalised in f32, so a single
//! bright texel among millions is still found with the right probability. Inside the chosen texel
//! the direction is uniform in face coordinates; the returned pdf is per unit *solid angle*:
//! `p(w) = P(texel) / A_texel * (1 + a^2 + b^2)^(3/2)` with `A_texel = (2/N)^2` (cube-face Jacobian).
//!
//! Degenerate input has defined behaviour: a zero column is never chosen, a zero tile reports
//! `energy == 0` and is never asked to sample (its pdf is 0 everywhere), an all-zero map gives
//! six empty faces.

pub use super::conditionals::{Conditionals, STRIP};
use super::rng::ONE_MINUS_EPSILON;
use super::tiles::TileGrid;
use crate::envmap::{CubeMap, face_ab_to_vec, luminance, texel_solid_angle};
use glam::{Vec2, Vec3};

/// Piecewise-constant 1D distribution on `[0, 1)` with `n` bins.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    /// Bin weights (non-negative).
    pub func: Vec<f32>,
    /// `n + 1` normalised CDF values, `cdf[0] = 0`, `cdf[n] = 1` (uniform when the total is 0).
    pub cdf: Vec<f32>,
    /// Sum of the weights (f64-accumulated).
    pub total: f64,
}

impl Distribution1D {
    pub fn new(func: Vec<f32>) -> Self {
        let n = func.len();
        assert!(n > 0);
        let mut prefix = Vec::with_capacity(n + 1);
        let mut acc = 0.0f64;
        prefix.push(0.0);
        for &f in &func {
            debug_assert!(f >= 0.0 && f.is_finite());
            acc += f as f64;
            prefix.push(acc);
        }
        let cdf = if acc > 0.0 {
            prefix.iter().map(|&p| (p / acc) as f32).collect::<Vec<_>>()
        } else {
            (0..=n).map(|i| i as f32 / n as f32).collect()
        };
        let mut cdf = cdf;
        cdf[n] = 1.0;
        Distribution1D {
            func,
            cdf,
            total: acc,
        }
    }

    pub fn len(&self) -> usize {
        self.func.len()
    }
    pub fn is_empty(&self) -> bool {
        self.total <= 0.0
    }

    /// Discrete probability of bin `i`: `func[i] / total` (0 for an empty distribution).
    #[inline]
    pub fn bin_pmf(&self, i: usize) -> f32 {
        if self.total > 0.0 {
            (self.func[i] as f64 / self.total) as f32
        } else {
            0.0
        }
    }

    /// Sample: bin `i` with `cdf[i] <= u < cdf[i+1]` (zero-width bins are never returned for
    /// `u < 1`), and the remapped offset `(u - cdf[i]) / (cdf[i+1] - cdf[i])` in `[0, 1)`.
    #[inline]
    pub fn sample(&self, u: f32) -> (usize, f32) {
        let n = self.func.len();
        // Largest i in [0, n-1] with cdf[i] <= u.
        let i = self.cdf[..n].partition_point(|&c| c <= u).saturating_sub(1);
        let w = self.cdf[i + 1] - self.cdf[i];
        let du = if w > 0.0 {
            ((u - self.cdf[i]) / w).clamp(0.0, ONE_MINUS_EPSILON)
        } else {
            0.0
        };
        (i, du)
    }

    /// Invert: the `u` that [`Self::sample`] maps to bin `i` and offset `du`.
    #[inline]
    pub fn invert(&self, i: usize, du: f32) -> f32 {
        self.cdf[i] + du * (self.cdf[i + 1] - self.cdf[i])
    }
}

/// One tile's share of a face distribution: its marginal over its own columns and its energy.
#[derive(Clone, Debug)]
pub struct TileDistribution {
    /// First column of the tile.
    pub col0: usize,
    /// The tile's band of rows in the face's [`Conditionals`].
    pub band: usize,
    /// Marginal over the tile's columns (weights = the columns' sums within the tile).
    pub marginal: Distribution1D,
    /// `I_t`: sum of luminance x solid angle over the tile (f64-accumulated).
    pub energy: f64,
    /// `(N/2)^2 / I_t`: a texel's weight times this is its pdf per unit face area
    /// ([`FaceDistribution::pdf_area`]).
    pub area_scale: f32,
}

/// The tabulated distribution of one cube face, as `K x K` tiles (`K = 1`: the paper's, one
/// distribution per face), each with its own marginal over its columns and, in the shared
/// [`Conditionals`], its own band of each column.
#[derive(Clone, Debug)]
pub struct FaceDistribution {
    pub size: usize,
    /// One band of rows in every column per tile row.
    pub conditional: Conditionals,
    /// The tiles, row-major (`ty K + tx`).
    pub tiles: Vec<TileDistribution>,
    /// `I_f`: the face's energy, the sum of its tiles' (f64-accumulated).
    pub energy: f64,
}

/// One sample drawn from a face: direction, face coordinates and solid-angle pdf.
#[derive(Clone, Copy, Debug)]
pub struct FaceSample {
    pub dir: Vec3,
    pub col: usize,
    pub row: usize,
    pub pdf: f32,
}

impl FaceDistribution {
    /// Build from one face's radiance and texel solid angles (both row-major, `n x n`), one
    /// distribution per tile of `grid`.
    pub fn build(grid: TileGrid, face: &[Vec3], omega: &[f32]) -> Self {
        Self::from_conditionals(Conditionals::build(grid, face, omega))
    }

    /// [`Self::build`] into this distribution's memory (same size and tiles).
    pub fn rebuild(&mut self, face: &[Vec3], omega: &[f32]) {
        self.conditional.rebuild(face, omega);
        (self.tiles, self.energy) = Self::summary(&self.conditional);
    }

    /// The distribution of `conditional`'s face.
    pub fn from_conditionals(conditional: Conditionals) -> Self {
        let (tiles, energy) = Self::summary(&conditional);
        FaceDistribution {
            size: conditional.size,
            conditional,
            tiles,
            energy,
        }
    }

    /// The tiles (marginal over columns, energy, area pdf scale) of a face's conditionals, and
    /// the face's energy.
    fn summary(c: &Conditionals) -> (Vec<TileDistribution>, f64) {
        let (n, g) = (c.size, c.grid);
        let tiles: Vec<TileDistribution> = (0..g.per_face())
            .map(|t| {
                let (c0, c1, _, _) = g.span(t);
                let band = t / g.k;
                let totals = &c.totals[band * n..][c0..c1];
                let marginal = Distribution1D::new(totals.iter().map(|&t| t as f32).collect());
                let energy: f64 = totals.iter().sum();
                let area_scale = if energy > 0.0 {
                    ((n * n) as f64 * 0.25 / energy) as f32
                } else {
                    0.0
                };
                TileDistribution {
                    col0: c0,
                    band,
                    marginal,
                    energy,
                    area_scale,
                }
            })
            .collect();
        let energy = tiles.iter().map(|t| t.energy).sum();
        (tiles, energy)
    }

    /// The tile holding texel (`col`, `row`).
    #[inline]
    pub fn tile(&self, col: usize, row: usize) -> &TileDistribution {
        let g = self.conditional.grid;
        &self.tiles[g.of(row) * g.k + g.of(col)]
    }

    /// Texel (`col`, `row`)'s `P(texel | its tile) * (N/2)^2`: the pdf per unit face area, so that
    /// `p(w) = pdf_area * (1 + a^2 + b^2)^(3/2)`. A product, not a stored table: the pass that
    /// needs every texel's (the estimator's texel table) computes it on its way.
    #[inline]
    pub fn pdf_area(&self, col: usize, row: usize) -> f32 {
        self.conditional.weight(col, row) * self.tile(col, row).area_scale
    }

    /// Discrete probability of texel `(col, row)` within its tile.
    #[inline]
    pub fn texel_pmf(&self, col: usize, row: usize) -> f32 {
        let t = self.tile(col, row);
        t.marginal.bin_pmf(col - t.col0) * self.conditional.bin_pmf(col, row)
    }

    /// A sample of tile `tile` (`0` with one tile per face): `u -> (col, du)` via the tile's
    /// CDF(u), then `v -> (row, dv)` via its band of CDF(v|u); uniform in face coordinates inside
    /// the texel. Returns `None` on an empty tile.
    #[inline]
    pub fn sample(&self, face: usize, tile: usize, u: Vec2) -> Option<FaceSample> {
        let t = &self.tiles[tile];
        if t.energy <= 0.0 {
            return None;
        }
        let n = self.size;
        let (c, du) = t.marginal.sample(u.x);
        let col = t.col0 + c;
        let (row, dv) = self.conditional.sample(col, t.band, u.y);
        let h = 2.0 / n as f32;
        let a = -1.0 + (col as f32 + du) * h;
        let b = -1.0 + (row as f32 + dv) * h;
        let pdf = self.pdf_ab(col, row, a, b);
        Some(FaceSample {
            dir: face_ab_to_vec(face, a, b).normalize(),
            col,
            row,
            pdf,
        })
    }

    /// Solid-angle pdf of the tile holding texel `(col, row)` at face coordinates `(a, b)` in
    /// that texel: `P(texel) / (2/N)^2 * (1 + a^2 + b^2)^(3/2)`.
    #[inline]
    pub fn pdf_ab(&self, col: usize, row: usize, a: f32, b: f32) -> f32 {
        let q = 1.0 + a * a + b * b;
        self.pdf_area(col, row) * q * q.sqrt()
    }

    /// Invert: the `u` that [`Self::sample`] of the tile holding face coordinates `(a, b)` maps
    /// to them.
    pub fn invert(&self, a: f32, b: f32) -> Vec2 {
        let ((col, du), (row, dv)) = (texel_offset(a, self.size), texel_offset(b, self.size));
        let t = self.tile(col, row);
        Vec2::new(
            t.marginal.invert(col - t.col0, du),
            self.conditional.invert(col, row, dv),
        )
    }
}

/// The texel of face coordinate `a` on faces of `n` texels and the offset in it, in `[0, 1)`
/// ([`FaceDistribution::invert`] and sub-texel refinement; the WGSL's `texel_offset`).
#[inline]
pub fn texel_offset(a: f32, n: usize) -> (usize, f32) {
    let x = ((a + 1.0) * 0.5 * n as f32).clamp(0.0, n as f32 - 1e-3);
    let c = x as usize;
    (c, (x - c as f32).clamp(0.0, ONE_MINUS_EPSILON))
}

/// The six face distributions of one frame (each in `K x K` tiles).
#[derive(Clone, Debug)]
pub struct CubeDistribution {
    pub size: usize,
    /// The tiles of every face.
    pub grid: TileGrid,
    pub faces: Vec<FaceDistribution>,
}

/// Exact texel solid angles of one face of `n x n` texels (row-major), computed once per size and
/// shared: they depend only on `n`, and four `atan2` per texel would otherwise dominate the build.
pub fn face_solid_angles(n: usize) -> std::sync::Arc<Vec<f32>> {
    use std::collections::HashMap;
    use std::sync::{Arc, Mutex, OnceLock};
    static CACHE: OnceLock<Mutex<HashMap<usize, Arc<Vec<f32>>>>> = OnceLock::new();
    let cache = CACHE.get_or_init(|| Mutex::new(HashMap::new()));
    if let Some(t) = cache.lock().unwrap().get(&n) {
        return t.clone();
    }
    let t = Arc::new(
        (0..n * n)
            .map(|i| texel_solid_angle(i % n, i / n, n) as f32)
            .collect::<Vec<f32>>(),
    );
    cache.lock().unwrap().insert(n, t.clone());
    t
}

/// Texel weights `Y * Omega` of one face (`N * N`, same layout as the map's face).
pub fn face_texel_weights(face: &[Vec3], omega: &[f32]) -> Vec<f32> {
    // Zipped with the face's solid angles: no division or modulo per texel.
    face.iter()
        .zip(omega)
        .map(|(&c, &om)| luminance(c).max(0.0) * om)
        .collect()
}

/// Texel weights `Y * Omega` of a cube map (`6 * N * N`, same layout as the map).
pub fn texel_weights(map: &CubeMap) -> Vec<f32> {
    let n = map.size;
    let omega = face_solid_angles(n);
    map.data
        .chunks(n * n)
        .flat_map(|face| face_texel_weights(face, &omega))
        .collect()
}

impl CubeDistribution {
    /// The paper's distribution: one per face.
    pub fn build(map: &CubeMap) -> Self {
        Self::build_tiled(map, 1)
    }

    /// One distribution per tile, `k x k` tiles per face (clamped to `1..=min(N, MAX_TILES)`).
    pub fn build_tiled(map: &CubeMap, k: usize) -> Self {
        use rayon::prelude::*;
        let n = map.size;
        let grid = TileGrid::new(n, k);
        let omega = face_solid_angles(n);
        // The faces in parallel, and within each its strips of columns (Conditionals::build).
        let faces = map
            .data
            .par_chunks(n * n)
            .map(|face| FaceDistribution::build(grid, face, &omega))
            .collect();
        CubeDistribution {
            size: n,
            grid,
            faces,
        }
    }

    /// The next frame's distribution into this one's memory: what a stream does every frame.
    /// A map of another size is built anew (with as many tiles, where it can hold them).
    pub fn rebuild(&mut self, map: &CubeMap) {
        use rayon::prelude::*;
        if map.size != self.size {
            *self = Self::build_tiled(map, self.grid.k);
            return;
        }
        let n = map.size;
        let omega = face_solid_angles(n);
        self.faces
            .par_iter_mut()
            .zip(map.data.par_chunks(n * n))
            .for_each(|(fd, face)| fd.rebuild(face, &omega));
    }

    /// Region (tile over the cube, [`TileGrid::region`]) energies `I_t`.
    pub fn region_energies(&self) -> Vec<f64> {
        self.faces
            .iter()
            .flat_map(|f| f.tiles.iter().map(|t| t.energy))
            .collect()
    }

    /// A sample of region `r` ([`FaceDistribution::sample`] of its face and tile).
    #[inline]
    pub fn sample_region(&self, r: usize, u: Vec2) -> Option<FaceSample> {
        let k2 = self.grid.per_face();
        self.faces[r / k2].sample(r / k2, r % k2, u)
    }

    /// Face energies `I_f`.
    pub fn energies(&self) -> [f64; 6] {
        std::array::from_fn(|f| self.faces[f].energy)
    }

    /// Per-tile solid-angle pdf `p_t(w)` of direction `d` (0 on an empty tile), and its face.
    #[inline]
    pub fn face_pdf(&self, d: Vec3) -> (usize, f32) {
        let (f, _, p) = self.locate(d);
        (f, p)
    }

    /// Face, texel index into the cube map's `data`, and per-tile solid-angle pdf of direction
    /// `d`: one face/texel lookup serves both the pdf and the radiance.
    #[inline]
    pub fn locate(&self, d: Vec3) -> (usize, usize, f32) {
        let t = crate::envmap::dir_to_texel(d, self.size);
        (
            t.face,
            t.index(self.size),
            self.faces[t.face].pdf_ab(t.col, t.row, t.a, t.b),
        )
    }
}
