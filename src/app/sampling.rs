//! `EnvMapSamplingPlugin`: the per-frame distribution build and light pool on the GPU, recorded in
//! the render world's `RenderGraph` schedule before `camera_driver` — only when the frame (or the
//! pool seed / size) changed, so a static map costs nothing per frame after the first build.

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
}

pub struct EnvMapSamplingPlugin;

impl Plugin for EnvMapSamplingPlugin {
    fn build(&self, app: &mut App) {
        let Some(render_app) = app.get_sub_app_mut(RenderApp) else { return };
        render_app
            .init_resource::<EnvSamplingState>()
            .init_resource::<EnvisCounters>()
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
) {
    let (Some(frame), Some(settings)) = (frame, settings) else { return };
    let (n, m) = (frame.map.size, settings.sampling.pool_per_face());
    if state.sampler.as_ref().is_none_or(|s| s.n != n || s.m != m) {
        if state.failed == Some((n, m)) {
            return;
        }
        match EnvSampler::with_device(device.wgpu_device(), &queue, n, m, false) {
            Ok(s) => {
                *state = EnvSamplingState { sampler: Some(s), ..default() };
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
    let sampler = state.sampler.as_ref().expect("allocated above");
    if state.uploaded != Some(frame.generation) {
        sampler.upload(&queue, &frame.map);
        state.uploaded = Some(frame.generation);
        state.dirty = true;
        counters.bump(|c| &c.uploads);
    }
    let seed = pool_seed(settings.sampling.seed);
    if state.seed != Some(seed) {
        sampler.set_seed(&queue, seed);
        state.seed = Some(seed);
        state.dirty = true;
    }
}

/// Record the build (five compute dispatches) into this frame's command stream, before any camera.
pub fn build_env_distribution(mut ctx: RenderContext, mut state: ResMut<EnvSamplingState>, counters: Res<EnvisCounters>) {
    if !state.dirty {
        return;
    }
    if let Some(s) = &state.sampler {
        s.encode(ctx.command_encoder());
        counters.bump(|c| &c.builds);
    }
    state.dirty = false;
}
