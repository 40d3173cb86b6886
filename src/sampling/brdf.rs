//! Materials: a Lambert lobe plus an optional glossy lobe (normalised Phong / Lafortune, or GGX
//! with F = 1), each with `eval` / `sample` / `pdf`. Mixtures choose a lobe by the lobes'
//! luminance weights; their pdf is the weighted sum (one-sample model).
//!
//! All directions are world-space unit vectors pointing away from the surface; `o` is the view
//! direction. Back-facing views (`<n, o> <= 0`) reflect nothing.

use super::rng::{ONE_MINUS_EPSILON, Rng, to_unit};
use super::warp::*;
use crate::envmap::luminance;
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};

/// `<r, i>` in the shading frame, with `r = (-o.x, -o.y, o.z)` the mirror direction of `o`.
#[inline]
fn mirror_cos(ol: Vec3, il: Vec3) -> f32 {
    il.z * ol.z - il.x * ol.x - il.y * ol.y
}

/// The glossy lobe of a material.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub enum Lobe {
    None,
    /// Normalised Phong around the mirror direction: `f = ks (e+2)/(2 pi) max(0, <r, i>)^e`.
    Phong {
        exponent: f32,
    },
    /// GGX microfacet, perfect conductor (F = 1), height-correlated Smith masking.
    Ggx {
        alpha: f32,
    },
    /// GGX as Bevy's `StandardMaterial` shades it: the same microfacet lobe with Schlick's Fresnel,
    /// `F = ks + (f90 - ks) (1 - <o, m>)^5`, where `ks` is F0 and `f90 = saturate(16.5 (F0.r +
    /// F0.g + F0.b))` ([`bevy_f90`]). Sampled and weighted exactly like [`Lobe::Ggx`].
    GgxSchlick {
        alpha: f32,
    },
}

impl Lobe {
    /// The GGX roughness of either GGX lobe.
    #[inline]
    pub fn ggx_alpha(self) -> Option<f32> {
        match self {
            Lobe::Ggx { alpha } | Lobe::GgxSchlick { alpha } => Some(alpha),
            _ => None,
        }
    }
}

/// Bevy's reflectance at grazing angles for a given F0 (`pbr_lighting.wgsl`, `fresnel`): 0 for a
/// black F0 (so a reflectance-0 dielectric has no specular lobe at all), 1 from F0 ~ 0.02 up.
#[inline]
pub fn bevy_f90(f0: Vec3) -> f32 {
    (f0.dot(Vec3::splat(50.0 * 0.33))).clamp(0.0, 1.0)
}

/// Schlick's Fresnel with Bevy's f90, for `<o, m>` = `o_m`.
#[inline]
pub fn fresnel_schlick(f0: Vec3, o_m: f32) -> Vec3 {
    let f90 = bevy_f90(f0);
    let x = (1.0 - o_m).clamp(0.0, 1.0);
    let x2 = x * x;
    f0 + (Vec3::splat(f90) - f0) * (x2 * x2 * x)
}

#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Material {
    /// Diffuse albedo.
    pub kd: Vec3,
    /// Specular albedo (tint) of the glossy lobe.
    pub ks: Vec3,
    pub lobe: Lobe,
}

/// The three calls the renderer's hot loops make on a BRDF, in the shading frame (z = normal).
/// [`Material`] implements them for every lobe; [`Lambert`] implements them for a material with
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

/// A GGX-only material (no diffuse part): [`Material`]'s GGX lobe with the lobe known at compile
/// time, and its BRDF samples drawn on all lanes at once. Bit-identical to the `Material` path
/// (with `kd = 0` the diffuse terms add exact zeros there).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ggx {
    pub ks: Vec3,
    pub alpha: f32,
    /// Schlick's Fresnel ([`Lobe::GgxSchlick`]) instead of `F = ks`.
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
    /// ([`Material::sample_local`] with `kd = 0`, written without branches).
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

/// A Phong-only material (no diffuse part): [`Material`]'s Phong lobe with the lobe known at
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
    /// ([`Material::sample_local`] with `kd = 0`).
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

/// The GGX lobe's `f(o, i)` for `o.z, i.z > 0`: `F D / (2 (i.z s(o.z) + o.z s(i.z)))`.
#[inline(always)]
fn ggx_value(ks: Vec3, alpha: f32, schlick: bool, ol: Vec3, il: Vec3) -> Vec3 {
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

/// The normalised Phong lobe's `f` given `<r, i>^e`: `ks (e + 2) / (2 pi) <r, i>^e`.
#[inline(always)]
fn phong_value(ks: Vec3, e: f32, cos_pow_e: f32) -> Vec3 {
    ks * ((e + 2.0) * 0.5 * FRAC_1_PI * cos_pow_e)
}

impl LocalBsdf for Material {
    #[inline(always)]
    fn eval_local(&self, ol: Vec3, il: Vec3) -> Vec3 {
        Material::eval_local(self, ol, il)
    }
    #[inline(always)]
    fn pdf_local(&self, ol: Vec3, il: Vec3) -> f32 {
        Material::pdf_local(self, ol, il)
    }
    #[inline(always)]
    fn sample_local(&self, ol: Vec3, u: Vec2) -> Option<(Vec3, f32)> {
        Material::sample_local(self, ol, u)
    }
}

/// Smallest Phong exponent / GGX roughness used for evaluation; inputs are clamped into range.
pub const MIN_ALPHA: f32 = 1e-4;
pub const MAX_EXPONENT: f32 = 1e6;

impl Material {
    /// The material as a [`Lambert`] when it has no glossy lobe.
    pub fn as_lambert(&self) -> Option<Lambert> {
        (self.lobe == Lobe::None).then_some(Lambert { kd: self.kd })
    }
    /// The material as a [`Phong`] when it is a Phong lobe with no diffuse part.
    pub fn as_phong(&self) -> Option<Phong> {
        match self.lobe {
            Lobe::Phong { exponent } if self.kd == Vec3::ZERO => Some(Phong {
                ks: self.ks,
                exponent,
            }),
            _ => None,
        }
    }
    /// The material as a [`Ggx`] when it is a GGX lobe with no diffuse part.
    pub fn as_ggx(&self) -> Option<Ggx> {
        let (alpha, schlick) = match self.lobe {
            Lobe::Ggx { alpha } => (alpha, false),
            Lobe::GgxSchlick { alpha } => (alpha, true),
            Lobe::None | Lobe::Phong { .. } => return None,
        };
        (self.kd == Vec3::ZERO).then_some(Ggx {
            ks: self.ks,
            alpha,
            schlick,
        })
    }
    pub fn diffuse(albedo: f32) -> Self {
        Material {
            kd: Vec3::splat(albedo),
            ks: Vec3::ZERO,
            lobe: Lobe::None,
        }
    }
    pub fn phong(albedo: f32, exponent: f32) -> Self {
        Material {
            kd: Vec3::ZERO,
            ks: Vec3::splat(albedo),
            lobe: Lobe::Phong {
                exponent: exponent.clamp(0.0, MAX_EXPONENT),
            },
        }
    }
    pub fn ggx(albedo: f32, alpha: f32) -> Self {
        Material {
            kd: Vec3::ZERO,
            ks: Vec3::splat(albedo),
            lobe: Lobe::Ggx {
                alpha: alpha.clamp(MIN_ALPHA, 1.0),
            },
        }
    }

    /// Probability of choosing the diffuse lobe when sampling.
    #[inline]
    pub fn diffuse_weight(&self) -> f32 {
        if self.lobe == Lobe::None {
            return 1.0;
        }
        let (d, s) = (luminance(self.kd), luminance(self.ks));
        if d + s <= 0.0 { 0.0 } else { d / (d + s) }
    }

    /// True when the BRDF is zero everywhere (albedo 0).
    pub fn is_black(&self) -> bool {
        self.kd.max_element() <= 0.0 && (self.lobe == Lobe::None || self.ks.max_element() <= 0.0)
    }

    /// BRDF value `f(o, i)` (without the cosine).
    #[inline]
    pub fn eval(&self, f: &Frame, o: Vec3, i: Vec3) -> Vec3 {
        self.eval_local(f.to_local(o), f.to_local(i))
    }

    /// Solid-angle pdf of [`Self::sample`] choosing `i`.
    #[inline]
    pub fn pdf(&self, f: &Frame, o: Vec3, i: Vec3) -> f32 {
        self.pdf_local(f.to_local(o), f.to_local(i))
    }

    /// Sample a direction from `u` (`u.x` also chooses the lobe and is re-stretched), returning
    /// the world direction and its pdf, or `None` when the sample is invalid (below the surface,
    /// or a back-facing view).
    #[inline]
    pub fn sample(&self, f: &Frame, o: Vec3, u: Vec2) -> Option<(Vec3, f32)> {
        self.sample_local(f.to_local(o), u)
            .map(|(il, p)| (f.to_world(il).normalize(), p))
    }

    /// [`Self::eval`] in the shading frame (z = normal).
    #[inline]
    pub fn eval_local(&self, ol: Vec3, il: Vec3) -> Vec3 {
        if ol.z <= 0.0 || il.z <= 0.0 {
            return Vec3::ZERO;
        }
        let mut v = self.kd * FRAC_1_PI;
        match self.lobe {
            Lobe::None => {}
            Lobe::Phong { exponent: e } => {
                let c = mirror_cos(ol, il);
                if c > 0.0 {
                    v += phong_value(self.ks, e, c.powf(e));
                }
            }
            Lobe::Ggx { alpha } => v += ggx_value(self.ks, alpha, false, ol, il),
            Lobe::GgxSchlick { alpha } => v += ggx_value(self.ks, alpha, true, ol, il),
        }
        v
    }

    /// [`Self::pdf`] in the shading frame.
    #[inline]
    pub fn pdf_local(&self, ol: Vec3, il: Vec3) -> f32 {
        if ol.z <= 0.0 {
            return 0.0;
        }
        let wd = self.diffuse_weight();
        let mut p = wd * cosine_hemisphere_pdf(il);
        if wd < 1.0 {
            let ps = match self.lobe {
                Lobe::None => 0.0,
                Lobe::Phong { exponent: e } => phong_lobe_pdf(mirror_cos(ol, il), e),
                Lobe::Ggx { alpha } | Lobe::GgxSchlick { alpha } => {
                    ggx_vndf_reflect_pdf(ol, il, alpha)
                }
            };
            p += (1.0 - wd) * ps;
        }
        p
    }

    /// [`Self::sample`] in the shading frame: `(i_local, pdf)`.
    #[inline]
    pub fn sample_local(&self, ol: Vec3, u: Vec2) -> Option<(Vec3, f32)> {
        if ol.z <= 0.0 {
            return None;
        }
        let wd = self.diffuse_weight();
        let il = if u.x < wd {
            sample_cosine_hemisphere(Vec2::new((u.x / wd).min(ONE_MINUS_EPSILON), u.y))
        } else {
            let ux = ((u.x - wd) / (1.0 - wd)).clamp(0.0, ONE_MINUS_EPSILON);
            match self.lobe {
                Lobe::None => return None,
                Lobe::Phong { exponent: e } => {
                    let r = Frame::new(Vec3::new(-ol.x, -ol.y, ol.z));
                    r.to_world(sample_phong_lobe(Vec2::new(ux, u.y), e))
                }
                Lobe::Ggx { alpha } | Lobe::GgxSchlick { alpha } => {
                    reflect(ol, sample_ggx_vndf(ol, alpha, Vec2::new(ux, u.y)))
                }
            }
        };
        if il.z <= 0.0 {
            return None;
        }
        let p = self.pdf_local(ol, il);
        if p > 0.0 && p.is_finite() {
            Some((il, p))
        } else {
            None
        }
    }

    /// Angular width (radians) of the narrowest lobe, for quadrature refinement in the reference.
    pub fn lobe_width(&self) -> f32 {
        match self.lobe {
            Lobe::None => PI / 2.0,
            Lobe::Phong { exponent } => (1.0 / (exponent + 1.0).sqrt()).min(PI / 2.0),
            Lobe::Ggx { alpha } | Lobe::GgxSchlick { alpha } => alpha.min(PI / 2.0),
        }
    }
}
