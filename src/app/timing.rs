//! Per-pass times of the app, as a resource: CPU time to record each pass, and GPU time from
//! timestamp queries where the device has them, read back asynchronously (a pass is timed again
//! only after its previous result has been read, so the frame path never waits for the GPU).

use bevy::prelude::*;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, Mutex};

/// Milliseconds per pass (the latest value; `None` until measured or without timestamps).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct PassTimes {
    /// Distribution build + pool: GPU time, and CPU time to upload + record.
    pub build_gpu_ms: Option<f64>,
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

/// Two timestamps around one pass, resolved and mapped without blocking.
pub struct AsyncTimer {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    readback: wgpu::Buffer,
    state: Arc<AtomicU8>,
    period_ns: f32,
}

impl AsyncTimer {
    /// `None` when the device has no timestamp queries.
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue, label: &str) -> Option<Self> {
        if !device.features().contains(wgpu::Features::TIMESTAMP_QUERY) {
            return None;
        }
        let set = device.create_query_set(&wgpu::QuerySetDescriptor { label: Some(label), ty: wgpu::QueryType::Timestamp, count: 2 });
        let buf = |usage| device.create_buffer(&wgpu::BufferDescriptor { label: Some(label), size: 16, usage, mapped_at_creation: false });
        Some(AsyncTimer {
            set,
            resolve: buf(wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC),
            readback: buf(wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ),
            state: Arc::new(AtomicU8::new(IDLE)),
            period_ns: queue.get_timestamp_period(),
        })
    }

    /// Whether this pass should be timed now (the previous result has been collected).
    pub fn ready(&self) -> bool {
        self.state.load(Ordering::Acquire) == IDLE
    }
    pub fn compute_writes(&self) -> wgpu::ComputePassTimestampWrites<'_> {
        wgpu::ComputePassTimestampWrites { query_set: &self.set, beginning_of_pass_write_index: Some(0), end_of_pass_write_index: Some(1) }
    }
    pub fn render_writes(&self) -> wgpu::RenderPassTimestampWrites<'_> {
        wgpu::RenderPassTimestampWrites { query_set: &self.set, beginning_of_pass_write_index: Some(0), end_of_pass_write_index: Some(1) }
    }
    /// After the timed pass: resolve into the readback buffer.
    pub fn resolve(&self, enc: &mut wgpu::CommandEncoder) {
        enc.resolve_query_set(&self.set, 0..2, &self.resolve, 0);
        enc.copy_buffer_to_buffer(&self.resolve, 0, &self.readback, 0, 16);
        self.state.store(WRITTEN, Ordering::Release);
    }
    /// Call once per frame, after the frame that resolved was submitted: requests the mapping,
    /// and returns the milliseconds once they are mapped.
    pub fn poll(&self) -> Option<f64> {
        match self.state.load(Ordering::Acquire) {
            WRITTEN => {
                self.state.store(MAPPING, Ordering::Release);
                let st = self.state.clone();
                self.readback.slice(..).map_async(wgpu::MapMode::Read, move |r| {
                    st.store(if r.is_ok() { MAPPED } else { IDLE }, Ordering::Release);
                });
                None
            }
            MAPPED => {
                let t: [u64; 2] = {
                    let v = self.readback.slice(..).get_mapped_range();
                    bytemuck::pod_read_unaligned(&v[..16])
                };
                self.readback.unmap();
                self.state.store(IDLE, Ordering::Release);
                (t[1] > t[0]).then(|| (t[1] - t[0]) as f64 * self.period_ns as f64 * 1e-6)
            }
            _ => None,
        }
    }
}
