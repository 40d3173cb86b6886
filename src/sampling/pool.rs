//! The per-frame light-sample pool: the same number `M` of samples on every face.
//!
//! Sample `i` of face `f` uses Latin-hypercube stratification with hash permutations:
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

/// `M` samples per face, face-major: sample `i` of face `f` is `samples[f * M + i]`.
#[derive(Clone, Debug)]
pub struct LightPool {
    pub per_face: usize,
    pub samples: Vec<PoolSample>,
}

/// The 2D point of pool sample `i` of face `face` (`m` samples per face) for `seed`.
#[inline]
pub fn pool_point(seed: u32, face: u32, i: u32, m: u32) -> Vec2 {
    let pu = permute(i, m, hash_combine(&[seed, face, 0x5eed_0001]));
    let pv = permute(i, m, hash_combine(&[seed, face, 0x5eed_0002]));
    let ju = to_unit(hash_combine(&[seed, face, i, 1]));
    let jv = to_unit(hash_combine(&[seed, face, i, 2]));
    // (p + xi) / m, kept strictly below 1.
    let u = ((pu as f32 + ju) / m as f32).min(ONE_MINUS_EPSILON);
    let v = ((pv as f32 + jv) / m as f32).min(ONE_MINUS_EPSILON);
    Vec2::new(u, v)
}

impl LightPool {
    pub fn build(map: &CubeMap, dist: &CubeDistribution, per_face: usize, seed: u32) -> Self {
        use rayon::prelude::*;
        let m = per_face;
        let samples = (0..6 * m)
            .into_par_iter()
            .map(|k| {
                let (f, i) = (k / m.max(1), k % m.max(1));
                let p = pool_point(seed, f as u32, i as u32, m as u32);
                match dist.faces[f].sample(f, p) {
                    Some(s) => PoolSample {
                        dir: s.dir,
                        radiance: map.texel(f, s.col, s.row),
                        pdf: s.pdf,
                    },
                    None => PoolSample::default(),
                }
            })
            .collect();
        LightPool {
            per_face: m,
            samples,
        }
    }

    #[inline]
    pub fn get(&self, face: usize, i: usize) -> &PoolSample {
        &self.samples[face * self.per_face + i]
    }
}
