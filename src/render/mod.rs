//! The CPU renderer (the oracle for the GPU pipeline): per-frame distribution + pool build, then
//! deferred shading of a G-buffer with one of four estimators, in parallel and deterministic for a
//! given seed (every pixel has its own random stream).

pub mod output;
pub mod reference;
pub mod scene;

use crate::envmap::CubeMap;
use crate::error::{Error, Result};
use crate::sampling::rng::{Rng, hash};
use crate::sampling::warp::Frame;
use crate::sampling::{
    Counts, CubeDistribution, GlobalDistribution, Heuristic, LANES, LightPool, LocalBsdf,
    face_count, face_weights, mis,
};
use glam::{Vec2, Vec3};
use rayon::prelude::*;
pub use scene::{GPixel, sphere_gbuffer};

/// Which estimator shades the pixels. The same lowercase names serve the command line
/// (`--strategy`), scene files (`strategy = "paper"`), JSON output and the demo panel.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum Strategy {
    /// The seed's method: per-pixel face weighting (light energy x pseudo form factor) of the
    /// shared pool, N_L light + N_B BRDF samples combined by MIS.
    Paper,
    /// pbrt-style: one lat-long distribution for the whole sphere, N_L samples per pixel, MIS
    /// with N_B BRDF samples.
    Global,
    /// Light only: N_L + N_B pool samples spread over faces by face energy alone (no cosine).
    Light,
    /// BRDF only: N_L + N_B BRDF samples.
    Brdf,
}

crate::vocab::display_as_value_enum!(Strategy);

/// Sampling settings of a render.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Settings {
    /// N_L.
    pub light_samples: usize,
    /// N_B.
    pub brdf_samples: usize,
    /// M: pool samples per face (0 = N_L).
    pub pool_size: usize,
    pub strategy: Strategy,
    pub counts: Counts,
    pub mis: Heuristic,
    pub seed: u32,
    /// Start each pixel at a random offset into the pool (decorrelates pixels).
    pub pixel_offset: bool,
    /// Let each pixel's material choose the split of the `N_L + N_B` budget (`paper` only): see
    /// [`budget_for`].
    pub material_budget: bool,
}

/// Phong exponents from here up, and GGX roughness from here down, count as near-mirror lobes.
pub const NEAR_MIRROR_EXPONENT: f32 = 1000.0;
pub const NEAR_MIRROR_ALPHA: f32 = 0.02;

/// The material-driven split of a pixel's budget `(N_L, N_B)` (the `paper` strategy with
/// [`Settings::material_budget`]):
/// - diffuse only (no glossy lobe): all `N_L + N_B` samples from the light pool. Light sampling
///   with face weighting covers every direction the cosine lobe reaches, so it is unbiased alone,
///   and the accuracy sweep shows light samples beat BRDF samples on diffuse at every budget.
/// - a near-mirror lobe with no diffuse part: all samples from the BRDF. Light samples almost never
///   land in the lobe, and the BRDF pdf covers its whole support.
/// - otherwise the user's split, combined by MIS.
///
/// Each choice is an unbiased estimator on its own, so mixing them per pixel stays unbiased.
#[inline]
pub fn budget_for(m: &crate::sampling::Material, nl: usize, nb: usize) -> (usize, usize) {
    use crate::sampling::Lobe;
    let near_mirror = match m.lobe {
        Lobe::None => false,
        Lobe::Phong { exponent } => exponent >= NEAR_MIRROR_EXPONENT,
        Lobe::Ggx { alpha } => alpha <= NEAR_MIRROR_ALPHA,
    };
    if m.lobe == Lobe::None || m.ks.max_element() <= 0.0 {
        (nl + nb, 0)
    } else if near_mirror && m.kd.max_element() <= 0.0 {
        (0, nl + nb)
    } else {
        (nl, nb)
    }
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            light_samples: 32,
            brdf_samples: 32,
            pool_size: 0,
            strategy: Strategy::Paper,
            counts: Counts::Fractional,
            mis: Heuristic::Balance,
            seed: 0,
            pixel_offset: false,
            material_budget: false,
        }
    }
}

impl Settings {
    /// Refuse settings that cannot produce an estimate.
    pub fn validate(&self) -> Result<()> {
        if self.light_samples == 0 && self.brdf_samples == 0 {
            return Err(Error::invalid(
                "--light-samples and --brdf-samples are both 0: nothing to estimate with",
            ));
        }
        if self.light_samples > 1 << 16 || self.brdf_samples > 1 << 16 || self.pool_size > 1 << 20 {
            return Err(Error::invalid(
                "sample counts above 65536 per pixel (or a pool above 2^20 per face) are refused",
            ));
        }
        Ok(())
    }
    /// M, the samples per face in the pool.
    pub fn pool_per_face(&self) -> usize {
        let all = self.strategy == Strategy::Light
            || (self.strategy == Strategy::Paper && self.material_budget);
        if self.pool_size > 0 {
            self.pool_size
        } else {
            self.light_samples.max(1) + if all { self.brdf_samples } else { 0 }
        }
    }
}

/// The light pool's seed for a render seed (shared with the GPU backend, so both draw one pool).
pub fn pool_seed(seed: u32) -> u32 {
    hash(seed ^ 0xA511_E9B3)
}

/// Everything built once per environment frame.
pub struct FrameData<'a> {
    pub map: &'a CubeMap,
    pub dist: CubeDistribution,
    pub energies: [f64; 6],
    pub pool: LightPool,
    pub global: Option<GlobalDistribution>,
    /// Per cube texel, radiance and `pdf_area` interleaved (`(r, g, b, p)`), so a BRDF-sampled
    /// direction costs one memory access for both its radiance and its light density.
    pub texels: Vec<glam::Vec4>,
}

impl<'a> FrameData<'a> {
    pub fn prepare(map: &'a CubeMap, s: &Settings) -> Self {
        let dist = CubeDistribution::build(map);
        let energies = dist.energies();
        let pool = if matches!(s.strategy, Strategy::Paper | Strategy::Light) {
            LightPool::build(map, &dist, s.pool_per_face(), pool_seed(s.seed))
        } else {
            LightPool {
                per_face: 0,
                samples: Vec::new(),
            }
        };
        let global = (s.strategy == Strategy::Global).then(|| GlobalDistribution::build(map));
        let nn = map.size * map.size;
        let texels = map
            .data
            .iter()
            .enumerate()
            .map(|(i, c)| c.extend(dist.faces[i / nn].pdf_area[i % nn]))
            .collect();
        FrameData {
            map,
            dist,
            energies,
            pool,
            global,
            texels,
        }
    }
}

/// Per-pixel sample accounting (the seed's red / green / yellow).
#[derive(Clone, Copy, Debug, Default)]
pub struct PixelStats {
    /// Light samples available to the pixel (6 M for the pool, N_L for `global`).
    pub available: u32,
    /// Light samples used with a positive cosine.
    pub green: u32,
    /// Light samples used with a non-positive cosine (wasted).
    pub yellow: u32,
    /// BRDF samples drawn.
    pub brdf: u32,
}

impl PixelStats {
    pub fn red(&self) -> u32 {
        self.available.saturating_sub(self.green + self.yellow)
    }
}

/// One pixel's estimate of `L(p, o) = integral of f(o, w) <n, w>+ L(w) dw`.
///
/// On x86-64 CPUs with AVX2 and FMA this runs a copy of the same code compiled for them (LLVM
/// vectorises the sample loops 8 wide). Rust never fuses a multiply and an add on its own, so
/// both copies round identically: the result does not depend on the CPU. `ENVIS_PORTABLE=1`
/// forces the baseline copy (for comparisons).
pub fn shade_pixel(
    fd: &FrameData,
    s: &Settings,
    px: &GPixel,
    pixel_index: u32,
) -> (Vec3, PixelStats) {
    #[cfg(target_arch = "x86_64")]
    if simd::enabled() {
        // SAFETY: the CPU supports the features `shade_pixel_avx2` is compiled for.
        return unsafe { simd::shade_pixel_avx2(fd, s, px, pixel_index) };
    }
    shade_pixel_portable(fd, s, px, pixel_index)
}

#[cfg(target_arch = "x86_64")]
mod simd {
    use super::*;
    /// AVX2 + FMA present and `ENVIS_PORTABLE` unset (decided once per process).
    #[inline]
    pub fn enabled() -> bool {
        static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
        *ON.get_or_init(|| {
            std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
                && std::env::var_os("ENVIS_PORTABLE").is_none()
        })
    }
    #[target_feature(enable = "avx2,fma")]
    pub fn shade_pixel_avx2(
        fd: &FrameData,
        s: &Settings,
        px: &GPixel,
        pixel_index: u32,
    ) -> (Vec3, PixelStats) {
        shade_pixel_portable(fd, s, px, pixel_index)
    }
}

/// [`shade_pixel`] compiled for the baseline target.
#[inline(always)]
fn shade_pixel_portable(
    fd: &FrameData,
    s: &Settings,
    px: &GPixel,
    pixel_index: u32,
) -> (Vec3, PixelStats) {
    let n = px.n.normalize_or_zero();
    let o = px.o.normalize_or_zero();
    if n == Vec3::ZERO || o == Vec3::ZERO || n.dot(o) <= 0.0 || px.material.is_black() {
        return (Vec3::ZERO, PixelStats::default());
    }
    // A diffuse-only pixel runs the same code compiled for `Lambert` (no lobe dispatch per
    // sample); the results are bit-identical to the general `Material` path.
    match px.material.as_lambert() {
        Some(lambert) => shade_with(fd, s, &px.material, &lambert, n, o, pixel_index),
        None => shade_with(fd, s, &px.material, &px.material, n, o, pixel_index),
    }
}

/// [`shade_pixel`] for a visible pixel (unit `n`, `o`, `<n, o> > 0`) with BRDF `bsdf` (the
/// pixel's `material`, or a specialised view of it).
#[inline(always)]
fn shade_with<B: LocalBsdf>(
    fd: &FrameData,
    s: &Settings,
    material: &crate::sampling::Material,
    bsdf: &B,
    n: Vec3,
    o: Vec3,
    pixel_index: u32,
) -> (Vec3, PixelStats) {
    let mut st = PixelStats::default();
    let frame = Frame::new(n);
    let ol = frame.to_local(o);
    let mat = bsdf;
    let mut rng = Rng::new(s.seed, pixel_index);
    let mut sum = Vec3::ZERO;
    let (nl, nb) = match s.strategy {
        Strategy::Paper if s.material_budget => {
            budget_for(material, s.light_samples, s.brdf_samples)
        }
        Strategy::Paper | Strategy::Global => (s.light_samples, s.brdf_samples),
        Strategy::Light => (s.light_samples + s.brdf_samples, 0),
        Strategy::Brdf => (0, s.light_samples + s.brdf_samples),
    };
    let nb_f = nb as f32;
    let size = fd.map.size;
    // Light-sample density on each face (N_f, clamped to the pool): `n_L(w) = density[f] p_f(w)`.
    let mut density = [0.0f32; 6];

    match s.strategy {
        Strategy::Paper | Strategy::Light => {
            let m = fd.pool.per_face;
            st.available = (6 * m) as u32;
            let fw = face_weights(n, &fd.energies, s.strategy == Strategy::Paper);
            let offset = if s.pixel_offset && m > 0 {
                rng.next_u32() as usize % m
            } else {
                0
            };
            for (f, dens) in density.iter_mut().enumerate() {
                let c = face_count(fw.mu[f] * nl as f32, m, s.counts);
                *dens = c.density;
                // Pool index (offset + k) mod m, kept in range without a division per sample.
                let mut idx = offset;
                for k in 0..c.taken {
                    let ls = fd.pool.get(f, idx);
                    idx += 1;
                    if idx == m {
                        idx = 0;
                    }
                    if ls.pdf <= 0.0 {
                        continue;
                    }
                    let cos = n.dot(ls.dir);
                    if cos <= 0.0 {
                        st.yellow += 1;
                        continue;
                    }
                    st.green += 1;
                    let weight = if k + 1 == c.taken { c.last_weight } else { 1.0 };
                    let il = frame.to_local(ls.dir);
                    let n_l = c.density * ls.pdf;
                    let n_b = if nb > 0 {
                        nb_f * mat.pdf_local(ol, il)
                    } else {
                        0.0
                    };
                    sum += mat.eval_local(ol, il)
                        * ls.radiance
                        * (weight * cos * mis::weight_over_density(s.mis, n_l, n_b));
                }
            }
        }
        Strategy::Global => {
            let g = fd
                .global
                .as_ref()
                .expect("global distribution built for Strategy::Global");
            st.available = nl as u32;
            for _ in 0..nl {
                let u = Vec2::new(rng.next_f32(), rng.next_f32());
                let Some((d, p)) = g.sample(u) else { continue };
                let cos = n.dot(d);
                if cos <= 0.0 {
                    st.yellow += 1;
                    continue;
                }
                st.green += 1;
                let il = frame.to_local(d);
                let n_l = nl as f32 * p;
                let n_b = if nb > 0 {
                    nb_f * mat.pdf_local(ol, il)
                } else {
                    0.0
                };
                sum += mat.eval_local(ol, il)
                    * fd.map.lookup(d)
                    * (cos * mis::weight_over_density(s.mis, n_l, n_b));
            }
        }
        Strategy::Brdf => {}
    }

    // BRDF samples in chunks of LANES, structure of arrays: pass 1 draws the local directions
    // (vectorised for a branch-free sampler), pass 2 turns them into world directions, texels
    // and cube Jacobians (vectorised), pass 3 prefetches the texels, pass 4 loads them and
    // shades. The loads are independent, so they overlap instead of stalling one by one. Same
    // random draws, same arithmetic, same summation order as one scalar loop.
    let mut smp = crate::sampling::SampleLanes::default();
    let mut hit = HitLanes::default();
    let n_size = size as u32;
    let mut left = nb;
    while left > 0 {
        let count = left.min(LANES);
        left -= count;
        st.brdf += count as u32;
        mat.sample_lanes(ol, &mut rng, count, &mut smp);
        for k in 0..LANES {
            let d = frame.to_world(smp.dir(k));
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
            // One texel gives both the radiance and the light density of the direction.
            let t = fd.texels[hit.texel[k] as usize];
            let n_l = match s.strategy {
                Strategy::Paper => density[hit.face[k] as usize] * t.w * hit.jac[k],
                Strategy::Global => {
                    nl as f32
                        * fd.global
                            .as_ref()
                            .map_or(0.0, |g| g.pdf(Vec3::new(hit.x[k], hit.y[k], hit.z[k])))
                }
                _ => 0.0,
            };
            let il = smp.dir(k);
            sum += mat.eval_local(ol, il)
                * t.truncate()
                * (il.z * mis::weight_over_density(s.mis, nb_f * p, n_l));
        }
    }
    (sum, st)
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

/// Statistics of a render, written by `--stats`.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct RenderStats {
    pub width: usize,
    pub height: usize,
    pub strategy: String,
    pub counts: String,
    pub mis: String,
    pub light_samples: usize,
    pub brdf_samples: usize,
    pub pool_per_face: usize,
    pub seed: u32,
    pub pixel_offset: bool,
    pub material_budget: bool,
    /// Distribution (CDF tables, face energies) + light-sample pool build, milliseconds.
    pub build_ms: f64,
    /// Shading of all pixels, milliseconds.
    pub shade_ms: f64,
    /// Pixels with geometry.
    pub shaded_pixels: u64,
    /// Light samples used + BRDF samples drawn, over all pixels.
    pub samples_evaluated: u64,
    /// BRDF samples drawn, over all pixels (0 for a diffuse scene with `material_budget`).
    pub brdf_samples_drawn: u64,
    /// Samples evaluated per second of shading.
    pub samples_per_second: f64,
    /// Mean over shaded pixels of the fraction of available light samples discarded by face weighting.
    pub red: f64,
    /// ... used with a positive cosine.
    pub green: f64,
    /// ... used with a non-positive cosine.
    pub yellow: f64,
    /// Mean over shaded pixels of yellow / (green + yellow).
    pub wasted: f64,
    /// NaN / Inf / negative texels clamped when loading the map.
    pub clamped_texels: crate::envmap::SanitizeReport,
}

impl RenderStats {
    /// Statistics header of a render with settings `s` (timings and counts still empty).
    pub fn for_settings(width: usize, height: usize, s: &Settings, pool_per_face: usize) -> Self {
        RenderStats {
            width,
            height,
            strategy: s.strategy.to_string(),
            counts: format!("{:?}", s.counts).to_lowercase(),
            mis: format!("{:?}", s.mis).to_lowercase(),
            light_samples: s.light_samples,
            brdf_samples: s.brdf_samples,
            pool_per_face,
            seed: s.seed,
            pixel_offset: s.pixel_offset,
            material_budget: s.material_budget,
            ..Default::default()
        }
    }

    /// Fill the sample counts and red / green / yellow fractions from per-pixel statistics
    /// (`None` = no geometry); `shade_ms` must be set.
    pub fn accumulate(&mut self, per_pixel: &[Option<PixelStats>]) {
        let (mut red, mut green, mut yellow, mut wasted) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        for st in per_pixel.iter().flatten() {
            self.shaded_pixels += 1;
            self.samples_evaluated += (st.green + st.yellow + st.brdf) as u64;
            self.brdf_samples_drawn += st.brdf as u64;
            if st.available > 0 {
                let a = st.available as f64;
                red += st.red() as f64 / a;
                green += st.green as f64 / a;
                yellow += st.yellow as f64 / a;
            }
            if st.green + st.yellow > 0 {
                wasted += st.yellow as f64 / (st.green + st.yellow) as f64;
            }
        }
        let np = self.shaded_pixels.max(1) as f64;
        (self.red, self.green, self.yellow, self.wasted) =
            (red / np, green / np, yellow / np, wasted / np);
        self.samples_per_second = self.samples_evaluated as f64 / (self.shade_ms / 1e3).max(1e-9);
    }
}

/// A rendered image and its statistics.
pub struct Rendered {
    pub image: crate::envmap::Image,
    pub stats: RenderStats,
}

/// Render a G-buffer of `width x height` pixels (row-major, `None` = no geometry).
pub fn render(
    map: &CubeMap,
    gbuf: &[Option<GPixel>],
    width: usize,
    height: usize,
    s: &Settings,
) -> Result<Rendered> {
    s.validate()?;
    assert_eq!(gbuf.len(), width * height);
    let t0 = std::time::Instant::now();
    let fd = FrameData::prepare(map, s);
    let build_ms = t0.elapsed().as_secs_f64() * 1e3;
    let t1 = std::time::Instant::now();
    let out: Vec<(Vec3, Option<PixelStats>)> = gbuf
        .par_iter()
        .enumerate()
        .map(|(i, px)| match px {
            Some(p) => {
                let (c, st) = shade_pixel(&fd, s, p, i as u32);
                (c, Some(st))
            }
            None => (Vec3::ZERO, None),
        })
        .collect();
    let shade_ms = t1.elapsed().as_secs_f64() * 1e3;

    let mut stats = RenderStats::for_settings(width, height, s, fd.pool.per_face);
    stats.build_ms = build_ms;
    stats.shade_ms = shade_ms;
    let per_pixel: Vec<Option<PixelStats>> = out.iter().map(|(_, st)| *st).collect();
    stats.accumulate(&per_pixel);
    let image = crate::envmap::Image {
        width,
        height,
        data: out.into_iter().map(|(c, _)| c).collect(),
    };
    Ok(Rendered { image, stats })
}

/// How one pool sample serves a pixel (the seed's sample-debug colours).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum SampleKind {
    /// Red: not taken, discarded by face weighting (beyond the face's `ceil(N_f)`, or an empty slot).
    Discarded,
    /// Green: taken, positive cosine.
    Used,
    /// Yellow: taken, non-positive cosine (wasted).
    Wasted,
}

/// One pool sample as the pixel sees it.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct DebugSample {
    pub face: usize,
    pub dir: Vec3,
    pub kind: SampleKind,
}

/// The sample-debug view of one pixel: face weights, counts, every pool sample classified, and
/// the estimate.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PixelDebug {
    pub mu: [f32; 6],
    /// `N_f = mu_f N_L` (before clamping to the pool).
    pub n_f: [f32; 6],
    pub samples: Vec<DebugSample>,
    pub estimate: Vec3,
}

/// Classify every pool sample for pixel `px` exactly as [`shade_pixel`]'s light loop uses them
/// (same face weights, counts, offset), for the `paper` and `light` strategies.
pub fn debug_pixel(fd: &FrameData, s: &Settings, px: &GPixel, pixel_index: u32) -> PixelDebug {
    let (estimate, _) = shade_pixel(fd, s, px, pixel_index);
    let n = px.n.normalize_or_zero();
    let m = fd.pool.per_face;
    let nl = match s.strategy {
        Strategy::Light => s.light_samples + s.brdf_samples,
        Strategy::Paper if s.material_budget => {
            budget_for(&px.material, s.light_samples, s.brdf_samples).0
        }
        _ => s.light_samples,
    };
    let fw = face_weights(n, &fd.energies, s.strategy != Strategy::Light);
    let mut rng = Rng::new(s.seed, pixel_index);
    let offset = if s.pixel_offset && m > 0 {
        rng.next_u32() as usize % m
    } else {
        0
    };
    let mut samples = Vec::with_capacity(6 * m);
    let o = px.o.normalize_or_zero();
    let live = matches!(s.strategy, Strategy::Paper | Strategy::Light)
        && n != Vec3::ZERO
        && o != Vec3::ZERO
        && n.dot(o) > 0.0
        && !px.material.is_black();
    for f in 0..6 {
        let c = face_count(fw.mu[f] * nl as f32, m, s.counts);
        for j in 0..m {
            let ls = fd.pool.get(f, j);
            let k = (j + m - offset) % m; // position of slot j in this pixel's order
            let kind = if !live || k >= c.taken || ls.pdf <= 0.0 {
                SampleKind::Discarded
            } else if n.dot(ls.dir) <= 0.0 {
                SampleKind::Wasted
            } else {
                SampleKind::Used
            };
            samples.push(DebugSample {
                face: f,
                dir: ls.dir,
                kind,
            });
        }
    }
    PixelDebug {
        mu: fw.mu,
        n_f: std::array::from_fn(|f| fw.mu[f] * nl as f32),
        samples,
        estimate,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Material;

    /// The `Lambert` specialisation of the hot loops gives the general `Material` path's values
    /// bit for bit, for every strategy and both heuristics.
    #[test]
    fn lambert_path_is_bit_identical() {
        let map = crate::envmap::sky::sky_cube(16, 10.0);
        let w = 24;
        let mut gbuf = sphere_gbuffer(w, w, Material::diffuse(0.7));
        for (i, px) in gbuf.iter_mut().flatten().enumerate() {
            px.material.kd = Vec3::new(0.2 + 0.01 * (i % 50) as f32, 0.5, 0.9);
        }
        for strategy in [
            Strategy::Paper,
            Strategy::Global,
            Strategy::Light,
            Strategy::Brdf,
        ] {
            for mis in [Heuristic::Balance, Heuristic::Power] {
                let s = Settings {
                    strategy,
                    mis,
                    light_samples: 7,
                    brdf_samples: 5,
                    seed: 11,
                    pixel_offset: true,
                    ..Default::default()
                };
                let fd = FrameData::prepare(&map, &s);
                let mut lit = 0;
                for (i, px) in gbuf.iter().enumerate() {
                    let Some(px) = px else { continue };
                    let (n, o) = (px.n.normalize(), px.o.normalize());
                    let lambert = px.material.as_lambert().unwrap();
                    let (a, sa) = shade_with(&fd, &s, &px.material, &lambert, n, o, i as u32);
                    let (b, sb) = shade_with(&fd, &s, &px.material, &px.material, n, o, i as u32);
                    assert_eq!(
                        a.to_array().map(f32::to_bits),
                        b.to_array().map(f32::to_bits),
                        "{strategy:?} {mis:?} pixel {i}"
                    );
                    assert_eq!(
                        (sa.green, sa.yellow, sa.brdf),
                        (sb.green, sb.yellow, sb.brdf)
                    );
                    lit += (a.max_element() > 0.0) as usize;
                }
                assert!(lit > 100, "{strategy:?}: only {lit} lit pixels");
            }
        }
    }

    /// The dispatching `shade_pixel` (the AVX2 + FMA copy on CPUs that have them) and the
    /// baseline copy agree bit for bit on every material kind.
    #[test]
    fn simd_copy_is_bit_identical() {
        let map = crate::envmap::sky::sky_cube(16, 10.0);
        for mat in [
            Material::diffuse(0.8),
            Material::phong(0.9, 150.0),
            Material::ggx(0.9, 0.3),
            Material {
                kd: Vec3::splat(0.4),
                ks: Vec3::splat(0.5),
                lobe: crate::sampling::Lobe::Ggx { alpha: 0.1 },
            },
        ] {
            let gbuf = sphere_gbuffer(20, 20, mat);
            for strategy in [Strategy::Paper, Strategy::Global] {
                let s = Settings {
                    strategy,
                    light_samples: 9,
                    brdf_samples: 19,
                    seed: 4,
                    ..Default::default()
                };
                let fd = FrameData::prepare(&map, &s);
                for (i, px) in gbuf.iter().enumerate() {
                    let Some(px) = px else { continue };
                    let (a, _) = shade_pixel(&fd, &s, px, i as u32);
                    let (b, _) = shade_pixel_portable(&fd, &s, px, i as u32);
                    assert_eq!(
                        a.to_array().map(f32::to_bits),
                        b.to_array().map(f32::to_bits),
                        "{mat:?} {strategy:?} pixel {i}"
                    );
                }
            }
        }
    }
}
