//! The conditional distributions of a face, `CDF(v|u)` for every column `u`, in the layout the
//! per-frame build streams: strips of columns, each stored row by row, built one strip per task
//! in a single pass over the texels (`docs/benchmarks.md` has what the layout bought).

use super::rng::ONE_MINUS_EPSILON;
use super::tiles::TileGrid;
use crate::envmap::luminance;
use glam::Vec3;

/// Columns per strip of [`Conditionals`]' layout.
pub const STRIP: usize = 64;

/// The conditional distributions over rows of every column of a face, `CDF(v|u)`, laid out the
/// way the build streams the face: the columns are cut into strips of [`STRIP`], and each strip
/// is stored row by row (its `m` columns contiguous within a row). The build then reads each
/// texel once, in memory order, and writes every sum next to the last one, and the strips are
/// built in parallel, each in its own contiguous block; sampling a column walks a stride of `m`.
///
/// With tiles ([`TileGrid`], `K > 1`) each column is cut into `K` bands, one per tile row, and each
/// band has its own CDF and total: the conditional of a column within a tile. `K = 1` is one band.
#[derive(Clone, Debug)]
pub struct Conditionals {
    pub size: usize,
    /// The face's tiles: one band of rows per tile row.
    pub grid: TileGrid,
    /// Texel weights (luminance x solid angle), strip by strip, `n` rows each.
    weights: Vec<f32>,
    /// Normalised CDF values, strip by strip, `n + K` rows each: band `b` from row
    /// [`Self::band_base`]`(b)`, its rows + 1 values (`0` first, `1` last).
    cdf: Vec<f32>,
    /// Column sums per band (f64-accumulated), band-major: band `b`, column `c` at `b n + c`.
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

    /// Rows of the CDF table per column: `n + K` (each band adds its leading 0).
    #[inline]
    fn cdf_rows(&self) -> usize {
        self.size + self.grid.k
    }

    /// The CDF table row where band `b` starts.
    #[inline]
    pub fn band_base(&self, b: usize) -> usize {
        self.grid.bound(b) + b
    }

    /// Entry `i` of column `col`'s CDF table (`0..n + K`; with one band, `CDF(v|u = col)` at row
    /// boundary `i`).
    #[inline]
    pub fn cdf(&self, col: usize, i: usize) -> f32 {
        self.cdf[self.at(col, i, self.cdf_rows())]
    }

    /// Texel (`col`, `row`)'s weight.
    #[inline]
    pub fn weight(&self, col: usize, row: usize) -> f32 {
        self.weights[self.at(col, row, self.size)]
    }

    /// Sum of column `col`'s weights in band (tile row) `band`.
    #[inline]
    pub fn total(&self, band: usize, col: usize) -> f64 {
        self.totals[band * self.size + col]
    }

    /// Discrete probability of row `row` in column `col`, within its band.
    #[inline]
    pub fn bin_pmf(&self, col: usize, row: usize) -> f32 {
        let t = self.total(self.grid.of(row), col);
        if t > 0.0 {
            (self.weight(col, row) as f64 / t) as f32
        } else {
            0.0
        }
    }

    /// [`Distribution1D::sample`](super::Distribution1D::sample) of column `col` within band
    /// `band`: row `r` (of the face) with `cdf[r] <= u < cdf[r + 1]`, and the remapped offset.
    #[inline]
    pub fn sample(&self, col: usize, band: usize, u: f32) -> (usize, f32) {
        let (r0, r1) = (self.grid.bound(band), self.grid.bound(band + 1));
        let base = self.band_base(band);
        // Largest i in [0, rows - 1] with cdf(base + i) <= u: a binary search down the band.
        let (mut lo, mut len) = (0usize, r1 - r0);
        while len > 0 {
            let half = len / 2;
            if self.cdf(col, base + lo + half) <= u {
                lo += half + 1;
                len -= half + 1;
            } else {
                len = half;
            }
        }
        let i = lo.saturating_sub(1);
        let (c0, c1) = (self.cdf(col, base + i), self.cdf(col, base + i + 1));
        let w = c1 - c0;
        let dv = if w > 0.0 {
            ((u - c0) / w).clamp(0.0, ONE_MINUS_EPSILON)
        } else {
            0.0
        };
        (r0 + i, dv)
    }

    /// Invert: the `u` that [`Self::sample`] maps to row `row` and offset `dv` in column `col`.
    #[inline]
    pub fn invert(&self, col: usize, row: usize, dv: f32) -> f32 {
        let b = self.grid.of(row);
        let i = self.band_base(b) + row - self.grid.bound(b);
        let (c0, c1) = (self.cdf(col, i), self.cdf(col, i + 1));
        c0 + dv * (c1 - c0)
    }

    /// The conditionals of an `n x n` face of radiance `face` and texel solid angles `omega`
    /// (both row-major), one band per tile row of `grid`: one pass per strip of columns, in
    /// parallel. Down the strip's rows it computes each weight, adds it to its column's running
    /// f64 sum and stores the prefix; then, with the strip still in cache, it divides each column
    /// by its total.
    pub fn build(grid: TileGrid, face: &[Vec3], omega: &[f32]) -> Self {
        let n = grid.size;
        let mut c = Conditionals {
            size: n,
            grid,
            weights: vec![0.0; n * n],
            cdf: vec![0.0; (n + grid.k) * n],
            totals: vec![0.0; grid.k * n],
        };
        c.rebuild(face, omega);
        c
    }

    /// [`Self::build`] into this table's memory (same size): a stream's next frame reuses the
    /// last one's, so the build touches no fresh pages. Every entry is overwritten.
    pub fn rebuild(&mut self, face: &[Vec3], omega: &[f32]) {
        use rayon::prelude::*;
        let (n, grid) = (self.size, self.grid);
        let rows = self.cdf_rows();
        let mut totals = vec![0.0f64; n * grid.k];
        self.weights
            .par_chunks_mut(n * STRIP)
            .zip(self.cdf.par_chunks_mut(rows * STRIP))
            .zip(totals.par_chunks_mut(STRIP * grid.k))
            .enumerate()
            .for_each(|(k, ((w, cdf), totals))| {
                strip(Strip {
                    grid,
                    c0: k * STRIP,
                    face,
                    omega,
                    w,
                    cdf,
                    totals,
                })
            });
        // The strips wrote their totals strip-major (band within strip); store them band-major.
        for (k, chunk) in totals.chunks(STRIP * grid.k).enumerate() {
            let m = chunk.len() / grid.k;
            for b in 0..grid.k {
                self.totals[b * n + k * STRIP..][..m].copy_from_slice(&chunk[b * m..][..m]);
            }
        }
    }

    /// The table from row-major weights, per-column CDFs (`n + K` values each, column after
    /// column, band after band) and band-major column totals, e.g. read back from the GPU.
    pub fn from_columns(grid: TileGrid, weights: &[f32], cdf: &[f32], totals: Vec<f64>) -> Self {
        let n = grid.size;
        let rows = n + grid.k;
        let mut out = Conditionals {
            size: n,
            grid,
            weights: vec![0.0; n * n],
            cdf: vec![0.0; rows * n],
            totals,
        };
        for c in 0..n {
            for r in 0..rows {
                let i = out.at(c, r, rows);
                out.cdf[i] = cdf[c * rows + r];
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
/// `face`, solid angles `omega`), into the strip's blocks `w` (`n x m`), `cdf` (`(n + K) x m`)
/// and `totals` (`K x m`, band-major).
struct Strip<'a> {
    grid: TileGrid,
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
        grid,
        c0,
        face,
        omega,
        w,
        cdf,
        totals,
    } = job;
    let n = grid.size;
    let m = totals.len() / grid.k;
    for b in 0..grid.k {
        let (r0, r1) = (grid.bound(b), grid.bound(b + 1));
        // The band's CDF rows: its leading 0 at `base`, the prefix of row r at `base + 1 + r - r0`.
        let base = r0 + b;
        let rows = r1 - r0;
        // Down the rows: each weight, its column's running f64 sum, the prefix as f32.
        let mut acc = [0.0f64; STRIP];
        for r in r0..r1 {
            let (src, om) = (&face[r * n + c0..][..m], &omega[r * n + c0..][..m]);
            let (wr, cr) = (
                &mut w[r * m..][..m],
                &mut cdf[(base + 1 + r - r0) * m..][..m],
            );
            for j in 0..m {
                let x = luminance(src[j]).max(0.0) * om[j];
                wr[j] = x;
                acc[j] += x as f64;
                cr[j] = acc[j] as f32;
            }
        }
        totals[b * m..][..m].copy_from_slice(&acc[..m]);
        normalise_band(&mut cdf[base * m..][..(rows + 1) * m], m, &acc);
    }
}

/// Divide a band's prefix sums (`rows + 1` rows of `m` columns, row 0 to be the leading 0) by
/// their column totals `acc`, row by row (contiguous, while the strip is in cache).
#[inline(always)]
fn normalise_band(cdf: &mut [f32], m: usize, acc: &[f64; STRIP]) {
    let rows = cdf.len() / m - 1;
    cdf[..m].fill(0.0);
    let inv: [f64; STRIP] = std::array::from_fn(|j| if acc[j] > 0.0 { 1.0 / acc[j] } else { 0.0 });
    for r in 1..rows {
        for (v, &k) in cdf[r * m..][..m].iter_mut().zip(&inv) {
            *v = ((*v as f64 * k) as f32).min(1.0);
        }
    }
    // An empty column: uniform (it is never chosen: the marginal gives it 0).
    for j in (0..m).filter(|&j| acc[j] <= 0.0) {
        for r in 1..rows {
            cdf[r * m + j] = r as f32 / rows as f32;
        }
    }
    cdf[rows * m..][..m].fill(1.0);
}
