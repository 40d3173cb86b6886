//! Reservoir resampling on the GPU (`shaders/resampling.wgsl`): the twin of
//! [`envis::render::resampling::resample_frame`], pass for pass, with the same random streams.
//! Per frame: the paper's sampler is built on the rest of the map (as the CPU's `FrameData`),
//! then up to five dispatches over the pixels: `candidates`, `history_targets` (the canonical
//! samples' targets at the history pixels, with the previous frame's shadow geometry bound; only
//! with a history), `temporal`, `spatial` and `shade_reservoirs`. The previous frame's surfaces,
//! split map, shadow geometry and reservoirs stay on the device for the next frame. Read back
//! (a sequence's output, not a frame path's): the image (its alpha the history length), the
//! per-pixel sample counts and the reuse counters. `envis_cli/tests/lab/gpu_resampling.rs` compares whole sequences with the CPU.

mod frame;
mod layout;
mod passes;

pub use layout::{FrameReuse, GpuReservoir, GpuSurface, ResampleParams, split_tables};
pub use passes::{BvhBuffers, PASSES, PassBuffers, ResamplingPasses, STORAGE_BUFFERS};

pub use frame::storage_init;
use frame::{FrameBuffers, Readback};

use super::GpuContext;
use super::sampler::EnvSampler;
use super::shading::ShadeParams;
use envis::envmap::Image;
use envis::error::{Error, Result};
use envis::render::resampling::{Resampling, ReuseStats, Screen, frame_seed};
use envis::render::{RenderStats, Settings, Strategy, pool_seed};
use envis::visibility::FlatBvh;

/// The most spatial neighbours the shaders take (the WGSL's `MAX_DOMAINS`, generated from it by
/// `shaders::resampling_constants`, is one more: the canonical pixel).
pub const MAX_SPATIAL: u32 = 8;

/// The confidence `M` the history overlay draws red (`HISTORY_FULL_SCALE` in
/// `shaders/lighting.wgsl`): the default `max_history`.
pub const HISTORY_FULL_SCALE: f32 = 20.0;

/// What temporal reuse needs of the caller: per pixel, where it was in the previous frame (the
/// pixel, and the distance from the previous camera its point had then), and whether the
/// previous frame's bright part is this one's ([`envis::render::resampling::BrightLight::same_light`]).
pub struct GpuHistory<'a> {
    pub reproject: &'a [Option<(usize, f32)>],
    pub same_bright: bool,
    /// How far the previous frame's map and this one's agree as light
    /// ([`envis::render::resampling::map_agreement`] of their rests).
    pub map_agreement: f32,
    /// Nothing that casts shadows moved since the previous frame
    /// ([`envis::render::resampling::History::still_geometry`]).
    pub still_geometry: bool,
}

/// A frame as [`GpuResampler::frame`] takes it.
pub struct GpuFrame<'a> {
    /// The frame's screen (`screen.occluder` is not read: the shadow geometry is `bvh`).
    pub screen: &'a Screen<'a>,
    pub bvh: Option<&'a FlatBvh>,
    /// Where the previous call's frame is this one's history.
    pub history: Option<GpuHistory<'a>>,
}

/// A resampled frame from the GPU.
pub struct GpuResampled {
    pub image: Image,
    pub stats: RenderStats,
    pub reuse: ReuseStats,
}

/// The previous frame, on the device.
struct Previous {
    surfaces: wgpu::Buffer,
    split: wgpu::Buffer,
    n: u32,
    bvh: Option<(wgpu::Buffer, wgpu::Buffer, u32)>,
    /// The temporal pass's output: the next frame's history.
    reservoirs: wgpu::Buffer,
    pixels: usize,
}

/// The resampling pipelines, the sampler they build on, and the previous frame.
pub struct GpuResampler {
    passes: ResamplingPasses,
    shade_params: wgpu::Buffer,
    params: wgpu::Buffer,
    sampler: Option<((usize, usize, usize, bool), EnvSampler)>,
    prev: Option<Previous>,
}

impl GpuResampler {
    /// The pipelines on `ctx`'s device; an error (one line) where it cannot bind what they need.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let device = &ctx.device;
        ResamplingPasses::supported(&device.limits())?;
        Ok(GpuResampler {
            passes: ResamplingPasses::new(device),
            shade_params: super::uniform_buffer::<ShadeParams>(device, "envis resampling shade"),
            params: super::uniform_buffer::<ResampleParams>(device, "envis resampling params"),
            sampler: None,
            prev: None,
        })
    }

    /// Forget the history: the next frame starts afresh.
    pub fn reset(&mut self) {
        self.prev = None;
    }

    /// Resample frame `frame` of a sequence: the twin of
    /// [`envis::render::resampling::resample_frame`], its history the previous call's frame
    /// where `input.history` is given. A history is ignored (the frame starts afresh, as after
    /// [`GpuResampler::reset`]) when the previous frame had another pixel count: its buffers are
    /// sized by it, and the CLI's sequences keep one size.
    pub fn frame(
        &mut self,
        ctx: &GpuContext,
        input: GpuFrame,
        s: &Settings,
        r: &Resampling,
        frame: u32,
    ) -> Result<GpuResampled> {
        let GpuFrame {
            screen: cur,
            bvh,
            history,
        } = input;
        check(cur, s, r)?;
        let s = Settings {
            seed: frame_seed(s.seed, frame),
            ..*s
        };
        let n_px = cur.width * cur.height;
        let history = history.filter(|_| self.prev.as_ref().is_some_and(|p| p.pixels == n_px));
        let t0 = std::time::Instant::now();
        self.build(ctx, cur, &s)?;
        let build_ms = t0.elapsed().as_secs_f64() * 1e3;
        let t1 = std::time::Instant::now();
        let f = FrameBuffers::new(ctx, cur, bvh, history.as_ref().map(|h| h.reproject));
        let params = self.params_for(cur, &f, history.as_ref(), r, s.seed);
        ctx.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        let (_, sampler) = self.sampler.as_ref().expect("built above");
        let shade = ShadeParams::new(&s, sampler.n, sampler.m, n_px);
        ctx.queue
            .write_buffer(&self.shade_params, 0, bytemuck::bytes_of(&shade));
        let out = self.dispatch(ctx, &f, history.is_some())?;
        let shade_ms = t1.elapsed().as_secs_f64() * 1e3;
        let mut stats = RenderStats::for_settings(cur.width, cur.height, &s, s.pool_per_face());
        (stats.build_ms, stats.shade_ms) = (build_ms, shade_ms);
        let result = out.into_frame(cur, stats);
        self.prev = Some(f.into_previous(cur.split.rest.size as u32));
        Ok(result)
    }

    /// Build the paper's sampler on the rest of `cur`'s map (a new one when the sizes change).
    fn build(&mut self, ctx: &GpuContext, cur: &Screen, s: &Settings) -> Result<()> {
        let rest = &cur.split.rest;
        let global = s.strategy == Strategy::Global;
        let key = (rest.size, s.pool_slots(), s.pool_block_count(), global);
        if self.sampler.as_ref().is_none_or(|(k, _)| *k != key) {
            let mut sampler = EnvSampler::for_settings(ctx, rest.size, s)?;
            if global {
                sampler.enable_global(&ctx.device, &ctx.queue)?;
            }
            self.sampler = Some((key, sampler));
        }
        let (_, sampler) = self.sampler.as_ref().expect("set above");
        sampler.upload(&ctx.queue, rest);
        ctx.wait(sampler.run(ctx, pool_seed(s.seed)))
    }

    fn params_for(
        &self,
        cur: &Screen,
        f: &FrameBuffers,
        history: Option<&GpuHistory>,
        r: &Resampling,
        seed: u32,
    ) -> ResampleParams {
        let prev = self.prev.as_ref().filter(|_| history.is_some());
        ResampleParams::for_frame(&FrameReuse {
            width: cur.width as u32,
            height: cur.height as u32,
            face_size: cur.split.rest.size as u32,
            prev_face_size: prev.map(|p| p.n),
            bright_count: f.bright_count,
            bright_history: history.is_some_and(|h| h.same_bright),
            temporal: r.temporal,
            spatial: r.spatial,
            max_history: r.max_history,
            unbiased: r.unbiased,
            seed,
            bvh_nodes: f.bvh.as_ref().map_or(0, |b| b.2),
            prev_bvh_nodes: prev.and_then(|p| p.bvh.as_ref()).map_or(0, |b| b.2),
            layers: u32::MAX,
            map_agreement: history.map_or(1.0, |h| h.map_agreement),
            still_geometry: history.is_some_and(|h| h.still_geometry),
            world_from_map: glam::Mat3::IDENTITY,
        })
    }
}

/// What the GPU passes cannot do, as one-line errors: the CPU oracle's test mutations, shadowed
/// candidates, more neighbours than the shaders hold.
fn check(cur: &Screen, s: &Settings, r: &Resampling) -> Result<()> {
    s.validate_for(cur.split.rest.size)?;
    assert_eq!(cur.gbuf.len(), cur.width * cur.height);
    if r.mutation.is_some() {
        return Err(Error::invalid(
            "resampling mutations are the CPU oracle's tests; the GPU passes have none",
        ));
    }
    if r.candidate_visibility {
        return Err(Error::invalid(
            "shadow-tested candidates are a CPU-only experiment of the resampling oracle",
        ));
    }
    if r.max_history == 0 {
        // The passes cap a confidence at max(1, max_history) (ResampleParams::for_frame), the
        // oracle at max_history: refused rather than differing.
        return Err(Error::invalid(
            "max_history 0: a reservoir's history cap must be at least 1 frame",
        ));
    }
    if r.spatial > MAX_SPATIAL {
        return Err(Error::invalid(format!(
            "spatial {} neighbours: the GPU passes take at most {MAX_SPATIAL}",
            r.spatial
        )));
    }
    Ok(())
}

impl GpuResampler {
    /// The passes in one submission, and the readback.
    fn dispatch(&self, ctx: &GpuContext, f: &FrameBuffers, history: bool) -> Result<Readback> {
        let (_, sampler) = self.sampler.as_ref().expect("built before dispatch");
        let prev = self.prev.as_ref().filter(|_| history);
        let buffers = PassBuffers {
            sampler,
            shade_params: &self.shade_params,
            params: &self.params,
            surfaces: &f.surfaces,
            prev_surfaces: prev.map(|p| &p.surfaces),
            split: &f.split,
            prev_split: prev.map(|p| &p.split),
            bright: Some((&f.bright_cdf, &f.bright_ids)),
            bvh: bvh_buffers(&f.bvh),
            prev_bvh: prev.and_then(|p| bvh_buffers(&p.bvh)),
            res: [&f.res[0], &f.res[1], &f.res[2], &f.res[3]],
            history: prev.map(|p| &p.reservoirs),
            reproject: f.reproject.as_ref(),
            hist_targets: &f.hist_targets,
            counters: &f.counters,
            color: &f.color,
            stats: &f.stats,
            pixels: f.pixels as u32,
        };
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        self.passes.record(&ctx.device, &mut enc, &buffers);
        ctx.wait(ctx.queue.submit([enc.finish()]))?;
        let n = f.pixels as u64;
        let data = ctx.read_many(&[
            (&f.color, 0, n * 16),
            (&f.stats, 0, n * 16),
            (&f.counters, 0, n * 16),
        ])?;
        Ok(Readback {
            color: bytemuck::pod_collect_to_vec(&data[0]),
            stats: bytemuck::pod_collect_to_vec(&data[1]),
            counters: bytemuck::pod_collect_to_vec(&data[2]),
        })
    }
}

/// An uploaded BVH (nodes, triangles, node count) as the passes bind it.
fn bvh_buffers(b: &Option<(wgpu::Buffer, wgpu::Buffer, u32)>) -> Option<BvhBuffers<'_>> {
    b.as_ref().map(|b| (&b.0, &b.1))
}
