//! Environment maps: the cube-map type, the direction conventions, loaders, resampling and the
//! built-in procedural sky.
//!
//! Conventions (written once, in `docs/conventions.md`, and used everywhere):
//! - Lat-long maps use Mitsuba 3's mapping: `d = (sin t sin p, cos t, -sin t cos p)`,
//!   `p = 2 pi u`, `t = pi v`, +Y up, `u` along image columns, `v` down the rows.
//! - Cube faces are stored in the order +X, -X, +Y, -Y, +Z, -Z with the Vulkan/wgpu/OpenGL cube
//!   texture orientation, so a GPU `textureSample(cube, dir)` and [`dir_to_face_uv`] agree.

pub mod color;
pub mod hdr;
pub mod load;
pub mod resample;
pub mod sky;

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

/// The six cube faces in storage order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Face {
    PosX = 0,
    NegX = 1,
    PosY = 2,
    NegY = 3,
    PosZ = 4,
    NegZ = 5,
}

impl Face {
    pub const ALL: [Face; 6] = [
        Face::PosX,
        Face::NegX,
        Face::PosY,
        Face::NegY,
        Face::PosZ,
        Face::NegZ,
    ];
    pub fn from_index(i: usize) -> Face {
        Face::ALL[i]
    }
    pub fn name(self) -> &'static str {
        ["+X", "-X", "+Y", "-Y", "+Z", "-Z"][self as usize]
    }
}

/// Unnormalised direction of face coordinates `(a, b)` in `[-1, 1]^2` (a = 2u-1, b = 2v-1).
#[inline]
pub fn face_ab_to_vec(face: usize, a: f32, b: f32) -> Vec3 {
    match face {
        0 => Vec3::new(1.0, -b, -a),
        1 => Vec3::new(-1.0, -b, a),
        2 => Vec3::new(a, 1.0, b),
        3 => Vec3::new(a, -1.0, -b),
        4 => Vec3::new(a, -b, 1.0),
        _ => Vec3::new(-a, -b, -1.0),
    }
}

/// f64 twin of [`face_ab_to_vec`] (used by the reference and the tests).
#[inline]
pub fn face_ab_to_dvec(face: usize, a: f64, b: f64) -> DVec3 {
    match face {
        0 => DVec3::new(1.0, -b, -a),
        1 => DVec3::new(-1.0, -b, a),
        2 => DVec3::new(a, 1.0, b),
        3 => DVec3::new(a, -1.0, -b),
        4 => DVec3::new(a, -b, 1.0),
        _ => DVec3::new(-a, -b, -1.0),
    }
}

/// Unit direction of texture coordinates `(u, v)` in `[0, 1]^2` on `face`.
#[inline]
pub fn face_uv_to_dir(face: usize, u: f32, v: f32) -> Vec3 {
    face_ab_to_vec(face, 2.0 * u - 1.0, 2.0 * v - 1.0).normalize()
}

/// Per face: (component giving `a`, its sign, component giving `b`, its sign); see the table in
/// `docs/conventions.md`.
const FACE_AB: [(usize, f32, usize, f32); 6] = [
    (2, -1.0, 1, -1.0), // +X: a = -z, b = -y
    (2, 1.0, 1, -1.0),  // -X: a = +z, b = -y
    (0, 1.0, 2, 1.0),   // +Y: a = +x, b = +z
    (0, 1.0, 2, -1.0),  // -Y: a = +x, b = -z
    (0, 1.0, 1, -1.0),  // +Z: a = +x, b = -y
    (0, -1.0, 1, -1.0), // -Z: a = -x, b = -y
];

/// Face and face coordinates `(a, b)` in `[-1, 1]^2` of a (not necessarily unit) direction.
/// Ties between axes go to X, then Y, then Z. Returns face 0, (0,0) for the zero vector.
/// Branch-free (boolean arithmetic + a table), because random directions make the branches of a
/// nested if/else unpredictable.
#[inline]
pub fn dir_to_face_ab(d: Vec3) -> (usize, f32, f32) {
    let v = d.to_array();
    let (ax, ay, az) = (v[0].abs(), v[1].abs(), v[2].abs());
    let is_x = (ax >= ay) & (ax >= az);
    let is_y = !is_x & (ay >= az);
    let axis = (!is_x) as usize * (1 + (!is_y) as usize);
    let m = v[axis].abs();
    if m == 0.0 {
        return (0, 0.0, 0.0);
    }
    let face = 2 * axis + (v[axis] < 0.0) as usize;
    let (ia, sa, ib, sb) = FACE_AB[face];
    let r = 1.0 / m;
    (face, sa * v[ia] * r, sb * v[ib] * r)
}

/// [`dir_to_texel`] for one lane of a structure-of-arrays loop: the table lookup and the
/// component indexing become selects, so a loop over lanes vectorises. Returns
/// `(face, a, b, texel index)`; bit-identical to [`dir_to_texel`] (tested).
#[inline(always)]
pub fn dir_to_texel_lane(x: f32, y: f32, z: f32, n: u32) -> (u32, f32, f32, u32) {
    let (ax, ay, az) = (x.abs(), y.abs(), z.abs());
    let is_x = (ax >= ay) & (ax >= az);
    let is_y = !is_x & (ay >= az);
    let v_axis = if is_x {
        x
    } else if is_y {
        y
    } else {
        z
    };
    let m = v_axis.abs();
    let neg = v_axis < 0.0;
    let face = if is_x {
        0
    } else if is_y {
        2
    } else {
        4
    } + neg as u32;
    // FACE_AB as selects: a from z on the X faces, else x; b from z on the Y faces, else y.
    let (src_a, src_b) = (if is_x { z } else { x }, if is_y { z } else { y });
    let sign_a = if is_x {
        if neg { 1.0 } else { -1.0 }
    } else if !is_y & neg {
        -1.0
    } else {
        1.0
    };
    let sign_b = if is_y {
        if neg { -1.0 } else { 1.0 }
    } else {
        -1.0
    };
    let r = 1.0 / m;
    let zero = m == 0.0;
    let a = if zero { 0.0 } else { sign_a * src_a * r };
    let b = if zero { 0.0 } else { sign_b * src_b * r };
    let face = if zero { 0 } else { face };
    let nf = n as f32;
    let (col, row) = (
        texel_coord(0.5 * (a + 1.0) * nf, nf),
        texel_coord(0.5 * (b + 1.0) * nf, nf),
    );
    (face, a, b, (face * n + row) * n + col)
}

/// `(t as i32).clamp(0, n - 1)` for `nf = n as f32`, `1 <= n < 2^24` ([`uv_to_texel`]'s rounding),
/// with the clamp done in float: then the conversion needs no saturation, which kept LLVM from
/// vectorising the lane loops (it left them scalar, with branches on the face, measured). Equal
/// for every `t`: truncation is monotonic and fixes `0` and `n - 1`, and NaN goes to 0 as
/// `as i32` sends it.
#[inline(always)]
fn texel_coord(t: f32, nf: f32) -> u32 {
    let last = nf - 1.0;
    let t = if t > 0.0 { t } else { 0.0 };
    let t = if t < last { t } else { last };
    // SAFETY: `t` is finite and in `[0, n - 1]`, which i32 holds.
    unsafe { t.to_int_unchecked::<i32>() as u32 }
}

/// Face and texture coordinates `(u, v)` in `[0, 1]^2` of a direction.
#[inline]
pub fn dir_to_face_uv(d: Vec3) -> (usize, f32, f32) {
    let (f, a, b) = dir_to_face_ab(d);
    (f, 0.5 * (a + 1.0), 0.5 * (b + 1.0))
}

/// Texel `(col, row)` of face coordinates on a face of `n` x `n` texels (clamped to the face).
#[inline]
pub fn uv_to_texel(u: f32, v: f32, n: usize) -> (usize, usize) {
    let c = ((u * n as f32) as isize).clamp(0, n as isize - 1) as usize;
    let r = ((v * n as f32) as isize).clamp(0, n as isize - 1) as usize;
    (c, r)
}

/// The texel a direction falls in on faces of `n x n` texels: face, face coordinates `(a, b)`,
/// column and row (nearest lookup). The one place direction -> texel is decided, so the radiance
/// lookup, the light pdf and the shading loop always agree on the texel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TexelHit {
    pub face: usize,
    pub a: f32,
    pub b: f32,
    pub col: usize,
    pub row: usize,
}

impl TexelHit {
    /// Index into a cube map's `data` (or any table in the same layout).
    #[inline]
    pub fn index(&self, n: usize) -> usize {
        (self.face * n + self.row) * n + self.col
    }
}

/// [`TexelHit`] of direction `d` on faces of `n x n` texels.
#[inline]
pub fn dir_to_texel(d: Vec3, n: usize) -> TexelHit {
    let (face, a, b) = dir_to_face_ab(d);
    let (col, row) = uv_to_texel(0.5 * (a + 1.0), 0.5 * (b + 1.0), n);
    TexelHit {
        face,
        a,
        b,
        col,
        row,
    }
}

/// Lat-long (Mitsuba 3) direction of `(u, v)`: `d = (sin t sin p, cos t, -sin t cos p)`.
#[inline]
pub fn latlong_to_dir(u: f32, v: f32) -> Vec3 {
    let (sp, cp) = (2.0 * std::f32::consts::PI * u).sin_cos();
    let (st, ct) = (std::f32::consts::PI * v).sin_cos();
    Vec3::new(st * sp, ct, -st * cp)
}

/// f64 twin of [`latlong_to_dir`].
#[inline]
pub fn latlong_to_dvec(u: f64, v: f64) -> DVec3 {
    let (sp, cp) = (2.0 * std::f64::consts::PI * u).sin_cos();
    let (st, ct) = (std::f64::consts::PI * v).sin_cos();
    DVec3::new(st * sp, ct, -st * cp)
}

/// Inverse of [`latlong_to_dir`] for a unit direction: `(u, v)` with `u` in `[0, 1)`.
#[inline]
pub fn dir_to_latlong(d: Vec3) -> (f32, f32) {
    let t = d.y.clamp(-1.0, 1.0).acos();
    let mut p = d.x.atan2(-d.z);
    if p < 0.0 {
        p += 2.0 * std::f32::consts::PI;
    }
    let u = p / (2.0 * std::f32::consts::PI);
    (if u >= 1.0 { 0.0 } else { u }, t / std::f32::consts::PI)
}

/// Solid angle of the face rectangle `[a0, a1] x [b0, b1]` (face coordinates in `[-1, 1]`).
/// `Omega = A(a1,b1) - A(a0,b1) - A(a1,b0) + A(a0,b0)`, `A(x, y) = atan2(x y, sqrt(x^2 + y^2 + 1))`.
#[inline]
pub fn face_rect_solid_angle(a0: f64, b0: f64, a1: f64, b1: f64) -> f64 {
    fn corner(x: f64, y: f64) -> f64 {
        (x * y).atan2((x * x + y * y + 1.0).sqrt())
    }
    corner(a1, b1) - corner(a0, b1) - corner(a1, b0) + corner(a0, b0)
}

/// Solid angle of texel `(col, row)` on a face of `n` x `n` texels.
#[inline]
pub fn texel_solid_angle(col: usize, row: usize, n: usize) -> f64 {
    let h = 2.0 / n as f64;
    let a0 = -1.0 + col as f64 * h;
    let b0 = -1.0 + row as f64 * h;
    face_rect_solid_angle(a0, b0, a0 + h, b0 + h)
}

/// Per-map report of texels that were not finite and non-negative: they are clamped to zero and
/// counted here, and never reach a distribution.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct SanitizeReport {
    /// Texels with at least one NaN channel.
    pub nan: u64,
    /// Texels with an infinite channel (and no NaN).
    pub inf: u64,
    /// Texels with a finite negative channel (and no NaN or Inf).
    pub negative: u64,
    /// Texels with a finite channel above [`MAX_RADIANCE`] (clamped to it): such values would
    /// overflow f32 in luminance, filtering or CDF sums.
    pub huge: u64,
}

/// Largest radiance kept; finite values above it are clamped to it (and counted).
pub const MAX_RADIANCE: f32 = 1e30;

impl SanitizeReport {
    pub fn total(&self) -> u64 {
        self.nan + self.inf + self.negative + self.huge
    }
    pub fn add(&mut self, o: SanitizeReport) {
        self.nan += o.nan;
        self.inf += o.inf;
        self.negative += o.negative;
        self.huge += o.huge;
    }
}

impl std::fmt::Display for SanitizeReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} NaN, {} Inf, {} negative texels clamped to 0",
            self.nan, self.inf, self.negative
        )?;
        if self.huge > 0 {
            write!(
                f,
                ", {} texels above {MAX_RADIANCE:e} clamped to it",
                self.huge
            )?;
        }
        Ok(())
    }
}

/// Clamp one RGB texel: every channel that is NaN, infinite or negative becomes 0, and a finite
/// channel above [`MAX_RADIANCE`] becomes `MAX_RADIANCE`. Counts the texel once, under its first
/// problem in the order NaN, Inf, negative, huge.
#[inline]
pub fn sanitize_texel(c: Vec3, report: &mut SanitizeReport) -> Vec3 {
    let a = c.to_array();
    if a.iter().any(|x| x.is_nan()) {
        report.nan += 1;
    } else if a.iter().any(|x| x.is_infinite()) {
        report.inf += 1;
    } else if a.iter().any(|&x| x < 0.0) {
        report.negative += 1;
    } else if a.iter().any(|&x| x > MAX_RADIANCE) {
        report.huge += 1;
    } else {
        return c;
    }
    Vec3::from_array(a.map(|x| {
        if x.is_finite() && x > 0.0 {
            x.min(MAX_RADIANCE)
        } else {
            0.0
        }
    }))
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
