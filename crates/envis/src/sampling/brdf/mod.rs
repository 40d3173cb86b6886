//! Materials: a Lambert lobe plus an optional glossy lobe (normalised Phong / Lafortune, or GGX
//! with F = 1), each with `eval` / `sample` / `pdf`. Mixtures choose a lobe by the lobes'
//! luminance weights; their pdf is the weighted sum (one-sample model).
//!
//! All directions are world-space unit vectors pointing away from the surface; `o` is the view
//! direction. Back-facing views (`<n, o> <= 0`) reflect nothing.
//!
//! One file per concern: [`Material`] here (any lobe, chosen at run time), the [`LocalBsdf`]
//! calls and their [`SampleLanes`] in `lanes.rs`, and the lobes known at compile time, which
//! the renderer's hot loops use for single-lobe pixels: `lambert.rs`, `phong.rs`, `ggx.rs`.

mod ggx;
mod lambert;
mod lanes;
mod phong;

pub use ggx::Ggx;
pub use lambert::Lambert;
pub use lanes::{LANES, LocalBsdf, SampleLanes};
pub use phong::Phong;

use super::rng::ONE_MINUS_EPSILON;
use super::warp::*;
use crate::envmap::luminance;
use ggx::ggx_value;
use glam::{Vec2, Vec3};
use phong::phong_value;
use std::f32::consts::{FRAC_1_PI, PI};

/// `<r, i>` in the shading frame, with `r = (-o.x, -o.y, o.z)` the mirror direction of `o`.
#[inline]
pub(super) fn mirror_cos(ol: Vec3, il: Vec3) -> f32 {
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
