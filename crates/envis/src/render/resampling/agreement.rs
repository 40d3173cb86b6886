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

use crate::envmap::{CubeMap, luminance};
use crate::render::GPixel;
use crate::sampling::brdf::Lobe;
use crate::sampling::distribution::face_solid_angles;
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

/// A history's confidence falls by `1/e` where this fraction of its map's light moved
/// ([`map_agreement`]). A moving sun moves under 0.5% of the rest's light a frame (the
/// confidence kept: 99.9%); a carousel step from the built-in sky to `park.exr` 35% (dropped).
/// Measured on `motion-carousel.toml` (4 seeds, 48², docs/temporal.md): without it restir's
/// error at the switch was 85x today's 32 + 32's and 12 frames on still 32x (before the
/// switch, 4.8x); with it, back within 2x of that in 2 frames.
pub const MAP_AGREEMENT_SCALE: f32 = 0.05;

/// `1` where two frames' maps light the scene alike, falling towards `0` as their light moves:
/// `exp(-((1 - overlap) / MAP_AGREEMENT_SCALE)^2)`, the overlap `Σ min(p_a, p_b)` over texels
/// of each map's energy (`Y Ω`) normalised to 1 (0 for maps of different face sizes). The
/// temporal pass scales the history's confidence by it: a history made under another map
/// holds samples drawn for that map's light, and at full confidence it outweighs the new
/// candidates for a dozen frames (re-evaluating its samples under the new map keeps it
/// unbiased, not useful). It reads the maps only, never the samples: unbiased.
pub fn map_agreement(a: &CubeMap, b: &CubeMap) -> f32 {
    let disagreement = 1.0 - light_overlap(a, b);
    (-(disagreement / MAP_AGREEMENT_SCALE).powi(2)).exp()
}

/// `Σ min(p_a, p_b)` over texels, `p` each map's energy (`Y Ω`) normalised to 1: 1 for maps
/// equal up to a scale (or both dark), 0 for maps lit in different directions or of
/// different face sizes.
fn light_overlap(a: &CubeMap, b: &CubeMap) -> f32 {
    if a.size != b.size || a.data.len() != b.data.len() {
        return 0.0;
    }
    let omega = face_solid_angles(a.size);
    let energy = |m: &CubeMap| -> Vec<f64> {
        (m.data.iter().zip(omega.iter().cycle()))
            .map(|(l, &w)| luminance(*l) as f64 * w as f64)
            .collect()
    };
    let (ea, eb) = (energy(a), energy(b));
    let (sa, sb) = (ea.iter().sum::<f64>(), eb.iter().sum::<f64>());
    if !(sa > 0.0 && sb > 0.0) {
        return if sa == sb { 1.0 } else { 0.0 };
    }
    let shared: f64 = ea.iter().zip(&eb).map(|(x, y)| (x / sa).min(y / sb)).sum();
    shared.clamp(0.0, 1.0) as f32
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
    /// Maps that light alike agree (a scaled copy, a sun moved by a minute of the sky's clock);
    /// a sky eight hours earlier keeps a tenth (its rest, without the sun, shares 92% of its
    /// light), a map of light elsewhere or of another face size nothing; the overlap is what is
    /// shared, and the agreement falls to `1/e` at `MAP_AGREEMENT_SCALE` of the light moved.
    #[test]
    fn maps_agree_as_far_as_their_light_does() {
        use crate::envmap::sky::sky_cube;
        let split = |h: f32| crate::render::resampling::Split::new(&sky_cube(16, h)).rest;
        let sky = split(14.0);
        let brighter = CubeMap {
            data: sky.data.iter().map(|l| *l * 3.0).collect(),
            ..sky.clone()
        };
        assert!((map_agreement(&sky, &brighter) - 1.0).abs() < 1e-5);
        let a_minute_on = map_agreement(&sky, &split(14.0 + 1.0 / 60.0));
        assert!(a_minute_on > 0.99, "{a_minute_on}");
        let dawn = map_agreement(&sky, &split(6.0));
        assert!(dawn > 0.02 && dawn < 0.2, "{dawn}");
        let up = CubeMap::from_fn(16, |d| Vec3::splat(d.y.max(0.0)));
        let down = CubeMap::from_fn(16, |d| Vec3::splat((-d.y).max(0.0)));
        assert_eq!(light_overlap(&up, &down), 0.0);
        assert_eq!(map_agreement(&up, &CubeMap::from_fn(8, |_| Vec3::ONE)), 0.0);
        // Half the light moved: an overlap of 1/2.
        let half = CubeMap::from_fn(16, |d| Vec3::splat(d.y.abs()));
        assert!((light_overlap(&up, &half) - 0.5).abs() < 1e-3);
        let at_scale = (-1.0f32).exp();
        let mix = |t: f32| {
            let data = (up.data.iter().zip(&half.data)).map(|(a, b)| *a * (1.0 - t) + *b * t);
            CubeMap {
                data: data.collect(),
                ..up.clone()
            }
        };
        // Mixing in t of `half` adds t of `up`'s light below the horizon: t / (1 + t) of the
        // mix's light is where `up` has none.
        let t = MAP_AGREEMENT_SCALE / (1.0 - MAP_AGREEMENT_SCALE);
        assert!((map_agreement(&up, &mix(t)) - at_scale).abs() < 0.01);
    }
}
