//! `EnvisSamplingPlugin`: the sampling distribution and light pool of every environment in use,
//! built on the GPU from the `Image` texture itself (resample, distribution, pool) in the render
//! world's `RenderGraph` schedule before `camera_driver`, so every camera of the frame shades with
//! this frame's distribution.
//!
//! A distribution is kept per (image, face size, pool size, pool seed): cameras that agree share
//! one; an accumulating camera, whose pool changes every frame, has its own. It is rebuilt only
//! when the image changed (an `AssetEvent`, or a new GPU texture), every frame for a `dynamic`
//! environment, and when its pool seed changed; distributions no camera used this frame are
//! dropped.

use super::components::{EnvironmentSampling, EnvisEnvironment};
use super::programs::EnvisPrograms;
use super::ready::BevyStarted;
use super::timing::EnvisTimings;
use super::{Counters, EnvisCounters};
use bevy::camera::visibility::RenderLayers;
use bevy::core_pipeline::schedule::camera_driver;
use bevy::ecs::query::QueryItem;
use bevy::prelude::*;
use bevy::render::camera::TemporalJitter;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::extract_component::ExtractComponentPlugin;
use bevy::render::extract_resource::{ExtractResource, ExtractResourcePlugin};
use bevy::render::render_asset::RenderAssets;
use bevy::render::renderer::{
    RenderContext, RenderDevice, RenderGraph, RenderGraphSystems, RenderQueue,
};
use bevy::render::sync_world::MainEntity;
use bevy::render::texture::GpuImage;
use bevy::render::view::ExtractedView;
use bevy::render::{Render, RenderApp, RenderSystems};
use envis::envmap::resample::SourceLayout;
use envis::render::{Strategy, pool_seed};
use envis_wgpu::EnvSampler;
use envis_wgpu::resample::source_view;
use std::collections::{HashMap, HashSet};

pub use super::scene_revision::{SceneRevision, track_scene_changes};

mod accumulation;
mod slots;
use accumulation::{accumulation_key, frame_seed, next_frame};
use slots::{check_source, slot_for};

/// How often each environment image changed in the main world (its `AssetEvent`s), extracted to
/// the render world: a new version means "rebuild from this image".
#[derive(Resource, Clone, Default, ExtractResource)]
pub struct EnvImageVersions(pub HashMap<AssetId<Image>, u64>);

/// Whose seed a pool has: every camera with this seed, or one accumulating camera.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SeedOwner {
    Shared(u32),
    View(Entity),
}

/// Identifies a distribution + pool in the render world.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SamplerKey {
    pub image: AssetId<Image>,
    pub face_size: usize,
    /// Tiles per face side (`K`, already clamped to the face size).
    pub tiles: usize,
    /// Slots per region (`M` x blocks) and the blocks they split into.
    pub pool_slots: usize,
    pub pool_blocks: usize,
    pub seed: SeedOwner,
}

/// One built distribution and what it was built from.
pub struct SamplerSlot {
    pub sampler: EnvSampler,
    /// The source texture (all layers) and its layout, also read by the lighting pass for the
    /// background at full resolution.
    pub source: wgpu::TextureView,
    pub layout: SourceLayout,
    width: u32,
    /// (image version, texture) the table was last resampled from; the pool seed last drawn.
    built: Option<(u64, bevy::render::render_resource::TextureId)>,
    seed: Option<u32>,
    dirty: bool,
    /// Times the distribution was built (the lighting pass resets accumulation when it changes).
    pub generation: u64,
}

/// The view's distribution and accumulation state (render world, on the view entity).
#[derive(Component, Clone, Copy, Debug)]
pub struct ViewSampling {
    pub key: SamplerKey,
    /// Frames averaged before this one (0: this frame starts the mean).
    pub frame: u32,
    /// Seed of this frame's per-pixel streams.
    pub seed: u32,
}

/// Every distribution of the render world.
#[derive(Resource, Default)]
pub struct EnvSamplers {
    pub slots: HashMap<SamplerKey, SamplerSlot>,
    /// Per view: what its accumulation key was and how many frames it has averaged.
    accumulation: HashMap<Entity, (u64, u32)>,
    /// Per jittered view that does not accumulate: frames drawn, so that each draws new samples.
    ticks: HashMap<Entity, u32>,
    /// Images already reported as unusable (reported once).
    refused: HashSet<AssetId<Image>>,
}

pub struct EnvisSamplingPlugin;

impl Plugin for EnvisSamplingPlugin {
    fn build(&self, app: &mut App) {
        super::share_resources(app);
        super::programs::add_programs(app);
        super::components::require_camera_set_up(app);
        app.init_resource::<EnvImageVersions>()
            .init_resource::<SceneRevision>()
            .add_plugins((
                ExtractComponentPlugin::<EnvironmentSampling, EnvisSamplingPlugin>::default(),
                ExtractComponentPlugin::<EnvisEnvironment>::default(),
                ExtractResourcePlugin::<EnvImageVersions>::default(),
                ExtractResourcePlugin::<SceneRevision>::default(),
            ))
            .add_systems(
                PostUpdate,
                (
                    // After the asset events of this frame are sent (and before extraction
                    // drops a render-world-only image's bytes from the main world).
                    track_image_versions.after(bevy::asset::AssetEventSystems),
                    track_scene_changes
                        .after(bevy::asset::AssetEventSystems)
                        .after(bevy::mesh::mark_3d_meshes_as_changed_if_their_assets_changed)
                        .after(bevy::transform::TransformSystems::Propagate)
                        .after(bevy::camera::visibility::VisibilitySystems::VisibilityPropagate),
                ),
            );
        let Some(render_app) = app.get_sub_app_mut(RenderApp) else {
            return;
        };
        render_app
            .init_resource::<EnvSamplers>()
            .add_systems(Render, prepare_samplers.in_set(RenderSystems::Prepare))
            .add_systems(
                RenderGraph,
                // In the frame's render phase (after Bevy's diagnostics begin the frame), before
                // any camera.
                build_distributions
                    .in_set(RenderGraphSystems::Render)
                    .before(camera_driver),
            );
    }
}

impl EnvSamplers {
    /// The distribution of `key` once it has been built (from the frame of its first build:
    /// the builds are recorded before any camera).
    pub fn built(&self, key: &SamplerKey) -> Option<&SamplerSlot> {
        self.slots.get(key).filter(|s| s.generation > 0)
    }
}

/// Bump the version of every environment image that was added or changed on the CPU, and count
/// the bytes Bevy uploads for it (a GPU-written image never counts any).
pub fn track_image_versions(
    mut events: MessageReader<AssetEvent<Image>>,
    mut versions: ResMut<EnvImageVersions>,
    envs: Query<&EnvisEnvironment>,
    images: Res<Assets<Image>>,
    counters: Res<EnvisCounters>,
) {
    let used: HashSet<AssetId<Image>> = envs.iter().map(|e| e.image.id()).collect();
    for ev in events.read() {
        let (AssetEvent::Added { id } | AssetEvent::Modified { id }) = *ev else {
            continue;
        };
        if !used.contains(&id) {
            continue;
        }
        *versions.0.entry(id).or_default() += 1;
        let bytes = images
            .get(id)
            .and_then(|i| i.data.as_ref())
            .map_or(0, |d| d.len());
        counters.add(|c| &c.image_bytes_uploaded, bytes as u64);
    }
    // Forget images no camera uses any more.
    if versions.0.keys().any(|id| !used.contains(id)) {
        versions.0.retain(|id, _| used.contains(id));
    }
}

/// What else of a view its distribution and seed depend on: its layers (which casters shadow
/// it, for the accumulation key) and whether it is jittered (TAA) or resamples: both average
/// over frames, so each frame draws a new seed.
type ViewExtras = (
    Option<&'static RenderLayers>,
    Has<TemporalJitter>,
    Has<super::components::EnvironmentResampling>,
);

/// A view's components as [`prepare_samplers`] reads them.
type SamplingViewData = (
    Entity,
    &'static MainEntity,
    &'static ExtractedView,
    &'static EnvironmentSampling,
    &'static EnvisEnvironment,
    ViewExtras,
    Option<&'static ViewSampling>,
);

/// The render world's shared state [`prepare_samplers`] reads.
#[derive(bevy::ecs::system::SystemParam)]
pub struct SamplingInputs<'w> {
    accumulated: Res<'w, super::AccumulatedFrames>,
    images: Res<'w, RenderAssets<GpuImage>>,
    versions: Option<Res<'w, EnvImageVersions>>,
    scene: Option<Res<'w, SceneRevision>>,
    device: Res<'w, RenderDevice>,
    queue: Res<'w, RenderQueue>,
    counters: Res<'w, EnvisCounters>,
    programs: Option<Res<'w, EnvisPrograms>>,
}

/// Per view: choose (and allocate) its distribution, decide whether that needs a rebuild, and
/// track accumulation. Drops distributions and view state that no view uses any more. A view
/// whose new image is still loading keeps the distribution it had (lit by the old map until
/// the new one is there); a view with no distribution loses its [`ViewSampling`].
pub fn prepare_samplers(
    mut commands: Commands,
    views: Query<SamplingViewData>,
    inputs: SamplingInputs,
    mut samplers: ResMut<EnvSamplers>,
) {
    let samplers = &mut *samplers;
    let mut used = HashSet::new();
    let mut frames = cleared_frames(&inputs.accumulated);
    for view in &views {
        let (entity, main) = (view.0, view.1.id());
        let sampled = view_sampling(samplers, &inputs, view)
            .or_else(|| kept_while_loading(samplers, &inputs, view));
        match sampled {
            Some(vs) => {
                if let Some(f) = frames.as_mut() {
                    f.insert(main, vs.frame);
                }
                used.insert(vs.key);
                commands.entity(entity).insert(vs);
            }
            None => {
                commands.entity(entity).remove::<ViewSampling>();
            }
        }
    }
    let live_views: HashSet<Entity> = views.iter().map(|v| v.0).collect();
    drop_unused(samplers, (&used, &live_views), &inputs.counters);
}

/// The view's distribution for its image this frame, allocated and marked for a rebuild as
/// needed; `None` while the image is not on the GPU, cannot be used, or the build is not
/// compiled yet.
fn view_sampling(
    samplers: &mut EnvSamplers,
    inputs: &SamplingInputs,
    (entity, _, view, sampling, env, (layers, jittered, resampled), _): QueryItem<SamplingViewData>,
) -> Option<ViewSampling> {
    // Resampling, as TAA, averages over frames: each frame draws new samples.
    let jittered = jittered || resampled;
    let build = inputs.programs.as_ref()?.build()?;
    let gpu = inputs.images.get(env.image.id())?;
    let layout = usable_layout(samplers, gpu, env)?;
    let version = image_version(inputs.versions.as_deref(), env.image.id());
    let scene = inputs.scene.as_ref().map_or(0, |s| s.0);
    let (frame, seed, key) = view_frame(
        samplers,
        entity,
        (view, sampling, env),
        (layers, jittered),
        (version, scene),
    );
    let device = (&*inputs.device, &*inputs.queue);
    let slot = slot_for(
        samplers,
        key,
        (gpu, layout),
        build,
        device,
        &inputs.counters,
    )?;
    let source = (gpu, layout, (version, env.dynamic));
    slot.refresh(source, pool_seed(seed), sampling.strategy, device);
    Some(ViewSampling { key, frame, seed })
}

/// While a view's image is not loaded yet (a new image replaced its old one), the view keeps
/// the distribution it had, built from the old image: no frame goes without light.
fn kept_while_loading(
    samplers: &EnvSamplers,
    inputs: &SamplingInputs,
    (_, _, _, _, env, _, previous): QueryItem<SamplingViewData>,
) -> Option<ViewSampling> {
    let previous = previous?;
    let loading = inputs.images.get(env.image.id()).is_none();
    (loading && previous.key.image != env.image.id() && samplers.built(&previous.key).is_some())
        .then_some(*previous)
}

/// The frames each view has averaged (shared with the main world), emptied for this frame's
/// views; `None` when its lock is poisoned (the counts are then not kept).
fn cleared_frames(
    accumulated: &super::AccumulatedFrames,
) -> Option<std::sync::MutexGuard<'_, HashMap<Entity, u32>>> {
    let mut frames = accumulated.0.lock().ok();
    if let Some(f) = frames.as_mut() {
        f.clear();
    }
    frames
}

/// How often the main world changed an environment image (0 before its first change is seen).
fn image_version(versions: Option<&EnvImageVersions>, image: AssetId<Image>) -> u64 {
    versions.and_then(|v| v.0.get(&image).copied()).unwrap_or(0)
}

/// A view's frame: how many frames its mean averaged before it, its seed and its distribution's
/// key.
fn view_frame(
    samplers: &mut EnvSamplers,
    entity: Entity,
    (view, sampling, env): (&ExtractedView, &EnvironmentSampling, &EnvisEnvironment),
    (layers, jittered): (Option<&RenderLayers>, bool),
    (version, scene): (u64, u64),
) -> (u32, u32, SamplerKey) {
    // Accumulation: restart the mean whenever anything the image depends on changed.
    let layers = super::shadows::layers_of(layers);
    let acc_key = accumulation_key(sampling, env, (view, layers), (version, scene));
    let (frame, tick) = next_frame(samplers, entity, (sampling, env), acc_key, jittered);
    let seed = frame_seed(sampling.seed, frame, tick);
    let key = sampler_key(sampling, env, entity, tick.is_some());
    (frame, seed, key)
}

/// Drop the distributions no view used this frame and the state of views that are gone, and
/// count the distributions left.
fn drop_unused(
    samplers: &mut EnvSamplers,
    (used, live_views): (&HashSet<SamplerKey>, &HashSet<Entity>),
    counters: &EnvisCounters,
) {
    samplers.slots.retain(|k, _| used.contains(k));
    counters.0.live_distributions.store(
        samplers.slots.len() as u64,
        std::sync::atomic::Ordering::Relaxed,
    );
    samplers.accumulation.retain(|e, _| live_views.contains(e));
    samplers.ticks.retain(|e, _| live_views.contains(e));
}

/// The layout of a view's environment image, or `None` (said once per image) when envis cannot
/// use it.
fn usable_layout(
    samplers: &mut EnvSamplers,
    gpu: &GpuImage,
    env: &EnvisEnvironment,
) -> Option<SourceLayout> {
    match check_source(gpu) {
        Ok(l) => Some(l),
        Err(e) => {
            if samplers.refused.insert(env.image.id()) {
                error!("envis: the environment image cannot be used: {e}");
            }
            None
        }
    }
}

/// The face size a camera's distribution is built at (its `face_size`, within what the passes
/// allow).
pub(crate) fn face_size_of(sampling: &EnvironmentSampling) -> usize {
    sampling.face_size.clamp(1, 2048)
}

/// Which distribution a view uses: its image, face size, tiles and pool, and whose seed (the
/// view's own when it accumulates or is jittered, `ticking`; else shared by every view with its
/// seed).
fn sampler_key(
    sampling: &EnvironmentSampling,
    env: &EnvisEnvironment,
    entity: Entity,
    ticking: bool,
) -> SamplerKey {
    let face_size = face_size_of(sampling);
    SamplerKey {
        image: env.image.id(),
        face_size,
        tiles: envis::sampling::TileGrid::new(face_size, sampling.tiles).k,
        pool_slots: sampling.pool_slots(),
        pool_blocks: sampling.pool_block_count(),
        seed: if sampling.accumulate || ticking {
            SeedOwner::View(entity)
        } else {
            SeedOwner::Shared(sampling.seed)
        },
    }
}

/// Record every pending build (resample, distribution, pool) into this frame's command stream,
/// before any camera.
pub fn build_distributions(
    mut ctx: RenderContext,
    mut samplers: ResMut<EnvSamplers>,
    programs: Option<Res<EnvisPrograms>>,
    (counters, timings): (Res<EnvisCounters>, Res<EnvisTimings>),
    started: Option<Res<BevyStarted>>,
) {
    let t0 = std::time::Instant::now();
    // Not before Bevy's own start-up pipelines are compiled (see `BevyStarted`).
    if started.is_some_and(|s| !s.started()) {
        return;
    }
    let samplers = &mut *samplers;
    let Some(resampler) = programs.as_ref().and_then(|p| p.resample()) else {
        return;
    };
    let device = ctx.render_device().wgpu_device().clone();
    // GPU times in Bevy's render diagnostics (`render/envis_resample/elapsed_gpu`, ...).
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let mut any = false;
    for slot in samplers.slots.values_mut().filter(|s| s.dirty) {
        let enc = ctx.command_encoder();
        let source = envis_wgpu::resample::Source {
            view: &slot.source,
            layout: slot.layout,
            width: slot.width,
        };
        let span = diagnostics.time_span(enc, "envis_resample");
        resampler.encode(&device, enc, source, &slot.sampler, None);
        span.end(enc);
        let span = diagnostics.time_span(enc, "envis_distribution");
        slot.sampler.encode_distribution(enc, None);
        span.end(enc);
        let span = diagnostics.time_span(enc, "envis_pool");
        slot.sampler.encode_pool(enc, None);
        span.end(enc);
        slot.dirty = false;
        slot.generation += 1;
        any = true;
        counters.bump(|c| &c.builds);
    }
    if any {
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        timings.set(|t| t.build_cpu_ms = Some(ms));
    }
}
