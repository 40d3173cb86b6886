//! The Lambert lobe alone, known at compile time ([`super::Material`] with no glossy lobe).

use super::{LANES, LocalBsdf, SampleLanes};
use crate::sampling::rng::{ONE_MINUS_EPSILON, Rng, to_unit};
use crate::sampling::warp::*;
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// A Lambert-only material: `f = kd / pi`, cosine sampling, pdf = `cos / pi`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lambert {
    pub kd: Vec3,
}

impl LocalBsdf for Lambert {
    #[inline(always)]
    fn eval_local(&self, ol: Vec3, il: Vec3) -> Vec3 {
        if ol.z <= 0.0 || il.z <= 0.0 {
            Vec3::ZERO
        } else {
            self.kd * FRAC_1_PI
        }
    }
    #[inline(always)]
    fn pdf_local(&self, ol: Vec3, il: Vec3) -> f32 {
        if ol.z <= 0.0 {
            0.0
        } else {
            cosine_hemisphere_pdf(il)
        }
    }
    #[inline(always)]
    fn sample_local(&self, ol: Vec3, u: Vec2) -> Option<(Vec3, f32)> {
        if ol.z <= 0.0 {
            return None;
        }
        let il = sample_cosine_hemisphere(Vec2::new(u.x.min(ONE_MINUS_EPSILON), u.y));
        if il.z <= 0.0 {
            return None;
        }
        let p = cosine_hemisphere_pdf(il);
        if p > 0.0 && p.is_finite() {
            Some((il, p))
        } else {
            None
        }
    }
    /// [`LocalBsdf::sample_local`] on all lanes at once: the random draws come from one
    /// jump-ahead fill and the warp is branch-free, so the loop vectorises.
    #[inline(always)]
    fn sample_lanes(&self, ol: Vec3, rng: &mut Rng, count: usize, out: &mut SampleLanes) {
        let mut r = [0u32; 2 * LANES];
        rng.fill_u32(&mut r[..2 * count]);
        let live = ol.z > 0.0;
        for k in 0..LANES {
            let u = Vec2::new(
                to_unit(r[2 * k]).min(ONE_MINUS_EPSILON),
                to_unit(r[2 * k + 1]),
            );
            let il = sample_cosine_hemisphere(u);
            let p = cosine_hemisphere_pdf(il);
            let ok = live & (il.z > 0.0) & (p > 0.0) & p.is_finite();
            out.set(k, il, if ok { p } else { 0.0 });
            // eval_local's value wherever the sample is valid (o.z > 0 and i.z > 0 there).
            out.set_value(k, self.kd * FRAC_1_PI);
        }
    }
}
