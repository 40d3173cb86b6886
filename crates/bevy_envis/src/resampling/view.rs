//! One resampling camera's buffers on the device, kept from frame to frame: what it gathers, its
//! reservoirs and image, and the previous frame (surfaces, split map, temporal reservoirs, shadow
//! geometry and camera) that temporal reuse reads. Two of each kept buffer alternate: this
//! frame's is the next frame's previous one, with no copies.

use bevy::prelude::*;
use envis::error::Result;
use envis_wgpu::resampling::{GpuReservoir, GpuSurface, ResampleParams};
use envis_wgpu::sampler::{check_binding, storage};
use envis_wgpu::shading::ShadeParams;

/// Bytes per pixel of a [`GpuSurface`] and of a pixel's two reservoirs (a light and a BRDF one).
const SURFACE_BYTES: u64 = size_of::<GpuSurface>() as u64;
const RESERVOIRS_BYTES: u64 = 2 * size_of::<GpuReservoir>() as u64;

/// The previous frame as the next one reuses it.
pub(super) struct PreviousFrame {
    pub camera: Vec3,
    pub forward: Vec3,
    /// The map's face size (the split map's indexing).
    pub face_size: u32,
    /// The map's rotation and the camera's render layers: a change drops the history (the
    /// split map is indexed in map space; other layers cast other shadows).
    pub rotation: Quat,
    pub layers: u32,
    /// Its bright part, where it had one (`bright::BrightSplit`): the bright history is reused
    /// only while it is the same light.
    pub bright: Option<std::sync::Arc<envis::render::resampling::BrightLight>>,
    /// Its shadow BVH (nodes, triangles, node count), when it cast shadow rays: the view's
    /// copy ([`BvhCopy`]), not the live buffers, which moving instances rewrite in place.
    pub bvh: Option<(wgpu::Buffer, wgpu::Buffer, u32)>,
    /// That geometry's (generation, placement): the same this frame, nothing moved.
    pub geometry: Option<(u64, u64)>,
}

/// The shadow BVH as the last frame traversed it. `upload_shadow_geometry` rewrites the live
/// buffers in place when instances move (before the frame's passes run), so the previous
/// frame's geometry, which `history_targets` traces, survives only as a copy, made on the
/// device after a frame whose geometry (generation, placement) differs from the copy's: every
/// frame while something moves, never while nothing does.
pub(super) struct BvhCopy {
    pub nodes: wgpu::Buffer,
    pub triangles: wgpu::Buffer,
    /// The geometry's (generation, placement) the copy holds.
    pub key: (u64, u64),
}

impl BvhCopy {
    /// Record the copy of `live` (nodes, triangles) into `enc` unless `copy` already holds
    /// `key`; new buffers where the sizes changed. Returns the copy.
    pub(super) fn update<'a>(
        copy: &'a mut Option<BvhCopy>,
        device: &wgpu::Device,
        enc: &mut wgpu::CommandEncoder,
        (nodes, triangles): (&wgpu::Buffer, &wgpu::Buffer),
        key: (u64, u64),
    ) -> &'a BvhCopy {
        let fits =
            |c: &BvhCopy| c.nodes.size() == nodes.size() && c.triangles.size() == triangles.size();
        let c = match copy.take() {
            Some(c) if c.key == key => return copy.insert(c),
            Some(c) if fits(&c) => c,
            _ => BvhCopy {
                nodes: storage(device, "envis previous bvh nodes", nodes.size()),
                triangles: storage(device, "envis previous bvh triangles", triangles.size()),
                key,
            },
        };
        enc.copy_buffer_to_buffer(nodes, 0, &c.nodes, 0, None);
        enc.copy_buffer_to_buffer(triangles, 0, &c.triangles, 0, None);
        copy.insert(BvhCopy { key, ..c })
    }
}

/// A resampling camera's buffers.
pub(super) struct ViewResampling {
    /// Viewport pixels and cube texels the buffers were made for.
    pub size: UVec2,
    pub texels: u32,
    pub shade_params: wgpu::Buffer,
    pub params: wgpu::Buffer,
    pub gather_view: wgpu::Buffer,
    /// This frame's and the previous frame's (`parity` picks which is which).
    surfaces: [wgpu::Buffer; 2],
    split: [wgpu::Buffer; 2],
    /// Temporal reuse's output: the next frame's history.
    temporal: [wgpu::Buffer; 2],
    /// Candidates (and, after shading, the final reservoirs), and after spatial reuse.
    pub candidates: wgpu::Buffer,
    pub spatial: wgpu::Buffer,
    pub reproject: wgpu::Buffer,
    pub hist_targets: wgpu::Buffer,
    pub counters: wgpu::Buffer,
    /// The image the lighting pass shows (w: the reservoir's confidence).
    pub color: wgpu::Buffer,
    pub stats: wgpu::Buffer,
    /// The pass ran for this view since the last `Prepare` (a frame it skipped breaks the
    /// history: the motion vectors reach one frame back).
    pub ran: bool,
    pub bvh_copy: Option<BvhCopy>,
    /// Counts copied for `ResamplingReadback`, in flight.
    pub reads: super::readback::Readbacks,
    /// Its map's split and the sampler on its rest, where the map is on the CPU (`CpuEnvMaps`).
    pub bright: Option<super::bright::BrightSplit>,
    parity: usize,
    /// The previous frame, while its history is valid.
    pub prev: Option<PreviousFrame>,
}

impl ViewResampling {
    /// Buffers for a `size` viewport over a map of `texels` cube texels; an error (one line)
    /// where they exceed what the device can bind.
    pub(super) fn new(device: &wgpu::Device, size: UVec2, texels: u32) -> Result<Self> {
        let px = size.x as u64 * size.y as u64;
        let limits = device.limits();
        check_binding(&limits, "resampling reservoirs", px * RESERVOIRS_BYTES)?;
        check_binding(&limits, "resampling surfaces", px * SURFACE_BYTES)?;
        check_binding(&limits, "resampling split map", texels as u64 * 32)?;
        let two = |label: &str, bytes: u64| {
            [storage(device, label, bytes), storage(device, label, bytes)]
        };
        let uniform = |label: &str, bytes: u64| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        Ok(ViewResampling {
            size,
            texels,
            shade_params: uniform("envis resampling shade", size_of::<ShadeParams>() as u64),
            params: uniform(
                "envis resampling params",
                size_of::<ResampleParams>() as u64,
            ),
            gather_view: uniform(
                "envis gather view",
                size_of::<super::gather::GatherView>() as u64,
            ),
            surfaces: two("envis surfaces", px * SURFACE_BYTES),
            split: two("envis split map", texels as u64 * 32),
            temporal: two("envis temporal reservoirs", px * RESERVOIRS_BYTES),
            candidates: storage(device, "envis candidates", px * RESERVOIRS_BYTES),
            spatial: storage(device, "envis spatial reservoirs", px * RESERVOIRS_BYTES),
            reproject: storage(device, "envis reprojection", px * 8),
            hist_targets: storage(device, "envis history targets", px * 8),
            counters: storage(device, "envis reuse counters", px * 16),
            color: storage(device, "envis resampled color", px * 16),
            stats: storage(device, "envis candidate stats", px * 16),
            ran: false,
            bvh_copy: None,
            reads: Default::default(),
            bright: None,
            parity: 0,
            prev: None,
        })
    }

    /// This frame's kept buffers: surfaces, split map, temporal reservoirs.
    pub(super) fn current(&self) -> (&wgpu::Buffer, &wgpu::Buffer, &wgpu::Buffer) {
        let i = self.parity;
        (&self.surfaces[i], &self.split[i], &self.temporal[i])
    }

    /// The previous frame's kept buffers.
    pub(super) fn previous(&self) -> (&wgpu::Buffer, &wgpu::Buffer, &wgpu::Buffer) {
        let i = 1 - self.parity;
        (&self.surfaces[i], &self.split[i], &self.temporal[i])
    }

    /// After a frame is recorded: it becomes the previous one.
    pub(super) fn advance(&mut self, prev: PreviousFrame) {
        self.parity = 1 - self.parity;
        self.prev = Some(prev);
    }
}
