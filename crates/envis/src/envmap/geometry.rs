//! Directions and texels: the cube faces and their `(a, b)` / `(u, v)` coordinates, the
//! lat-long mapping (Mitsuba 3's), and texel solid angles (`docs/conventions.md`).

use glam::{DVec3, Vec3};

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
pub(super) fn texel_coord(t: f32, nf: f32) -> u32 {
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
