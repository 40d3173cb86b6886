//! A resampling camera's per-frame counts read back, for offline tools (`envis sequence
//! --backend gpu`): with [`ResamplingReadback`] on the camera, the pass copies its per-pixel
//! counters after each frame, and the totals arrive in the component's sink a few frames later,
//! tagged with the `tag` the frame was extracted with. Never on a game's frame path: nothing
//! waits, and a camera without the component copies nothing.

use crate::timing::AsyncRead;
use bevy::prelude::*;

/// Read this resampling camera's counts back every frame (see the module docs). Set `tag`
/// before a frame to recognise its counts in `sink`.
#[derive(Component, Clone, Default)]
pub struct ResamplingReadback {
    pub tag: u32,
    pub sink: ResamplingCounts,
}

/// Where the counts arrive, each with its frame's tag.
pub type ResamplingCounts = crate::tagged::Tagged<FrameCounts>;

/// One frame's totals over the viewport, as the headless twin counts them
/// (`envis_wgpu::resampling::GpuResampler`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
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
    /// Pixels whose bright part's history did (`ReuseStats::bright_temporal_accepted`).
    pub bright_temporal_accepted: u64,
    /// The rest's confidence `M` (the history overlay's) over the shaded pixels.
    pub mean_history: f64,
}

impl FrameCounts {
    /// Totals of the per-pixel `counters` (rays, history accepted, neighbours accepted, bright
    /// history accepted), `stats` (light samples available, green, yellow, BRDF samples) and
    /// `color` (image, `M`) of `shaders/resampling.wgsl`.
    fn sum(counters: &[[u32; 4]], stats: &[[u32; 4]], color: &[[f32; 4]]) -> Self {
        let mut c = FrameCounts::default();
        for ((r, s), px) in counters.iter().zip(stats).zip(color) {
            let shaded = s[0] + s[3] > 0;
            c.shadow_rays += r[0] as u64;
            c.temporal_accepted += r[1] as u64;
            c.spatial_accepted += r[2] as u64;
            c.bright_temporal_accepted += r[3] as u64;
            c.shaded_pixels += shaded as u64;
            c.samples_evaluated += (s[1] + s[2] + s[3]) as u64;
            c.mean_history += if shaded { px[3] as f64 } else { 0.0 };
        }
        c.mean_history /= c.shaded_pixels.max(1) as f64;
        c
    }
}

/// One frame's copies in flight: its tag and sink, and the counters', stats' and image's reads.
struct Pending {
    tag: u32,
    sink: ResamplingCounts,
    reads: [AsyncRead; 3],
    got: [Option<Vec<u8>>; 3],
}

/// A view's reads in flight, oldest first.
#[derive(Default)]
pub(super) struct Readbacks(Vec<Pending>);

impl Readbacks {
    /// Record this frame's copies of `counters`, `stats` and `color` (per pixel, 16 bytes
    /// each).
    pub(super) fn copy(
        &mut self,
        device: &wgpu::Device,
        enc: &mut wgpu::CommandEncoder,
        r: &ResamplingReadback,
        buffers: [&wgpu::Buffer; 3],
    ) {
        let reads = buffers.map(|b| {
            let a = AsyncRead::new(device, "envis resampling readback", b.size());
            a.copy_from(enc, b);
            a
        });
        self.0.push(Pending {
            tag: r.tag,
            sink: r.sink.clone(),
            reads,
            got: [None, None, None],
        });
    }

    /// Once per frame, after the copying frames were submitted: map what was copied, and hand
    /// each frame whose three reads all arrived to its sink.
    pub(super) fn poll(&mut self) {
        self.0.retain_mut(|p| {
            for (slot, read) in p.got.iter_mut().zip(&p.reads) {
                if slot.is_none() {
                    *slot = read.poll();
                }
            }
            let [Some(c), Some(s), Some(px)] = &p.got else {
                return true;
            };
            let counts = FrameCounts::sum(
                &bytemuck::pod_collect_to_vec(c),
                &bytemuck::pod_collect_to_vec(s),
                &bytemuck::pod_collect_to_vec(px),
            );
            p.sink.push(p.tag, counts);
            false
        });
    }
}
