//! The estimator: one pixel's Monte Carlo estimate of the reflected environment light, from the
//! frame's light pool (or the global distribution) and the pixel's BRDF samples, combined by MIS.
//! The twin of `shaders/shade.wgsl`.

use super::{GPixel, PixelStats, PoolLayout, Settings, Strategy, pool_seed};
use crate::envmap::CubeMap;
use crate::sampling::SubTexels;
use crate::sampling::rng::Rng;
use crate::sampling::tiles::draw_tile;
use crate::sampling::warp::Frame;
use crate::sampling::{
    CubeDistribution, GlobalDistribution, LANES, LightPool, LocalBsdf, MAX_REGIONS, MAX_TILES,
    TileCounts, TileWeights, face_count, mis,
};
use glam::{Vec2, Vec3};

mod brdf_samples;
mod light_samples;
mod pool_window;
use brdf_samples::brdf_samples;
use light_samples::{global_samples, light_pool_samples};
pub use pool_window::{PoolWindow, pool_window};

/// Radiance of the environment at full resolution, by direction (see [`FrameData::fine`]).
pub type FineRadiance<'a> = &'a (dyn Fn(Vec3) -> Vec3 + Sync);

/// Where a pixel's samples go: summed into its estimate ([`Vec3`]), or streamed into a
/// reservoir as resampling candidates ([`super::resampling`]). Each sample reports its direction,
/// `fl` (BRDF x radiance), its cosine and `scale`, so that its contribution is `fl * scale`
/// (`scale` = weight x cosine x MIS weight over density): the Vec3 sink adds exactly that, in the
/// same order of operations as before there were sinks (renders bit-identical).
pub trait Sink {
    fn add(&mut self, dir: Vec3, fl: Vec3, cos: f32, scale: f32);
}

impl Sink for Vec3 {
    #[inline(always)]
    fn add(&mut self, _dir: Vec3, fl: Vec3, _cos: f32, scale: f32) {
        *self += fl * scale;
    }
}

/// Everything built once per environment frame.
pub struct FrameData<'a> {
    pub map: &'a CubeMap,
    /// Where radiance is read when the distribution (`map`) is a coarser copy of the environment:
    /// light samples, global samples and BRDF samples then take their radiance from here, their
    /// densities still from `map`. Unbiased as long as every direction with radiance here has a
    /// positive density in `map` (a coarse texel built from its fine texels is positive wherever
    /// one of them is), or is reached by the BRDF samples. `None`: radiance is `map`'s.
    pub fine: Option<FineRadiance<'a>>,
    /// The second level of the light density over the map at its own resolution
    /// ([`crate::sampling::subtexel`]): the pool's samples refined to its texels, and BRDF
    /// samples' light densities taking its factor; every sample's radiance is read from its map
    /// (a BRDF sample's in the same lookup as its factor). `None`: uniform inside the `map`'s
    /// texels.
    pub sub: Option<SubTexels<'a>>,
    /// The scene's shadow rays: a light or BRDF sample it blocks contributes nothing. `None`:
    /// nothing occludes (no rays are cast).
    pub occluder: Option<&'a dyn crate::visibility::Occluder>,
    pub dist: CubeDistribution,
    /// The corners and energies of the faces' tiles (`K = 1`: the faces): the per-pixel weights.
    pub tiles: TileWeights,
    pub pool: LightPool,
    pub global: Option<GlobalDistribution>,
    /// Per cube texel, radiance and `pdf_area` interleaved (`(r, g, b, p)`), so a BRDF-sampled
    /// direction costs one memory access for both its radiance and its light density.
    pub texels: Vec<glam::Vec4>,
}

impl<'a> FrameData<'a> {
    pub fn prepare(map: &'a CubeMap, s: &Settings) -> Self {
        let dist = CubeDistribution::build_tiled(map, s.tiles);
        let tiles = TileWeights::new(dist.grid, &dist.region_energies());
        let pool = if matches!(s.strategy, Strategy::Paper | Strategy::Light) {
            LightPool::build_blocks(
                map,
                &dist,
                s.pool_per_face(),
                s.pool_block_count(),
                pool_seed(s.seed),
            )
        } else {
            LightPool {
                per_region: 0,
                block: 0,
                samples: Vec::new(),
            }
        };
        let global = (s.strategy == Strategy::Global).then(|| GlobalDistribution::build(map));
        let n = map.size;
        let texels = map
            .data
            .chunks(n * n)
            .zip(&dist.faces)
            .flat_map(|(face, fd)| {
                face.iter()
                    .enumerate()
                    .map(|(t, c)| c.extend(fd.pdf_area(t % n, t / n)))
            })
            .collect();
        FrameData {
            map,
            fine: None,
            sub: None,
            occluder: None,
            dist,
            tiles,
            pool,
            global,
            texels,
        }
    }

    /// Read radiance from `fine` instead of `map` (the Bevy pass reads the full-resolution image).
    pub fn with_fine(mut self, fine: FineRadiance<'a>) -> Self {
        self.fine = Some(fine);
        self
    }

    /// Sample the light inside `map`'s texels by the luminance of `fine`'s
    /// ([`crate::sampling::subtexel`]): refine the pool, and keep the factor for the BRDF
    /// samples' MIS. Every sample's radiance is then read from `fine` ([`Self::radiance`]), so
    /// densities and radiance come from the same map. No change where `fine` is not a whole
    /// multiple of `map`'s face size.
    pub fn with_sub_texels(mut self, fine: &'a CubeMap) -> Self {
        self.sub = SubTexels::new(fine, self.map.size);
        if let Some(sub) = &self.sub {
            sub.refine_pool(&self.dist, &mut self.pool);
        }
        self
    }

    /// The radiance in direction `d`, given `map`'s value there: from the sub-texels' map when
    /// the pool was refined, else from `fine`, else `coarse`.
    #[inline(always)]
    pub fn radiance(&self, d: Vec3, coarse: Vec3) -> Vec3 {
        match (&self.sub, self.fine) {
            (Some(sub), _) => sub.fine.lookup(d),
            (None, Some(f)) => f(d),
            (None, None) => coarse,
        }
    }
}

/// One pixel's estimate of `L(p, o) = integral of f(o, w) <n, w>+ L(w) dw`.
///
/// On x86-64 CPUs with AVX2 and FMA this runs a copy of the same code compiled for them (LLVM
/// vectorises the sample loops 8 wide), and on those with AVX-512 one compiled for that (16
/// wide: one register per lane chunk). Rust never fuses a multiply and an add on its own, so
/// the copies round identically: the result does not depend on the CPU. `ENVIS_ISA` or
/// `ENVIS_PORTABLE=1` caps the choice (for comparisons; [`crate::cpu::isa`]).
pub fn shade_pixel(
    fd: &FrameData,
    s: &Settings,
    px: &GPixel,
    pixel_index: u32,
) -> (Vec3, PixelStats) {
    shade_pixel_at(fd, s, px, None, pixel_index)
}

/// [`shade_pixel`] for a pixel whose surface point is `at`: with `fd.occluder`, every light and
/// BRDF sample above the horizon casts a shadow ray from there.
pub fn shade_pixel_at(
    fd: &FrameData,
    s: &Settings,
    px: &GPixel,
    at: Option<Vec3>,
    pixel_index: u32,
) -> (Vec3, PixelStats) {
    shade_pixel_on(crate::cpu::isa(), fd, s, px, at, pixel_index)
}

/// [`shade_pixel_at`] run by the copy compiled for `isa`, or by the best the CPU supports where
/// that is less ([`crate::cpu::detected`]).
pub fn shade_pixel_on(
    isa: crate::cpu::Isa,
    fd: &FrameData,
    s: &Settings,
    px: &GPixel,
    at: Option<Vec3>,
    pixel_index: u32,
) -> (Vec3, PixelStats) {
    let mut sum = Vec3::ZERO;
    let st = shade_pixel_into(isa, fd, s, px, at, pixel_index, &mut sum);
    (sum, st)
}

/// [`shade_pixel_on`] with the samples sent to `sink` instead of summed (the resampling
/// candidates: [`super::resampling`]).
pub fn shade_pixel_into<S: Sink>(
    isa: crate::cpu::Isa,
    fd: &FrameData,
    s: &Settings,
    px: &GPixel,
    at: Option<Vec3>,
    pixel_index: u32,
    sink: &mut S,
) -> PixelStats {
    use crate::cpu::Isa;
    #[cfg(target_arch = "x86_64")]
    match isa.min(crate::cpu::detected()) {
        // SAFETY (both): the CPU supports the copy's features (`detected`).
        Isa::Avx512 => {
            return unsafe { simd::shade_pixel_avx512(fd, s, px, at, pixel_index, sink) };
        }
        Isa::Avx2 => return unsafe { simd::shade_pixel_avx2(fd, s, px, at, pixel_index, sink) },
        Isa::Portable => {}
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = isa;
    shade_pixel_portable(fd, s, px, at, pixel_index, sink)
}

#[cfg(target_arch = "x86_64")]
mod simd {
    use super::*;

    /// A copy of [`shade_pixel_portable`] compiled with the target features `$features`.
    macro_rules! compiled_for {
        ($name:ident, $features:literal) => {
            #[target_feature(enable = $features)]
            pub fn $name<S: Sink>(
                fd: &FrameData,
                s: &Settings,
                px: &GPixel,
                at: Option<Vec3>,
                pixel_index: u32,
                sink: &mut S,
            ) -> PixelStats {
                shade_pixel_portable(fd, s, px, at, pixel_index, sink)
            }
        };
    }

    compiled_for!(shade_pixel_avx2, "avx2,fma");
    compiled_for!(
        shade_pixel_avx512,
        "avx512f,avx512vl,avx512bw,avx512dq,avx2,fma"
    );
}

/// [`shade_pixel`] compiled for the baseline target.
#[inline(always)]
fn shade_pixel_portable(
    fd: &FrameData,
    s: &Settings,
    px: &GPixel,
    at: Option<Vec3>,
    pixel_index: u32,
    sink: &mut impl Sink,
) -> PixelStats {
    let Some((n, o)) = shading_directions(px) else {
        return PixelStats::default();
    };
    let material = &px.material;
    // Shadow rays only where there is an occluder and a point to cast them from; what the
    // pixel's rays share is set up once here.
    let shadow = fd
        .occluder
        .zip(at)
        .map(|(occ, p)| (occ, occ.at_point(p, n)));
    // A diffuse-, GGX- or Phong-only pixel runs the same code compiled for `Lambert`, `Ggx` or
    // `Phong` (no lobe dispatch per sample; BRDF samples drawn on all lanes at once where the
    // sampler is branch-free); the results are bit-identical to the general `Material` path.
    let dirs = (n, o, shadow);
    if let Some(lambert) = material.as_lambert() {
        shade_with(fd, s, material, &lambert, dirs, pixel_index, sink)
    } else if let Some(ggx) = material.as_ggx() {
        shade_with(fd, s, material, &ggx, dirs, pixel_index, sink)
    } else if let Some(phong) = material.as_phong() {
        shade_with(fd, s, material, &phong, dirs, pixel_index, sink)
    } else {
        shade_with(fd, s, material, material, dirs, pixel_index, sink)
    }
}

/// A shadow-casting scene and the point its rays leave from.
type Shadow<'a> = Option<(
    &'a dyn crate::visibility::Occluder,
    crate::visibility::ShadowPoint,
)>;

/// What the sample loops of one visible pixel share.
struct Pixel<'a, B> {
    fd: &'a FrameData<'a>,
    s: &'a Settings,
    bsdf: &'a B,
    frame: Frame,
    n: Vec3,
    /// The view direction in the shading frame.
    ol: Vec3,
    /// N_L and N_B for this pixel.
    nl: usize,
    nb: usize,
    shadow: Shadow<'a>,
}

impl<B: LocalBsdf> Pixel<'_, B> {
    /// One light sample in direction `dir` (radiance from `radiance`, read only when the
    /// sample is above the horizon), of weight `weight` and light density `n_l`: counted green
    /// or yellow, and added to `sum` with its MIS weight against the pixel's BRDF samples.
    #[inline(always)]
    fn light_sample(
        &self,
        dir: Vec3,
        radiance: impl FnOnce() -> Vec3,
        weight: f32,
        n_l: f32,
        sum: &mut impl Sink,
        st: &mut PixelStats,
    ) {
        let cos = self.n.dot(dir);
        if cos <= 0.0 {
            st.yellow += 1;
            return;
        }
        if self.blocked(dir, st) {
            st.blocked += 1;
            return;
        }
        st.green += 1;
        let il = self.frame.to_local(dir);
        let (f, n_b) = if self.nb > 0 {
            let (f, p) = self.bsdf.eval_pdf_local(self.ol, il);
            (f, self.nb as f32 * p)
        } else {
            (self.bsdf.eval_local(self.ol, il), 0.0)
        };
        let scale = weight * cos * mis::weight_over_density(self.s.heuristic, n_l, n_b);
        sum.add(dir, f * radiance(), cos, scale);
    }
}

impl<B> Pixel<'_, B> {
    /// Whether the scene blocks direction `dir` (a shadow ray, counted; never with no occluder).
    #[inline(always)]
    fn blocked(&self, dir: Vec3, st: &mut PixelStats) -> bool {
        let Some((occ, at)) = &self.shadow else {
            return false;
        };
        st.shadow_rays += 1;
        occ.occluded_from(at, dir)
    }
}

/// [`shade_pixel`] for a visible pixel (unit `n`, `o`, `<n, o> > 0`) with BRDF `bsdf` (the
/// pixel's `material`, or a specialised view of it). The light samples (from the pool, or from
/// the global distribution), then the BRDF samples, combined by MIS: `shade_counts` in
/// `shaders/shade.wgsl` calls the same functions in the same order, with the same random draws.
#[inline(always)]
fn shade_with<B: LocalBsdf>(
    fd: &FrameData,
    s: &Settings,
    material: &crate::sampling::Material,
    bsdf: &B,
    (n, o, shadow): (Vec3, Vec3, Shadow),
    pixel_index: u32,
    sum: &mut impl Sink,
) -> PixelStats {
    let frame = Frame::new(n);
    let (nl, nb) = s.budget(material);
    let px = Pixel {
        fd,
        s,
        bsdf,
        frame,
        n,
        ol: frame.to_local(o),
        nl,
        nb,
        shadow,
    };
    let mut st = PixelStats::default();
    let mut rng = Rng::new(s.seed, pixel_index);
    // Light-sample density on each region (N_t, clamped to the pool): `n_L(w) = density[t] p_t(w)`.
    let mut density = [0.0f32; MAX_REGIONS];
    match s.strategy {
        Strategy::Paper | Strategy::Light => {
            light_pool_samples(&px, &mut rng, &mut density, sum, &mut st);
        }
        Strategy::Global => global_samples(&px, &mut rng, sum, &mut st),
        Strategy::Brdf => {}
    }
    brdf_samples(&px, &mut rng, &density, sum, &mut st);
    st
}

/// The unit normal and view of a pixel that reflects anything (both non-zero, the view in front
/// of the surface, a material that is not black); `None` for a pixel whose estimate is 0.
#[inline(always)]
pub fn shading_directions(px: &GPixel) -> Option<(Vec3, Vec3)> {
    let n = px.n.normalize_or_zero();
    let o = px.o.normalize_or_zero();
    let visible = n != Vec3::ZERO && o != Vec3::ZERO && n.dot(o) > 0.0;
    (visible && !px.material.is_black()).then_some((n, o))
}

#[cfg(test)]
#[path = "estimator_tests.rs"]
mod tests;
