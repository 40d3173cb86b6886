//! The map's bright part (a sun, a lamp) as a light of its own: a table of its texels, sampled
//! in proportion to `Y Ω`, with the pdf and the inverse of its samples beside the sampler (as
//! pbrt-v4's `util/sampling.h` keeps them). `bright.rs` splits a map into this and the rest.

use crate::envmap::{CubeMap, dir_to_texel, face_ab_to_vec, luminance};
use crate::sampling::distribution::{Distribution1D, face_solid_angles};
use glam::{Vec2, Vec3};

/// The bright part as a light of its own: its texels, chosen in proportion to `Y Ω`, the
/// direction uniform in face coordinates inside the texel (as the paper's face sampler does).
pub struct BrightLight {
    size: usize,
    /// Cube-map indices of the bright texels, and their radiance.
    texels: Vec<u32>,
    radiance: Vec<Vec3>,
    /// Per cube-map texel: its place in `texels`, or `u32::MAX`.
    place: Vec<u32>,
    dist: Option<Distribution1D>,
}

impl BrightLight {
    /// The texels of `map` brighter than `threshold`.
    pub fn new(map: &CubeMap, threshold: f32) -> Self {
        let n = map.size;
        let omega = face_solid_angles(n);
        let mut place = vec![u32::MAX; map.data.len()];
        let (mut texels, mut radiance, mut weights) = (Vec::new(), Vec::new(), Vec::new());
        for (i, l) in map.data.iter().enumerate() {
            if luminance(*l) > threshold {
                place[i] = texels.len() as u32;
                texels.push(i as u32);
                radiance.push(*l);
                weights.push(luminance(*l) * omega[i % (n * n)]);
            }
        }
        let dist = (!weights.is_empty()).then(|| Distribution1D::new(weights));
        BrightLight {
            size: n,
            texels,
            radiance,
            place,
            dist,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.dist.is_none()
    }

    /// Its texels in table order: cube-map index, radiance and probability (the GPU's copy,
    /// `envis_wgpu::resampling`).
    pub fn texels(&self) -> impl Iterator<Item = (u32, Vec3, f32)> + '_ {
        let pmf = |k| self.dist.as_ref().map_or(0.0, |d| d.bin_pmf(k));
        (self.texels.iter().zip(&self.radiance).enumerate())
            .map(move |(k, (&t, &l))| (t, l, pmf(k)))
    }

    /// The CDF over [`Self::texels`] (empty without a bright part).
    pub fn cdf(&self) -> &[f32] {
        self.dist.as_ref().map_or(&[], |d| &d.cdf)
    }

    /// Whether `other` is the same light: the same texels with the same radiance. The bright
    /// part's history is reused only then: a moving sun moves radiance by orders of magnitude
    /// between a sample's frame and the next (measured: 300x the error of no reuse).
    pub fn same_light(&self, other: &BrightLight) -> bool {
        self.size == other.size && self.texels == other.texels && self.radiance == other.radiance
    }

    /// Whether direction `d` is in the bright part.
    pub fn contains(&self, d: Vec3) -> bool {
        self.place[dir_to_texel(d, self.size).index(self.size)] != u32::MAX
    }

    /// The bright part's radiance in direction `d` (zero outside it).
    pub fn radiance(&self, d: Vec3) -> Vec3 {
        match self.place[dir_to_texel(d, self.size).index(self.size)] {
            u32::MAX => Vec3::ZERO,
            k => self.radiance[k as usize],
        }
    }

    /// A direction and its solid-angle pdf: `u.x` chooses the texel (and is re-stretched across
    /// it), `u.y` the other coordinate. `None` when there is no bright part.
    pub fn sample(&self, u: Vec2) -> Option<(Vec3, f32)> {
        let dist = self.dist.as_ref()?;
        let (k, du) = dist.sample(u.x);
        let (n, t) = (self.size, self.texels[k] as usize);
        let (face, row, col) = (t / (n * n), (t / n) % n, t % n);
        let h = 2.0 / n as f32;
        let a = -1.0 + (col as f32 + du) * h;
        let b = -1.0 + (row as f32 + u.y) * h;
        let d = face_ab_to_vec(face, a, b).normalize();
        Some((d, self.texel_pdf(k, a, b)))
    }

    /// Invert: the `u` that [`Self::sample`] maps to direction `d` (`None` outside the bright
    /// part).
    pub fn invert(&self, d: Vec3) -> Option<Vec2> {
        let dist = self.dist.as_ref()?;
        let t = dir_to_texel(d, self.size);
        let k = self.place[t.index(self.size)];
        if k == u32::MAX {
            return None;
        }
        let x = (t.a + 1.0) * 0.5 * self.size as f32 - t.col as f32;
        let y = (t.b + 1.0) * 0.5 * self.size as f32 - t.row as f32;
        Some(Vec2::new(
            dist.invert(k as usize, x.clamp(0.0, 1.0)),
            y.clamp(0.0, 1.0),
        ))
    }

    /// The solid-angle pdf of [`Self::sample`] choosing `d` (0 outside the bright part).
    pub fn pdf(&self, d: Vec3) -> f32 {
        let t = dir_to_texel(d, self.size);
        match self.place[t.index(self.size)] {
            u32::MAX => 0.0,
            k => self.texel_pdf(k as usize, t.a, t.b),
        }
    }

    /// `P(texel k) / (2/N)^2 * (1 + a^2 + b^2)^(3/2)` at face coordinates `(a, b)`.
    fn texel_pdf(&self, k: usize, a: f32, b: f32) -> f32 {
        let Some(dist) = &self.dist else { return 0.0 };
        let h = 2.0 / self.size as f32;
        let q = 1.0 + a * a + b * b;
        dist.bin_pmf(k) / (h * h) * q * q.sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::envmap::sky::{sky_cube, sun_direction};
    use crate::render::resampling::bright_threshold;
    use crate::sampling::rng::Rng;

    /// `invert` takes a sample's direction back to its random numbers.
    #[test]
    fn bright_light_inverts_its_samples() {
        let map = sky_cube(16, 9.0);
        let light = BrightLight::new(&map, bright_threshold(&map));
        let mut rng = Rng::new(3, 0);
        let mut n = 0;
        for _ in 0..2000 {
            let u = Vec2::new(rng.next_f32(), rng.next_f32());
            let Some((d, _)) = light.sample(u) else {
                panic!("the sky has a sun")
            };
            let back = light.invert(d).expect("a sample is in the bright part");
            assert!(
                (back - u).abs().max_element() < 2e-3,
                "{u} -> {d} -> {back}"
            );
            n += 1;
        }
        assert_eq!(n, 2000);
        assert_eq!(light.invert(-sun_direction(9.0)), None);
    }
}
