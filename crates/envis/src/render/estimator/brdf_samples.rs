//! The pixel's N_B BRDF samples, drawn and shaded on lanes: the twin of `brdf_samples` in
//! `shaders/shade.wgsl` (which draws one sample at a time: the GPU's lanes are its pixels).

use super::*;

/// The N_B BRDF samples, in chunks of LANES, structure of arrays: pass 1 draws the local
/// directions (vectorised for a branch-free sampler), pass 2 turns them into world directions,
/// texels and cube Jacobians (vectorised), pass 3 prefetches the texels, pass 4 loads them and
/// shades. The loads are independent, so they overlap instead of stalling one by one. Same
/// random draws, same arithmetic, same summation order as one scalar loop.
#[inline(always)]
pub(super) fn brdf_samples<B: LocalBsdf>(
    px: &Pixel<B>,
    rng: &mut Rng,
    density: &[f32; MAX_REGIONS],
    sum: &mut impl Sink,
    st: &mut PixelStats,
) {
    let (fd, s, mat, ol) = (px.fd, px.s, px.bsdf, px.ol);
    let nb_f = px.nb as f32;
    let mut smp = crate::sampling::SampleLanes::default();
    let mut hit = HitLanes::default();
    let n_size = fd.map.size as u32;
    let tiles_k = fd.dist.grid.k as u32;
    let mut left = px.nb;
    while left > 0 {
        let count = left.min(LANES);
        left -= count;
        st.brdf += count as u32;
        mat.sample_lanes(ol, rng, count, &mut smp);
        for k in 0..LANES {
            let d = px.frame.to_world(smp.dir(k));
            let (face, a, b, texel) = crate::envmap::dir_to_texel_lane(d.x, d.y, d.z, n_size);
            let q = 1.0 + a * a + b * b;
            (hit.x[k], hit.y[k], hit.z[k]) = (d.x, d.y, d.z);
            (hit.face[k], hit.texel[k], hit.jac[k]) = (face, texel, q * q.sqrt());
        }
        for k in 0..count {
            prefetch(&fd.texels[hit.texel[k] as usize]);
        }
        for k in 0..count {
            let p = smp.pdf[k];
            if p <= 0.0 {
                continue;
            }
            // One texel gives both the radiance and the light density of the direction; with
            // sub-texels one fine texel gives both radiance and the density's factor.
            let t = fd.texels[hit.texel[k] as usize];
            let d = Vec3::new(hit.x[k], hit.y[k], hit.z[k]);
            let (fine, factor) = match &fd.sub {
                Some(sub) => {
                    let (l, f) = sub.radiance_and_factor(d);
                    (Some(l), f)
                }
                None => (None, 1.0),
            };
            let n_l = light_density(px, density, &hit, k, (t.w, factor), tiles_k);
            let il = smp.dir(k);
            if px.blocked(d, st) {
                continue;
            }
            // The value the sampler computed with the sample (`LocalBsdf::sample_lanes`).
            let scale = il.z * mis::weight_over_density(s.heuristic, nb_f * p, n_l);
            let l = fine.unwrap_or_else(|| fd.radiance(d, t.truncate()));
            sum.add(d, smp.value(k) * l, il.z, scale);
        }
    }
}

/// The light technique's density `n_L` in the direction of BRDF sample `k` of `hit`, whose
/// texel's `pdf_area` and sub-texel factor (1 when the pool was not refined) are `(pdf_area,
/// factor)`: the pixel's region density times the light pdf there, or the `global` baseline's.
#[inline(always)]
fn light_density<B: LocalBsdf>(
    px: &Pixel<B>,
    density: &[f32; MAX_REGIONS],
    hit: &HitLanes,
    k: usize,
    (pdf_area, factor): (f32, f32),
    tiles_k: u32,
) -> f32 {
    let fd = px.fd;
    match px.s.strategy {
        Strategy::Paper => {
            // With one tile per face the region is the face (no divisions).
            let r = match tiles_k {
                1 => hit.face[k],
                _ => region_of_texel(hit.texel[k], fd.map.size as u32, tiles_k),
            };
            // Multiplying by a factor of 1 is exact: unrefined renders are unchanged.
            density[r as usize] * pdf_area * hit.jac[k] * factor
        }
        Strategy::Global => {
            let d = Vec3::new(hit.x[k], hit.y[k], hit.z[k]);
            px.nl as f32 * fd.global.as_ref().map_or(0.0, |g| g.pdf(d))
        }
        _ => 0.0,
    }
}

/// World directions, faces, texels and cube Jacobians of a chunk of BRDF samples.
#[derive(Default)]
struct HitLanes {
    x: [f32; LANES],
    y: [f32; LANES],
    z: [f32; LANES],
    face: [u32; LANES],
    texel: [u32; LANES],
    jac: [f32; LANES],
}

/// The region ([`crate::sampling::TileGrid::region`]) of cube texel `texel` (index into the map's
/// data) of faces `n` texels wide cut into `k x k` tiles.
#[inline(always)]
fn region_of_texel(texel: u32, n: u32, k: u32) -> u32 {
    let (face, rest) = (texel / (n * n), texel % (n * n));
    let (row, col) = (rest / n, rest % n);
    face * k * k + (row * k / n) * k + col * k / n
}

/// Hint the CPU to start loading `x`'s cache line (no effect on results; a no-op off x86-64).
#[inline(always)]
fn prefetch<T>(x: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: prefetching is a hint; it never faults and reads nothing observable. The pointer
    // comes from a live reference.
    unsafe {
        std::arch::x86_64::_mm_prefetch(x as *const T as *const i8, std::arch::x86_64::_MM_HINT_T0)
    };
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}
