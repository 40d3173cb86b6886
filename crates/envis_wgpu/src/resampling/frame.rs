//! One resampled frame's device buffers, and what comes back of them.

use super::{GpuResampled, Previous, layout};
use crate::GpuContext;
use crate::sampler::storage;
use envis::envmap::Image;
use envis::render::resampling::{ReuseStats, Screen};
use envis::render::{PixelStats, RenderStats};
use envis::visibility::FlatBvh;
use glam::Vec3;
use wgpu::util::DeviceExt;

/// A storage buffer holding `data` (at least 256 bytes: an empty table still binds).
pub fn storage_init<T: bytemuck::Pod>(
    device: &wgpu::Device,
    label: &str,
    data: &[T],
) -> wgpu::Buffer {
    let bytes: &[u8] = bytemuck::cast_slice(data);
    let mut v = bytes.to_vec();
    v.resize(bytes.len().max(256), 0);
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: &v,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
    })
}

/// One frame's buffers.
pub(super) struct FrameBuffers {
    pub(super) surfaces: wgpu::Buffer,
    pub(super) split: wgpu::Buffer,
    pub(super) bright_cdf: wgpu::Buffer,
    pub(super) bright_ids: wgpu::Buffer,
    pub(super) bright_count: u32,
    pub(super) bvh: Option<(wgpu::Buffer, wgpu::Buffer, u32)>,
    pub(super) reproject: Option<wgpu::Buffer>,
    /// Candidates, after temporal reuse (the next history), after spatial reuse, shaded.
    pub(super) res: [wgpu::Buffer; 4],
    pub(super) hist_targets: wgpu::Buffer,
    pub(super) counters: wgpu::Buffer,
    pub(super) color: wgpu::Buffer,
    pub(super) stats: wgpu::Buffer,
    pub(super) pixels: usize,
}

impl FrameBuffers {
    pub(super) fn new(
        ctx: &GpuContext,
        cur: &Screen,
        bvh: Option<&FlatBvh>,
        reproject: Option<&[Option<(usize, f32)>]>,
    ) -> Self {
        let device = &ctx.device;
        let n_px = cur.width * cur.height;
        let surfaces = layout::surfaces(cur.gbuf, cur.points, cur.surfaces);
        let (tex, cdf, ids) = layout::split_tables(cur.split);
        let res = |label| storage(device, label, n_px as u64 * 96);
        FrameBuffers {
            surfaces: storage_init(device, "envis surfaces", &surfaces),
            split: storage_init(device, "envis split map", &tex),
            bright_cdf: storage_init(device, "envis bright cdf", &cdf),
            bright_ids: storage_init(device, "envis bright texels", &ids),
            bright_count: ids.len() as u32,
            bvh: bvh.map(|b| {
                let (nodes, tris) = crate::visibility::upload_bvh(device, b);
                (nodes, tris, b.tlas_nodes() as u32)
            }),
            reproject: reproject
                .map(|m| storage_init(device, "envis reprojection", &layout::reprojection(m))),
            res: [
                res("envis candidates"),
                res("envis temporal reservoirs"),
                res("envis spatial reservoirs"),
                res("envis final reservoirs"),
            ],
            hist_targets: storage(device, "envis history targets", n_px as u64 * 8),
            counters: storage(device, "envis reuse counters", n_px as u64 * 16),
            color: storage(device, "envis resampled color", n_px as u64 * 16),
            stats: storage(device, "envis candidate stats", n_px as u64 * 16),
            pixels: n_px,
        }
    }

    pub(super) fn into_previous(self, n: u32) -> Previous {
        let [_, temporal, _, _] = self.res;
        Previous {
            surfaces: self.surfaces,
            split: self.split,
            n,
            bvh: self.bvh,
            reservoirs: temporal,
            pixels: self.pixels,
        }
    }
}

/// What the frame's dispatches read back.
pub(super) struct Readback {
    pub(super) color: Vec<[f32; 4]>,
    pub(super) stats: Vec<[u32; 4]>,
    pub(super) counters: Vec<[u32; 4]>,
}

impl Readback {
    /// The image, the statistics as the CPU twin counts them, and what reuse did.
    pub(super) fn into_frame(self, cur: &Screen, mut stats: RenderStats) -> GpuResampled {
        let per_pixel: Vec<Option<PixelStats>> = (self.stats.iter().zip(cur.gbuf))
            .map(|(q, g)| {
                g.as_ref().map(|_| PixelStats {
                    available: q[0],
                    green: q[1],
                    yellow: q[2],
                    brdf: q[3],
                    ..Default::default()
                })
            })
            .collect();
        stats.accumulate(&per_pixel);
        stats.shadow_rays += self.counters.iter().map(|c| c[0] as u64).sum::<u64>();
        let shaded = cur.gbuf.iter().filter(|p| p.is_some()).count().max(1);
        let rest_m: f64 = (cur.gbuf.iter().enumerate())
            .filter(|(_, p)| p.is_some())
            .map(|(i, _)| self.color[i][3] as f64)
            .sum();
        let reuse = ReuseStats {
            temporal_accepted: self.counters.iter().map(|c| c[1] as u64).sum(),
            bright_temporal_accepted: self.counters.iter().map(|c| c[3] as u64).sum(),
            spatial_accepted: self.counters.iter().map(|c| c[2] as u64).sum(),
            mean_history: rest_m / shaded as f64,
        };
        let image = Image {
            width: cur.width,
            height: cur.height,
            data: (self.color.iter())
                .map(|c| Vec3::new(c[0], c[1], c[2]))
                .collect(),
        };
        GpuResampled {
            image,
            stats,
            reuse,
        }
    }
}
