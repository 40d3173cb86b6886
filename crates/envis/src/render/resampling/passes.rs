//! The per-pixel passes of a resampled frame: the candidates and their shadow ray, temporal
//! reuse against the reprojected history, spatial reuse among neighbours.

use super::{
    Domain, DomainSurface, History, Reproject, Resampling, Reservoir, SPATIAL_CONFIDENCE,
    SPATIAL_RADIUS, SPATIAL_UNTIL_HISTORY, Screen, Surface, combine, lobe_agreement, similar,
};
use crate::render::estimator::{FrameData, shade_pixel_into};
use crate::render::resampling::{
    CandidateSink, Part, Reservoirs, bright_light_samples, bright_reservoir,
};
use crate::render::{PixelStats, Settings};
use crate::sampling::rng::Rng;
use glam::Vec3;

/// In the unbiased mode the bright part's history is reused only where the history pixel's
/// point is this pixel's, within this fraction of its distance from the camera: a still
/// camera over still geometry. Elsewhere its history's penumbra is another point's, and
/// pairwise MIS pays two rays for a worse estimate than the candidates' own: on the motion
/// scene with the sun fixed and the camera orbiting a third of a degree a frame (4 seeds,
/// frames 16..31 at 48², docs/temporal.md), 4.49x the relMSE of today's 32 + 32 at 6.39 rays a
/// pixel with it, 3.90x at 4.99 without; held still it is what brings 1.91x to 0.68x. The
/// test reads the two points only, never the samples: unbiased.
pub const BRIGHT_SAME_POINT: f32 = 1e-4;

/// Whether points `a` and `b`, at distance `depth` from the camera, are the same surface point
/// ([`BRIGHT_SAME_POINT`]): where the bright history is reused, and where, nothing having
/// moved ([`super::History::still_geometry`]), the history's visibility is known.
pub fn same_point(a: Vec3, b: Vec3, depth: f32) -> bool {
    a.distance(b) <= BRIGHT_SAME_POINT * depth
}

/// What the candidates pass gives a pixel.
pub(super) struct Candidates {
    /// Its reservoirs, each culled where its sample is blocked.
    pub res: Reservoirs,
    pub stats: Option<PixelStats>,
    pub rays: u32,
}

/// Pixel `i`'s candidates: the rest's reservoir (the paper's samples) and the bright part's
/// ([`bright_reservoir`], more of them where the previous frame saw a `penumbra`), the sample
/// statistics and the shadow rays cast.
pub(super) fn candidates(
    cur: &Screen,
    fd: &FrameData,
    s: &Settings,
    (r, penumbra): (&Resampling, bool),
    i: usize,
    mut rng: Rng,
) -> Candidates {
    let Some(at) = cur.surface(i, Part::Rest) else {
        return Candidates {
            res: Default::default(),
            stats: None,
            rays: 0,
        };
    };
    let mut bright_rng = Rng::new(rng.next_u32(), i as u32);
    let mut sink = CandidateSink::new(rng);
    // Without a surface point the candidates cast no shadow rays; with one (and `fd.occluder`)
    // a blocked candidate never reaches the sink.
    let point = r.candidate_visibility.then_some(at.point);
    let st = shade_pixel_into(crate::cpu::isa(), fd, s, at.px, point, i as u32, &mut sink);
    let mut q = sink.finish();
    let mut rays = 0;
    if point.is_some() {
        q.visible = true;
    } else if q.is_live() {
        q.visible = at.visible(q.dir, &mut rays);
        if !q.visible {
            q.ucw = 0.0;
        }
    }
    let n = bright_light_samples(r.unbiased, penumbra);
    let bright = bright_reservoir(&cur.split.bright, &at, n, (&mut bright_rng, &mut rays));
    Candidates {
        res: [q, bright],
        stats: Some(st),
        rays,
    }
}

/// Whether the previous frame's bright candidates found a penumbra at pixel `i`'s place
/// (`reproject`, no geometric test: any surface there will do) or at a pixel beside it: a
/// penumbra is a band, and two or three candidates see both sides of it only some of the time.
pub(super) fn penumbra_before(h: &History, reproject: Reproject, i: usize) -> bool {
    let Some((q, _)) = reproject(i) else {
        return false;
    };
    let (w, ht) = (h.screen.width as i64, h.screen.height as i64);
    let (x, y) = ((q % h.screen.width) as i64, (q / h.screen.width) as i64);
    (-1..=1)
        .flat_map(|dy| (-1..=1).map(move |dx| (x + dx, y + dy)))
        .filter(|&(a, b)| a >= 0 && b >= 0 && a < w && b < ht)
        .any(|(a, b)| h.reservoirs[(b * w + a) as usize][Part::Bright as usize].penumbra)
}

/// Pixel `i` after temporal reuse: its reservoir, the rays cast, whether history was accepted
/// (1 or 0). The bright part's history, in the unbiased mode, only where the point has not
/// moved ([`BRIGHT_SAME_POINT`]). The history's confidence is capped at `max_history` and
/// scaled by how far the two pixels' targets agree ([`lobe_agreement`]) and by `maps`, how far
/// the two frames' maps do (`map_agreement`). Where nothing moved ([`History::still_geometry`] and the same point) the
/// combination casts no rays.
pub(super) fn temporal(
    cur: &Screen,
    h: &History,
    (reproject, maps): (Reproject, f32),
    r: &Resampling,
    (res, part): (&[Reservoirs], Part),
    i: usize,
    mut rng: Rng,
) -> (Reservoir, u32, u32) {
    let own = res[i][part as usize];
    let Some(at) = cur.surface(i, part) else {
        return (own, 0, 0);
    };
    let Some((q, p, same)) = history_pixel(cur, h, reproject, (r, part), (i, &at)) else {
        return (own, 0, 0);
    };
    let mut old = h.reservoirs[q][part as usize];
    old.m = old.m.min(r.max_history as f32) * lobe_agreement(at.px, p.px) * maps;
    // The same point under the same geometry sees what the history pixel saw: the unbiased
    // combination's two rays (`V_c(X_i)`, `V_i(X_c)`) would find each live sample visible
    // (both reservoirs are culled where blocked from their own pixel), so they are not cast.
    let (at, p) = match r.unbiased && h.still_geometry && same {
        true => (at.without_rays(), p.without_rays()),
        false => (at, p),
    };
    let mut history = Domain::reused(old, p, cur.split, at.px);
    // The biased mode shadow-tests a final sample from elsewhere, but trusts the rest's history
    // (the sky, seen from half a pixel away a frame ago): 2.66 rays a pixel instead of 3.56 on
    // the motion scene, and a lower error (4.2x against 4.9x: a sky sample found blocked
    // from here at shading is lost, where the history knew it lit this spot). Not the bright
    // part's: a sun sample seen last frame, now behind a moving object, measured 68x.
    if part == Part::Rest {
        history.res.visible = old.visible;
    }
    let domains = [Domain::own(own, at), history];
    let mut rays = 0;
    let out = combine(&domains, r.unbiased, r.mutation, &mut rng, &mut rays);
    (out, rays, 1)
}

/// Pixel `i`'s history pixel for `part` (`at` its surface): the reprojected pixel where it
/// passes the geometric tests (and, for the unbiased mode's bright part, [`same_point`]), its
/// surface, and whether its point is this pixel's.
fn history_pixel<'a>(
    cur: &Screen,
    h: &History<'a>,
    reproject: Reproject,
    (r, part): (&Resampling, Part),
    (i, at): (usize, &DomainSurface),
) -> Option<(usize, DomainSurface<'a>, bool)> {
    let (q, depth) = reproject(i)?;
    let p = h.screen.surface(q, part)?;
    let expect = Surface {
        depth,
        id: cur.surfaces[i].id,
    };
    let same = same_point(at.point, p.point, cur.surfaces[i].depth);
    let moved = part == Part::Bright && r.unbiased && !same;
    (similar(at.px.n, expect, p.px.n, h.screen.surfaces[q]) && !moved).then_some((q, p, same))
}

/// Pixel `i` after spatial reuse: its reservoir, the rays cast, the neighbours accepted. A
/// neighbour's confidence is capped at [`SPATIAL_CONFIDENCE`] of the pixel's and scaled by
/// [`lobe_agreement`].
pub(super) fn spatial(
    cur: &Screen,
    r: &Resampling,
    (res, part): (&[Reservoirs], Part),
    i: usize,
    mut rng: Rng,
) -> (Reservoir, u32, u32) {
    let own = res[i][part as usize];
    let Some(at) = cur.surface(i, part) else {
        return (own, 0, 0);
    };
    let (w, h) = (cur.width as i64, cur.height as i64);
    let (x, y) = ((i % cur.width) as i64, (i / cur.width) as i64);
    let mut domains = vec![Domain::own(own, at)];
    let wanted = if own.m < SPATIAL_UNTIL_HISTORY {
        r.spatial
    } else {
        0
    };
    for _ in 0..wanted {
        let (u1, u2) = (rng.next_f32(), rng.next_f32());
        let rad = SPATIAL_RADIUS * u1.sqrt();
        let (sin, cos) = (std::f32::consts::TAU * u2).sin_cos();
        let (nx, ny) = (
            x + (rad * cos).round() as i64,
            y + (rad * sin).round() as i64,
        );
        if (nx, ny) == (x, y) || nx < 0 || ny < 0 || nx >= w || ny >= h {
            continue;
        }
        let j = (ny * w + nx) as usize;
        let Some(nb) = cur.surface(j, part) else {
            continue;
        };
        if !similar(at.px.n, cur.surfaces[i], nb.px.n, cur.surfaces[j]) {
            continue;
        }
        let mut q = res[j][part as usize];
        q.m = q.m.min(SPATIAL_CONFIDENCE * own.m) * lobe_agreement(at.px, nb.px);
        domains.push(Domain::reused(q, nb, cur.split, at.px));
    }
    let accepted = domains.len() as u32 - 1;
    if accepted == 0 {
        return (own, 0, 0);
    }
    let mut rays = 0;
    let out = combine(&domains, r.unbiased, r.mutation, &mut rng, &mut rays);
    (out, rays, accepted)
}
