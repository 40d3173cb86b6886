//! The per-pixel passes of a resampled frame: the candidates and their shadow ray, temporal
//! reuse against the reprojected history, spatial reuse among neighbours.

use super::{
    Domain, History, Reproject, Resampling, Reservoir, SPATIAL_CONFIDENCE, SPATIAL_RADIUS,
    SPATIAL_UNTIL_HISTORY, Screen, Surface, combine, lobe_agreement, same_point, similar,
};
use crate::render::estimator::{FrameData, shade_pixel_into};
use crate::render::resampling::{
    CandidateSink, Part, Reservoirs, bright_light_samples, bright_reservoir,
};
use crate::render::{PixelStats, Settings};
use crate::sampling::rng::Rng;

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
/// moved ([`super::BRIGHT_SAME_POINT`]). The history's confidence is capped at `max_history` and scaled by how far the two
/// pixels' targets agree ([`lobe_agreement`]) and by `maps`, how far the two frames' maps do
/// (`map_agreement`).
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
    let prev = reproject(i).and_then(|(q, depth)| {
        let p = h.screen.surface(q, part)?;
        let expect = Surface {
            depth,
            id: cur.surfaces[i].id,
        };
        let here = cur.surfaces[i].depth;
        let moved = part == Part::Bright && r.unbiased && !same_point(at.point, p.point, here);
        (similar(at.px.n, expect, p.px.n, h.screen.surfaces[q]) && !moved).then_some((q, p))
    });
    let Some((q, p)) = prev else {
        return (own, 0, 0);
    };
    let mut old = h.reservoirs[q][part as usize];
    old.m = old.m.min(r.max_history as f32) * lobe_agreement(at.px, p.px) * maps;
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
