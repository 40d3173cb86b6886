//! `EnvisLightingPlugin`: the face-weighted MIS lighting pass of every camera with
//! [`EnvironmentSampling`] and an [`EnvisEnvironment`]. It runs after Bevy's deferred lighting
//! (which keeps lighting `StandardMaterial` pixels with Bevy's own lights and shadows) and adds
//! the environment term on top; `EnvisMaterial` pixels get the environment alone; the background
//! shows the environment image. The pass decodes the G-buffer and runs the same `shade` function
//! as the headless backend (`shaders/shade.wgsl`), limited to the camera's viewport.

use super::components::{EnvironmentSampling, EnvisEnvironment};
use super::lighting_uniforms::{PROBE_BYTES, ViewParts, decode_probe, lighting_view};
use super::sampling::{EnvSamplers, ViewSampling};
use super::timing::{AsyncRead, AsyncTimer, EnvisTimings};
use super::{EnvisCounters, EnvisProbe, Overlay};
use crate::gpu::shaders;
use crate::gpu::shading::ShadeParams;
use crate::render::Strategy;
use bevy::camera::visibility::RenderLayers;
use bevy::core_pipeline::core_3d::main_opaque_pass_3d;
use bevy::core_pipeline::prepass::ViewPrepassTextures;
use bevy::core_pipeline::schedule::{Core3d, Core3dSystems};
use bevy::light::Skybox;
use bevy::prelude::*;
use bevy::render::camera::{ExtractedCamera, TemporalJitter};
use bevy::render::renderer::{RenderContext, RenderDevice, ViewQuery};
use bevy::render::view::{ExtractedView, ViewTarget};
use bevy::render::{Render, RenderApp, RenderStartup, RenderSystems};
use std::collections::HashMap;
use std::sync::Mutex;
use wgpu::util::DeviceExt;

/// The lighting pipeline (raw wgpu, shared WGSL with the headless backend), one per target format.
#[derive(Resource)]
pub struct LightingPipelines {
    layout: wgpu::BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    module: wgpu::ShaderModule,
    by_format: Mutex<HashMap<wgpu::TextureFormat, wgpu::RenderPipeline>>,
    /// Times the first envis camera's lighting pass of a frame.
    timer: Option<AsyncTimer>,
    /// The probed pixel's record (`lighting_uniforms::PROBE_RECORD`) and its readback.
    probe: wgpu::Buffer,
    probe_read: AsyncRead,
    /// Bound in place of the shadow BVH when a camera casts no shadow rays.
    no_shadows: wgpu::Buffer,
    /// The seed of the frame whose probe is being read back.
    probe_seed: Mutex<u32>,
    /// Per view: the running mean of the accumulated frames (one vec4 per pixel) and its size.
    accum: Mutex<HashMap<Entity, (wgpu::Buffer, UVec2)>>,
}

impl LightingPipelines {
    fn new(device: &wgpu::Device, queue: &wgpu::Queue) -> Self {
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
    fn accumulation_buffer(
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

    fn pipeline(&self, device: &wgpu::Device, format: wgpu::TextureFormat) -> wgpu::RenderPipeline {
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

/// Adds the envis lighting pass to every camera with [`EnvironmentSampling`] and an
/// [`EnvisEnvironment`].
pub struct EnvisLightingPlugin;

impl Plugin for EnvisLightingPlugin {
    fn build(&self, app: &mut App) {
        super::share_resources(app);
        app.add_systems(PostUpdate, super::coverage::warn_forward_meshes);
        let Some(render_app) = app.get_sub_app_mut(RenderApp) else {
            return;
        };
        render_app
            .add_systems(RenderStartup, init_lighting)
            .add_systems(
                Render,
                (poll_lighting_readbacks, drop_stale_view_buffers).in_set(RenderSystems::Prepare),
            )
            .add_systems(
                Core3d,
                mis_lighting
                    .after(bevy::pbr::deferred::deferred_lighting)
                    .before(main_opaque_pass_3d)
                    .in_set(Core3dSystems::MainPass),
            );
    }
}

/// Accumulation buffers of views that are gone (or stopped sampling) are freed.
fn drop_stale_view_buffers(
    pipes: Option<Res<LightingPipelines>>,
    views: Query<Entity, With<ViewSampling>>,
) {
    let Some(pipes) = pipes else { return };
    let mut map = pipes.accum.lock().expect("accumulation buffers");
    if map.keys().any(|e| !views.contains(*e)) {
        map.retain(|e, _| views.contains(*e));
    }
}

fn init_lighting(
    mut commands: Commands,
    device: Res<RenderDevice>,
    queue: Res<bevy::render::renderer::RenderQueue>,
) {
    commands.insert_resource(LightingPipelines::new(device.wgpu_device(), &queue));
}

/// Collect the lighting pass's GPU time and the probed pixel of an earlier frame (never waits).
fn poll_lighting_readbacks(
    pipes: Option<Res<LightingPipelines>>,
    timings: Res<EnvisTimings>,
    probe: Res<EnvisProbe>,
) {
    let Some(pipes) = pipes else { return };
    if let Some(ms) = pipes.timer.as_ref().and_then(|t| t.poll()) {
        timings.set(|t| t.lighting_gpu_ms = Some(ms));
    }
    if let Some(bytes) = pipes.probe_read.poll() {
        let seed = *pipes.probe_seed.lock().expect("probe seed");
        if let Some(r) = decode_probe(&bytes, seed) {
            *probe.lock().expect("probe") = Some(r);
        }
    }
}

/// What else of a view changes its lighting: which casters it sees, TAA's jitter, a skybox.
type ViewExtras = (
    Option<&'static RenderLayers>,
    Option<&'static TemporalJitter>,
    Option<&'static Skybox>,
);

/// A lit view's components: Bevy's target, prepass and extracted view, envis's settings.
type LightingViewData = (
    &'static ViewTarget,
    &'static ViewPrepassTextures,
    &'static ExtractedView,
    &'static ExtractedCamera,
    &'static EnvironmentSampling,
    &'static EnvisEnvironment,
    &'static ViewSampling,
    ViewExtras,
);

/// The per-view lighting pass: G-buffer + this frame's distribution and pool -> HDR radiance,
/// added to Bevy's lighting inside the view's viewport.
#[allow(clippy::too_many_arguments)]
fn mis_lighting(
    view: ViewQuery<LightingViewData>,
    pipes: Option<Res<LightingPipelines>>,
    samplers: Res<EnvSamplers>,
    shadows: (
        Option<Res<super::shadows::ShadowGeometry>>,
        Option<Res<super::shadows::GpuShadowGeometry>>,
    ),
    counters: Res<EnvisCounters>,
    timings: Res<EnvisTimings>,
    mut ctx: RenderContext,
) {
    let t0 = std::time::Instant::now();
    let view_entity = view.entity();
    let (target, prepass, ev, cam, sampling, env, vs, (render_layers, jitter, skybox)) =
        view.into_inner();
    let (Some(pipes), Some(slot)) = (pipes, samplers.slots.get(&vs.key)) else {
        return;
    };
    let sampler = &slot.sampler;
    let (Some(depth), Some(deferred), Some(ids)) = (
        prepass.depth_view(),
        prepass.deferred_view(),
        prepass.deferred_lighting_pass_id.as_ref(),
    ) else {
        return;
    };
    let mut s = sampling.settings();
    if s.strategy == Strategy::Global && !sampler.has_global() {
        return; // its distribution is built from the next frame on
    }
    if s.light_samples + s.brdf_samples == 0 {
        s.light_samples = 1;
    }
    let vp = ev.viewport;
    s.seed = vs.seed;
    let mut params = ShadeParams::new(&s, sampler.n, sampler.m, (vp.z * vp.w) as usize);
    let parts = ViewParts {
        ev,
        cam,
        jitter,
        render_layers,
        skybox: skybox.is_some_and(|s| s.image.is_some()),
    };
    let lv = lighting_view(parts, sampling, env, slot.layout);
    // Shadow rays when the camera asks for them and the uploaded geometry is this frame's.
    let geometry = match shadows {
        (Some(g), Some(gpu)) if g.enabled(sampling.shadows) && gpu.generation == g.generation => {
            params.bvh_nodes = gpu.node_count;
            Some(gpu)
        }
        _ => None,
    };
    let (bvh_nodes, bvh_triangles) = geometry
        .as_ref()
        .map_or((&pipes.no_shadows, &pipes.no_shadows), |g| {
            (&g.nodes, &g.triangles)
        });
    let device = ctx.render_device().wgpu_device().clone();
    let accum = pipes.accumulation_buffer(&device, view_entity, sampling.accumulate, vp);
    let pipeline = pipes.pipeline(&device, target.main_texture_format());
    let ubuf = |label: &str, bytes: &[u8]| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytes,
            usage: wgpu::BufferUsages::UNIFORM,
        })
    };
    let (pbuf, vbuf) = (
        ubuf("envis shade params", bytemuck::bytes_of(&params)),
        ubuf("envis lighting view", bytemuck::bytes_of(&lv)),
    );
    use wgpu::BindingResource as R;
    let resources = [
        R::TextureView(deferred),
        R::TextureView(depth),
        sampler.texels.as_entire_binding(),
        sampler.pool.as_entire_binding(),
        R::Buffer(sampler.regions_binding()),
        pbuf.as_entire_binding(),
        vbuf.as_entire_binding(),
        pipes.probe.as_entire_binding(),
        accum.as_entire_binding(),
        sampler.gdist.as_entire_binding(),
        R::TextureView(&ids.texture.default_view),
        R::TextureView(&slot.source),
        bvh_nodes.as_entire_binding(),
        bvh_triangles.as_entire_binding(),
    ];
    let entries: Vec<wgpu::BindGroupEntry> = resources
        .into_iter()
        .enumerate()
        .map(|(i, resource)| wgpu::BindGroupEntry {
            binding: i as u32,
            resource,
        })
        .collect();
    let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("envis lighting"),
        layout: &pipes.layout,
        entries: &entries,
    });
    let probing = sampling.probe.is_some() && pipes.probe_read.ready();
    let timer = pipes.timer.as_ref().filter(|t| t.ready());
    let enc = ctx.command_encoder();
    if probing {
        enc.clear_buffer(&pipes.probe, 0, None);
    }
    if sampling.accumulate && vs.frame == 0 {
        // A restart: every pixel's mean and count start again, also those this frame does not
        // shade (no geometry yet: a mesh is drawn from the frame after it was spawned).
        enc.clear_buffer(&accum, 0, None);
    }
    {
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("envis mis lighting"),
            color_attachments: &[Some(target.get_color_attachment())],
            depth_stencil_attachment: None,
            timestamp_writes: timer.map(|t| t.render_writes()),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        // Only this camera's viewport: a split-screen neighbour keeps its pixels.
        pass.set_viewport(vp.x as f32, vp.y as f32, vp.z as f32, vp.w as f32, 0.0, 1.0);
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.draw(0..3, 0..1);
    }
    if let Some(t) = timer {
        t.resolve(enc);
    }
    if probing {
        pipes.probe_read.copy_from(enc, &pipes.probe);
        *pipes.probe_seed.lock().expect("probe seed") = vs.seed;
    }
    counters.bump(|c| &c.lighting_passes);
    if sampling.overlay != Overlay::None {
        counters.bump(|c| &c.overlay_passes);
    }
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    timings.set(|t| t.lighting_cpu_ms = Some(ms));
}
