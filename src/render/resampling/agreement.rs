//! How far two pixels' targets agree as functions of direction, judged from their G-buffers
//! alone: the confidence a reused reservoir keeps.
//!
//! Why: pairwise MIS bounds a reused sample's weight by the confidence ratio `M_i / M_c` times
//! how much its target grew from there to here. With a history of 20 frames against one
//! frame of candidates, a sample near the old normal's horizon (or at the edge of the old
//! glossy lobe) that is central here gets up to 20x the integral, and as the next history it
//! stays for frames. Measured on the motion scene without shadows, camera orbiting a third of
//! a degree a frame (docs/temporal.md): restir 3.5x the error of today's 32 + 32, against
//! 0.22x held still. A confidence that falls as the lobes part keeps the ratio small where the
//! targets differ. It reads only geometry (normals, view directions, materials), never the
//! samples, so the MIS weights stay independent of the samples they weigh: unbiased (a
//! confidence computed from the samples was measured biased, docs/temporal.md).

use crate::envmap::luminance;
use crate::render::GPixel;
use crate::sampling::brdf::Lobe;
use crate::sampling::warp::reflect;
use glam::Vec3;

/// A lobe may move by this fraction of its angular width before the reused confidence falls
/// by `1/e`. Swept on the motion scene without shadows (frames 16..31 at 48², relMSE ratio
/// to today's 32 + 32): 1.0 gave 3.5x, 0.3 2.2x, 0.1 0.64x, 0.03 0.68x; the same scene held
/// still, 0.19x at 1.0 and 0.13x at 0.1 (spatial neighbours on curved surfaces weigh less).
pub const AGREEMENT_SCALE: f32 = 0.1;

/// Angular width (radians) of the diffuse cosine lobe.
pub const DIFFUSE_WIDTH: f32 = 1.0;

/// The scaled width never falls under this (radians): a mirror (GGX `alpha` 0, as a Bevy
/// material of roughness 0 gives) would otherwise divide 0 by 0 where nothing moved.
pub const MIN_AGREEMENT_WIDTH: f32 = 1e-3;

/// `1` where pixels `a` and `b` have the same target (as a function of direction), falling
/// towards `0` as their lobes part: per lobe (diffuse about the normal, glossy about the
/// mirror direction) `exp(-(angle / (AGREEMENT_SCALE width))^2)`, mixed by the lobes' albedos
/// (`a`'s material: the geometric tests only pair pixels of one object).
pub fn lobe_agreement(a: &GPixel, b: &GPixel) -> f32 {
    let (na, nb) = (a.n.normalize_or_zero(), b.n.normalize_or_zero());
    let diffuse = near(na, nb, DIFFUSE_WIDTH);
    let m = &a.material;
    let Some(width) = glossy_width(m.lobe) else {
        return diffuse;
    };
    let (kd, ks) = (luminance(m.kd), luminance(m.ks));
    if kd + ks <= 0.0 {
        return diffuse;
    }
    let (oa, ob) = (a.o.normalize_or_zero(), b.o.normalize_or_zero());
    let glossy = near(reflect(oa, na), reflect(ob, nb), width);
    (kd * diffuse + ks * glossy) / (kd + ks)
}

/// `exp(-(angle(x, y) / (AGREEMENT_SCALE width))^2)` for unit `x`, `y`, the squared angle
/// taken as the squared chord `|x - y|^2` (equal to fourth order; exactly 0 for equal vectors,
/// and no `acos` for the WGSL twin to round otherwise).
fn near(x: Vec3, y: Vec3, width: f32) -> f32 {
    let w = (AGREEMENT_SCALE * width).max(MIN_AGREEMENT_WIDTH);
    (-(x - y).length_squared() / (w * w)).exp()
}

/// Angular half-width (radians) of a glossy lobe about the mirror direction: `2 alpha` for
/// GGX (twice its half-vector spread), `sqrt(2 / e)` for Phong (`cos^e` falls to `1/e`);
/// `None` without one.
fn glossy_width(lobe: Lobe) -> Option<f32> {
    match lobe {
        Lobe::None => None,
        Lobe::Phong { exponent } => Some((2.0 / exponent.max(1e-3)).sqrt()),
        Lobe::Ggx { alpha } | Lobe::GgxSchlick { alpha } => Some(2.0 * alpha),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::brdf::Material;

    fn px(n: Vec3, o: Vec3, material: Material) -> GPixel {
        GPixel { n, o, material }
    }

    fn diffuse() -> Material {
        Material {
            kd: Vec3::splat(0.8),
            ks: Vec3::ZERO,
            lobe: Lobe::None,
        }
    }

    fn glossy(alpha: f32) -> Material {
        Material {
            kd: Vec3::ZERO,
            ks: Vec3::splat(0.8),
            lobe: Lobe::Ggx { alpha },
        }
    }

    #[test]
    fn same_geometry_agrees_fully() {
        let (n, o) = (Vec3::new(0.3, 1.0, 0.2).normalize(), Vec3::Z);
        for m in [diffuse(), glossy(0.2), glossy(0.0)] {
            assert_eq!(lobe_agreement(&px(n, o, m), &px(n, o, m)), 1.0);
        }
    }

    #[test]
    fn agreement_falls_as_lobes_part() {
        let o = Vec3::new(0.0, 0.6, 0.8);
        let tilt = |deg: f32| {
            let t = deg.to_radians();
            Vec3::new(t.sin(), t.cos(), 0.0)
        };
        let d = |deg| lobe_agreement(&px(Vec3::Y, o, diffuse()), &px(tilt(deg), o, diffuse()));
        // The diffuse width: 0.1 rad (5.7 degrees) to 1/e.
        assert!(d(1.0) > 0.9 && (d(5.73) - (-1.0f32).exp()).abs() < 0.01 && d(20.0) < 1e-4);
        // A diffuse surface ignores the view; a glossy one follows its mirror direction.
        let seen_from =
            |m: Material, view: Vec3| lobe_agreement(&px(Vec3::Y, o, m), &px(Vec3::Y, view, m));
        let view = Vec3::new(0.1, 0.6, 0.8).normalize();
        assert_eq!(seen_from(diffuse(), view), 1.0);
        assert!(seen_from(glossy(0.2), view) < 0.5);
        // A rougher lobe tolerates the same move better.
        assert!(seen_from(glossy(0.8), view) > seen_from(glossy(0.2), view));
    }
}
