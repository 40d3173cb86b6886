//! `EnvisLightingPlugin`: the face-weighted MIS lighting pass of every camera with
//! [`EnvironmentSampling`] and an [`EnvisEnvironment`]. It runs after Bevy's deferred lighting
//! (which keeps lighting `StandardMaterial` pixels with Bevy's own lights and shadows) and adds
//! the environment term on top; `EnvisMaterial` pixels get the environment alone; the background
//! shows the environment image. The pass decodes the G-buffer and runs the same `shade` function
//! as the headless backend (`shaders/shade.wgsl`), limited to the camera's viewport.

use super::components::{EnvironmentSampling, EnvisEnvironment};
use super::lighting_uniforms::{LightingView, ViewParts, decode_probe, lighting_view};
use super::programs::EnvisPrograms;
use super::ready::{BevyReadiness, ReadyReport};
use super::sampling::{EnvSamplers, SamplerSlot, ViewSampling};
use super::timing::EnvisTimings;
use super::{EnvisCounters, EnvisProbe, Overlay};
use bevy::camera::visibility::RenderLayers;
use bevy::core_pipeline::core_3d::main_opaque_pass_3d;
use bevy::core_pipeline::prepass::ViewPrepassTextures;
use bevy::core_pipeline::schedule::{Core3d, Core3dSystems};
use bevy::ecs::system::SystemParam;
use bevy::light::Skybox;
use bevy::pbr::deferred::DeferredLightingPipeline;
use bevy::prelude::*;
use bevy::render::camera::{ExtractedCamera, TemporalJitter};
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::render_resource::{PipelineCache, TextureFormat, TextureView};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderQueue, ViewQuery};
use bevy::render::sync_world::MainEntity;
use bevy::render::view::{ExtractedView, ViewTarget};
use bevy::render::{Render, RenderApp, RenderStartup, RenderSystems};
use envis::render::Strategy;
use envis_wgpu::sampler::EnvSampler;
use envis_wgpu::shading::ShadeParams;

mod pipelines;
pub use pipelines::{LightingEntry, LightingResources, lighting_layout};

/// Adds the envis lighting pass to every camera with [`EnvironmentSampling`] and an
/// [`EnvisEnvironment`], and the [`EnvisLightReady`](super::EnvisLightReady) marker on the
/// cameras it lit.
pub struct EnvisLightingPlugin;

impl Plugin for EnvisLightingPlugin {
    fn build(&self, app: &mut App) {
        super::share_resources(app);
        super::programs::add_programs(app);
        super::ready::add_ready(app);
        app.add_systems(PostUpdate, super::coverage::warn_forward_meshes);
        let Some(render_app) = app.get_sub_app_mut(RenderApp) else {
            return;
        };
        render_app
            .init_resource::<ShownImages>()
            .add_systems(RenderStartup, init_lighting)
            .add_systems(
                Render,
                (poll_lighting_readbacks, drop_stale_view_buffers).in_set(RenderSystems::Prepare),
            )
            .add_systems(Render, ShownImages::clear.in_set(RenderSystems::Cleanup))
            .add_systems(
                Core3d,
                envis_lighting
                    .after(bevy::pbr::deferred::deferred_lighting)
                    .before(main_opaque_pass_3d)
                    .in_set(Core3dSystems::MainPass),
            );
    }
}

/// Images a pass before this one made for a view this frame, which the lighting pass shows
/// instead of its own estimate (the resampling pass's image): the one way resampling hands its
/// result to lighting, so lighting needs nothing of resampling. Each is taken once; what a frame
/// did not take is dropped at its end.
#[derive(Resource, Default)]
pub struct ShownImages(std::sync::Mutex<std::collections::HashMap<Entity, wgpu::Buffer>>);

impl ShownImages {
    /// Show `image` (laid out as `shaders/lighting.wgsl`'s accumulation binding) on `view` this
    /// frame.
    pub fn show(&self, view: Entity, image: wgpu::Buffer) {
        if let Ok(mut images) = self.0.lock() {
            images.insert(view, image);
        }
    }

    /// The image made for `view` this frame, if any (taken: a second call gets `None`).
    fn take(&self, view: Entity) -> Option<wgpu::Buffer> {
        self.0.lock().ok()?.remove(&view)
    }

    fn clear(images: Res<ShownImages>) {
        if let Ok(mut images) = images.0.lock() {
            images.clear();
        }
    }
}

/// Buffers of views that are gone (or stopped sampling) are freed.
fn drop_stale_view_buffers(
    res: Option<Res<LightingResources>>,
    views: Query<Entity, With<ViewSampling>>,
) {
    if let Some(res) = res {
        res.retain_views(|e| views.contains(e));
    }
}

/// The view's lighting pipeline for this frame: the one showing the resampled image where the
/// pass has one and draws no overlay, once compiled (until then the shading one, `shade`, shows
/// it, the same); else `shade`.
fn pick_pipeline(
    programs: &EnvisPrograms,
    format: TextureFormat,
    showing: bool,
    shade: wgpu::RenderPipeline,
) -> wgpu::RenderPipeline {
    let show = showing
        .then(|| programs.lighting(format, LightingEntry::ShowResampled))
        .flatten();
    show.unwrap_or(shade)
}

fn init_lighting(mut commands: Commands, device: Res<RenderDevice>) {
    commands.insert_resource(LightingResources::new(device.wgpu_device()));
}

/// Collect the probed pixel of an earlier frame (never waits).
fn poll_lighting_readbacks(res: Option<Res<LightingResources>>, probe: Res<EnvisProbe>) {
    let Some(res) = res else { return };
    if let Some(bytes) = res.probe_read.poll() {
        let seed = *res.probe_seed.lock().expect("probe seed");
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

/// [`ViewExtras`] as the view query reads them.
type ViewExtrasItem<'a> = (
    Option<&'a RenderLayers>,
    Option<&'a TemporalJitter>,
    Option<&'a Skybox>,
);

/// A lit view's components: Bevy's target, prepass and extracted view, envis's settings, and
/// what says whether Bevy is ready under it.
type LightingViewData = (
    &'static ViewTarget,
    &'static ViewPrepassTextures,
    &'static ExtractedView,
    &'static ExtractedCamera,
    &'static EnvironmentSampling,
    &'static EnvisEnvironment,
    &'static ViewSampling,
    ViewExtras,
    (
        &'static MainEntity,
        Option<&'static DeferredLightingPipeline>,
    ),
);

/// The render world's state the lighting pass reads.
#[derive(SystemParam)]
pub struct LightingInputs<'w> {
    cache: Res<'w, PipelineCache>,
    programs: Option<Res<'w, EnvisPrograms>>,
    res: Option<Res<'w, LightingResources>>,
    samplers: Res<'w, EnvSamplers>,
    shadows: Shadows<'w>,
    counters: Res<'w, EnvisCounters>,
    timings: Res<'w, EnvisTimings>,
    queue: Res<'w, RenderQueue>,
    shown: Res<'w, ShownImages>,
    report: Res<'w, ReadyReport>,
}

/// The scene's shadow geometry on the CPU (its generation) and on the GPU.
pub(super) type Shadows<'w> = (
    Option<Res<'w, super::shadows::ShadowGeometry>>,
    Option<Res<'w, super::shadows::GpuShadowGeometry>>,
);

/// The per-view lighting pass: G-buffer + this frame's distribution and pool -> HDR radiance,
/// added to Bevy's lighting inside the view's viewport. A view is lit from the frame its
/// programs are compiled, its distribution built and Bevy's passes under it ready
/// ([`BevyReadiness`]); until then Bevy's image is left as it is.
pub(crate) fn envis_lighting(
    view: ViewQuery<LightingViewData>,
    inputs: LightingInputs,
    mut readiness: ResMut<BevyReadiness>,
    mut ctx: RenderContext,
) {
    let t0 = std::time::Instant::now();
    let view_entity = view.entity();
    let (target, prepass, ev, cam, sampling, env, vs, extras, (main, deferred)) = view.into_inner();
    let i = &inputs;
    let (Some(programs), Some(res), Some(slot)) = (&i.programs, &i.res, i.samplers.built(&vs.key))
    else {
        return;
    };
    let Some(prepass_views) = prepass_views(prepass) else {
        return;
    };
    let vp = ev.viewport;
    let Some((params, mut lv, geometry)) =
        view_uniforms((ev, cam, extras), (sampling, env, vs), slot, &i.shadows)
    else {
        return;
    };
    // Compiled off the frame path: lit from the frame its pipeline is ready.
    let Some(shade) = programs.lighting(ev.target_format, LightingEntry::Shade) else {
        return;
    };
    if !readiness.allows(view_entity, &i.cache, deferred) {
        return;
    }
    // The resampling pass's image, where it ran for this view this frame.
    let resampled = i.shown.take(view_entity);
    lv.resampled = resampled.is_some() as u32;
    let showing = resampled.is_some() && sampling.overlay == Overlay::None;
    let render_pipeline = pick_pipeline(programs, ev.target_format, showing, shade);
    let (bvh_nodes, bvh_triangles) = geometry.map_or((&res.no_shadows, &res.no_shadows), |g| {
        (&g.nodes, &g.triangles)
    });
    let device = ctx.render_device().clone();
    let (pbuf, vbuf, accum) = res.view_buffers(
        (device.wgpu_device(), &i.queue),
        view_entity,
        (sampling.accumulate, vp),
        (bytemuck::bytes_of(&params), bytemuck::bytes_of(&lv)),
    );
    // The resampled image takes the accumulation's binding (`shaders/lighting.wgsl`).
    let bind = lighting_bind_group(
        (device.wgpu_device(), programs),
        (slot, res),
        prepass_views,
        [&pbuf, &vbuf, resampled.as_ref().unwrap_or(&accum)],
        (bvh_nodes, bvh_triangles),
    );
    encode_lighting(
        &mut ctx,
        (res, &accum),
        (sampling, vs),
        (target, vp, &render_pipeline, &bind),
    );
    i.report.lit(main.id());
    count_lighting_pass((&i.counters, &i.timings), sampling, t0);
}

/// The prepass views the pass reads: the deferred G-buffer, depth and the lighting-pass ids;
/// `None` while the prepass has not made them.
fn prepass_views(
    prepass: &ViewPrepassTextures,
) -> Option<(&TextureView, &TextureView, &TextureView)> {
    let (Some(depth), Some(deferred), Some(ids)) = (
        prepass.depth_view(),
        prepass.deferred_view(),
        prepass.deferred_lighting_pass_id.as_ref(),
    ) else {
        return None;
    };
    Some((deferred, depth, &ids.texture.default_view))
}

/// The view's shading parameters (with the BVH's node count), its view uniforms and the shadow
/// geometry its rays traverse; `None` while the global strategy's distribution is not built (see
/// [`shade_params`]).
fn view_uniforms<'a>(
    (ev, cam, (render_layers, jitter, skybox)): (&ExtractedView, &ExtractedCamera, ViewExtrasItem),
    (sampling, env, vs): (&EnvironmentSampling, &EnvisEnvironment, &ViewSampling),
    slot: &SamplerSlot,
    shadows: &'a Shadows,
) -> Option<(
    ShadeParams,
    LightingView,
    Option<&'a super::shadows::GpuShadowGeometry>,
)> {
    let mut params = shade_params(sampling, vs.seed, &slot.sampler, ev.viewport)?;
    let parts = ViewParts {
        ev,
        cam,
        jitter,
        render_layers,
        skybox: skybox.is_some_and(|s| s.image.is_some()),
    };
    let lv = lighting_view(parts, sampling, env, slot.layout);
    let (geometry, bvh_nodes) = shadow_geometry(shadows, sampling);
    params.bvh_nodes = bvh_nodes;
    Some((params, lv, geometry))
}

/// Record the view's pass into the frame's encoder: the probe cleared when a pixel is probed,
/// the accumulation on a restart, the pass itself, then the probe copied for readback.
fn encode_lighting(
    ctx: &mut RenderContext,
    (res, accum): (&LightingResources, &wgpu::Buffer),
    (sampling, vs): (&EnvironmentSampling, &ViewSampling),
    (target, vp, pipeline, bind): (&ViewTarget, UVec4, &wgpu::RenderPipeline, &wgpu::BindGroup),
) {
    let probing = sampling.probe.is_some() && res.probe_read.ready();
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let enc = ctx.command_encoder();
    if probing {
        enc.clear_buffer(&res.probe, 0, None);
    }
    if sampling.accumulate && vs.frame == 0 {
        // A restart: every pixel's mean and count start again, also those this frame does not
        // shade (no geometry yet: a mesh is drawn from the frame after it was spawned).
        enc.clear_buffer(accum, 0, None);
    }
    record_lighting_pass(enc, &diagnostics, target, vp, pipeline, bind);
    if probing {
        res.probe_read.copy_from(enc, &res.probe);
        *res.probe_seed.lock().expect("probe seed") = vs.seed;
    }
}

/// Count the lighting pass (and its overlay, which runs inside it) and keep its CPU time since
/// `t0`.
fn count_lighting_pass(
    (counters, timings): (&EnvisCounters, &EnvisTimings),
    sampling: &EnvironmentSampling,
    t0: std::time::Instant,
) {
    counters.bump(|c| &c.lighting_passes);
    if sampling.overlay != Overlay::None {
        counters.bump(|c| &c.overlay_passes);
    }
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    timings.set(|t| t.lighting_cpu_ms = Some(ms));
}

/// The shadow geometry the view's rays traverse, and its BVH's node count (0: no shadow rays):
/// when the camera asks for shadows and the uploaded geometry is this frame's.
pub(super) fn shadow_geometry<'a>(
    shadows: &'a Shadows,
    sampling: &EnvironmentSampling,
) -> (Option<&'a super::shadows::GpuShadowGeometry>, u32) {
    match shadows {
        (Some(g), Some(gpu)) if g.enabled(sampling.shadows) && gpu.generation == g.generation => {
            (Some(&**gpu), gpu.node_count)
        }
        _ => (None, 0),
    }
}

/// The view's shading parameters: its settings with the view's `seed`, over its viewport `vp`.
/// `None` while the global strategy's distribution is not built (it is from the next frame on).
pub(super) fn shade_params(
    sampling: &EnvironmentSampling,
    seed: u32,
    sampler: &EnvSampler,
    vp: UVec4,
) -> Option<ShadeParams> {
    let mut s = *sampling;
    if s.strategy == Strategy::Global && !sampler.has_global() {
        return None;
    }
    if s.light_samples + s.brdf_samples == 0 {
        s.light_samples = 1;
    }
    s.seed = seed;
    Some(ShadeParams::new(
        &s,
        sampler.n,
        sampler.m,
        (vp.z * vp.w) as usize,
    ))
}

/// The lighting pass's bind group, in binding order (`lighting_layout`): the prepass views
/// (deferred G-buffer, depth, lighting-pass ids), the sampler's tables, the per-view buffers
/// (params, view, accumulation or the resampled image), the source image and the shadow BVH.
fn lighting_bind_group(
    (device, programs): (&wgpu::Device, &EnvisPrograms),
    (slot, res): (&SamplerSlot, &LightingResources),
    (deferred, depth, ids): (&TextureView, &TextureView, &TextureView),
    [pbuf, vbuf, accum]: [&wgpu::Buffer; 3],
    (bvh_nodes, bvh_triangles): (&wgpu::Buffer, &wgpu::Buffer),
) -> wgpu::BindGroup {
    use wgpu::BindingResource as R;
    let sampler = &slot.sampler;
    let entries = envis_wgpu::sequential_entries([
        R::TextureView(deferred),
        R::TextureView(depth),
        sampler.texels.as_entire_binding(),
        sampler.pool.as_entire_binding(),
        R::Buffer(sampler.regions_binding()),
        pbuf.as_entire_binding(),
        vbuf.as_entire_binding(),
        res.probe.as_entire_binding(),
        accum.as_entire_binding(),
        sampler.gdist.as_entire_binding(),
        R::TextureView(ids),
        R::TextureView(&slot.source),
        bvh_nodes.as_entire_binding(),
        bvh_triangles.as_entire_binding(),
    ]);
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("envis lighting"),
        layout: programs.lighting_group_layout(),
        entries: &entries,
    })
}

/// One fullscreen triangle over the view's target, limited to its viewport `vp`, timed in
/// Bevy's render diagnostics (`render/envis_lighting/elapsed_gpu`).
fn record_lighting_pass(
    enc: &mut wgpu::CommandEncoder,
    diagnostics: &impl RecordDiagnostics,
    target: &ViewTarget,
    vp: UVec4,
    pipeline: &wgpu::RenderPipeline,
    bind: &wgpu::BindGroup,
) {
    let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("envis mis lighting"),
        color_attachments: &[Some(target.get_color_attachment())],
        depth_stencil_attachment: None,
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
    let span = diagnostics.pass_span(&mut pass, "envis_lighting");
    // Only this camera's viewport: a split-screen neighbour keeps its pixels.
    pass.set_viewport(vp.x as f32, vp.y as f32, vp.z as f32, vp.w as f32, 0.0, 1.0);
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, bind, &[]);
    pass.draw(0..3, 0..1);
    span.end(&mut pass);
}
