//! What the GPU build wrote, read back to the CPU: its timings and clamped-texel counts, and
//! (tests and debugging only: the frame path never reads back) every table as the CPU twin's
//! types, so each stage can be compared with its twin on exactly the GPU's input.

use super::*;

impl EnvSampler {
    /// The last build's GPU milliseconds (distribution + pool, when the device has timestamps)
    /// and clamped-texel counts, in one readback.
    pub fn read_report(&self, ctx: &GpuContext) -> Result<(Option<f64>, SanitizeReport)> {
        let mut parts = vec![(&self.problems, 0, 16)];
        parts.extend(
            [&self.timer, &self.pool_timer]
                .into_iter()
                .flatten()
                .map(|t| t.part()),
        );
        let data = ctx.read_many(&parts)?;
        let c: Vec<u32> = bytemuck::pod_collect_to_vec(&data[0]);
        let ms = match (data.get(1), data.get(2)) {
            (Some(d), Some(p)) => crate::shading::PassTimer::ms(ctx, d)
                .zip(crate::shading::PassTimer::ms(ctx, p))
                .map(|(d, p)| d + p),
            _ => None,
        };
        Ok((ms, sanitize_report(&c)))
    }

    /// Texels clamped by the GPU sanitise pass of the last build.
    pub fn read_problems(&self, ctx: &GpuContext) -> Result<SanitizeReport> {
        let c: Vec<u32> = ctx.read(&self.problems, 0, 4)?;
        Ok(sanitize_report(&c))
    }

    /// Read every table back (tests and debugging only; the frame path never does this).
    pub fn read_tables(&self, ctx: &GpuContext) -> Result<GpuTables> {
        let (n, m, k) = (self.n, self.m, self.tiles);
        let grid = TileGrid::new(n, k);
        let regions = grid.regions();
        let texels: Vec<[f32; 4]> = ctx.read(&self.texels, 0, 6 * n * n)?;
        let totals: Vec<f32> = ctx.read(&self.totals, 0, totals_columns(k) + 6 * k * n)?;
        let pool: Vec<[f32; 4]> = ctx.read(&self.pool, 0, regions * m * 2)?;
        let record = |r: usize| &totals[REGION_RECORD * r..][..REGION_RECORD];
        Ok(GpuTables {
            grid,
            m,
            blocks: self.blocks,
            weights: ctx.read(&self.weights, 0, 6 * n * n)?,
            cond_cdf: ctx.read(&self.cdfs, 0, 6 * n * (n + k))?,
            marg_cdf: ctx.read(&self.cdfs, 6 * n * (n + k), regions * (n + 1))?,
            energies: (0..regions).map(|r| record(r)[3]).collect(),
            corners: (0..regions)
                .map(|r| std::array::from_fn(|j| Vec3::from_slice(&record(r)[4 * j..])))
                .collect(),
            col_totals: totals[totals_columns(k)..].to_vec(),
            radiance: texels.iter().map(|t| Vec3::new(t[0], t[1], t[2])).collect(),
            pdf_area: texels.iter().map(|t| t[3]).collect(),
            pool: pool
                .chunks_exact(2)
                .map(|p| PoolSample {
                    dir: Vec3::new(p[0][0], p[0][1], p[0][2]),
                    pdf: p[0][3],
                    radiance: Vec3::new(p[1][0], p[1][1], p[1][2]),
                })
                .collect(),
        })
    }
}

/// The sanitise pass's four counters (NaN, Inf, negative, huge), in the order it writes them.
fn sanitize_report(c: &[u32]) -> SanitizeReport {
    SanitizeReport {
        nan: c[0] as u64,
        inf: c[1] as u64,
        negative: c[2] as u64,
        huge: c[3] as u64,
    }
}

/// Everything the GPU build wrote, on the CPU.
#[derive(Clone, Debug)]
pub struct GpuTables {
    /// Face size and tiles.
    pub grid: TileGrid,
    pub m: usize,
    pub blocks: usize,
    pub weights: Vec<f32>,
    /// Per (face, column) `n + K` values: the CDFs of its `K` bands.
    pub cond_cdf: Vec<f32>,
    /// Per region `n + 1` values (its columns + 1 used).
    pub marg_cdf: Vec<f32>,
    /// Per region (face, or tile), its energy.
    pub energies: Vec<f32>,
    /// Per region, its corner directions (as [`TileGrid::corners`]).
    pub corners: Vec<[Vec3; 4]>,
    /// Per (face, band, column), the column's total in the band.
    pub col_totals: Vec<f32>,
    pub radiance: Vec<Vec3>,
    pub pdf_area: Vec<f32>,
    pub pool: Vec<PoolSample>,
}

impl GpuTables {
    /// The GPU's tables as a CPU [`CubeDistribution`], so the CPU twin of a later stage (the pool,
    /// the shading) can be run on exactly the GPU's input and compared stage by stage.
    pub fn to_distribution(&self) -> CubeDistribution {
        let (g, n, k) = (self.grid, self.grid.size, self.grid.k);
        let faces = (0..6)
            .map(|f| {
                let totals: Vec<f64> = self.col_totals[f * k * n..(f + 1) * k * n]
                    .iter()
                    .map(|&t| t as f64)
                    .collect();
                let conditional = Conditionals::from_columns(
                    g,
                    &self.weights[f * n * n..(f + 1) * n * n],
                    &self.cond_cdf[f * n * (n + k)..(f + 1) * n * (n + k)],
                    totals,
                );
                let tiles = (0..g.per_face())
                    .map(|t| self.tile(f * g.per_face() + t))
                    .collect::<Vec<_>>();
                FaceDistribution {
                    size: n,
                    energy: tiles.iter().map(|t| t.energy).sum(),
                    conditional,
                    tiles,
                }
            })
            .collect();
        CubeDistribution {
            size: n,
            grid: g,
            faces,
        }
    }

    /// Region `r`'s tile as the GPU built it.
    fn tile(&self, r: usize) -> TileDistribution {
        let (g, n) = (self.grid, self.grid.size);
        let (f, _, ty) = g.split(r);
        let (c0, c1, _, _) = g.span(r);
        let e = self.energies[r];
        TileDistribution {
            col0: c0,
            band: ty,
            marginal: Distribution1D {
                func: self.col_totals[(f * g.k + ty) * n..][c0..c1].to_vec(),
                cdf: self.marg_cdf[r * (n + 1)..][..c1 - c0 + 1].to_vec(),
                total: e as f64,
            },
            energy: e as f64,
            // `pdf_table`'s scale, computed as it does (in f32).
            area_scale: if e > 0.0 {
                (n * n) as f32 * 0.25 / e
            } else {
                0.0
            },
        }
    }

    /// The pool as a CPU [`LightPool`].
    pub fn to_pool(&self) -> LightPool {
        LightPool {
            per_region: self.m,
            block: self.m / self.blocks.max(1),
            samples: self.pool.clone(),
        }
    }

    /// The sanitised radiance as a cube map.
    pub fn to_map(&self) -> CubeMap {
        CubeMap {
            size: self.grid.size,
            data: self.radiance.clone(),
        }
    }
}
