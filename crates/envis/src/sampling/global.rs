//! The `global` baseline (pbrt-style): one piecewise-constant 2D distribution over the whole
//! sphere in lat-long (Mitsuba 3 convention) at `4N x 2N` cells for `N x N` cube faces.
//!
//! Cell weight = mean luminance of 4x4 sub-points (nearest cube texel) x cell solid angle, plus a
//! defensive floor of 1% of the mean cell weight, so the pdf is positive wherever a bright cube
//! texel could hide between sub-points (light sampling alone stays unbiased). Sample: row from the
//! marginal over `v`, column from the row's conditional over `u`, uniform `(u, v)` in the cell;
//! `p(w) = p(u, v) / (2 pi^2 sin t)`.

use super::distribution::Distribution1D;
use crate::envmap::{CubeMap, dir_to_latlong, latlong_to_dir, luminance};
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

#[derive(Clone, Debug)]
pub struct GlobalDistribution {
    pub width: usize,
    pub height: usize,
    /// Over rows (`v`).
    pub marginal: Distribution1D,
    /// Per row, over columns (`u`).
    pub conditional: Vec<Distribution1D>,
}

impl GlobalDistribution {
    pub fn build(map: &CubeMap) -> Self {
        use rayon::prelude::*;
        let (w, h) = (4 * map.size, 2 * map.size);
        let s = 4;
        let mut cells: Vec<f32> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let mut acc = 0.0;
                for sy in 0..s {
                    for sx in 0..s {
                        let u = (x as f32 + (sx as f32 + 0.5) / s as f32) / w as f32;
                        let v = (y as f32 + (sy as f32 + 0.5) / s as f32) / h as f32;
                        acc += luminance(map.lookup(latlong_to_dir(u, v)));
                    }
                }
                let t0 = PI * y as f32 / h as f32;
                let t1 = PI * (y + 1) as f32 / h as f32;
                acc / (s * s) as f32 * (t0.cos() - t1.cos())
            })
            .collect();
        let mean = cells.iter().map(|&c| c as f64).sum::<f64>() / cells.len() as f64;
        let floor = if mean > 0.0 {
            (0.01 * mean) as f32
        } else {
            1.0
        };
        for (i, c) in cells.iter_mut().enumerate() {
            let y = i / w;
            let t0 = PI * y as f32 / h as f32;
            let t1 = PI * (y + 1) as f32 / h as f32;
            // Floor per unit solid angle, so it does not favour the poles.
            *c += floor * (t0.cos() - t1.cos()) * h as f32 / 2.0;
        }
        let conditional: Vec<Distribution1D> = (0..h)
            .map(|y| Distribution1D::new(cells[y * w..(y + 1) * w].to_vec()))
            .collect();
        let marginal = Distribution1D::new(conditional.iter().map(|d| d.total as f32).collect());
        GlobalDistribution {
            width: w,
            height: h,
            marginal,
            conditional,
        }
    }

    /// Sample a direction and its solid-angle pdf; `None` at the (measure-zero) poles.
    #[inline]
    pub fn sample(&self, u: Vec2) -> Option<(Vec3, f32)> {
        let (y, dv) = self.marginal.sample(u.y);
        let (x, du) = self.conditional[y].sample(u.x);
        let uu = (x as f32 + du) / self.width as f32;
        let vv = (y as f32 + dv) / self.height as f32;
        let d = latlong_to_dir(uu, vv);
        let p = self.pdf_cell(x, y, vv);
        if p > 0.0 && p.is_finite() {
            Some((d, p))
        } else {
            None
        }
    }

    #[inline]
    fn pdf_cell(&self, x: usize, y: usize, v: f32) -> f32 {
        let st = (PI * v).sin();
        if st <= 0.0 {
            return 0.0;
        }
        let puv = self.marginal.bin_pmf(y)
            * self.conditional[y].bin_pmf(x)
            * (self.width * self.height) as f32;
        puv / (2.0 * PI * PI * st)
    }

    /// Solid-angle pdf of direction `d`.
    #[inline]
    pub fn pdf(&self, d: Vec3) -> f32 {
        let (u, v) = dir_to_latlong(d);
        let x = ((u * self.width as f32) as usize).min(self.width - 1);
        let y = ((v * self.height as f32) as usize).min(self.height - 1);
        self.pdf_cell(x, y, v)
    }
}
