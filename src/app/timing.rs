//! Per-pass times of the app, as a resource: CPU time to record each pass, and GPU time from
//! timestamp queries where the device has them, read back asynchronously (a pass is timed again
//! only after its previous result has been read, so the frame path never waits for the GPU).

use bevy::prelude::*;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, Mutex};

/// Milliseconds per pass (the latest value; `None` until measured or without timestamps).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct PassTimes {
    /// The environment image resampled into the distribution's cube texels: GPU time.
    pub resample_gpu_ms: Option<f64>,
    /// Distribution build (CDFs, face energies, pdf table): GPU time.
    pub build_gpu_ms: Option<f64>,
    /// Light-sample pool: GPU time.
    pub pool_gpu_ms: Option<f64>,
    /// CPU time to record the resample, build and pool.
    pub build_cpu_ms: Option<f64>,
    /// Lighting pass (all envis cameras of the last frame): GPU time, CPU time to record.
    pub lighting_gpu_ms: Option<f64>,
    pub lighting_cpu_ms: Option<f64>,
}

/// Shared by the main and the render world (the render world writes, the panel reads).
#[derive(Resource, Clone, Default, Deref)]
pub struct EnvisTimings(pub Arc<Mutex<PassTimes>>);

impl EnvisTimings {
    pub fn get(&self) -> PassTimes {
        *self.0.lock().expect("timings")
    }
    pub(crate) fn set(&self, f: impl FnOnce(&mut PassTimes)) {
        f(&mut self.0.lock().expect("timings"));
    }
}

const IDLE: u8 = 0;
const WRITTEN: u8 = 1;
const MAPPING: u8 = 2;
const MAPPED: u8 = 3;

/// A small GPU -> CPU copy that never blocks: copy into it after a pass, then [`Self::poll`]
/// once per frame until the bytes arrive. A new copy is accepted only when the last one was read.
pub struct AsyncRead {
    readback: wgpu::Buffer,
    size: u64,
    state: Arc<AtomicU8>,
}

impl AsyncRead {
    pub fn new(device: &wgpu::Device, label: &str, size: u64) -> Self {
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        AsyncRead {
            readback,
            size,
            state: Arc::new(AtomicU8::new(IDLE)),
        }
    }
    /// Whether a new copy can be recorded (the previous bytes have been collected).
    pub fn ready(&self) -> bool {
        self.state.load(Ordering::Acquire) == IDLE
    }
    pub fn copy_from(&self, enc: &mut wgpu::CommandEncoder, src: &wgpu::Buffer) {
        enc.copy_buffer_to_buffer(src, 0, &self.readback, 0, self.size);
        self.state.store(WRITTEN, Ordering::Release);
    }
    /// Call once per frame after the copying frame was submitted: requests the mapping, and
    /// returns the bytes once mapped.
    pub fn poll(&self) -> Option<Vec<u8>> {
        match self.state.load(Ordering::Acquire) {
            WRITTEN => {
                self.state.store(MAPPING, Ordering::Release);
                let st = self.state.clone();
                self.readback
                    .slice(..)
                    .map_async(wgpu::MapMode::Read, move |r| {
                        st.store(if r.is_ok() { MAPPED } else { IDLE }, Ordering::Release);
                    });
                None
            }
            MAPPED => {
                let v = self.readback.slice(..).get_mapped_range().to_vec();
                self.readback.unmap();
                self.state.store(IDLE, Ordering::Release);
                Some(v)
            }
            _ => None,
        }
    }
}

/// Two timestamps around one pass, resolved and read back with an [`AsyncRead`].
pub struct AsyncTimer {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    read: AsyncRead,
    period_ns: f32,
}

impl AsyncTimer {
    /// `None` when the device has no timestamp queries.
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue, label: &str) -> Option<Self> {
        if !device.features().contains(wgpu::Features::TIMESTAMP_QUERY) {
            return None;
        }
        let (set, resolve) = crate::gpu::timestamp_pair(device, label);
        Some(AsyncTimer {
            set,
            resolve,
            read: AsyncRead::new(device, label, 16),
            period_ns: queue.get_timestamp_period(),
        })
    }

    /// Whether this pass should be timed now (the previous result has been collected).
    pub fn ready(&self) -> bool {
        self.read.ready()
    }
    pub fn compute_writes(&self) -> wgpu::ComputePassTimestampWrites<'_> {
        wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(0),
            end_of_pass_write_index: Some(1),
        }
    }
    pub fn render_writes(&self) -> wgpu::RenderPassTimestampWrites<'_> {
        wgpu::RenderPassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(0),
            end_of_pass_write_index: Some(1),
        }
    }
    /// After the timed pass: resolve into the readback buffer.
    pub fn resolve(&self, enc: &mut wgpu::CommandEncoder) {
        enc.resolve_query_set(&self.set, 0..2, &self.resolve, 0);
        self.read.copy_from(enc, &self.resolve);
    }
    /// Milliseconds of the timed pass, once they have arrived.
    pub fn poll(&self) -> Option<f64> {
        let v = self.read.poll()?;
        let t: [u64; 2] = bytemuck::pod_read_unaligned(&v[..16]);
        (t[1] > t[0]).then(|| (t[1] - t[0]) as f64 * self.period_ns as f64 * 1e-6)
    }
}
