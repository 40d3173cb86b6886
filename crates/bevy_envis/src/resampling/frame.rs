//! One frame of a resampling view: its uniforms ([`write_uniforms`]), the gather and the
//! passes ([`record`]), and what the next frame keeps of it ([`hand_over`]).

use super::EnvironmentResampling;
use super::bright::BrightSplit;
use super::gather::{GatherInputs, GatherPipelines, GatherView};
use super::view::{BvhCopy, PreviousFrame, ViewResampling};
use crate::components::EnvisEnvironment;
use crate::shadows::GpuShadowGeometry;
use bevy::prelude::*;
use bevy::render::camera::TemporalJitter;
use bevy::render::renderer::RenderQueue;
use bevy::render::view::ExtractedView;
use envis_wgpu::resampling::{
    BvhBuffers, FrameReuse, PassBuffers, ResampleParams, ResamplingPasses,
};

/// What of the view and its settings a frame's uniforms and passes take.
pub(super) struct FrameInputs<'a> {
    pub ev: &'a ExtractedView,
    pub env: &'a EnvisEnvironment,
    pub settings: &'a EnvironmentResampling,
    pub layers: u32,
    pub jitter: Option<&'a TemporalJitter>,
    pub seed: u32,
    /// The shadow BVH (nodes, triangles, node count) when the camera casts shadow rays, and
    /// its geometry's (generation, placement).
    pub bvh: Option<(wgpu::Buffer, wgpu::Buffer, u32)>,
    pub geometry: Option<(u64, u64)>,
}

/// The gather's view, the shading's and the passes' parameters.
pub(super) fn write_uniforms(
    queue: &RenderQueue,
    state: &ViewResampling,
    f: &FrameInputs,
    shade: &envis_wgpu::shading::ShadeParams,
) {
    let ev = f.ev;
    let vp = ev.viewport;
    let world_from_view = ev.world_from_view.to_matrix();
    let clip_from_view = crate::lighting_uniforms::rasterised_clip_from_view(ev, f.jitter);
    let prev = state.prev.as_ref();
    let camera = ev.world_from_view.translation();
    let forward = ev.world_from_view.forward().as_vec3();
    let gv = GatherView {
        world_from_clip: (world_from_view * clip_from_view.inverse()).to_cols_array_2d(),
        env_from_world: Mat4::from_quat(f.env.rotation.inverse()).to_cols_array_2d(),
        camera: camera.to_array(),
        orthographic: (ev.clip_from_view.w_axis.w == 1.0) as u32,
        forward: forward.to_array(),
        has_prev: prev.is_some() as u32,
        prev_camera: prev.map_or(camera, |p| p.camera).to_array(),
        texel_count: state.texels,
        prev_forward: prev.map_or(forward, |p| p.forward).to_array(),
        _pad: 0,
        viewport: [vp.x as f32, vp.y as f32, vp.z as f32, vp.w as f32],
    };
    let r = f.settings;
    // The bright part's tables replace the gather's whole map; its history is reused while
    // it is the same light.
    let bright = state.bright.as_ref();
    if let Some(b) = bright {
        b.write(queue, state.current().1);
    }
    let bright_history = (bright.zip(prev.and_then(|p| p.bright.as_ref())))
        .is_some_and(|(b, p)| b.bright.same_light(p));
    let params = ResampleParams::for_frame(&FrameReuse {
        width: vp.z,
        height: vp.w,
        face_size: (state.texels / 6).isqrt(),
        prev_face_size: prev.map(|p| p.face_size),
        bright_count: bright.map_or(0, |b| b.count),
        bright_history,
        temporal: r.temporal,
        spatial: r.spatial,
        max_history: r.max_history,
        unbiased: r.unbiased,
        seed: f.seed,
        bvh_nodes: f.bvh.as_ref().map_or(0, |b| b.2),
        prev_bvh_nodes: prev.and_then(|p| p.bvh.as_ref()).map_or(0, |b| b.2),
        layers: f.layers,
        map_agreement: map_agreement(bright, prev),
        // The same (generation, placement): nothing moved (the copy the history traces is it).
        still_geometry: f.geometry.is_some() && prev.is_some_and(|p| p.geometry == f.geometry),
        world_from_map: Mat3::from_quat(f.env.rotation),
    });
    queue.write_buffer(&state.gather_view, 0, bytemuck::bytes_of(&gv));
    queue.write_buffer(&state.shade_params, 0, bytemuck::bytes_of(shade));
    queue.write_buffer(&state.params, 0, bytemuck::bytes_of(&params));
}

/// The gather and the resampling passes of one frame.
pub(super) fn record(
    enc: &mut wgpu::CommandEncoder,
    device: &wgpu::Device,
    (passes, gather): (&ResamplingPasses, &GatherPipelines),
    state: &mut ViewResampling,
    (sampler, (gbuffer, depth, pass_ids, motion_vectors)): (
        &envis_wgpu::sampler::EnvSampler,
        (
            &wgpu::TextureView,
            &wgpu::TextureView,
            &wgpu::TextureView,
            &wgpu::TextureView,
        ),
    ),
    f: &FrameInputs,
) {
    let (surfaces, split, temporal) = state.current();
    let pixels = state.size.x * state.size.y;
    let inputs = GatherInputs {
        gbuffer,
        depth,
        pass_ids,
        motion_vectors,
        view: &state.gather_view,
        texels: &sampler.texels,
        surfaces,
        reproject: &state.reproject,
        split,
    };
    let whole_map = if state.bright.is_some() {
        0
    } else {
        state.texels
    };
    gather.record(device, enc, &inputs, (pixels, whole_map));
    let prev = state.prev.as_ref();
    let (prev_surfaces, prev_split, history) = state.previous();
    let bright = state.bright.as_ref();
    let buffers = PassBuffers {
        sampler: bright.map_or(sampler, |b| &b.sampler),
        shade_params: &state.shade_params,
        params: &state.params,
        surfaces,
        prev_surfaces: prev.map(|_| prev_surfaces),
        split,
        prev_split: prev.map(|_| prev_split),
        bright: bright.map(|b| (&b.cdf, &b.ids)),
        bvh: bvh_buffers(&f.bvh),
        prev_bvh: prev.and_then(|p| bvh_buffers(&p.bvh)),
        // The shading's final reservoirs go to the candidates' buffer (read by no later pass).
        res: [
            &state.candidates,
            temporal,
            &state.spatial,
            &state.candidates,
        ],
        history: prev.map(|_| history),
        reproject: prev.map(|_| &state.reproject),
        hist_targets: &state.hist_targets,
        counters: &state.counters,
        color: &state.color,
        stats: &state.stats,
        pixels,
    };
    passes.record(device, enc, &buffers);
}

/// A kept BVH (nodes, triangles, node count) as the passes bind it.
fn bvh_buffers(b: &Option<(wgpu::Buffer, wgpu::Buffer, u32)>) -> Option<BvhBuffers<'_>> {
    b.as_ref().map(|b| (&b.0, &b.1))
}

/// Whether this frame may reuse the previous one: temporal reuse on, no reset, and the same
/// map size, map rotation and render layers.
pub(super) fn history_valid(prev: Option<&PreviousFrame>, f: &FrameInputs, face_size: u32) -> bool {
    prev.is_some_and(|p| {
        f.settings.temporal
            && !f.settings.reset
            && p.face_size == face_size
            && p.rotation == f.env.rotation
            && p.layers == f.layers
    })
}

/// The rest's history confidence factor ([`ResampleParams::map_agreement`]): the split's, where
/// there is one; 0 in a frame without a split after one with it (a new version of the map is
/// being read: a change the CPU cannot measure yet); 1 where the map is never split.
fn map_agreement(bright: Option<&BrightSplit>, prev: Option<&PreviousFrame>) -> f32 {
    match (bright, prev.and_then(|p| p.bright.as_ref())) {
        (Some(b), _) => b.map_agreement,
        (None, Some(_)) => 0.0,
        (None, None) => 1.0,
    }
}

/// After the frame's passes: the next frame's previous frame, its shadow geometry a copy of
/// this frame's (see [`BvhCopy`]).
pub(super) fn hand_over(
    state: &mut ViewResampling,
    device: &wgpu::Device,
    enc: &mut wgpu::CommandEncoder,
    geometry: Option<&GpuShadowGeometry>,
    f: &FrameInputs,
    face_size: u32,
) {
    let bvh = geometry.map(|g| {
        let key = (g.generation, g.placement);
        let live = (&g.nodes, &g.triangles);
        let c = BvhCopy::update(&mut state.bvh_copy, device, enc, live, key);
        (c.nodes.clone(), c.triangles.clone(), g.node_count)
    });
    state.advance(PreviousFrame {
        camera: f.ev.world_from_view.translation(),
        forward: f.ev.world_from_view.forward().as_vec3(),
        face_size,
        rotation: f.env.rotation,
        layers: f.layers,
        bright: state.bright.as_ref().map(|b| b.bright.clone()),
        bvh,
        geometry: f.geometry,
    });
}
