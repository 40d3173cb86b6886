//! A resampling camera's per-frame counts read back, for offline tools (`envis sequence
//! --backend gpu`): with [`ResamplingReadback`] on the camera, the pass copies its per-pixel
//! counters after each frame, and the totals arrive in the component's sink a few frames later,
//! tagged with the `tag` the frame was extracted with. Never on a game's frame path: nothing
//! waits, and a camera without the component copies nothing.

use crate::app::timing::AsyncRead;
use bevy::prelude::*;
use std::sync::{Arc, Mutex};

/// Read this resampling camera's counts back every frame (see the module docs). Set `tag`
/// before a frame to recognise its counts in `sink`.
#[derive(Component, Clone, Default)]
pub struct ResamplingReadback {
    pub tag: u32,
    pub sink: ResamplingCounts,
}

/// Where the counts arrive, each with its frame's tag.
#[derive(Clone, Default)]
pub struct ResamplingCounts(Arc<Mutex<Vec<(u32, FrameCounts)>>>);

impl ResamplingCounts {
    /// The counts of the frame tagged `tag`, once they arrived.
    pub fn take(&self, tag: u32) -> Option<FrameCounts> {
        let mut got = self.0.lock().ok()?;
        let i = got.iter().position(|(t, _)| *t == tag)?;
        Some(got.swap_remove(i).1)
    }
}

/// One frame's totals over the viewport, as the headless twin counts them
/// (`gpu::resampling::GpuResampler`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrameCounts {
    /// Shadow rays: the selected samples' and the unbiased reuse's visibility rays.
    pub shadow_rays: u64,
    /// Pixels that drew a candidate (Bevy's G-buffer has geometry there).
    pub shaded_pixels: u64,
    /// Light samples used and BRDF samples drawn as candidates.
    pub samples_evaluated: u64,
    /// Pixels whose history passed the geometric tests, and neighbours that did.
    pub temporal_accepted: u64,
    pub spatial_accepted: u64,
}

impl FrameCounts {
    /// Totals of the per-pixel `counters` (rays, history accepted, neighbours accepted, -) and
    /// `stats` (light samples available, green, yellow, BRDF samples) of
    /// `shaders/resampling.wgsl`.
    fn sum(counters: &[[u32; 4]], stats: &[[u32; 4]]) -> Self {
        let mut c = FrameCounts::default();
        for (r, s) in counters.iter().zip(stats) {
            c.shadow_rays += r[0] as u64;
            c.temporal_accepted += r[1] as u64;
            c.spatial_accepted += r[2] as u64;
            c.shaded_pixels += (s[0] + s[3] > 0) as u64;
            c.samples_evaluated += (s[1] + s[2] + s[3]) as u64;
        }
        c
    }
}

/// One frame's copies in flight: its tag and sink, and the counters' and stats' reads.
struct Pending {
    tag: u32,
    sink: ResamplingCounts,
    counters: AsyncRead,
    stats: AsyncRead,
    got: [Option<Vec<u8>>; 2],
}

/// A view's reads in flight, oldest first.
#[derive(Default)]
pub(super) struct Readbacks(Vec<Pending>);

impl Readbacks {
    /// Record this frame's copies of `counters` and `stats` (per pixel, 16 bytes each).
    pub(super) fn copy(
        &mut self,
        device: &wgpu::Device,
        enc: &mut wgpu::CommandEncoder,
        r: &ResamplingReadback,
        (counters, stats): (&wgpu::Buffer, &wgpu::Buffer),
    ) {
        let mut read = |label, b: &wgpu::Buffer| {
            let a = AsyncRead::new(device, label, b.size());
            a.copy_from(enc, b);
            a
        };
        let counters = read("envis resampling counters readback", counters);
        let stats = read("envis resampling stats readback", stats);
        self.0.push(Pending {
            tag: r.tag,
            sink: r.sink.clone(),
            counters,
            stats,
            got: [None, None],
        });
    }

    /// Once per frame, after the copying frames were submitted: map what was copied, and hand
    /// each frame whose bytes both arrived to its sink.
    pub(super) fn poll(&mut self) {
        self.0.retain_mut(|p| {
            for (slot, read) in p.got.iter_mut().zip([&p.counters, &p.stats]) {
                if slot.is_none() {
                    *slot = read.poll();
                }
            }
            let [Some(c), Some(s)] = &p.got else {
                return true;
            };
            let counts = FrameCounts::sum(
                &bytemuck::pod_collect_to_vec(c),
                &bytemuck::pod_collect_to_vec(s),
            );
            if let Ok(mut got) = p.sink.0.lock() {
                got.push((p.tag, counts));
            }
            false
        });
    }
}
