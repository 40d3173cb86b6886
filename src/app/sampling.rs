//! `EnvMapSamplingPlugin`: the per-frame distribution build and light pool on the GPU, recorded in
//! the render world's `RenderGraph` schedule before `camera_driver` — only when the frame (or the
//! pool seed / size) changed, so a static map costs nothing per frame after the first build.

use super::timing::{AsyncTimer, EnvisTimings};
use super::{EnvFrame, EnvisCounters, EnvisSettings};
use crate::gpu::EnvSampler;
use crate::render::pool_seed;
use bevy::core_pipeline::schedule::camera_driver;
use bevy::prelude::*;
use bevy::render::renderer::{RenderContext, RenderDevice, RenderGraph, RenderQueue};
use bevy::render::{Render, RenderApp, RenderSystems};

/// The GPU sampler of the render world and what it currently holds.
#[derive(Resource, Default)]
pub struct EnvSamplingState {
    pub sampler: Option<EnvSampler>,
    /// Generation of the frame in `sampler.texels`.
    pub uploaded: Option<u64>,
    seed: Option<u32>,
    /// The uploaded frame (or seed) has not been built yet.
    dirty: bool,
    /// Last allocation error, reported once.
    failed: Option<(usize, usize)>,
    timer: Option<AsyncTimer>,
    pool_timer: Option<AsyncTimer>,
}

pub struct EnvMapSamplingPlugin;

impl Plugin for EnvMapSamplingPlugin {
    fn build(&self, app: &mut App) {
        let Some(render_app) = app.get_sub_app_mut(RenderApp) else {
            return;
        };
        render_app
            .init_resource::<EnvSamplingState>()
            .init_resource::<EnvisCounters>()
            .init_resource::<EnvisTimings>()
            .add_systems(Render, prepare_env_sampler.in_set(RenderSystems::Prepare))
            .add_systems(RenderGraph, build_env_distribution.before(camera_driver));
    }
}

/// (Re)allocate when the face size or pool size changed; upload a new frame; set the pool seed.
pub fn prepare_env_sampler(
    frame: Option<Res<EnvFrame>>,
    settings: Option<Res<EnvisSettings>>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    mut state: ResMut<EnvSamplingState>,
    counters: Res<EnvisCounters>,
    timings: Res<EnvisTimings>,
) {
    let (Some(frame), Some(settings)) = (frame, settings) else {
        return;
    };
    let t0 = std::time::Instant::now();
    if let Some(ms) = state.timer.as_ref().and_then(|t| t.poll()) {
        timings.set(|t| t.build_gpu_ms = Some(ms));
    }
    if let Some(ms) = state.pool_timer.as_ref().and_then(|t| t.poll()) {
        timings.set(|t| t.pool_gpu_ms = Some(ms));
    }
    let (n, m) = (frame.map.size, settings.sampling.pool_per_face());
    if state.sampler.as_ref().is_none_or(|s| s.n != n || s.m != m) {
        if state.failed == Some((n, m)) {
            return;
        }
        match EnvSampler::with_device(device.wgpu_device(), &queue, n, m, false) {
            Ok(s) => {
                let timer = AsyncTimer::new(device.wgpu_device(), &queue, "envis build timer");
                let pool_timer = AsyncTimer::new(device.wgpu_device(), &queue, "envis pool timer");
                *state = EnvSamplingState {
                    sampler: Some(s),
                    timer,
                    pool_timer,
                    ..default()
                };
                counters.bump(|c| &c.allocations);
            }
            Err(e) => {
                error!("envis: {e}");
                state.failed = Some((n, m));
                return;
            }
        }
    }
    let state = &mut *state;
    if settings.sampling.strategy == crate::render::Strategy::Global
        && state.sampler.as_ref().is_some_and(|s| !s.has_global())
    {
        let s = state.sampler.as_mut().expect("allocated above");
        match s.enable_global(device.wgpu_device(), &queue) {
            Ok(()) => state.dirty = true,
            Err(e) => error!("envis: {e}"),
        }
    }
    let sampler = state.sampler.as_ref().expect("allocated above");
    if state.uploaded != Some(frame.generation) {
        sampler.upload(&queue, &frame.map);
        state.uploaded = Some(frame.generation);
        state.dirty = true;
        counters.bump(|c| &c.uploads);
    }
    let seed = pool_seed(settings.frame_seed());
    if state.seed != Some(seed) {
        sampler.set_seed(&queue, seed);
        state.seed = Some(seed);
        state.dirty = true;
    }
    if settings.always_rebuild {
        state.dirty = true;
    }
    if state.dirty {
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        timings.set(|t| t.build_cpu_ms = Some(ms));
    }
}

/// Record the build (five compute dispatches) into this frame's command stream, before any camera.
pub fn build_env_distribution(
    mut ctx: RenderContext,
    mut state: ResMut<EnvSamplingState>,
    counters: Res<EnvisCounters>,
    timings: Res<EnvisTimings>,
) {
    if !state.dirty {
        return;
    }
    let t0 = std::time::Instant::now();
    if let Some(s) = &state.sampler {
        let timer = state.timer.as_ref().filter(|t| t.ready());
        let pool_timer = state.pool_timer.as_ref().filter(|t| t.ready());
        let enc = ctx.command_encoder();
        s.encode_with(
            enc,
            timer.map(|t| t.compute_writes()),
            pool_timer.map(|t| t.compute_writes()),
        );
        for t in [timer, pool_timer].into_iter().flatten() {
            t.resolve(enc);
        }
        counters.bump(|c| &c.builds);
    }
    state.dirty = false;
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    timings.set(|t| t.build_cpu_ms = Some(t.build_cpu_ms.unwrap_or(0.0) + ms));
}
