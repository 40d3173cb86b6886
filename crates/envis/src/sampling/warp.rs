//! Warps from `[0,1)^2` to directions in a local frame (z = axis), each with its pdf beside it
//! (per unit solid angle) and, where it exists in closed form, its inverse.

use super::fastmath::{azimuth, pow_unit, sin_cos_fast};
use super::rng::ONE_MINUS_EPSILON;
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};

/// Orthonormal basis around a unit vector (Duff et al. 2017, branchless).
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub t: Vec3,
    pub b: Vec3,
    pub n: Vec3,
}

impl Frame {
    pub fn new(n: Vec3) -> Self {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        Frame {
            t: Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
            b: Vec3::new(b, sign + n.y * n.y * a, -n.y),
            n,
        }
    }
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.t), v.dot(self.b), v.dot(self.n))
    }
    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.t * v.x + self.b * v.y + self.n * v.z
    }
}

/// Cosine-weighted hemisphere (Malley): uniform disk point in polar form,
/// `r = sqrt(u1)`, `phi = 2 pi u2 - pi`, lifted to `z = sqrt(1 - r^2)`; pdf = `cos / pi`.
/// Branch-free (the concentric map's branch is unpredictable); inverse: [`invert_cosine_hemisphere`].
#[inline]
pub fn sample_cosine_hemisphere(u: Vec2) -> Vec3 {
    let r = u.x.sqrt();
    let (s, c) = sin_cos_fast(2.0 * PI * u.y - PI);
    Vec3::new(r * c, r * s, (1.0 - u.x).max(0.0).sqrt())
}
/// Inverse of [`sample_cosine_hemisphere`].
#[inline]
pub fn invert_cosine_hemisphere(v: Vec3) -> Vec2 {
    let phi = v.y.atan2(v.x); // in [-pi, pi]
    Vec2::new(
        (v.x * v.x + v.y * v.y).min(1.0),
        ((phi + PI) / (2.0 * PI)).min(ONE_MINUS_EPSILON),
    )
}
#[inline]
pub fn cosine_hemisphere_pdf(v: Vec3) -> f32 {
    v.z.max(0.0) * FRAC_1_PI
}

/// Phong lobe around +z: `cos a = u1^(1/(e+1))`, `phi = 2 pi u2`; pdf = `(e+1)/(2 pi) cos^e a`.
/// Branch-free (powers by [`pow_unit`], the azimuth by [`azimuth`]), so a loop of samples
/// vectorises.
#[inline(always)]
pub fn sample_phong_lobe(u: Vec2, e: f32) -> Vec3 {
    let c = pow_unit(u.x, 1.0 / (e + 1.0));
    // sin^2 = (1 - c)(1 + c) keeps precision for c close to 1 (large exponents).
    let s = ((1.0 - c) * (1.0 + c)).max(0.0).sqrt();
    let (cp, sp) = azimuth(u.y);
    Vec3::new(s * cp, s * sp, c)
}
/// pdf of [`sample_phong_lobe`] given `cos_a`, the cosine between the direction and the lobe axis.
#[inline]
pub fn phong_lobe_pdf(cos_a: f32, e: f32) -> f32 {
    if cos_a <= 0.0 {
        0.0
    } else {
        (e + 1.0) * 0.5 * FRAC_1_PI * cos_a.powf(e)
    }
}
/// Inverse of [`sample_phong_lobe`].
#[inline]
pub fn invert_phong_lobe(v: Vec3, e: f32) -> Vec2 {
    let mut phi = v.y.atan2(v.x);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    Vec2::new(v.z.max(0.0).powf(e + 1.0), phi / (2.0 * PI))
}

/// GGX (Trowbridge-Reitz) normal distribution, isotropic:
/// `D(m) = a^2 / (pi (m_x^2 + m_y^2 + a^2 m_z^2)^2)` (written so it stays accurate for tiny a).
#[inline]
pub fn ggx_d(m: Vec3, alpha: f32) -> f32 {
    if m.z <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let t = m.x * m.x + m.y * m.y + a2 * m.z * m.z;
    a2 / (PI * t * t)
}

/// `s(z) = sqrt(z^2 (1 - a^2) + a^2)`, the building block of Smith's Lambda in stable form.
#[inline]
pub fn ggx_s(z: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    (z * z * (1.0 - a2) + a2).max(0.0).sqrt()
}

/// Smith G1 in stable form: `G1(z) = 2 z / (z + s(z))`.
#[inline]
pub fn ggx_g1(z: f32, alpha: f32) -> f32 {
    if z <= 0.0 {
        0.0
    } else {
        2.0 * z / (z + ggx_s(z, alpha))
    }
}

/// Visible-normal sampling by spherical caps (Dupuy & Benyoub 2023): view `o` (local, `o.z > 0`)
/// -> microfacet normal `m`; the reflected direction has pdf
/// `G1(o) D(m) / (4 o.z) = D(m) / (2 (o.z + s(o.z)))`. Branch-free (the azimuth by
/// [`azimuth`]), so a loop of samples vectorises.
#[inline]
pub fn sample_ggx_vndf(o: Vec3, alpha: f32, u: Vec2) -> Vec3 {
    let vh = Vec3::new(alpha * o.x, alpha * o.y, o.z).normalize();
    let (cp, sp) = azimuth(u.x);
    let z = (1.0 - u.y) * (1.0 + vh.z) - vh.z;
    let st = (1.0 - z * z).clamp(0.0, 1.0).sqrt();
    let c = Vec3::new(st * cp, st * sp, z);
    let h = c + vh;
    Vec3::new(alpha * h.x, alpha * h.y, h.z.max(0.0)).normalize_or(Vec3::Z)
}

/// Solid-angle pdf of the direction `i = reflect(o, m)` chosen by [`sample_ggx_vndf`].
#[inline]
pub fn ggx_vndf_reflect_pdf(o: Vec3, i: Vec3, alpha: f32) -> f32 {
    if o.z <= 0.0 || i.z <= 0.0 {
        return 0.0;
    }
    let m = (o + i).normalize_or_zero();
    if m == Vec3::ZERO {
        return 0.0;
    }
    ggx_d(m, alpha) / (2.0 * (o.z + ggx_s(o.z, alpha)))
}

/// Mirror `o` about `m`: `2 (o.m) m - o`.
#[inline]
pub fn reflect(o: Vec3, m: Vec3) -> Vec3 {
    2.0 * o.dot(m) * m - o
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phong_warp_round_trips() {
        for e in [0.0f32, 10.0, 150.0] {
            for &(a, b) in &[(0.1f32, 0.2f32), (0.5, 0.5), (0.9, 0.01), (0.33, 0.77)] {
                let v = sample_phong_lobe(Vec2::new(a, b), e);
                let u = invert_phong_lobe(v, e);
                assert!(
                    (u.x - a).abs() < 1e-4 && (u.y - b).abs() < 1e-5,
                    "e={e} ({a},{b}) -> {u}"
                );
            }
        }
    }

    #[test]
    fn cosine_warp_round_trips() {
        for &(a, b) in &[(0.1f32, 0.2f32), (0.5, 0.5), (0.9, 0.01), (0.33, 0.77)] {
            let v = sample_cosine_hemisphere(Vec2::new(a, b));
            assert!((v.length() - 1.0).abs() < 1e-6);
            let u = invert_cosine_hemisphere(v);
            assert!(
                (u.x - a).abs() < 1e-5 && (u.y - b).abs() < 1e-5,
                "({a},{b}) -> {u}"
            );
        }
    }
}
