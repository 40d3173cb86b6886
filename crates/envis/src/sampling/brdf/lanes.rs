//! The calls the renderer's hot loops make on a BRDF ([`LocalBsdf`]), and the chunk of BRDF
//! samples they fill at once ([`SampleLanes`]).

use crate::sampling::rng::Rng;
use glam::{Vec2, Vec3};

/// The three calls the renderer's hot loops make on a BRDF, in the shading frame (z = normal).
/// [`Material`](super::Material) implements them for every lobe; [`Lambert`](super::Lambert) implements them for a material with
/// no glossy lobe, so that a diffuse pixel's loops compile without the lobe dispatch. Both give
/// bit-identical values for the same diffuse material.
pub trait LocalBsdf {
    /// `f(o, i)` without the cosine.
    fn eval_local(&self, ol: Vec3, il: Vec3) -> Vec3;
    /// Solid-angle pdf of [`LocalBsdf::sample_local`] choosing `il`.
    fn pdf_local(&self, ol: Vec3, il: Vec3) -> f32;
    /// `(i_local, pdf)` from `u`, or `None` for an invalid sample.
    fn sample_local(&self, ol: Vec3, u: Vec2) -> Option<(Vec3, f32)>;
    /// `(f(o, i), pdf(i))` at once, the same values as [`LocalBsdf::eval_local`] and
    /// [`LocalBsdf::pdf_local`]; a BRDF whose two share work (GGX: the half vector and `D`)
    /// overrides it.
    #[inline(always)]
    fn eval_pdf_local(&self, ol: Vec3, il: Vec3) -> (Vec3, f32) {
        (self.eval_local(ol, il), self.pdf_local(ol, il))
    }
    /// `count` (at most [`LANES`]) samples, each from the next two draws of `rng` in order, into
    /// `out` (pdf 0 marks an invalid sample). The same values as `count` calls of
    /// [`LocalBsdf::sample_local`], each valid one with its [`LocalBsdf::eval_local`] value; a
    /// BRDF with a branch-free sampler overrides it with a loop that vectorises.
    #[inline(always)]
    fn sample_lanes(&self, ol: Vec3, rng: &mut Rng, count: usize, out: &mut SampleLanes) {
        for k in 0..count {
            let u = Vec2::new(rng.next_f32(), rng.next_f32());
            let (il, p) = self.sample_local(ol, u).unwrap_or((Vec3::ZERO, 0.0));
            out.set(k, il, p);
            if p > 0.0 {
                out.set_value(k, self.eval_local(ol, il));
            }
        }
    }
}

/// Lanes per chunk of BRDF samples.
pub const LANES: usize = 16;

/// A chunk of local-frame BRDF samples, structure of arrays.
#[derive(Clone, Debug, Default)]
pub struct SampleLanes {
    pub x: [f32; LANES],
    pub y: [f32; LANES],
    pub z: [f32; LANES],
    /// Solid-angle pdf; 0 for an invalid sample.
    pub pdf: [f32; LANES],
    /// The BRDF value `f(o, i)` of each valid sample, by channel.
    pub fr: [f32; LANES],
    pub fg: [f32; LANES],
    pub fb: [f32; LANES],
}

impl SampleLanes {
    #[inline(always)]
    pub fn set(&mut self, k: usize, il: Vec3, pdf: f32) {
        (self.x[k], self.y[k], self.z[k], self.pdf[k]) = (il.x, il.y, il.z, pdf);
    }
    #[inline(always)]
    pub fn set_value(&mut self, k: usize, f: Vec3) {
        (self.fr[k], self.fg[k], self.fb[k]) = (f.x, f.y, f.z);
    }
    #[inline(always)]
    pub fn dir(&self, k: usize) -> Vec3 {
        Vec3::new(self.x[k], self.y[k], self.z[k])
    }
    #[inline(always)]
    pub fn value(&self, k: usize) -> Vec3 {
        Vec3::new(self.fr[k], self.fg[k], self.fb[k])
    }
}
