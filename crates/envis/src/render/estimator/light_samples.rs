//! The pixel's light samples: the paper's, from the frame's pool (per region, or per face with
//! each sample drawing its tile), or the pbrt-style baseline's from one lat-long distribution.
//! Their WGSL twins: `light_pool_samples`, `face_tile_samples`, `pool_sample` and `global_samples`
//! in `shaders/shade.wgsl`.

use super::*;

/// The paper's light samples: each region (face, or tile) weighted by `mu_t`, `N_t = mu_t N_L`,
/// fractional or integer counts, taken from its part of the pool (from the pixel's window,
/// wrapping): per tile, or with [`TileCounts::Face`] per face, each sample drawing its tile.
/// Writes the per-region densities the BRDF samples' MIS weights need.
#[inline(always)]
pub(super) fn light_pool_samples<B: LocalBsdf>(
    px: &Pixel<B>,
    rng: &mut Rng,
    density: &mut [f32; MAX_REGIONS],
    sum: &mut impl Sink,
    st: &mut PixelStats,
) {
    let (fd, s) = (px.fd, px.s);
    let w = pool_window(rng, s, &fd.pool);
    let regions = fd.tiles.len();
    st.available = (regions * w.len) as u32;
    // `C_t I_t` per region, then `N_t = C_t I_t / sum * N_L` (the WGSL's order).
    let total = fd
        .tiles
        .masses(px.n, s.strategy == Strategy::Paper, density);
    let k2 = fd.dist.grid.per_face();
    if k2 > 1 && s.tile_counts == TileCounts::Face {
        for f in 0..6 {
            face_tile_samples(px, rng, w, f, total, &mut density[f * k2..][..k2], sum, st);
        }
        return;
    }
    for (r, dens) in density[..regions].iter_mut().enumerate() {
        let mu = if total > 0.0 { *dens / total } else { 0.0 };
        let c = face_count(mu * px.nl as f32, w.len, s.counts);
        *dens = c.density;
        for (k, slot) in w.slots().take(c.taken).enumerate() {
            let weight = if k + 1 == c.taken { c.last_weight } else { 1.0 };
            pool_sample(px, r, slot, weight, c.density, sum, st);
        }
    }
}

/// [`TileCounts::Face`] for face `f`, whose tiles' masses `C_t I_t` are `tiles` (overwritten by
/// their densities `N_f C_t I_t / sum over the face`): the face's count `N_f`, each sample's tile
/// drawn with one random number ([`draw_tile`]), the tile's next slot in the window.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn face_tile_samples<B: LocalBsdf>(
    px: &Pixel<B>,
    rng: &mut Rng,
    w: PoolWindow,
    f: usize,
    total: f32,
    tiles: &mut [f32],
    sum: &mut impl Sink,
    st: &mut PixelStats,
) {
    let k2 = tiles.len();
    let mut mass = [0.0f32; MAX_TILES * MAX_TILES];
    mass[..k2].copy_from_slice(tiles);
    let face_mass: f32 = tiles.iter().sum();
    let mu = if total > 0.0 { face_mass / total } else { 0.0 };
    let c = face_count(mu * px.nl as f32, w.len, px.s.counts);
    for (d, &m) in tiles.iter_mut().zip(&mass) {
        *d = if face_mass > 0.0 {
            c.density * (m / face_mass)
        } else {
            0.0
        };
    }
    for (k, slot) in w.slots().take(c.taken).enumerate() {
        let Some(t) = draw_tile(&mass[..k2], face_mass, rng.next_f32()) else {
            return;
        };
        let weight = if k + 1 == c.taken { c.last_weight } else { 1.0 };
        pool_sample(px, f * k2 + t, slot, weight, tiles[t], sum, st);
    }
}

/// Pool slot `slot` of region `r` as a light sample of weight `weight` from a region sampled
/// with density `density` (`N_t`); an empty slot contributes nothing.
#[inline(always)]
fn pool_sample<B: LocalBsdf>(
    px: &Pixel<B>,
    r: usize,
    slot: usize,
    weight: f32,
    density: f32,
    sum: &mut impl Sink,
    st: &mut PixelStats,
) {
    let ls = px.fd.pool.get(r, slot);
    if ls.pdf <= 0.0 {
        return;
    }
    let radiance = || px.fd.radiance(ls.dir, ls.radiance);
    px.light_sample(ls.dir, radiance, weight, density * ls.pdf, sum, st);
}

/// The pbrt-style baseline's light samples: N_L draws from one lat-long distribution.
#[inline(always)]
pub(super) fn global_samples<B: LocalBsdf>(
    px: &Pixel<B>,
    rng: &mut Rng,
    sum: &mut impl Sink,
    st: &mut PixelStats,
) {
    let (fd, nl) = (px.fd, px.nl);
    let Some(g) = fd.global.as_ref() else {
        return; // FrameData::prepare builds it for Strategy::Global
    };
    st.available = nl as u32;
    for _ in 0..nl {
        let u = Vec2::new(rng.next_f32(), rng.next_f32());
        let Some((d, p)) = g.sample(u) else { continue };
        // Weight 1: 1 * cos is cos exactly, so this is the plain one-sample estimate.
        px.light_sample(
            d,
            || fd.radiance(d, fd.map.lookup(d)),
            1.0,
            nl as f32 * p,
            sum,
            st,
        );
    }
}
