//! The conditional distributions of a face, `CDF(v|u)` for every column `u`, in the layout the
//! per-frame build streams: strips of columns, each stored row by row, built one strip per task
//! in a single pass over the texels (`docs/benchmarks.md` has what the layout bought).

use super::rng::ONE_MINUS_EPSILON;
use crate::envmap::luminance;
use glam::Vec3;

/// Columns per strip of [`Conditionals`]' layout.
pub const STRIP: usize = 64;

/// The conditional distributions over rows of every column of a face, `CDF(v|u)`, laid out the
/// way the build streams the face: the columns are cut into strips of [`STRIP`], and each strip
/// is stored row by row (its `m` columns contiguous within a row). The build then reads each
/// texel once, in memory order, and writes every sum next to the last one, and the strips are
/// built in parallel, each in its own contiguous block; sampling a column walks a stride of `m`.
#[derive(Clone, Debug)]
pub struct Conditionals {
    pub size: usize,
    /// Texel weights (luminance x solid angle), strip by strip, `n` rows each.
    weights: Vec<f32>,
    /// Normalised CDF values, strip by strip, `n + 1` rows each (`0` first, `1` last).
    cdf: Vec<f32>,
    /// Column sums (f64-accumulated).
    pub totals: Vec<f64>,
}

impl Conditionals {
    /// Index of (`col`, `row`) in a strip-major table with `rows` rows per column.
    #[inline]
    fn at(&self, col: usize, row: usize, rows: usize) -> usize {
        let c0 = col - col % STRIP;
        let m = STRIP.min(self.size - c0);
        rows * c0 + row * m + (col - c0)
    }

    /// `CDF(v|u = col)` at row boundary `row` (`0..=n`).
    #[inline]
    pub fn cdf(&self, col: usize, row: usize) -> f32 {
        self.cdf[self.at(col, row, self.size + 1)]
    }

    /// Texel (`col`, `row`)'s weight.
    #[inline]
    pub fn weight(&self, col: usize, row: usize) -> f32 {
        self.weights[self.at(col, row, self.size)]
    }

    /// Sum of column `col`'s weights.
    #[inline]
    pub fn total(&self, col: usize) -> f64 {
        self.totals[col]
    }

    /// Discrete probability of row `row` in column `col`.
    #[inline]
    pub fn bin_pmf(&self, col: usize, row: usize) -> f32 {
        let t = self.totals[col];
        if t > 0.0 {
            (self.weight(col, row) as f64 / t) as f32
        } else {
            0.0
        }
    }

    /// [`Distribution1D::sample`](super::Distribution1D::sample) of column `col`: row `r` with `cdf[r] <= u < cdf[r + 1]`, and
    /// the remapped offset.
    #[inline]
    pub fn sample(&self, col: usize, u: f32) -> (usize, f32) {
        // Largest r in [0, n-1] with cdf(col, r) <= u: a binary search down the column.
        let (mut lo, mut len) = (0usize, self.size);
        while len > 0 {
            let half = len / 2;
            if self.cdf(col, lo + half) <= u {
                lo += half + 1;
                len -= half + 1;
            } else {
                len = half;
            }
        }
        let r = lo.saturating_sub(1);
        let (c0, c1) = (self.cdf(col, r), self.cdf(col, r + 1));
        let w = c1 - c0;
        let dv = if w > 0.0 {
            ((u - c0) / w).clamp(0.0, ONE_MINUS_EPSILON)
        } else {
            0.0
        };
        (r, dv)
    }

    /// Invert: the `u` that [`Self::sample`] maps to row `row` and offset `dv` in column `col`.
    #[inline]
    pub fn invert(&self, col: usize, row: usize, dv: f32) -> f32 {
        let (c0, c1) = (self.cdf(col, row), self.cdf(col, row + 1));
        c0 + dv * (c1 - c0)
    }

    /// The conditionals of an `n x n` face of radiance `face` and texel solid angles `omega`
    /// (both row-major): one pass per strip of columns, in parallel. Down the strip's rows it
    /// computes each weight, adds it to its column's running f64 sum and stores the prefix; then,
    /// with the strip still in cache, it divides each column by its total.
    pub fn build(n: usize, face: &[Vec3], omega: &[f32]) -> Self {
        let mut c = Conditionals {
            size: n,
            weights: vec![0.0; n * n],
            cdf: vec![0.0; (n + 1) * n],
            totals: vec![0.0; n],
        };
        c.rebuild(face, omega);
        c
    }

    /// [`Self::build`] into this table's memory (same size): a stream's next frame reuses the
    /// last one's, so the build touches no fresh pages. Every entry is overwritten.
    pub fn rebuild(&mut self, face: &[Vec3], omega: &[f32]) {
        use rayon::prelude::*;
        let n = self.size;
        self.weights
            .par_chunks_mut(n * STRIP)
            .zip(self.cdf.par_chunks_mut((n + 1) * STRIP))
            .zip(self.totals.par_chunks_mut(STRIP))
            .enumerate()
            .for_each(|(k, ((w, cdf), totals))| {
                strip(Strip {
                    n,
                    c0: k * STRIP,
                    face,
                    omega,
                    w,
                    cdf,
                    totals,
                })
            });
    }

    /// The table from row-major weights, per-column CDFs (`n + 1` values each, column after
    /// column) and column totals, e.g. read back from the GPU.
    pub fn from_columns(n: usize, weights: &[f32], cdf: &[f32], totals: Vec<f64>) -> Self {
        let mut out = Conditionals {
            size: n,
            weights: vec![0.0; n * n],
            cdf: vec![0.0; (n + 1) * n],
            totals,
        };
        for c in 0..n {
            for r in 0..=n {
                let i = out.at(c, r, n + 1);
                out.cdf[i] = cdf[c * (n + 1) + r];
            }
            for r in 0..n {
                let i = out.at(c, r, n);
                out.weights[i] = weights[r * n + c];
            }
        }
        out
    }
}

/// One strip of [`Conditionals::build`]: columns `c0..c0 + m` of an `n x n` face (radiance
/// `face`, solid angles `omega`), into the strip's blocks `w` (`n x m`), `cdf` (`(n + 1) x m`)
/// and `totals` (`m`).
struct Strip<'a> {
    n: usize,
    c0: usize,
    face: &'a [Vec3],
    omega: &'a [f32],
    w: &'a mut [f32],
    cdf: &'a mut [f32],
    totals: &'a mut [f64],
}

/// Build one strip: the AVX2 copy where the CPU has it (the same arithmetic, vectorised across
/// the strip's columns).
fn strip(job: Strip) {
    #[cfg(target_arch = "x86_64")]
    if crate::cpu::avx2_fma() {
        // SAFETY: the CPU supports the features `strip_avx2` is compiled for.
        return unsafe { strip_avx2(job) };
    }
    strip_portable(job)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn strip_avx2(job: Strip) {
    strip_portable(job)
}

#[inline(always)]
fn strip_portable(job: Strip) {
    let Strip {
        n,
        c0,
        face,
        omega,
        w,
        cdf,
        totals,
    } = job;
    let m = totals.len();
    // Down the rows: each weight, its column's running f64 sum, the prefix as f32.
    let mut acc = [0.0f64; STRIP];
    for r in 0..n {
        let (src, om) = (&face[r * n + c0..][..m], &omega[r * n + c0..][..m]);
        let (wr, cr) = (&mut w[r * m..][..m], &mut cdf[(r + 1) * m..][..m]);
        for j in 0..m {
            let x = luminance(src[j]).max(0.0) * om[j];
            wr[j] = x;
            acc[j] += x as f64;
            cr[j] = acc[j] as f32;
        }
    }
    totals.copy_from_slice(&acc[..m]);
    cdf[..m].fill(0.0);
    // Normalise row by row (contiguous, while the strip is in cache).
    let inv: [f64; STRIP] = std::array::from_fn(|j| if acc[j] > 0.0 { 1.0 / acc[j] } else { 0.0 });
    for r in 1..n {
        for (v, &k) in cdf[r * m..][..m].iter_mut().zip(&inv) {
            *v = ((*v as f64 * k) as f32).min(1.0);
        }
    }
    // An empty column: uniform (it is never chosen: the marginal gives it 0).
    for j in (0..m).filter(|&j| acc[j] <= 0.0) {
        for r in 1..n {
            cdf[r * m + j] = r as f32 / n as f32;
        }
    }
    cdf[n * m..][..m].fill(1.0);
}
