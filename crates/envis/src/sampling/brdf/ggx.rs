//! The GGX lobe: its value (shared with [`super::Material`]) and the GGX-only material known at
//! compile time.

use super::{LANES, LocalBsdf, SampleLanes, fresnel_schlick};
use crate::sampling::rng::{ONE_MINUS_EPSILON, Rng, to_unit};
use crate::sampling::warp::*;
use glam::{Vec2, Vec3};

/// A GGX-only material (no diffuse part): [`Material`](super::Material)'s GGX lobe with the lobe known at compile
/// time, and its BRDF samples drawn on all lanes at once. Bit-identical to the `Material` path
/// (with `kd = 0` the diffuse terms add exact zeros there).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ggx {
    pub ks: Vec3,
    pub alpha: f32,
    /// Schlick's Fresnel ([`Lobe::GgxSchlick`](super::Lobe::GgxSchlick)) instead of `F = ks`.
    pub schlick: bool,
}

impl LocalBsdf for Ggx {
    #[inline(always)]
    fn eval_local(&self, ol: Vec3, il: Vec3) -> Vec3 {
        if ol.z <= 0.0 || il.z <= 0.0 {
            return Vec3::ZERO;
        }
        ggx_value(self.ks, self.alpha, self.schlick, ol, il)
    }
    #[inline(always)]
    fn pdf_local(&self, ol: Vec3, il: Vec3) -> f32 {
        if ol.z <= 0.0 {
            return 0.0;
        }
        ggx_vndf_reflect_pdf(ol, il, self.alpha)
    }
    #[inline(always)]
    fn sample_local(&self, ol: Vec3, u: Vec2) -> Option<(Vec3, f32)> {
        let (il, _, p) = self.sample_one(ol, u);
        (p > 0.0).then_some((il, p))
    }
    /// One half vector, one `D` and one `s(o.z)` for both; the pdf computed by the same
    /// operations as [`ggx_vndf_reflect_pdf`], so bit-identical to it.
    #[inline(always)]
    fn eval_pdf_local(&self, ol: Vec3, il: Vec3) -> (Vec3, f32) {
        if ol.z <= 0.0 || il.z <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let alpha = self.alpha;
        let m = (ol + il).normalize_or_zero();
        let d = ggx_d(m, alpha);
        let so = ggx_s(ol.z, alpha);
        let pdf = if m == Vec3::ZERO {
            0.0
        } else {
            d / (2.0 * (ol.z + so))
        };
        let f = ggx_value_given(self.ks, alpha, self.schlick, (ol, il), (m, d, so));
        (f, pdf)
    }
    /// [`LocalBsdf::sample_local`] on all lanes at once: one jump-ahead fill of the random
    /// draws and a branch-free sampler, so the loop vectorises. (Written out, like `Phong`'s: a
    /// shared helper taking the sampler as a closure stopped LLVM vectorising this loop and
    /// halved GGX's speed, measured.)
    #[inline(always)]
    fn sample_lanes(&self, ol: Vec3, rng: &mut Rng, count: usize, out: &mut SampleLanes) {
        let mut r = [0u32; 2 * LANES];
        rng.fill_u32(&mut r[..2 * count]);
        for k in 0..LANES {
            let u = Vec2::new(to_unit(r[2 * k]), to_unit(r[2 * k + 1]));
            let (il, f, p) = self.sample_one(ol, u);
            out.set(k, il, p);
            out.set_value(k, f);
        }
    }
}

impl Ggx {
    /// One visible-normal sample, its BRDF value and its pdf, 0 for an invalid one
    /// ([`Material::sample_local`](super::Material::sample_local) with `kd = 0`, written without branches).
    #[inline(always)]
    fn sample_one(&self, ol: Vec3, u: Vec2) -> (Vec3, Vec3, f32) {
        let ux = u.x.clamp(0.0, ONE_MINUS_EPSILON);
        let il = reflect(ol, sample_ggx_vndf(ol, self.alpha, Vec2::new(ux, u.y)));
        // eval_pdf_local's pdf is 0 unless o.z > 0 and i.z > 0.
        let (f, p) = self.eval_pdf_local(ol, il);
        let ok = (p > 0.0) & p.is_finite();
        (il, f, if ok { p } else { 0.0 })
    }
}

/// The GGX lobe's `f(o, i)` for `o.z, i.z > 0`: `F D / (2 (i.z s(o.z) + o.z s(i.z)))`.
#[inline(always)]
pub(super) fn ggx_value(ks: Vec3, alpha: f32, schlick: bool, ol: Vec3, il: Vec3) -> Vec3 {
    let m = (ol + il).normalize_or_zero();
    let (d, so) = (ggx_d(m, alpha), ggx_s(ol.z, alpha));
    ggx_value_given(ks, alpha, schlick, (ol, il), (m, d, so))
}

/// [`ggx_value`] given the half vector `m`, `D(m)` and `s(o.z)` (which the pdf shares).
#[inline(always)]
fn ggx_value_given(
    ks: Vec3,
    alpha: f32,
    schlick: bool,
    (ol, il): (Vec3, Vec3),
    (m, d, so): (Vec3, f32, f32),
) -> Vec3 {
    // f = D G2 / (4 o.z i.z) = D / (2 (i.z s(o.z) + o.z s(i.z)))
    let den = 2.0 * (il.z * so + ol.z * ggx_s(il.z, alpha));
    if den > 0.0 {
        let f = if schlick {
            fresnel_schlick(ks, ol.dot(m))
        } else {
            ks
        };
        f * (d / den)
    } else {
        Vec3::ZERO
    }
}
