//! The lighting pass's GPU objects: its bind group layout and render pipelines (one per target
//! format), and each view's accumulation buffer.

use crate::app::lighting_uniforms::PROBE_BYTES;
use crate::app::timing::{AsyncRead, AsyncTimer};
use crate::gpu::shaders;
use bevy::prelude::*;
use std::collections::HashMap;
use std::sync::Mutex;

/// The lighting pipeline (raw wgpu, shared WGSL with the headless backend), one per target format.
#[derive(Resource)]
pub struct LightingPipelines {
    pub(super) layout: wgpu::BindGroupLayout,
    pub(super) pipeline_layout: wgpu::PipelineLayout,
    pub(super) module: wgpu::ShaderModule,
    pub(super) by_format: Mutex<HashMap<wgpu::TextureFormat, wgpu::RenderPipeline>>,
    /// Times the first envis camera's lighting pass of a frame.
    pub(super) timer: Option<AsyncTimer>,
    /// The probed pixel's record (`lighting_uniforms::PROBE_RECORD`) and its readback.
    pub(super) probe: wgpu::Buffer,
    pub(super) probe_read: AsyncRead,
    /// Bound in place of the shadow BVH when a camera casts no shadow rays.
    pub(super) no_shadows: wgpu::Buffer,
    /// The seed of the frame whose probe is being read back.
    pub(super) probe_seed: Mutex<u32>,
    /// Per view: the running mean of the accumulated frames (one vec4 per pixel) and its size.
    pub(super) accum: Mutex<HashMap<Entity, (wgpu::Buffer, UVec2)>>,
}

impl LightingPipelines {
    pub(super) fn new(device: &wgpu::Device, queue: &wgpu::Queue) -> Self {
        use wgpu::{BindingType as B, BufferBindingType as BB, ShaderStages as S};
        let e = |binding: u32, ty: B| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: S::FRAGMENT,
            ty,
            count: None,
        };
        let buf = |ty: BB| B::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("envis lighting layout"),
            entries: &[
                e(
                    0,
                    B::Texture {
                        sample_type: wgpu::TextureSampleType::Uint,
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                ),
                e(
                    1,
                    B::Texture {
                        sample_type: wgpu::TextureSampleType::Depth,
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                ),
                e(2, buf(BB::Storage { read_only: true })),
                e(3, buf(BB::Storage { read_only: true })),
                e(4, buf(BB::Storage { read_only: true })),
                e(5, buf(BB::Uniform)),
                e(6, buf(BB::Uniform)),
                e(7, buf(BB::Storage { read_only: false })),
                e(8, buf(BB::Storage { read_only: false })),
                e(9, buf(BB::Storage { read_only: true })),
                e(
                    10,
                    B::Texture {
                        sample_type: wgpu::TextureSampleType::Uint,
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                ),
                e(11, crate::gpu::resample::source_binding()),
                e(12, buf(BB::Storage { read_only: true })),
                e(13, buf(BB::Storage { read_only: true })),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("envis lighting"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let module = shaders::module(device, "envis lighting.wgsl", &shaders::lighting_source());
        let timer = AsyncTimer::new(device, queue, "envis lighting timer");
        let probe = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("envis probe"),
            size: PROBE_BYTES,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let probe_read = AsyncRead::new(device, "envis probe readback", PROBE_BYTES);
        // Bound in place of the shadow BVH when there is none (one triangle's 48 bytes).
        let no_shadows = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("envis no shadow geometry"),
            size: 48,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        LightingPipelines {
            layout,
            pipeline_layout,
            module,
            by_format: Mutex::new(HashMap::new()),
            timer,
            probe,
            probe_read,
            no_shadows,
            probe_seed: Mutex::new(0),
            accum: Mutex::new(HashMap::new()),
        }
    }

    /// The view's running-mean buffer: one vec4 per viewport pixel while accumulating (a new one,
    /// so a new mean, when the viewport size changes), a 16-byte placeholder otherwise.
    pub(super) fn accumulation_buffer(
        &self,
        device: &wgpu::Device,
        view: Entity,
        accumulate: bool,
        vp: UVec4,
    ) -> wgpu::Buffer {
        let buffer = |bytes: u64| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("envis accumulation"),
                size: bytes,
                // COPY_DST: cleared at every restart of the mean.
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let mut map = self.accum.lock().expect("accumulation buffers");
        let size = UVec2::new(vp.z.max(1), vp.w.max(1));
        let entry = map.entry(view).or_insert_with(|| (buffer(16), UVec2::ZERO));
        if accumulate && entry.1 != size {
            *entry = (buffer(size.x as u64 * size.y as u64 * 16), size);
        }
        entry.0.clone()
    }

    pub(super) fn pipeline(
        &self,
        device: &wgpu::Device,
        format: wgpu::TextureFormat,
    ) -> wgpu::RenderPipeline {
        let mut map = self.by_format.lock().expect("lighting pipelines");
        map.entry(format)
            .or_insert_with(|| {
                device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some("envis lighting"),
                    layout: Some(&self.pipeline_layout),
                    vertex: wgpu::VertexState {
                        module: &self.module,
                        entry_point: Some("fullscreen"),
                        compilation_options: Default::default(),
                        buffers: &[],
                    },
                    fragment: Some(wgpu::FragmentState {
                        module: &self.module,
                        entry_point: Some("lighting"),
                        compilation_options: Default::default(),
                        // Premultiplied: alpha 0 adds to Bevy's lighting, alpha 1 replaces.
                        targets: &[Some(wgpu::ColorTargetState {
                            format,
                            blend: Some(wgpu::BlendState::PREMULTIPLIED_ALPHA_BLENDING),
                            write_mask: wgpu::ColorWrites::ALL,
                        })],
                    }),
                    primitive: Default::default(),
                    depth_stencil: None,
                    multisample: Default::default(),
                    multiview_mask: None,
                    cache: None,
                })
            })
            .clone()
    }
}
