//! The map's bright part (a sun, a lamp: a few texels holding much of the light) is sampled
//! and shaded apart from the rest of the map.
//!
//! Why: the target of one reservoir is the *unshadowed* integrand, so where a sun is blocked
//! (a contact shadow) the reservoir selects the sun almost every time, its one shadow ray finds
//! it blocked, and the pixel's estimate is the unshadowed integral times a rare Bernoulli draw
//! (about 1 in 30 under the motion scene's sun): fireflies that reuse only averages slowly
//! (docs/temporal.md). Split by direction into two integrals, each gets an estimator that fits
//! it:
//! - **the rest** (the map with the bright texels zeroed, [`Split::rest`]) is smooth and mostly
//!   seen where the sun is not: the paper's face-weighted sampler is built on it, and its
//!   samples are resampled and reused across pixels and frames;
//! - **the bright part** is tiny, so its samples nearly share one visibility (except in a
//!   penumbra): [`BRIGHT_LIGHT_SAMPLES`] samples of its own table ([`BrightLight`], texels in
//!   proportion to `Y Ω`) and one of the BRDF, power heuristic, each shadow-tested, resampled
//!   to one ([`bright_reservoir`]) and reused across frames. Sampled from the paper's
//!   distribution instead, the sun would get a random number of the pixel's few light samples
//!   (its face's fractional count, and the face's sky beside it), the estimate's spread at
//!   4 + 4 candidates.
//!
//! The split is a fixed function of direction in each frame (a texel is bright or not), so the
//! two estimates sum to an unbiased estimate of the whole.

pub use super::bright_light::BrightLight;
use super::combine::DomainSurface;
use super::reservoir::{CandidateSink, Reservoir};
use crate::envmap::{CubeMap, luminance};
use crate::render::estimator::{Sink, shading_directions};
use crate::sampling::distribution::face_solid_angles;
use crate::sampling::mis::{Heuristic, weight_over_density};
use crate::sampling::rng::Rng;
use crate::sampling::warp::Frame;
use glam::{Vec2, Vec3};

/// A texel is bright when its luminance is over this many times the map's mean radiance...
pub const BRIGHT_OVER_MEAN: f64 = 16.0;
/// ...and the texels at least as bright cover at most this fraction of the sphere (a broad
/// bright region, an overcast sky's, is not split off: nothing gained, a ray more).
pub const BRIGHT_MAX_AREA: f64 = 0.005;

/// The two parts of a [`Split`] map, each resampled by reservoirs of its own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Part {
    /// The map with its bright texels zeroed: the paper's samples.
    Rest = 0,
    /// The bright texels: [`BrightLight`]'s samples.
    Bright = 1,
}

impl Part {
    pub const ALL: [Part; 2] = [Part::Rest, Part::Bright];
}

/// A frame's map split into its bright part and the rest.
pub struct Split {
    /// The map with its bright texels zeroed: what the paper's sampler and the reservoirs see.
    pub rest: CubeMap,
    pub bright: BrightLight,
}

impl Split {
    /// `map` split at [`bright_threshold`].
    pub fn new(map: &CubeMap) -> Self {
        Self::at(map, bright_threshold(map))
    }

    /// `map` whole: nothing is bright.
    pub fn whole(map: &CubeMap) -> Self {
        Self::at(map, f32::INFINITY)
    }

    /// Texels of luminance above `threshold` are bright.
    pub fn at(map: &CubeMap, threshold: f32) -> Self {
        let bright = BrightLight::new(map, threshold);
        let mut rest = map.clone();
        for (t, ..) in bright.texels() {
            rest.data[t as usize] = Vec3::ZERO;
        }
        Split { rest, bright }
    }

    /// The radiance of the map's `part` in direction `d` (zero outside it).
    pub fn radiance(&self, part: Part, d: Vec3) -> Vec3 {
        match part {
            Part::Rest => self.rest.lookup(d),
            Part::Bright => self.bright.radiance(d),
        }
    }
}

/// The luminance above which `map`'s texels are its bright part: the smallest texel luminance
/// over [`BRIGHT_OVER_MEAN`] times the mean such that the texels from it up cover at most
/// [`BRIGHT_MAX_AREA`] of the sphere. Infinite where no texel qualifies.
pub fn bright_threshold(map: &CubeMap) -> f32 {
    let omega = face_solid_angles(map.size);
    let mut energy = 0.0;
    let mut texels: Vec<(f32, f64)> = (map.data.iter().zip(omega.iter().cycle()))
        .map(|(l, &a)| {
            let (y, a) = (luminance(*l), a as f64);
            energy += y as f64 * a;
            (y, a)
        })
        .collect();
    let floor = BRIGHT_OVER_MEAN * energy / (4.0 * std::f64::consts::PI);
    let limit = BRIGHT_MAX_AREA * 4.0 * std::f64::consts::PI;
    texels.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
    let (mut i, mut area, mut threshold) = (0, 0.0, f32::INFINITY);
    // Whole groups of equal luminance at a time, so that the area bound holds with ties.
    while i < texels.len() && texels[i].0 as f64 > floor {
        let y = texels[i].0;
        let group = texels[i..].iter().take_while(|t| t.0 == y);
        let (count, group_area) = group.fold((0, 0.0), |(c, s), t| (c + 1, s + t.1));
        if area + group_area > limit {
            break;
        }
        area += group_area;
        // Bright are those strictly above the threshold: set just below this group.
        threshold = y.next_down();
        i += count;
    }
    threshold
}

/// Light samples of the bright part's candidates per pixel (each shadow-tested).
pub const BRIGHT_LIGHT_SAMPLES: usize = 2;
/// ...and in the biased mode, whose budget is two shadow rays a pixel: on the motion scene
/// (4 seeds, frames 16..31 at 48², docs/temporal.md) one sample gave 1.83 rays a pixel and
/// 7.0x the relMSE of today's 32 + 32, two 2.66 rays and 4.2x.
pub const BRIGHT_LIGHT_SAMPLES_BIASED: usize = 1;
/// ...and where the previous frame's candidates found a penumbra at the pixel's place or
/// beside it (unbiased mode). A penumbra's error is its few rays' draw, and penumbrae are few
/// pixels: on the motion scene (docs/temporal.md) 8 samples there measured 4.3x the relMSE of
/// today's 32 + 32 against 5.7x, for 0.4 more rays a pixel.
pub const BRIGHT_PENUMBRA_SAMPLES: usize = 8;
const _: () = assert!(BRIGHT_LIGHT_SAMPLES_BIASED <= BRIGHT_LIGHT_SAMPLES);
const _: () = assert!(BRIGHT_LIGHT_SAMPLES <= BRIGHT_PENUMBRA_SAMPLES);

/// The bright part's light samples at a pixel: [`BRIGHT_LIGHT_SAMPLES`],
/// [`BRIGHT_LIGHT_SAMPLES_BIASED`] in the biased mode, [`BRIGHT_PENUMBRA_SAMPLES`] where the
/// previous frame saw a `penumbra` (unbiased mode). The count depends on the previous frame's
/// draws only, never on this frame's candidates: each count's estimate is unbiased, so the mix
/// is too.
pub fn bright_light_samples(unbiased: bool, penumbra: bool) -> usize {
    match (unbiased, penumbra) {
        (false, _) => BRIGHT_LIGHT_SAMPLES_BIASED,
        (true, false) => BRIGHT_LIGHT_SAMPLES,
        (true, true) => BRIGHT_PENUMBRA_SAMPLES,
    }
}

/// The bright part's reservoir at a surface: `light_samples` samples of [`BrightLight`]
/// ([`bright_light_samples`]) and one of the BRDF (counted where it lands in the bright part), power
/// heuristic, each shadow-tested (a ray each, counted in `rays`) so that the target is the
/// shadowed integrand, one kept by resampling. Reused across frames (not across pixels).
/// The power heuristic, not the balance: on a diffuse surface the BRDF's density on the sun is
/// about 1/1000 of the light's, and a balance-weighted BRDF sample that lands on it counts
/// the whole sun a second time (measured: pixels at twice their reference).
/// Why visibility in the candidates: in a penumbra a reservoir culled by one ray is the whole
/// sun or nothing, and where the history pixel sees less of the sun than this one (a moving
/// camera), pairwise MIS gives this frame's sample the whole weight; with two rays the
/// candidates already hold the visible fraction. Measured on the motion scene (frames 16..31
/// at 48², docs/temporal.md): with the sun fixed, 8.4x the error of today's 32 + 32 against
/// 4.6x, for 0.8 more rays a pixel.
pub fn bright_reservoir(
    bright: &BrightLight,
    at: &DomainSurface,
    light_samples: usize,
    (rng, rays): (&mut Rng, &mut u32),
) -> Reservoir {
    let none = Reservoir {
        m: 1.0,
        ..Default::default()
    };
    if bright.is_empty() {
        return none;
    }
    let Some((n, o)) = shading_directions(at.px) else {
        return none;
    };
    let frame = Frame::new(n);
    let (mat, ol) = (&at.px.material, frame.to_local(o));
    let n = light_samples.min(BRIGHT_PENUMBRA_SAMPLES);
    let mut u = [0.0; 2 * BRIGHT_PENUMBRA_SAMPLES + 2];
    u[..2 * n + 2].fill_with(|| rng.next_f32());
    let mut sink = CandidateSink::new(Rng::new(rng.next_u32(), 0));
    let (mut seen, mut blocked) = (false, false);
    // `light`: whether `d` is one of the bright light's samples (else the BRDF's).
    let mut offer = |d: Vec3, light: bool| {
        let il = frame.to_local(d);
        let l = bright.radiance(d);
        if il.z <= 0.0 || l == Vec3::ZERO {
            return;
        }
        if !at.visible(d, rays) {
            blocked = true;
            return;
        }
        seen = true;
        let p_light = n as f32 * bright.pdf(d);
        let p_brdf = mat.pdf_local(ol, il);
        let (own, other) = if light {
            (p_light, p_brdf)
        } else {
            (p_brdf, p_light)
        };
        let scale = il.z * weight_over_density(Heuristic::Power, own, other);
        sink.add(d, mat.eval_local(ol, il) * l, il.z, scale);
    };
    for k in 0..n {
        if let Some((d, _)) = bright.sample(Vec2::new(u[2 * k], u[2 * k + 1])) {
            offer(d, true);
        }
    }
    let ub = Vec2::new(u[2 * n], u[2 * n + 1]);
    if let Some((il, _)) = mat.sample_local(ol, ub) {
        offer(frame.to_world(il).normalize(), false);
    }
    let mut q = sink.finish();
    // Every candidate was seen: what was kept is visible.
    q.visible = q.is_live();
    q.penumbra = seen && blocked;
    q
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::envmap::sky::{sky_cube, sun_direction};
    use crate::envmap::texel_solid_angle;
    use crate::sampling::rng::Rng;

    /// The built-in sky's sun is split off, and only it: the bright texels are few, hold most
    /// of the light, and the sun's direction is among them.
    #[test]
    fn the_sun_is_the_bright_part() {
        let map = sky_cube(32, 14.0);
        let threshold = bright_threshold(&map);
        let split = Split::at(&map, threshold);
        assert!(threshold.is_finite());
        assert!(split.bright.contains(sun_direction(14.0)));
        let (mut area, mut bright_energy, mut energy) = (0.0, 0.0, 0.0);
        for f in 0..6 {
            for r in 0..32 {
                for c in 0..32 {
                    let (y, a) = (luminance(map.texel(f, c, r)), texel_solid_angle(c, r, 32));
                    energy += y as f64 * a;
                    if y > threshold {
                        area += a;
                        bright_energy += y as f64 * a;
                    }
                }
            }
        }
        assert!(
            area <= BRIGHT_MAX_AREA * 4.0 * std::f64::consts::PI,
            "{area}"
        );
        assert!(bright_energy > 0.5 * energy, "{bright_energy} of {energy}");
        assert_eq!(split.radiance(Part::Rest, sun_direction(14.0)), Vec3::ZERO);
        assert_eq!(split.radiance(Part::Rest, Vec3::Y), map.lookup(Vec3::Y));
    }

    /// A surface that sees part of the sun flags a penumbra (with the penumbra's count of
    /// samples), one that sees all of it or none does not; and the count is the one the flag
    /// asks for.
    #[test]
    fn part_of_the_sun_is_a_penumbra() {
        use crate::render::GPixel;
        use crate::sampling::brdf::{Lobe, Material};
        use crate::visibility::Occluder;
        /// Blocks the directions on one side of a plane through the origin, or all, or none.
        struct Side(Vec3, f32);
        impl Occluder for Side {
            fn occluded(&self, _p: Vec3, _n: Vec3, d: Vec3) -> bool {
                d.dot(self.0) > self.1
            }
        }
        let map = sky_cube(32, 14.0);
        let split = Split::new(&map);
        let sun = sun_direction(14.0);
        let across = sun.cross(Vec3::Y).normalize();
        let px = GPixel {
            n: Vec3::Y,
            o: Vec3::Y,
            material: Material {
                kd: Vec3::splat(0.8),
                ks: Vec3::ZERO,
                lobe: Lobe::None,
            },
        };
        let flagged = |occ: &Side| {
            let at = DomainSurface {
                split: &split,
                part: Part::Bright,
                px: &px,
                point: Vec3::ZERO,
                occluder: Some(occ),
            };
            let n = bright_light_samples(true, true);
            (0..64)
                .filter(|&k| {
                    let mut rng = Rng::new(k, 0);
                    bright_reservoir(&split.bright, &at, n, (&mut rng, &mut 0)).penumbra
                })
                .count()
        };
        // Half the sun's disc behind the plane: most draws of 8 see both sides.
        assert!(flagged(&Side(across, 0.0)) > 48);
        assert_eq!(flagged(&Side(across, 2.0)), 0, "nothing blocked");
        assert_eq!(flagged(&Side(across, -2.0)), 0, "everything blocked");
        assert_eq!(bright_light_samples(true, false), BRIGHT_LIGHT_SAMPLES);
        assert_eq!(bright_light_samples(true, true), BRIGHT_PENUMBRA_SAMPLES);
        assert_eq!(
            bright_light_samples(false, true),
            BRIGHT_LIGHT_SAMPLES_BIASED
        );
    }

    /// A map without a small bright region is not split: uniform, and a bright half.
    #[test]
    fn broad_light_is_not_split() {
        assert_eq!(
            bright_threshold(&CubeMap::from_fn(8, |_| Vec3::ONE)),
            f32::INFINITY
        );
        let half = CubeMap::from_fn(8, |d| Vec3::splat(if d.y > 0.0 { 100.0 } else { 0.01 }));
        assert_eq!(bright_threshold(&half), f32::INFINITY);
        assert!(Split::whole(&half).bright.is_empty());
    }
}
