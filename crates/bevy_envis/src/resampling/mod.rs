//! `EnvisResamplingPlugin`: reservoir resampling (ReSTIR) of the environment light for every
//! camera with [`EnvironmentResampling`] (besides [`EnvironmentSampling`] and
//! [`EnvisEnvironment`]): the Bevy pass of `render::resampling::resample_frame`
//! (`docs/temporal.md`). Per camera per frame, in the `Core3d` schedule after Bevy's deferred
//! lighting and before envis's lighting pass:
//! 1. the gather (`shaders/gather.wgsl`): Bevy's prepass textures (G-buffer, depth, lighting-pass
//!    ids, motion vectors) into the surfaces and the reprojection the passes read, and the
//!    map's texel table into the split map;
//! 2. the resampling passes themselves, the WGSL the headless twin runs
//!    (`envis_wgpu::resampling::ResamplingPasses`): candidates (the camera's `light_samples` +
//!    `brdf_samples`), temporal reuse of the previous frame's reservoirs, spatial reuse, shading
//!    with one shadow ray for the selected sample (plus the unbiased reuse's visibility rays).
//!
//! The lighting pass then shows the resampled image instead of its own estimate. Nothing is
//! read back, but for a camera with [`ResamplingReadback`] (offline tools: the frame's counts).
//! The map's bright part is resampled apart from the rest (`bright.rs`) where the camera's map
//! is on the CPU (`cpu_maps.rs`: the envis stream's frame, or a user image's texels); otherwise
//! the map is resampled whole, as `split_bright: false`. Bevy's
//! G-buffer has no object ids: the geometric tests are normal and depth.

mod bright;
mod cpu_maps;
mod frame;
mod gather;
mod readback;
mod view;

pub use cpu_maps::source_from_image;
pub use readback::{FrameCounts, ResamplingCounts, ResamplingReadback};

use super::components::{EnvironmentResampling, EnvironmentSampling, EnvisEnvironment};
use super::programs::EnvisPrograms;
use super::sampling::{EnvSamplers, ViewSampling};
use super::shadows::{GpuShadowGeometry, ShadowGeometry};
use super::{EnvisCounters, EnvisTimings, lighting};
use bevy::camera::visibility::RenderLayers;
use bevy::core_pipeline::prepass::ViewPrepassTextures;
use bevy::core_pipeline::schedule::{Core3d, Core3dSystems};
use bevy::prelude::*;
use bevy::render::camera::TemporalJitter;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::renderer::{RenderContext, RenderQueue, ViewQuery};
use bevy::render::sync_world::RenderEntity;
use bevy::render::view::ExtractedView;
use bevy::render::{ExtractSchedule, MainWorld, Render, RenderApp, RenderSystems};
use envis_wgpu::resampling::ResamplingPasses;
use frame::{FrameInputs, hand_over, history_valid, record, write_uniforms};
use gather::GatherPipelines;
use std::collections::HashMap;
use std::sync::Mutex;
use view::ViewResampling;

/// Adds the resampling pass to every camera with [`EnvironmentResampling`] (part of
/// `EnvisPlugin`).
pub struct EnvisResamplingPlugin;

impl Plugin for EnvisResamplingPlugin {
    fn build(&self, app: &mut App) {
        super::share_resources(app);
        super::programs::add_programs(app);
        app.register_type::<EnvironmentResampling>();
        let Some(render_app) = app.get_sub_app_mut(RenderApp) else {
            return;
        };
        render_app
            .init_resource::<ResamplingResources>()
            .init_resource::<cpu_maps::CpuEnvMaps>()
            .add_systems(ExtractSchedule, extract_resampling)
            .add_systems(
                Render,
                (drop_stale_views, poll_readbacks)
                    .chain()
                    .in_set(RenderSystems::Prepare),
            )
            .add_systems(
                Core3d,
                resample_environment
                    .after(bevy::pbr::deferred::deferred_lighting)
                    .before(lighting::envis_lighting)
                    .in_set(Core3dSystems::MainPass),
            );
    }
}

/// Copy each active camera's [`EnvironmentResampling`] (and [`ResamplingReadback`]) into the
/// render world (removed there when it is removed here), then clear its `reset`, as TAA does.
fn extract_resampling(
    mut commands: Commands,
    mut main_world: ResMut<MainWorld>,
    mut maps: ResMut<cpu_maps::CpuEnvMaps>,
) {
    let mut cameras = main_world.query::<(
        RenderEntity,
        &Camera,
        Option<&mut EnvironmentResampling>,
        Option<&ResamplingReadback>,
    )>();
    cpu_maps::extract_cpu_maps(&mut maps, &mut main_world);
    for (entity, camera, settings, readback) in cameras.iter_mut(&mut main_world) {
        let Ok(mut target) = commands.get_entity(entity) else {
            continue;
        };
        match readback {
            Some(r) => target.insert(r.clone()),
            None => target.remove::<ResamplingReadback>(),
        };
        match settings {
            Some(mut settings) if camera.is_active => {
                target.insert(*settings);
                // Only when set: an unconditional write would mark the component changed
                // every frame.
                if settings.reset {
                    settings.reset = false;
                }
            }
            _ => {
                target.remove::<EnvironmentResampling>();
            }
        }
    }
}

/// The buffers of views that are gone or stopped resampling are freed (and their history with
/// them: adding the component again starts afresh); a view the pass skipped last frame (its
/// map or prepass not ready) loses its history, which the motion vectors no longer reach.
fn drop_stale_views(
    res: Option<Res<ResamplingResources>>,
    views: Query<Entity, (With<EnvironmentResampling>, With<ViewSampling>)>,
    counters: Res<EnvisCounters>,
) {
    if let Some(res) = res
        && let Ok(mut kept) = res.views.lock()
    {
        kept.retain(|e, _| views.contains(*e));
        for v in kept.values_mut() {
            if !std::mem::take(&mut v.ran) {
                v.prev = None;
            }
        }
        counters
            .resampling_views
            .store(kept.len() as u64, std::sync::atomic::Ordering::Relaxed);
    }
}

/// Collect the counts copied for [`ResamplingReadback`] (never waits).
fn poll_readbacks(res: Option<Res<ResamplingResources>>) {
    if let Some(res) = res
        && let Ok(mut kept) = res.views.lock()
    {
        kept.values_mut().for_each(|v| v.reads.poll());
    }
}

/// The resampling pass's programs: the passes and the gather (compiled by
/// [`EnvisPrograms`], off the frame path).
pub struct ResamplingPrograms {
    passes: ResamplingPasses,
    gather: GatherPipelines,
}

impl ResamplingPrograms {
    /// Compile both on `device` (the caller checked that it can run them:
    /// [`ResamplingPasses::supported`]).
    pub(crate) fn new(device: &wgpu::Device) -> Self {
        ResamplingPrograms {
            passes: ResamplingPasses::new(device),
            gather: GatherPipelines::new(device),
        }
    }
}

/// What the resampling pass keeps: each resampling camera's buffers.
#[derive(Resource, Default)]
pub struct ResamplingResources {
    views: Mutex<HashMap<Entity, ViewResampling>>,
}

/// A resampling view's components.
type ResamplingViewData = (
    &'static ExtractedView,
    &'static ViewPrepassTextures,
    &'static EnvironmentSampling,
    &'static EnvisEnvironment,
    &'static ViewSampling,
    &'static EnvironmentResampling,
    Option<&'static RenderLayers>,
    Option<&'static TemporalJitter>,
    Option<&'static ResamplingReadback>,
);

/// The prepass views the gather reads: G-buffer, depth, lighting-pass ids, motion vectors.
fn prepass_views(
    p: &ViewPrepassTextures,
) -> Option<(
    &wgpu::TextureView,
    &wgpu::TextureView,
    &wgpu::TextureView,
    &wgpu::TextureView,
)> {
    Some((
        p.deferred_view()?,
        p.depth_view()?,
        &p.deferred_lighting_pass_id.as_ref()?.texture.default_view,
        p.motion_vectors_view()?,
    ))
}

/// The render world's state the resampling pass reads besides the view.
#[derive(bevy::ecs::system::SystemParam)]
pub struct ResamplingInputs<'w> {
    res: Option<Res<'w, ResamplingResources>>,
    programs: Option<Res<'w, EnvisPrograms>>,
    counters: Res<'w, EnvisCounters>,
    timings: Res<'w, EnvisTimings>,
    queue: Res<'w, RenderQueue>,
    readiness: Option<Res<'w, super::ready::BevyReadiness>>,
    shown: Option<Res<'w, lighting::ShownImages>>,
}

/// The per-view resampling pass: gather, then the resampling passes, recorded into the frame's
/// encoder.
fn resample_environment(
    view: ViewQuery<ResamplingViewData>,
    samplers: Res<EnvSamplers>,
    shadows: (Option<Res<ShadowGeometry>>, Option<Res<GpuShadowGeometry>>),
    inputs: ResamplingInputs,
    maps: Option<Res<cpu_maps::CpuEnvMaps>>,
    mut ctx: RenderContext,
) {
    let t0 = std::time::Instant::now();
    let ResamplingInputs {
        res,
        programs,
        counters,
        timings,
        queue,
        readiness,
        shown,
    } = inputs;
    let entity = view.entity();
    // Not before the view is lit: its G-buffer may not be Bevy's whole one yet.
    if readiness.is_some_and(|r| !r.allowed(entity)) {
        return;
    }
    let (ev, prepass, sampling, env, vs, settings, layers, jitter, readback) = view.into_inner();
    let (Some(res), Some(programs), Some(slot)) = (res, programs, samplers.slots.get(&vs.key))
    else {
        return;
    };
    let device = ctx.render_device().wgpu_device().clone();
    // Until its programs are compiled the camera is lit without resampling.
    let (Some(ResamplingPrograms { passes, gather }), Some(textures), Some(shade)) = (
        programs.resampling(),
        prepass_views(prepass),
        lighting::shade_params(sampling, vs.seed, &slot.sampler, ev.viewport),
    ) else {
        return;
    };
    let Ok(mut views) = res.views.lock() else {
        return;
    };
    let n = slot.sampler.n as u32;
    let Some(state) = view_state(&mut views, &device, entity, ev.viewport.zw(), 6 * n * n) else {
        return;
    };
    state.ran = true;
    let geometry = lighting::shadow_geometry(&shadows, sampling).0;
    let frame = FrameInputs {
        ev,
        env,
        settings,
        layers: super::shadows::layers_of(layers).0,
        jitter,
        seed: vs.seed,
        bvh: geometry.map(|g| (g.nodes.clone(), g.triangles.clone(), g.node_count)),
        geometry: geometry.map(|g| (g.generation, g.placement)),
    };
    if !history_valid(state.prev.as_ref(), &frame, n) {
        state.prev = None;
    }
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let enc = ctx.command_encoder();
    // Timed in Bevy's render diagnostics (`render/envis_resampling/elapsed_gpu`).
    let span = diagnostics.time_span(enc, "envis_resampling");
    bright::view_split(
        &mut state.bright,
        (maps.as_deref(), env.image.id()),
        &slot.sampler,
        envis::render::pool_seed(vs.seed),
        (&device, &queue, enc),
    );
    write_uniforms(&queue, state, &frame, &shade);
    record(
        enc,
        &device,
        (passes, gather),
        state,
        (&slot.sampler, textures),
        &frame,
    );
    if let Some(shown) = shown {
        shown.show(entity, state.color.clone());
    }
    let histories = state.prev.is_some();
    let bright = state.bright.as_ref().is_some_and(|b| b.count > 0);
    hand_over(state, &device, enc, geometry, &frame, n);
    if let Some(r) = readback {
        let buffers = [&state.counters, &state.stats, &state.color];
        state.reads.copy(&device, enc, r, buffers);
    }
    span.end(enc);
    counters.bump(|c| &c.resampling_passes);
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    timings.set(|t| t.resampling_cpu_ms = Some(ms));
    if histories {
        counters.bump(|c| &c.resampling_histories);
    }
    if bright {
        counters.bump(|c| &c.resampling_bright);
    }
}

/// The view's buffers, made anew when its viewport or map size changed (the history is lost
/// then); `None`, with a warning once, where the device cannot hold them.
fn view_state<'a>(
    views: &'a mut HashMap<Entity, ViewResampling>,
    device: &wgpu::Device,
    entity: Entity,
    size: UVec2,
    texels: u32,
) -> Option<&'a mut ViewResampling> {
    if views
        .get(&entity)
        .is_none_or(|v| v.size != size || v.texels != texels)
    {
        match ViewResampling::new(device, size, texels) {
            Ok(v) => {
                views.insert(entity, v);
            }
            Err(e) => {
                views.remove(&entity);
                bevy::log::warn_once!("envis resampling is off for a camera: {e}");
                return None;
            }
        }
    }
    views.get_mut(&entity)
}
