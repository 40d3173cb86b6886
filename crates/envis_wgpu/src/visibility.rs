//! Shadow rays on the GPU (`shaders/visibility.wgsl`): a flattened BVH ([`FlatBvh`]) in storage
//! buffers and a compute pass that traces a batch of rays. Its CPU twin is
//! [`FlatBvh::occluded`]; `tests/gpu.rs` compares them ray by ray. The lighting passes will call
//! the same `bvh_occluded`.

use super::{GpuContext, compute_pipeline, shaders};
use envis::error::Result;
use envis::visibility::{FlatBvh, FlatTop, Layers};
use glam::Vec3;
use wgpu::util::DeviceExt;

/// One shadow ray: from `o`, along `d`, hits counted with `t` in `(t_min, t_max)`.
#[derive(Clone, Copy, Debug)]
pub struct ShadowRay {
    pub o: Vec3,
    pub d: Vec3,
    pub t_min: f32,
    pub t_max: f32,
}

/// The BVH on the device and the ray-batch pipeline.
pub struct GpuBvh {
    pub nodes: wgpu::Buffer,
    pub triangles: wgpu::Buffer,
    pub node_count: u32,
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
}

/// Upload a flattened BVH: its node and triangle storage buffers (the layout `visibility.wgsl`
/// reads: each the top part, then the meshes'). Shared by [`GpuBvh`] and the Bevy pass's shadow
/// geometry.
pub fn upload_bvh(device: &wgpu::Device, bvh: &FlatBvh) -> (wgpu::Buffer, wgpu::Buffer) {
    let cat = |a: &[u8], b: &[u8]| [a, b].concat();
    let nodes = cat(
        bytemuck::cast_slice(&bvh.top.nodes),
        bytemuck::cast_slice(&bvh.meshes.nodes),
    );
    let triangles = cat(
        bytemuck::cast_slice(&bvh.top.records),
        bytemuck::cast_slice(&bvh.meshes.triangles),
    );
    (
        storage_init(device, "envis bvh nodes", &nodes),
        storage_init(device, "envis bvh triangles", &triangles),
    )
}

/// Instances moved: rewrite the top part of buffers [`upload_bvh`] made for the same instances
/// (the meshes' part, after it, stays).
pub fn write_top(
    queue: &wgpu::Queue,
    (nodes, triangles): (&wgpu::Buffer, &wgpu::Buffer),
    top: &FlatTop,
) {
    queue.write_buffer(nodes, 0, bytemuck::cast_slice(&top.nodes));
    queue.write_buffer(triangles, 0, bytemuck::cast_slice(&top.records));
}

fn storage_init(device: &wgpu::Device, label: &str, bytes: &[u8]) -> wgpu::Buffer {
    // A binding may not be empty nor shorter than one element (48 bytes for a triangle): a BVH
    // with no nodes binds zeros.
    let zeros = [0u8; 48];
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: if bytes.is_empty() { &zeros } else { bytes },
        // COPY_DST: the top part is rewritten in place when instances move (`write_top`);
        // COPY_SRC: the Bevy resampling pass keeps a copy as the previous frame's geometry.
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
    })
}

impl GpuBvh {
    pub fn new(ctx: &GpuContext, bvh: &FlatBvh) -> Self {
        let device = &ctx.device;
        let (nodes, triangles) = upload_bvh(device, bvh);
        use wgpu::BufferBindingType as BB;
        let read = BB::Storage { read_only: true };
        let kinds = [
            read,
            read,
            read,
            BB::Storage { read_only: false },
            BB::Uniform,
        ];
        let layout = super::buffer_layout(device, "envis trace rays", &kinds);
        let pipeline_layout = super::one_group_layout(device, "envis trace rays", &layout);
        let module = shaders::module(
            device,
            "envis trace_rays.wgsl",
            &shaders::trace_rays_source(),
        );
        let pipeline = compute_pipeline(device, &pipeline_layout, &module, "trace_rays");
        GpuBvh {
            nodes,
            triangles,
            node_count: bvh.tlas_nodes() as u32,
            layout,
            pipeline,
        }
    }

    /// Trace `rays`; `true` where a ray is blocked.
    pub fn trace(&self, ctx: &GpuContext, rays: &[ShadowRay]) -> Result<Vec<bool>> {
        self.trace_on(ctx, rays, Layers::ALL)
    }

    /// Trace `rays` cast for `layers` (only instances on one of them block;
    /// `FlatBvh::occluded_on` is the twin); `true` where a ray is blocked.
    pub fn trace_on(
        &self,
        ctx: &GpuContext,
        rays: &[ShadowRay],
        layers: Layers,
    ) -> Result<Vec<bool>> {
        let device = &ctx.device;
        let packed: Vec<[f32; 8]> = rays
            .iter()
            .map(|r| [r.o.x, r.o.y, r.o.z, r.t_min, r.d.x, r.d.y, r.d.z, r.t_max])
            .collect();
        let rays_buf = storage_init(device, "envis rays", bytemuck::cast_slice(&packed));
        let size = (4 * rays.len()).max(16) as u64;
        let out = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("envis blocked"),
            size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let counts = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("envis ray counts"),
            contents: bytemuck::cast_slice(&[self.node_count, rays.len() as u32, layers.0, 0]),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let bufs = [&self.nodes, &self.triangles, &rays_buf, &out, &counts];
        let bind = super::whole_buffers(device, "envis trace rays", &self.layout, &bufs);
        let mut enc = device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups((rays.len() as u32).div_ceil(64).max(1), 1, 1);
        }
        ctx.wait(ctx.queue.submit([enc.finish()]))?;
        let flags: Vec<u32> = ctx.read(&out, 0, rays.len())?;
        Ok(flags.into_iter().map(|f| f != 0).collect())
    }
}
