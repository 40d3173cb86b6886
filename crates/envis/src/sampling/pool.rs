//! The per-frame light-sample pool: the same number `M` of samples on every face (on every tile,
//! with `--tiles K`: a region is a face or a tile, [`super::tiles`]).
//!
//! Sample `i` of region `f` uses Latin-hypercube stratification with hash permutations:
//! `u = (perm_u(i) + xi_u) / M`, `v = (perm_v(i) + xi_v) / M`. Every sample is, on its own,
//! distributed exactly as the face pdf `p_f` (its stratum is uniformly random), so a pixel that
//! uses only the first `k` samples — or `k` samples from a random start offset — stays unbiased,
//! while the whole pool is stratified in both CDF dimensions.

use super::distribution::CubeDistribution;
use super::rng::{ONE_MINUS_EPSILON, hash_combine, permute, to_unit};
use crate::envmap::CubeMap;
use glam::{Vec2, Vec3};

/// One light sample of the pool. `pdf == 0` marks an unusable slot (empty face).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PoolSample {
    pub dir: Vec3,
    pub radiance: Vec3,
    /// Per-face solid-angle pdf `p_f(dir)`.
    pub pdf: f32,
}

/// `M` samples per region (face, or tile) in each of `B` blocks (`B = 1`: the paper's pool),
/// region-major: slot `j` of region `r` is `samples[r * per_region + j]`, and block `b` holds slots
/// `b M .. (b + 1) M`.
#[derive(Clone, Debug)]
pub struct LightPool {
    /// Slots per region, `B M`.
    pub per_region: usize,
    /// `M`, the samples per region of one block.
    pub block: usize,
    pub samples: Vec<PoolSample>,
}

/// The 2D point of pool sample `i` of region `region` (a face, or a tile; `m` samples per
/// region) for `seed`.
#[inline]
pub fn pool_point(seed: u32, region: u32, i: u32, m: u32) -> Vec2 {
    let pu = permute(i, m, hash_combine(&[seed, region, 0x5eed_0001]));
    let pv = permute(i, m, hash_combine(&[seed, region, 0x5eed_0002]));
    let ju = to_unit(hash_combine(&[seed, region, i, 1]));
    let jv = to_unit(hash_combine(&[seed, region, i, 2]));
    // (p + xi) / m, kept strictly below 1.
    let u = ((pu as f32 + ju) / m as f32).min(ONE_MINUS_EPSILON);
    let v = ((pv as f32 + jv) / m as f32).min(ONE_MINUS_EPSILON);
    Vec2::new(u, v)
}

/// The seed of block `b` of a pool seeded `seed`: block 0 is the paper's pool itself, so a pool of
/// one block is the same with or without blocks.
#[inline]
pub fn block_seed(seed: u32, b: u32) -> u32 {
    if b == 0 {
        seed
    } else {
        hash_combine(&[seed, b, 0xb10c])
    }
}

/// The 2D point of slot `j` of region `region` in a pool of blocks of `m` samples: a
/// Latin-hypercube point of its own block.
#[inline]
pub fn block_point(seed: u32, region: u32, j: u32, m: u32) -> Vec2 {
    pool_point(block_seed(seed, j / m), region, j % m, m)
}

impl LightPool {
    /// The paper's pool: `per_face` samples per region in one block.
    pub fn build(map: &CubeMap, dist: &CubeDistribution, per_face: usize, seed: u32) -> Self {
        Self::build_blocks(map, dist, per_face, 1, seed)
    }

    /// `blocks` independent stratified pools of `per_face` samples per region (face or tile of
    /// `dist`) (`PoolLayout::Blocks`), each drawn with its own [`block_seed`].
    pub fn build_blocks(
        map: &CubeMap,
        dist: &CubeDistribution,
        per_face: usize,
        blocks: usize,
        seed: u32,
    ) -> Self {
        use rayon::prelude::*;
        let (m, slots) = (per_face.max(1), per_face.max(1) * blocks.max(1));
        let k2 = dist.grid.per_face();
        let samples = (0..dist.grid.regions() * slots)
            .into_par_iter()
            .map(|k| {
                let (r, j) = (k / slots, k % slots);
                let p = block_point(seed, r as u32, j as u32, m as u32);
                match dist.sample_region(r, p) {
                    Some(s) => PoolSample {
                        dir: s.dir,
                        radiance: map.texel(r / k2, s.col, s.row),
                        pdf: s.pdf,
                    },
                    None => PoolSample::default(),
                }
            })
            .collect();
        LightPool {
            per_region: slots,
            block: m,
            samples,
        }
    }

    /// Slot `i` of region `r`.
    #[inline]
    pub fn get(&self, r: usize, i: usize) -> &PoolSample {
        &self.samples[r * self.per_region + i]
    }
}
