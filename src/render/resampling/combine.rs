//! Resampling several pixels' reservoirs into one (the temporal and the spatial pass), with the
//! MIS weights that keep the result unbiased.
//!
//! Domains `k` (the canonical pixel's own reservoir, a previous frame's, neighbours') hold
//! samples `X_k` with weights `W_k` and confidences `M_k`. One is selected with probability
//! proportional to `w_k = M_k p̂(X_k) W_k`, `p̂` the target at the pixel being shaded,
//! re-evaluated under this frame's map and geometry. The selected `Y` from domain `s` gets
//!
//! `W = (Σ w_k) m_s(Y) / p̂(Y)`, `m_s(Y) = p̂_s(Y) V_s(Y) / Σ_k M_k p̂_k(Y) V_k(Y)`,
//!
//! `p̂_k` and `V_k` being domain `k`'s own target and visibility (its pixel, its frame). Then
//! `E[f(Y) W] = Σ_s ∫ M_s m_s f = ∫ f` wherever some domain can produce `Y`, and the
//! canonical domain covers the whole integrand: unbiased (Bitterli et al. 2020, sec. 4.3, with
//! the generalised balance heuristic evaluated for the selected sample only). Visibility in the
//! weights is what a domain's support really is: every reservoir is culled (`W = 0`) where its
//! sample is blocked from its own pixel, so a neighbour cannot offer a direction it does not see.
//! The target at the canonical pixel includes its visibility: a reused sample it does not see
//! gets no weight (one ray per reused sample), so the selected `Y` is always seen. Cost: that,
//! plus one ray per other domain whose target is positive at `Y`: at most `2 (k - 1)` for `k`
//! domains.
//!
//! The biased option replaces `m_s` by `1 / Σ M_k`: no rays, darker where domains' visibility
//! differs (docs/temporal.md measures it).

use super::{Mutation, Reservoir, target_rgb};
use crate::envmap::{CubeMap, luminance};
use crate::render::GPixel;
use crate::sampling::rng::Rng;
use crate::visibility::Occluder;
use glam::Vec3;

/// Where a domain's target and visibility are evaluated: its pixel's surface in its frame.
#[derive(Clone, Copy)]
pub struct DomainSurface<'a> {
    pub map: &'a CubeMap,
    pub px: &'a GPixel,
    pub point: Vec3,
    pub occluder: Option<&'a dyn Occluder>,
}

impl DomainSurface<'_> {
    /// `p̂(d)` here, and whether `d` is unblocked (a shadow ray, counted in `rays`, cast only
    /// where the target is positive).
    pub fn target_visible(&self, d: Vec3, rays: &mut u32) -> f32 {
        let t = luminance(target_rgb(self.map, self.px, d));
        if t > 0.0 && !self.visible(d, rays) {
            return 0.0;
        }
        t
    }

    /// Whether `d` is unblocked from this surface (true with no occluder, no ray then).
    pub fn visible(&self, d: Vec3, rays: &mut u32) -> bool {
        let Some(occ) = self.occluder else {
            return true;
        };
        *rays += 1;
        !occ.occluded(self.point, self.px.n.normalize_or_zero(), d)
    }
}

/// One input of a combination: a reservoir, where it came from, and its sample's integrand
/// re-evaluated at the pixel being shaded.
pub struct Domain<'a> {
    pub res: Reservoir,
    pub at: DomainSurface<'a>,
    /// The unshadowed integrand of `res.dir` at the canonical pixel, this frame.
    pub here: Vec3,
}

impl<'a> Domain<'a> {
    /// The canonical pixel's own reservoir.
    pub fn own(res: Reservoir, at: DomainSurface<'a>) -> Self {
        Domain {
            res,
            at,
            here: res.rgb,
        }
    }

    /// Another pixel's (or frame's) reservoir `res`, made at `at`, its sample re-evaluated for
    /// the canonical pixel `px` under this frame's `map`.
    pub fn reused(res: Reservoir, at: DomainSurface<'a>, map: &CubeMap, px: &GPixel) -> Self {
        Domain {
            res,
            at,
            here: target_rgb(map, px, res.dir),
        }
    }
}

/// Whether the canonical pixel (`domains[0]`) sees reused sample `d` (a shadow ray).
fn canonical_sees(domains: &[Domain], d: &Domain, rays: &mut u32) -> bool {
    domains[0].at.visible(d.res.dir, rays)
}

/// Combine `domains` (the canonical pixel's own first) into the canonical pixel's reservoir.
/// Rays cast go to `rays`.
pub fn combine(
    domains: &[Domain],
    unbiased: bool,
    mutation: Option<Mutation>,
    rng: &mut Rng,
    rays: &mut u32,
) -> Reservoir {
    let m_total: f32 = domains.iter().map(|d| d.res.m).sum();
    let mut w_sum = 0.0f32;
    let mut selected = None;
    for (k, d) in domains.iter().enumerate() {
        let here = match mutation {
            // The reused sample keeps the target it had where it was made.
            Some(Mutation::StaleTarget) if k > 0 => d.res.target,
            _ => luminance(d.here),
        };
        let w = d.res.m * here * d.res.ucw;
        if !(w > 0.0 && w.is_finite()) {
            continue;
        }
        // Unbiased: a reused sample the canonical pixel does not see cannot be selected (the
        // target is p̂ V here). Without this a lit neighbour's sun sample wins in a shadow, is
        // blocked, and the pixel loses the sky sample its history had found.
        if unbiased && k > 0 && !canonical_sees(domains, d, rays) {
            continue;
        }
        w_sum += w;
        if rng.next_f32() * w_sum < w {
            selected = Some(k);
        }
    }
    let canonical = &domains[0];
    let Some(s) = selected else {
        return Reservoir {
            m: m_total,
            ucw: 0.0,
            ..canonical.res
        };
    };
    let chosen = &domains[s];
    let (y, rgb) = (chosen.res.dir, chosen.here);
    let target = luminance(rgb);
    let mut out = Reservoir {
        dir: y,
        ucw: 0.0,
        m: m_total,
        target,
        rgb,
        // Unbiased: every selectable sample was seen from here.
        visible: unbiased || (chosen.res.visible && s == 0),
    };
    if unbiased {
        let mut denom = 0.0f32;
        for (k, d) in domains.iter().enumerate() {
            let p = if k == s {
                // Its own sample: the target it was selected under, visible (it is culled
                // otherwise).
                d.res.target
            } else if k == 0 {
                target
            } else if mutation == Some(Mutation::DroppedMisTerm) {
                0.0
            } else {
                d.at.target_visible(y, rays)
            };
            denom += d.res.m * p;
        }
        if denom > 0.0 {
            out.ucw = w_sum * (chosen.res.target / denom) / target;
        }
    } else {
        out.ucw = w_sum / (target * m_total);
    }
    if !out.ucw.is_finite() {
        out.ucw = 0.0;
    }
    out
}
