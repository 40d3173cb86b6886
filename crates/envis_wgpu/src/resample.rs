//! The resample stage: an environment `Image` already on the GPU (a lat-long or cube texture) ->
//! the sampler's cube texel table, with no CPU round trip (`shaders/resample.wgsl`). Its CPU twin
//! is [`envis::envmap::resample::SourceImage::to_cube`]. The Bevy layer runs it whenever the
//! image changed, and every frame for a `dynamic` one.

use super::{EnvSampler, compute_pipeline, dispatch_size, shaders};
use envis::envmap::resample::SourceLayout;
use wgpu::util::DeviceExt;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ResampleParams {
    n: u32,
    s: u32,
    kind: u32,
    _pad: u32,
}

/// An environment texture as the resample reads it.
#[derive(Clone, Copy)]
pub struct Source<'a> {
    /// A view from [`source_view`].
    pub view: &'a wgpu::TextureView,
    pub layout: SourceLayout,
    /// Width of one layer in texels.
    pub width: u32,
}

/// The resample pipeline (one per device).
pub struct ImageResampler {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
}

impl ImageResampler {
    pub fn new(device: &wgpu::Device) -> Self {
        use wgpu::BufferBindingType as Kind;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("envis resample layout"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: source_binding(),
                    count: None,
                },
                super::buffer_entry(1, Kind::Storage { read_only: false }),
                super::buffer_entry(2, Kind::Uniform),
            ],
        });
        let pipeline_layout = super::one_group_layout(device, "envis resample", &layout);
        let module = shaders::module(device, "envis resample.wgsl", &shaders::resample_source());
        let pipeline = compute_pipeline(device, &pipeline_layout, &module, "resample");
        ImageResampler { layout, pipeline }
    }

    /// Record the resample of `source` into `sampler`'s texel table. The caller then records the
    /// build ([`EnvSampler::encode_with`]), which reads the table in the same command stream.
    pub fn encode(
        &self,
        device: &wgpu::Device,
        enc: &mut wgpu::CommandEncoder,
        source: Source<'_>,
        sampler: &EnvSampler,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let n = sampler.n as u32;
        let params = ResampleParams {
            n,
            s: source.layout.subpoints(source.width, n),
            kind: match source.layout {
                SourceLayout::LatLong => 0,
                SourceLayout::Cube => 1,
            },
            _pad: 0,
        };
        // A buffer per call: two samplers resampled in one frame must not share parameters
        // (queue writes all land before the frame's first command).
        let ubuf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("envis resample params"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("envis resample"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(source.view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: sampler.texels.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: ubuf.as_entire_binding(),
                },
            ],
        });
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("envis resample"),
            timestamp_writes,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &bind, &[]);
        let (x, y) = dispatch_size(6 * n * n, 64);
        pass.dispatch_workgroups(x, y, 1);
    }
}

/// How a source image is bound: a 2D array of unfilterable floats (any float format; texels are
/// read with `textureLoad`), one layer for lat-long, six for a cube.
pub fn source_binding() -> wgpu::BindingType {
    wgpu::BindingType::Texture {
        sample_type: wgpu::TextureSampleType::Float { filterable: false },
        view_dimension: wgpu::TextureViewDimension::D2Array,
        multisampled: false,
    }
}

/// The view of an environment texture that [`source_binding`] expects (mip 0, every layer).
pub fn source_view(texture: &wgpu::Texture) -> wgpu::TextureView {
    texture.create_view(&wgpu::TextureViewDescriptor {
        label: Some("envis environment source"),
        dimension: Some(wgpu::TextureViewDimension::D2Array),
        base_mip_level: 0,
        mip_level_count: Some(1),
        ..Default::default()
    })
}
