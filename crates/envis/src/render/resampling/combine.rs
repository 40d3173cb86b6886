//! Resampling several pixels' reservoirs into one (the temporal and the spatial pass), with the
//! MIS weights that keep the result unbiased.
//!
//! Domains (the canonical pixel's own reservoir `c`, then `k` others: a previous frame's, or
//! neighbours') hold samples `X_j` with weights `W_j` and confidences `M_j`. Each is streamed
//! into the result with the resampling weight `w_j = m_j(X_j) p_c(X_j) W_j`, where `p_c = p̂ V`
//! is the canonical pixel's target now (this frame's map and geometry) with its visibility, and
//! the selected `Y` gets `W = Σ w_j / p_c(Y)`: generalised resampled importance sampling (Lin et
//! al. 2022), unbiased whenever the MIS weights `m_j(x)` sum to 1 over the domains that can
//! produce `x`.
//!
//! The weights are **pairwise** (Bitterli 2022, ch. 9): the canonical domain is paired with each
//! other domain `i`, the pair holding `(M_i + M_c / k) / C` of the total confidence `C`, split
//! in proportion to `M_i p_i(x)` and `(M_c / k) p_c(x)`, where `p_i` is domain `i`'s own target
//! with its own visibility (its pixel, **its frame**: the previous frame's map, G-buffer and
//! shadow geometry are kept for this). The pairs' shares sum to 1 at every `x`. A domain's
//! support is exactly `p_i > 0`: every reservoir is culled (`W = 0`) where its sample is blocked
//! from its own pixel, and the canonical domain covers the whole shadowed integrand. Compared
//! with the generalised balance heuristic evaluated for the selected sample only (the first
//! version), every sample is weighted by its own MIS weight, so a neighbour's sample whose own
//! target was small, but whose target here is large, no longer inflates the others' weights.
//!
//! Shadow rays: `V_c(X_i)` for each other domain's sample and `V_i(X_c)` for the canonical
//! sample at each other domain (each only where the target is positive): at most `2 k`.
//!
//! The biased option selects by `M_j p̂(X_j) W_j` and weights by `1 / Σ M_j`: no rays, darker
//! where domains' visibility differs (docs/temporal.md measures it).

use super::{Mutation, Part, Reservoir, Split, target_rgb};
use crate::envmap::luminance;
use crate::render::GPixel;
use crate::sampling::rng::Rng;
use crate::visibility::Occluder;
use glam::Vec3;

/// Where a domain's target and visibility are evaluated: its pixel's surface in its frame.
#[derive(Clone, Copy)]
pub struct DomainSurface<'a> {
    /// Its frame's map, split, and the part the reservoirs resample.
    pub split: &'a Split,
    pub part: Part,
    pub px: &'a GPixel,
    pub point: Vec3,
    pub occluder: Option<&'a dyn Occluder>,
}

impl DomainSurface<'_> {
    /// `p̂(d)` here, and whether `d` is unblocked (a shadow ray, counted in `rays`, cast only
    /// where the target is positive).
    pub fn target_visible(&self, d: Vec3, rays: &mut u32) -> f32 {
        let t = luminance(target_rgb(self.split, self.part, self.px, d));
        if t > 0.0 && !self.visible(d, rays) {
            return 0.0;
        }
        t
    }

    /// This surface with every direction taken as unblocked (no occluder, no rays): for a
    /// combination whose live samples are known to be visible from it.
    pub fn without_rays(self) -> Self {
        DomainSurface {
            occluder: None,
            ..self
        }
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
    /// the canonical pixel `px` under this frame's map `split`. Its sample is not known to be
    /// visible from the canonical pixel (`res.visible` false; the caller may trust it).
    pub fn reused(res: Reservoir, at: DomainSurface<'a>, split: &Split, px: &GPixel) -> Self {
        Domain {
            res: Reservoir {
                visible: false,
                ..res
            },
            at,
            here: target_rgb(split, at.part, px, res.dir),
        }
    }
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
    if unbiased {
        pairwise(domains, mutation, rng, rays)
    } else {
        biased(domains, mutation, rng)
    }
}

/// `p̂_c(X_k) V_c(X_k)`: domain `k`'s sample's target at the canonical pixel now, with the
/// canonical pixel's visibility (a shadow ray for a reused sample with a positive target).
fn canonical_target(
    domains: &[Domain],
    k: usize,
    mutation: Option<Mutation>,
    rays: &mut u32,
) -> f32 {
    let d = &domains[k];
    if k == 0 {
        // Live only where its shadow ray found it unblocked.
        return if d.res.is_live() { d.res.target } else { 0.0 };
    }
    let t = match mutation {
        // The reused sample keeps the target it had where it was made.
        Some(Mutation::StaleTarget) => d.res.target,
        _ => luminance(d.here),
    };
    if !(t > 0.0 && d.res.is_live() && domains[0].at.visible(d.res.dir, rays)) {
        return 0.0;
    }
    t
}

/// Pairwise MIS weights of the canonical domain against neighbour `i`: the pair's share of the
/// total confidence `C`, split between the neighbour (its `M_i p_i(x)`) and the canonical
/// domain (`M_c / k` of its confidence, times `p_c(x)`). `p_i`, `p_c` are each domain's own
/// target with its own visibility at `x`; the pair's two weights sum to its share.
fn pair_share(m_i: f32, p_i: f32, m_c_share: f32, p_c: f32, c_total: f32) -> (f32, f32) {
    let share = (m_i + m_c_share) / c_total;
    let (a, b) = (m_i * p_i, m_c_share * p_c);
    if a + b <= 0.0 {
        return (0.0, 0.0);
    }
    (share * a / (a + b), share * b / (a + b))
}

/// Unbiased: generalised resampled importance sampling with pairwise MIS (Bitterli 2022, Lin et
/// al. 2022), every domain's sample weighted by its own MIS weight.
fn pairwise(
    domains: &[Domain],
    mutation: Option<Mutation>,
    rng: &mut Rng,
    rays: &mut u32,
) -> Reservoir {
    let c_total: f32 = domains.iter().map(|d| d.res.m).sum();
    let canonical = &domains[0];
    let k = (domains.len() - 1).max(1) as f32;
    let m_c_share = canonical.res.m / k;
    let dropped = mutation == Some(Mutation::DroppedMisTerm);
    let mut pick = Pick::default();
    for (j, d) in domains.iter().enumerate() {
        let p_here = canonical_target(domains, j, mutation, rays);
        if !(p_here > 0.0 && d.res.ucw > 0.0) {
            continue;
        }
        let m = if domains.len() == 1 {
            1.0
        } else if j == 0 {
            // The canonical sample against every neighbour: each neighbour's own target and
            // visibility at it (one ray each where its target is positive).
            domains[1..]
                .iter()
                .map(|nb| {
                    let p_i = if dropped {
                        0.0
                    } else {
                        nb.at.target_visible(d.res.dir, rays)
                    };
                    pair_share(nb.res.m, p_i, m_c_share, p_here, c_total).1
                })
                .sum::<f32>()
        } else {
            // Its own target (it is culled where blocked from its pixel) against the canonical.
            let p_c = if dropped { 0.0 } else { p_here };
            pair_share(d.res.m, d.res.target, m_c_share, p_c, c_total).0
        };
        pick.offer(j, m * p_here * d.res.ucw, rng);
    }
    // Every selectable sample was seen from here.
    pick.finish(domains, c_total, 1.0, |_| true)
}

/// Biased: selection by `M_k p̂(X_k) W_k` and weights `1 / Σ M_k`, no rays; the final sample's
/// visibility is tested by the caller unless its domain's `visible` says it is known.
fn biased(domains: &[Domain], mutation: Option<Mutation>, rng: &mut Rng) -> Reservoir {
    let m_total: f32 = domains.iter().map(|d| d.res.m).sum();
    let mut pick = Pick::default();
    for (k, d) in domains.iter().enumerate() {
        let here = match mutation {
            Some(Mutation::StaleTarget) if k > 0 => d.res.target,
            _ => luminance(d.here),
        };
        pick.offer(k, d.res.m * here * d.res.ucw, rng);
    }
    pick.finish(domains, m_total, m_total, |s| domains[s].res.visible)
}

/// Weighted reservoir sampling over the domains' samples (the combination's selection).
#[derive(Default)]
struct Pick {
    w_sum: f32,
    selected: Option<usize>,
}

impl Pick {
    /// Offer domain `j`'s sample with resampling weight `w` (skipped unless positive, finite).
    fn offer(&mut self, j: usize, w: f32, rng: &mut Rng) {
        if !(w > 0.0 && w.is_finite()) {
            return;
        }
        self.w_sum += w;
        if rng.next_f32() * self.w_sum < w {
            self.selected = Some(j);
        }
    }

    /// The combined reservoir, of confidence `m`: the selected sample re-evaluated here with
    /// `W = Σ w / (p̂(Y) norm)`, `visible(j)` whether it is known to be unblocked from here;
    /// nothing selected, the canonical reservoir emptied.
    fn finish(
        self,
        domains: &[Domain],
        m: f32,
        norm: f32,
        visible: impl Fn(usize) -> bool,
    ) -> Reservoir {
        let Some(s) = self.selected else {
            return Reservoir {
                m,
                ucw: 0.0,
                ..domains[0].res
            };
        };
        let chosen = &domains[s];
        let target = luminance(chosen.here);
        let ucw = self.w_sum / (target * norm);
        Reservoir {
            dir: chosen.res.dir,
            ucw: if ucw.is_finite() { ucw } else { 0.0 },
            m,
            target,
            rgb: chosen.here,
            visible: visible(s),
            penumbra: domains[0].res.penumbra,
        }
    }
}
