//! Sub-texel sampling on the GPU (`shaders/subtexel.wgsl`), twin of [`envis::sampling::subtexel`]:
//! the map at its own resolution with each texel's factor beside its radiance, and the pass that
//! moves the light pool's samples into its texels after the build.

use super::sampler::{EnvSampler, check_binding};
use super::{GpuContext, dispatch_size, shaders};
use envis::envmap::CubeMap;
use envis::error::Result;
use envis::sampling::SubTexels;

/// A cube map at its own resolution on the GPU: per texel `(r, g, b, factor)`, read by direction.
/// The factor is [`SubTexels::factors`]' for the distribution it was made for, 1 where that has
/// no sub-texel level.
pub struct FineRadiance {
    pub texels: wgpu::Buffer,
    /// Face size.
    pub size: u32,
    /// Fine texels per distribution texel side when the pool is to be refined
    /// ([`SubTexels::ratio_of`]), else 0.
    pub ratio: u32,
}

impl FineRadiance {
    /// Upload `map` with its factors over faces of `coarse` texels (refused, with the reason, if
    /// it exceeds the device's storage binding).
    pub fn new(ctx: &GpuContext, map: &CubeMap, coarse: usize) -> Result<Self> {
        let bytes = map.data.len() as u64 * 16;
        check_binding(&ctx.device.limits(), "the full-resolution map", bytes)?;
        let sub = SubTexels::new(map, coarse);
        let factor = |i: usize| sub.as_ref().map_or(1.0, |s| s.factors()[i]);
        let data: Vec<[f32; 4]> = (map.data.iter().enumerate())
            .map(|(i, c)| c.extend(factor(i)).to_array())
            .collect();
        use wgpu::util::DeviceExt;
        let texels = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("envis full-resolution radiance"),
                contents: bytemuck::cast_slice(&data),
                usage: wgpu::BufferUsages::STORAGE,
            });
        Ok(FineRadiance {
            texels,
            size: map.size as u32,
            ratio: sub.map_or(0, |s| s.ratio as u32),
        })
    }
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    n: u32,
    fine_n: u32,
    count: u32,
    _pad: u32,
}

/// The pool refinement pass: `refine_pool`, one thread per pool slot.
pub struct PoolRefine {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
}

impl PoolRefine {
    pub fn new(device: &wgpu::Device) -> Self {
        let ro = wgpu::BufferBindingType::Storage { read_only: true };
        let rw = wgpu::BufferBindingType::Storage { read_only: false };
        // Bindings 0..=3 as in `shaders/subtexel.wgsl`.
        let kinds = [rw, ro, ro, wgpu::BufferBindingType::Uniform];
        let layout = super::buffer_layout(device, "envis sub-texel layout", &kinds);
        let pl = super::one_group_layout(device, "envis sub-texel", &layout);
        let module = shaders::module(device, "envis subtexel.wgsl", &shaders::subtexel_source());
        let pipeline = super::compute_pipeline(device, &pl, &module, "refine_pool");
        PoolRefine { layout, pipeline }
    }

    /// Refine `sampler`'s pool (built, or queued to be) into `fine`'s texels and submit; nothing
    /// to do (`None`) where `fine` has no sub-texel level.
    pub fn run(
        &self,
        ctx: &GpuContext,
        sampler: &EnvSampler,
        fine: &FineRadiance,
    ) -> Option<wgpu::SubmissionIndex> {
        if fine.ratio == 0 {
            return None;
        }
        let count = sampler.pool_slots();
        let p = Params {
            n: sampler.n as u32,
            fine_n: fine.size,
            count,
            _pad: 0,
        };
        let params_uniform = super::uniform_buffer::<Params>(&ctx.device, "envis sub-texel params");
        ctx.queue
            .write_buffer(&params_uniform, 0, bytemuck::bytes_of(&p));
        let bufs = [
            &sampler.pool,
            &sampler.texels,
            &fine.texels,
            &params_uniform,
        ];
        let bind = super::whole_buffers(&ctx.device, "envis sub-texel", &self.layout, &bufs);
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("envis sub-texel refine"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind, &[]);
            let (x, y) = dispatch_size(count, 64);
            pass.dispatch_workgroups(x, y, 1);
        }
        Some(ctx.queue.submit([enc.finish()]))
    }
}
