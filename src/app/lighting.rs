//! `EnvisLightingPlugin`: the face-weighted MIS lighting pass of every camera with
//! [`EnvironmentSampling`] and an [`EnvisEnvironment`]. It runs after Bevy's deferred lighting
//! (which keeps lighting `StandardMaterial` pixels with Bevy's own lights and shadows) and adds
//! the environment term on top; `EnvisMaterial` pixels get the environment alone; the background
//! shows the environment image. The pass decodes the G-buffer and runs the same `shade` function
//! as the headless backend (`shaders/shade.wgsl`), limited to the camera's viewport.

use super::components::{EnvironmentSampling, EnvisEnvironment};
use super::lighting_uniforms::{ViewParts, decode_probe, lighting_view};
use super::sampling::{EnvSamplers, ViewSampling};
use super::timing::EnvisTimings;
use super::{EnvisCounters, EnvisProbe, Overlay};
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
use wgpu::util::DeviceExt;

mod pipelines;
pub use pipelines::LightingPipelines;

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
