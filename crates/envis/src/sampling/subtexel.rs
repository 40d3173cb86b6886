//! Sub-texel sampling: a light sample of the distribution's (coarse) texel moved to one of the
//! `r x r` texels of the map at its own resolution that the coarse texel covers, chosen in
//! proportion to their luminance. A two-level (hierarchical) distribution whose first level is
//! the paper's per-face CDFs, unchanged.
//!
//! Why: with `--face-size 32` and a 128² map, a sun a few fine texels wide sits inside one coarse
//! texel. Sampled uniformly inside it, one sample in ~16 hits the sun and carries ~16× the weight
//! (`docs/benchmarks.md`, "Radiance at full resolution"). With this level, samples go where the
//! fine radiance is.
//!
//! The second level's random numbers are the sample's position inside its coarse texel, which is
//! uniform there (the remapped offsets of [`super::Distribution1D::sample`]). So a pool sample is
//! refined *after* it is drawn: the pool, its stratification and the GPU's build stay as they
//! are, and the refinement is one more pass (`refine_pool` in `shaders/subtexel.wgsl`).
//!
//! Density: `p(w) = pdf_area(coarse) * factor(fine) * (1 + a^2 + b^2)^(3/2)`, with
//! `factor = r^2 Y / (sum of Y over the coarse texel's fine texels)`, and 1 over a black coarse
//! texel, which is sampled uniformly. Unbiased wherever the coarse density is: a fine texel with
//! radiance has `Y > 0`, so a positive factor.

use super::distribution::{CubeDistribution, texel_offset};
use super::pool::{LightPool, PoolSample};
use super::rng::ONE_MINUS_EPSILON;
use crate::envmap::{CubeMap, dir_to_texel, face_ab_to_vec, luminance};
use glam::Vec3;

/// The second level over a map at its own resolution (`fine`) for a distribution of faces
/// `coarse` texels wide, where `fine` is a whole multiple `r >= 2` of `coarse`.
pub struct SubTexels<'a> {
    pub fine: &'a CubeMap,
    /// The distribution's face size `N`.
    pub coarse: usize,
    /// Fine texels per coarse texel side, `r`.
    pub ratio: usize,
    /// Per fine texel (the map's layout), the factor its coarse texel's density takes there.
    factors: Vec<f32>,
}

impl<'a> SubTexels<'a> {
    /// `r` when a face of `fine` texels cuts into `coarse` blocks of `r x r`, `r >= 2`; `None`
    /// otherwise (then samples stay uniform in their coarse texel, as before this level).
    pub fn ratio_of(fine: usize, coarse: usize) -> Option<usize> {
        (coarse > 0 && fine > coarse && fine.is_multiple_of(coarse)).then(|| fine / coarse)
    }

    /// The second level of `fine` over faces of `coarse` texels, or `None` where
    /// [`Self::ratio_of`] has none.
    pub fn new(fine: &'a CubeMap, coarse: usize) -> Option<Self> {
        use rayon::prelude::*;
        let r = Self::ratio_of(fine.size, coarse)?;
        let mut sub = SubTexels {
            fine,
            coarse,
            ratio: r,
            factors: Vec::new(),
        };
        let sums: Vec<f32> = (0..6 * coarse * coarse)
            .into_par_iter()
            .map(|b| sub.block_sum(b / (coarse * coarse), b % coarse, b / coarse % coarse))
            .collect();
        let rr = (r * r) as f32;
        sub.factors = (0..fine.data.len())
            .into_par_iter()
            .map(|i| {
                let (face, rest) = (i / (fine.size * fine.size), i % (fine.size * fine.size));
                let (col, row) = (rest % fine.size / r, rest / fine.size / r);
                let s = sums[(face * coarse + row) * coarse + col];
                if s > 0.0 { rr * sub.y(i) / s } else { 1.0 }
            })
            .collect();
        Some(sub)
    }

    /// Per fine texel, the factor its coarse texel's density takes there (the map's layout):
    /// what the GPU reads beside the fine radiance.
    pub fn factors(&self) -> &[f32] {
        &self.factors
    }

    /// The factor at direction `d`: its fine texel's.
    #[inline]
    pub fn factor(&self, d: Vec3) -> f32 {
        let n = self.fine.size;
        self.factors[dir_to_texel(d, n).index(n)]
    }

    /// The radiance and the factor at direction `d`, from one lookup of its fine texel: what a
    /// BRDF sample needs (its radiance, and the light density's factor for its MIS weight).
    #[inline]
    pub fn radiance_and_factor(&self, d: Vec3) -> (Vec3, f32) {
        let n = self.fine.size;
        let i = dir_to_texel(d, n).index(n);
        (self.fine.data[i], self.factors[i])
    }

    /// Luminance of fine texel `i` (an index into the map's data), negatives as 0.
    #[inline]
    fn y(&self, i: usize) -> f32 {
        luminance(self.fine.data[i]).max(0.0)
    }

    /// Luminance of fine texel `(j, i)` of coarse texel (`col`, `row`) of `face`.
    #[inline]
    fn y_in(&self, face: usize, col: usize, row: usize, j: usize, i: usize) -> f32 {
        let r = self.ratio;
        self.y(self.fine.index(face, col * r + j, row * r + i))
    }

    /// Sum of luminance down fine column `j` of coarse texel (`col`, `row`).
    fn column_sum(&self, face: usize, col: usize, row: usize, j: usize) -> f32 {
        (0..self.ratio)
            .map(|i| self.y_in(face, col, row, j, i))
            .sum()
    }

    /// Sum of luminance over coarse texel (`col`, `row`): its columns' sums, left to right (the
    /// order [`Self::sample`] adds them in).
    fn block_sum(&self, face: usize, col: usize, row: usize) -> f32 {
        (0..self.ratio)
            .map(|j| self.column_sum(face, col, row, j))
            .sum()
    }

    /// A fine texel of coarse texel (`col`, `row`) of `face` for the offsets `(du, dv)` in
    /// `[0, 1)^2`: its column by the columns' sums, its row by luminance down that column, and
    /// the offsets remapped inside it. Returns the fine `(col, row)` and offsets.
    pub fn sample(
        &self,
        face: usize,
        col: usize,
        row: usize,
        du: f32,
        dv: f32,
    ) -> (usize, usize, f32, f32) {
        let r = self.ratio;
        let (j, du) = pick(r, du, |j| self.column_sum(face, col, row, j));
        let (i, dv) = pick(r, dv, |i| self.y_in(face, col, row, j, i));
        (col * r + j, row * r + i, du, dv)
    }

    /// Invert: the offsets `(du, dv)` in coarse texel (`fcol / r`, `frow / r`) that
    /// [`Self::sample`] maps to fine texel (`fcol`, `frow`) at offsets `(fu, fv)`.
    pub fn invert(&self, face: usize, fcol: usize, frow: usize, fu: f32, fv: f32) -> (f32, f32) {
        let r = self.ratio;
        let (col, row, j, i) = (fcol / r, frow / r, fcol % r, frow % r);
        let du = unpick(r, j, fu, |j| self.column_sum(face, col, row, j));
        let dv = unpick(r, i, fv, |i| self.y_in(face, col, row, j, i));
        (du, dv)
    }

    /// Pool sample `s` of `dist` (faces of [`Self::coarse`]) moved to a fine texel of its coarse
    /// texel, by its offsets in it: direction, the fine texel's radiance, density
    /// `pdf_area * factor * Jacobian`. An empty slot stays empty.
    pub fn refine(&self, dist: &CubeDistribution, s: &PoolSample) -> PoolSample {
        if s.pdf <= 0.0 {
            return *s;
        }
        let (n, fine) = (self.coarse, self.fine.size);
        let hit = dir_to_texel(s.dir, n);
        let (col, du) = texel_offset(hit.a, n);
        let (row, dv) = texel_offset(hit.b, n);
        let (fcol, frow, fu, fv) = self.sample(hit.face, col, row, du, dv);
        let h = 2.0 / fine as f32;
        let a = -1.0 + (fcol as f32 + fu) * h;
        let b = -1.0 + (frow as f32 + fv) * h;
        let q = 1.0 + a * a + b * b;
        let i = self.fine.index(hit.face, fcol, frow);
        PoolSample {
            dir: face_ab_to_vec(hit.face, a, b).normalize(),
            radiance: self.fine.data[i],
            pdf: dist.faces[hit.face].pdf_area(col, row) * self.factors[i] * (q * q.sqrt()),
        }
    }

    /// Every sample of `pool` (drawn from `dist`) [`Self::refine`]d.
    pub fn refine_pool(&self, dist: &CubeDistribution, pool: &mut LightPool) {
        use rayon::prelude::*;
        pool.samples
            .par_iter_mut()
            .for_each(|s| *s = self.refine(dist, s));
    }
}

/// One of `r` bins of weights `w(k)` for `u` in `[0, 1)` (uniform when they sum to 0) and `u`
/// remapped inside it: the bin where the running sum passes `u` times the total.
fn pick(r: usize, u: f32, w: impl Fn(usize) -> f32) -> (usize, f32) {
    let total: f32 = (0..r).map(&w).sum();
    if total <= 0.0 {
        let x = u * r as f32;
        let k = (x as usize).min(r - 1);
        return (k, (x - k as f32).clamp(0.0, ONE_MINUS_EPSILON));
    }
    let goal = u * total;
    let (mut acc, mut last) = (0.0f32, 0);
    for k in 0..r {
        let wk = w(k);
        if wk <= 0.0 {
            continue;
        }
        if goal < acc + wk {
            return (k, ((goal - acc) / wk).clamp(0.0, ONE_MINUS_EPSILON));
        }
        (acc, last) = (acc + wk, k);
    }
    // Rounding left the target past the last sum: the last bin with weight, at its end.
    (last, ONE_MINUS_EPSILON)
}

/// Invert [`pick`]: the `u` that maps to bin `k` at offset `f`.
fn unpick(r: usize, k: usize, f: f32, w: impl Fn(usize) -> f32) -> f32 {
    let total: f32 = (0..r).map(&w).sum();
    if total <= 0.0 {
        return (k as f32 + f) / r as f32;
    }
    let before: f32 = (0..k).map(&w).sum();
    (before + f * w(k)) / total
}
