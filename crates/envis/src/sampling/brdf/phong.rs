//! The normalised Phong lobe: its value (shared with [`super::Material`]) and the Phong-only
//! material known at compile time.

use super::{LANES, LocalBsdf, SampleLanes, mirror_cos};
use crate::sampling::rng::{ONE_MINUS_EPSILON, Rng, to_unit};
use crate::sampling::warp::*;
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// A Phong-only material (no diffuse part): [`Material`](super::Material)'s Phong lobe with the lobe known at
/// compile time, and one `powf` per sample for both the BRDF value and the pdf (they share
/// `<r, i>^e`). Bit-identical to the `Material` path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Phong {
    pub ks: Vec3,
    pub exponent: f32,
}

impl LocalBsdf for Phong {
    #[inline(always)]
    fn eval_local(&self, ol: Vec3, il: Vec3) -> Vec3 {
        self.eval_pdf_local(ol, il).0
    }
    #[inline(always)]
    fn pdf_local(&self, ol: Vec3, il: Vec3) -> f32 {
        if ol.z <= 0.0 {
            return 0.0;
        }
        phong_lobe_pdf(mirror_cos(ol, il), self.exponent)
    }
    #[inline(always)]
    fn sample_local(&self, ol: Vec3, u: Vec2) -> Option<(Vec3, f32)> {
        let (il, _, p) = self.sample_one(ol, u);
        (p > 0.0).then_some((il, p))
    }
    /// `<r, i>^e` once for both; each value by the same operations as `Material`'s Phong
    /// branch and [`phong_lobe_pdf`].
    #[inline(always)]
    fn eval_pdf_local(&self, ol: Vec3, il: Vec3) -> (Vec3, f32) {
        if ol.z <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let e = self.exponent;
        let c = mirror_cos(ol, il);
        if c <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let ce = c.powf(e);
        let pdf = (e + 1.0) * 0.5 * FRAC_1_PI * ce;
        let f = if il.z <= 0.0 {
            Vec3::ZERO
        } else {
            phong_value(self.ks, e, ce)
        };
        (f, pdf)
    }
    /// [`LocalBsdf::sample_local`] on all lanes at once: one jump-ahead fill of the random
    /// draws, then the directions by the branch-free warp ([`sample_phong_lobe`]) in a loop
    /// that vectorises, then each value and pdf by [`LocalBsdf::eval_pdf_local`]. The pdf keeps
    /// libm's `powf`, the call every other path makes, so it stays bit-identical to theirs;
    /// the vectorised `pow_unit` there measured no faster.
    #[inline(always)]
    fn sample_lanes(&self, ol: Vec3, rng: &mut Rng, count: usize, out: &mut SampleLanes) {
        let mut r = [0u32; 2 * LANES];
        rng.fill_u32(&mut r[..2 * count]);
        let axis = self.axis(ol);
        for k in 0..LANES {
            let u = Vec2::new(to_unit(r[2 * k]), to_unit(r[2 * k + 1]));
            out.set(k, self.direction(&axis, u), 0.0);
        }
        for k in 0..count {
            let (f, p) = self.value_pdf(ol, out.dir(k));
            out.pdf[k] = p;
            out.set_value(k, f);
        }
    }
}

impl Phong {
    /// One lobe sample, its BRDF value and its pdf, 0 for an invalid one
    /// ([`Material::sample_local`](super::Material::sample_local) with `kd = 0`).
    #[inline(always)]
    fn sample_one(&self, ol: Vec3, u: Vec2) -> (Vec3, Vec3, f32) {
        let il = self.direction(&self.axis(ol), u);
        let (f, p) = self.value_pdf(ol, il);
        (il, f, p)
    }

    /// The frame around the mirror direction of `ol`, the lobe's axis.
    #[inline(always)]
    fn axis(&self, ol: Vec3) -> Frame {
        Frame::new(Vec3::new(-ol.x, -ol.y, ol.z))
    }

    /// The lobe's direction for `u`, branch-free.
    #[inline(always)]
    fn direction(&self, axis: &Frame, u: Vec2) -> Vec3 {
        let ux = u.x.clamp(0.0, ONE_MINUS_EPSILON);
        axis.to_world(sample_phong_lobe(Vec2::new(ux, u.y), self.exponent))
    }

    /// A sampled direction's BRDF value and pdf, the pdf 0 where the sample is invalid.
    #[inline(always)]
    fn value_pdf(&self, ol: Vec3, il: Vec3) -> (Vec3, f32) {
        let (f, p) = self.eval_pdf_local(ol, il);
        let ok = (il.z > 0.0) & (p > 0.0) & p.is_finite();
        (f, if ok { p } else { 0.0 })
    }
}

/// The normalised Phong lobe's `f` given `<r, i>^e`: `ks (e + 2) / (2 pi) <r, i>^e`.
#[inline(always)]
pub(super) fn phong_value(ks: Vec3, e: f32, cos_pow_e: f32) -> Vec3 {
    ks * ((e + 2.0) * 0.5 * FRAC_1_PI * cos_pow_e)
}
