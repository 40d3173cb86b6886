//! Environment maps: the cube-map type, the direction conventions, loaders, resampling and the
//! built-in procedural sky.
//!
//! Conventions (written once, in `docs/conventions.md`, and used everywhere):
//! - Lat-long maps use Mitsuba 3's mapping: `d = (sin t sin p, cos t, -sin t cos p)`,
//!   `p = 2 pi u`, `t = pi v`, +Y up, `u` along image columns, `v` down the rows.
//! - Cube faces are stored in the order +X, -X, +Y, -Y, +Z, -Z with the Vulkan/wgpu/OpenGL cube
//!   texture orientation, so a GPU `textureSample(cube, dir)` and [`dir_to_face_uv`] agree.

pub mod color;
mod geometry;
pub mod hdr;
pub mod load;
pub mod resample;
mod sanitize;
pub mod sky;

pub use geometry::*;
pub use sanitize::{MAX_RADIANCE, SanitizeReport, sanitize_texel};

use glam::{DVec3, Vec3};

/// Rec. 709 luminance of linear RGB.
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// f64 twin of [`luminance`] (reference images and error metrics).
#[inline]
pub fn luminance_f64(c: DVec3) -> f64 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// An RGB image in linear float (row-major, top row first).
#[derive(Clone, Debug)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub data: Vec<Vec3>,
}

impl Image {
    pub fn new(width: usize, height: usize) -> Self {
        Image {
            width,
            height,
            data: vec![Vec3::ZERO; width * height],
        }
    }
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> Vec3 {
        self.data[y * self.width + x]
    }
    /// Clamp NaN/Inf/negative texels to zero and count them.
    pub fn sanitize(&mut self) -> SanitizeReport {
        let mut r = SanitizeReport::default();
        for t in &mut self.data {
            *t = sanitize_texel(*t, &mut r);
        }
        r
    }
}

/// A cube map of six square faces of `size` x `size` linear RGB texels.
/// Texel `(col, row)` of face `f` is at `data[(f * size + row) * size + col]`; `col` follows `u`,
/// `row` follows `v` (see [`face_uv_to_dir`]). Radiance is piecewise constant per texel (nearest
/// lookup): the sampler, the estimators and the reference all integrate this same function.
#[derive(Clone, Debug)]
pub struct CubeMap {
    pub size: usize,
    pub data: Vec<Vec3>,
}

impl CubeMap {
    pub fn new(size: usize) -> Self {
        assert!(size > 0, "cube face size must be positive");
        CubeMap {
            size,
            data: vec![Vec3::ZERO; 6 * size * size],
        }
    }

    /// Build from a function of the texel centre direction.
    pub fn from_fn(size: usize, f: impl Fn(Vec3) -> Vec3 + Sync) -> Self {
        use rayon::prelude::*;
        let mut m = CubeMap::new(size);
        let n = size;
        m.data.par_iter_mut().enumerate().for_each(|(i, t)| {
            let face = i / (n * n);
            let row = (i / n) % n;
            let col = i % n;
            let u = (col as f32 + 0.5) / n as f32;
            let v = (row as f32 + 0.5) / n as f32;
            *t = f(face_uv_to_dir(face, u, v));
        });
        m
    }

    #[inline]
    pub fn index(&self, face: usize, col: usize, row: usize) -> usize {
        (face * self.size + row) * self.size + col
    }

    #[inline]
    pub fn texel(&self, face: usize, col: usize, row: usize) -> Vec3 {
        self.data[self.index(face, col, row)]
    }

    /// Radiance in direction `d` (nearest texel).
    #[inline]
    pub fn lookup(&self, d: Vec3) -> Vec3 {
        self.data[dir_to_texel(d, self.size).index(self.size)]
    }

    /// Clamp NaN/Inf/negative texels to zero and count them.
    pub fn sanitize(&mut self) -> SanitizeReport {
        let mut r = SanitizeReport::default();
        for t in &mut self.data {
            *t = sanitize_texel(*t, &mut r);
        }
        r
    }

    /// Integral of RGB radiance over the sphere (f64): sum of texel radiance x texel solid angle.
    pub fn integral(&self) -> DVec3 {
        let n = self.size;
        let mut s = DVec3::ZERO;
        for f in 0..6 {
            for r in 0..n {
                for c in 0..n {
                    s += self.texel(f, c, r).as_dvec3() * texel_solid_angle(c, r, n);
                }
            }
        }
        s
    }
}

/// Block (column, row) of each face in the 4:3 horizontal cross, in face order +X, -X, +Y, -Y, +Z, -Z.
pub const CROSS_BLOCKS: [(usize, usize); 6] = [(2, 1), (0, 1), (1, 0), (1, 2), (1, 1), (3, 1)];

/// Unfold a cube map as a 4:3 horizontal cross (`+Y` above; `-X +Z +X -Z`; `-Y` below), the
/// layout [`load::Layout::HorizontalCross`] reads back. Empty blocks are black.
pub fn cube_to_cross(cube: &CubeMap) -> Image {
    let n = cube.size;
    let mut img = Image::new(4 * n, 3 * n);
    for (face, &(bx, by)) in CROSS_BLOCKS.iter().enumerate() {
        for r in 0..n {
            for c in 0..n {
                img.data[(by * n + r) * 4 * n + bx * n + c] = cube.texel(face, c, r);
            }
        }
    }
    img
}

#[cfg(test)]
mod tests {
    use super::geometry::texel_coord;
    use super::*;

    /// The lane version of the direction -> texel lookup matches the scalar one bit for bit,
    /// on random directions and on the hard ones (axes, ties between axes, zero, signed zeros).
    #[test]
    fn texel_lane_matches_scalar() {
        let mut dirs = vec![
            Vec3::ZERO,
            Vec3::new(-0.0, 0.0, -0.0),
            Vec3::ONE,
            -Vec3::ONE,
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(0.0, 1.0, -1.0),
            Vec3::new(-1.0, 0.0, 1.0),
        ];
        for f in 0..6 {
            let mut v = [0.0f32; 3];
            v[f / 2] = if f % 2 == 0 { 1.0 } else { -1.0 };
            dirs.push(Vec3::from_array(v));
        }
        let mut rng = crate::sampling::rng::Rng::new(3, 9);
        for _ in 0..200_000 {
            let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE;
            dirs.push(v);
        }
        for n in [1usize, 7, 64, 1024] {
            for &d in &dirs {
                let h = dir_to_texel(d, n);
                let (face, a, b, texel) = dir_to_texel_lane(d.x, d.y, d.z, n as u32);
                assert_eq!(
                    (face as usize, a.to_bits(), b.to_bits(), texel as usize),
                    (h.face, h.a.to_bits(), h.b.to_bits(), h.index(n)),
                    "{d} n={n}"
                );
            }
        }
    }

    /// The float clamp of `texel_coord` against the saturating integer clamp it replaces, on
    /// the values where they could part: NaN, infinities, both ends of the range and just past them.
    #[test]
    fn texel_coord_matches_the_saturating_clamp() {
        for n in [1u32, 2, 7, 64, 1024] {
            let nf = n as f32;
            let special = [
                f32::NAN,
                f32::INFINITY,
                f32::NEG_INFINITY,
                -0.0,
                0.0,
                -0.5,
                -1e30,
                1e30,
                f32::MIN_POSITIVE,
                0.999_999_94,
                nf - 1.0,
                nf - 1e-3,
                nf,
                nf + 0.5,
            ];
            let steps = (0..=4000).map(|i| -2.0 + (nf + 4.0) * i as f32 / 4000.0);
            for t in special.into_iter().chain(steps) {
                let want = (t as i32).clamp(0, n as i32 - 1) as u32;
                assert_eq!(texel_coord(t, nf), want, "t {t} n {n}");
            }
        }
    }

    #[test]
    fn face_round_trip() {
        for f in 0..6 {
            for &(u, v) in &[(0.5, 0.5), (0.1, 0.9), (0.73, 0.21), (0.01, 0.02)] {
                let d = face_uv_to_dir(f, u, v);
                let (g, u2, v2) = dir_to_face_uv(d);
                assert_eq!(f, g);
                assert!(
                    (u - u2).abs() < 1e-5 && (v - v2).abs() < 1e-5,
                    "{f} {u} {v} -> {u2} {v2}"
                );
            }
        }
    }

    #[test]
    fn solid_angles_sum_to_4pi() {
        for n in [1, 3, 16] {
            let mut s = 0.0;
            for r in 0..n {
                for c in 0..n {
                    s += texel_solid_angle(c, r, n);
                }
            }
            assert!((6.0 * s - 4.0 * std::f64::consts::PI).abs() < 1e-12);
        }
    }
}
