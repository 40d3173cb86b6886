//! The GPU stages: WGSL compute shaders (in `shaders/`) for the per-frame distribution build, the
//! light-sample pool and face-weighted MIS shading, recorded on any `wgpu::Device`.
//!
//! Every stage has a CPU twin in [`envis::sampling`] / [`envis::render`] that is its oracle: the
//! tests in `tests/gpu.rs` run each stage on a real Vulkan device (Mesa lavapipe in CI) and compare.
//! The stages only *record* commands into an encoder, so the same code serves the headless
//! backend ([`render_gpu`], `envis render --backend wgpu`) and the Bevy render world, which hands
//! over its own device and encoder.

pub mod codes;
pub use codes::GpuCode;
pub mod context;
pub mod resample;
pub mod resampling;
pub mod sampler;
pub mod shaders;
pub mod shading;
pub mod subtexel;
pub mod visibility;

pub use context::GpuContext;
pub use resample::ImageResampler;
pub use sampler::{BuildPipelines, EnvSampler, GpuTables};
pub use shading::{GpuGPixel, Shader};

use envis::envmap::CubeMap;
use envis::error::Result;
use envis::render::{GPixel, RenderStats, Rendered, Settings, Strategy};
use glam::Vec3;

/// A compute pipeline for entry point `entry` of `module` (labelled with the entry's name).
pub fn compute_pipeline(
    device: &wgpu::Device,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    entry: &str,
) -> wgpu::ComputePipeline {
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(entry),
        layout: Some(layout),
        module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    })
}

/// Bind group entries for `resources` at bindings 0, 1, 2, ... in order.
pub fn sequential_entries<'a>(
    resources: impl IntoIterator<Item = wgpu::BindingResource<'a>>,
) -> Vec<wgpu::BindGroupEntry<'a>> {
    (0u32..)
        .zip(resources)
        .map(|(binding, resource)| wgpu::BindGroupEntry { binding, resource })
        .collect()
}

/// A compute-stage bind group layout entry for a buffer binding of kind `ty`.
pub fn buffer_entry(binding: u32, ty: wgpu::BufferBindingType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A compute-stage layout of buffers only: binding `i` is a buffer of kind `kinds[i]`.
pub fn buffer_layout(
    device: &wgpu::Device,
    label: &str,
    kinds: &[wgpu::BufferBindingType],
) -> wgpu::BindGroupLayout {
    let entries: Vec<_> = (0u32..)
        .zip(kinds)
        .map(|(b, &ty)| buffer_entry(b, ty))
        .collect();
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: &entries,
    })
}

/// A uniform buffer sized for one `T`, which the host writes.
pub fn uniform_buffer<T>(device: &wgpu::Device, label: &str) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: std::mem::size_of::<T>() as u64,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// A bind group for `layout` binding each of `buffers` whole, binding `i` to `buffers[i]`.
pub fn whole_buffers(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    buffers: &[&wgpu::Buffer],
) -> wgpu::BindGroup {
    let entries: Vec<_> = (0u32..)
        .zip(buffers)
        .map(|(binding, b)| wgpu::BindGroupEntry {
            binding,
            resource: b.as_entire_binding(),
        })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &entries,
    })
}

/// The pipeline layout of a stage with one bind group, `layout`.
pub fn one_group_layout(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
) -> wgpu::PipelineLayout {
    device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    })
}

/// Two timestamp queries (a pass's start and end) and the 16-byte buffer they resolve into.
pub fn timestamp_pair(device: &wgpu::Device, label: &str) -> (wgpu::QuerySet, wgpu::Buffer) {
    let set = device.create_query_set(&wgpu::QuerySetDescriptor {
        label: Some(label),
        ty: wgpu::QueryType::Timestamp,
        count: 2,
    });
    let resolve = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: 16,
        usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    (set, resolve)
}

/// Workgroups for `count` threads of `wg_size`, split over (x, y) when x would pass the 65535
/// limit; shaders rebuild the linear id as `x + y * num_workgroups.x * wg_size`.
pub fn dispatch_size(count: u32, wg_size: u32) -> (u32, u32) {
    let groups = count.div_ceil(wg_size).max(1);
    if groups <= 65535 {
        (groups, 1)
    } else {
        let y = groups.div_ceil(65535);
        (groups.div_ceil(y), y)
    }
}

/// Per-pass GPU and CPU time of one headless frame, milliseconds.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct GpuTimings {
    /// Distribution build (weights, CDFs, pdf table) + pool, measured by timestamp queries when
    /// the device has them (`None` otherwise).
    pub build_gpu_ms: Option<f64>,
    pub shade_gpu_ms: Option<f64>,
    /// Wall time from submission to completion, per part (always available).
    pub build_wall_ms: f64,
    pub shade_wall_ms: f64,
}

/// Render a G-buffer on the GPU: the same contract as [`envis::render::render`] (same seed gives
/// the same random streams, so the images agree to float rounding).
pub fn render_gpu(
    ctx: &GpuContext,
    map: &CubeMap,
    gbuf: &[Option<GPixel>],
    width: usize,
    height: usize,
    s: &Settings,
) -> Result<(Rendered, GpuTimings)> {
    GpuRenderer::new(ctx).render(map, gbuf, width, height, s)
}

/// What a headless frame can add to the map and the G-buffer (the twin of
/// [`envis::render::Extras`]).
#[derive(Clone, Copy, Default)]
pub struct GpuExtras<'a> {
    /// The map at its own resolution: light and BRDF samples read their radiance here, `map`
    /// giving the densities (`envmap::load::LoadedEnv::fine`), and the pool is refined into its
    /// texels where it is a whole multiple of `map` (the twin of [`envis::render::Extras`]'
    /// `fine` and `sub_texels` both set, as `envis render` does).
    pub fine: Option<&'a CubeMap>,
    /// Shadow rays: the scene's flattened BVH, and each pixel's surface point.
    pub shadows: Option<(&'a envis::visibility::FlatBvh, &'a [Vec3])>,
}

/// A headless GPU renderer that keeps its pipelines between frames: one shader, and one sampler
/// per (face size, pool size, global table) it has been asked for.
pub struct GpuRenderer<'c> {
    ctx: &'c GpuContext,
    shader: Shader,
    samplers: std::collections::HashMap<SamplerKey, EnvSampler>,
    /// The pool's sub-texel pass, made when a frame first has a finer map.
    refine: Option<subtexel::PoolRefine>,
}

impl<'c> GpuRenderer<'c> {
    pub fn new(ctx: &'c GpuContext) -> Self {
        GpuRenderer {
            ctx,
            shader: Shader::new(ctx),
            samplers: Default::default(),
            refine: None,
        }
    }

    /// [`render_gpu`] with the cached pipelines.
    pub fn render(
        &mut self,
        map: &CubeMap,
        gbuf: &[Option<GPixel>],
        width: usize,
        height: usize,
        s: &Settings,
    ) -> Result<(Rendered, GpuTimings)> {
        self.render_with_shadows(map, gbuf, width, height, s, None)
    }

    /// [`Self::render`] with a shadow ray per sample through `shadows`' geometry, from each
    /// pixel's surface point (the CPU twin: [`envis::render::render_with`] with the same
    /// [`envis::visibility::FlatBvh`] as its occluder).
    pub fn render_with_shadows(
        &mut self,
        map: &CubeMap,
        gbuf: &[Option<GPixel>],
        width: usize,
        height: usize,
        s: &Settings,
        shadows: Option<(&envis::visibility::FlatBvh, &[Vec3])>,
    ) -> Result<(Rendered, GpuTimings)> {
        let extras = GpuExtras {
            shadows,
            fine: None,
        };
        self.render_with(map, extras, gbuf, width, height, s)
    }

    /// [`Self::render`] with [`GpuExtras`]: shadow rays, radiance at full resolution (the twin
    /// of [`envis::render::render_with`] with the same extras).
    pub fn render_with(
        &mut self,
        map: &CubeMap,
        extras: GpuExtras,
        gbuf: &[Option<GPixel>],
        width: usize,
        height: usize,
        s: &Settings,
    ) -> Result<(Rendered, GpuTimings)> {
        s.validate()?;
        assert_eq!(gbuf.len(), width * height);
        let ctx = self.ctx;
        let pixels: Vec<GpuGPixel> = gbuf.iter().map(GpuGPixel::from).collect();
        let key = self.warm_sampler(map, s, &pixels)?;
        let fine = extras
            .fine
            .map(|f| subtexel::FineRadiance::new(ctx, f, map.size))
            .transpose()?;
        let (mut timings, clamped) = self.build(key, map, s, fine.as_ref())?;
        let sampler = &self.samplers[&key];
        let bvh = extras
            .shadows
            .map(|(flat, points)| (visibility::GpuBvh::new(ctx, flat), points));
        let t1 = std::time::Instant::now();
        let shade = shading::ShadeExtras {
            shadows: bvh.as_ref().map(|(b, p)| (b, *p)),
            fine: fine.as_ref(),
        };
        let job = self.shader.shade_with(ctx, sampler, &pixels, s, shade)?;
        timings.shade_wall_ms = t1.elapsed().as_secs_f64() * 1e3;
        timings.shade_gpu_ms = job.gpu_ms;

        let mut stats = RenderStats::for_settings(width, height, s, s.pool_per_face());
        stats.build_ms = timings.build_wall_ms;
        stats.shade_ms = timings.shade_wall_ms;
        stats.accumulate(&job.pixel_stats(gbuf));
        stats.clamped_texels = clamped;
        let image = envis::envmap::Image {
            width,
            height,
            data: job
                .color
                .iter()
                .map(|c| Vec3::new(c[0], c[1], c[2]))
                .collect(),
        };
        Ok((Rendered { image, stats }, timings))
    }

    /// The cache key of the sampler settings `s` need on `map`, made (and its pipelines run
    /// once over `pixels`) if it is new.
    fn warm_sampler(
        &mut self,
        map: &CubeMap,
        s: &Settings,
        pixels: &[GpuGPixel],
    ) -> Result<SamplerKey> {
        let ctx = self.ctx;
        let global = s.strategy == Strategy::Global;
        let key = (map.size, s.pool_slots(), s.pool_block_count(), global);
        if !self.samplers.contains_key(&key) {
            let mut sampler = EnvSampler::for_settings(ctx, map.size, s)?;
            if global {
                sampler.enable_global(&ctx.device, &ctx.queue)?;
            }
            // Some drivers (lavapipe among them) compile a pipeline at its first dispatch: run the
            // new pipelines once, untimed, so that the timings below are steady-state frames.
            sampler.upload(&ctx.queue, map);
            ctx.wait(sampler.run(ctx, envis::render::pool_seed(s.seed)))?;
            self.shader.shade(ctx, &sampler, pixels, s)?;
            self.samplers.insert(key, sampler);
        }
        Ok(key)
    }

    /// One frame's build on sampler `key`: upload, distribution and pool, the pool refined into
    /// `fine`'s texels where it has a sub-texel level; its timings and clamped texels.
    fn build(
        &mut self,
        key: SamplerKey,
        map: &CubeMap,
        s: &Settings,
        fine: Option<&subtexel::FineRadiance>,
    ) -> Result<(GpuTimings, envis::envmap::SanitizeReport)> {
        let ctx = self.ctx;
        let fine = fine.filter(|f| f.ratio > 0);
        if fine.is_some() && self.refine.is_none() {
            self.refine = Some(subtexel::PoolRefine::new(&ctx.device));
        }
        let sampler = &self.samplers[&key];
        sampler.upload(&ctx.queue, map);
        let mut timings = GpuTimings::default();
        let t0 = std::time::Instant::now();
        let mut build_q = sampler.run(ctx, envis::render::pool_seed(s.seed));
        if let (Some(refine), Some(fine)) = (&self.refine, fine) {
            build_q = refine.run(ctx, sampler, fine).unwrap_or(build_q);
        }
        ctx.wait(build_q)?;
        timings.build_wall_ms = t0.elapsed().as_secs_f64() * 1e3;
        let (build_gpu_ms, clamped) = sampler.read_report(ctx)?;
        timings.build_gpu_ms = build_gpu_ms;
        Ok((timings, clamped))
    }
}

/// A cached sampler's face size, pool slots, pool blocks, and whether it builds `global`.
type SamplerKey = (usize, usize, usize, bool);
