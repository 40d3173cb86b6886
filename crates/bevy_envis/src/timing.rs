//! Per-pass times of the app, as a resource: CPU time to record each pass, and GPU time from
//! Bevy's render diagnostics (`RenderDiagnosticsPlugin`: timestamp queries where the device has
//! them, read back without waiting), which envis's passes record as `render/envis_*`.
//! [`AsyncRead`] is the non-blocking readback the probe uses.

use bevy::diagnostic::{DiagnosticPath, DiagnosticsStore};
use bevy::prelude::*;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, Mutex};

/// Milliseconds per pass (the latest value; `None` until measured or without timestamps).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct PassTimes {
    /// The environment image resampled into the distribution's cube texels: GPU time
    /// ([`RESAMPLE_GPU`]).
    pub resample_gpu_ms: Option<f64>,
    /// Distribution build (CDFs, face energies, pdf table): GPU time ([`DISTRIBUTION_GPU`]).
    pub build_gpu_ms: Option<f64>,
    /// Light-sample pool: GPU time ([`POOL_GPU`]).
    pub pool_gpu_ms: Option<f64>,
    /// CPU time to record the resample, build and pool.
    pub build_cpu_ms: Option<f64>,
    /// Lighting pass (the last envis camera's of the last frame measured): GPU time
    /// ([`LIGHTING_GPU`]), CPU time to record.
    pub lighting_gpu_ms: Option<f64>,
    pub lighting_cpu_ms: Option<f64>,
    /// Resampling pass (gather and the five passes; the last resampling camera's of the last
    /// frame measured): GPU time ([`RESAMPLING_GPU`]), CPU time to record.
    pub resampling_gpu_ms: Option<f64>,
    pub resampling_cpu_ms: Option<f64>,
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

/// Bevy's diagnostic paths of envis's GPU passes.
pub const RESAMPLE_GPU: DiagnosticPath =
    DiagnosticPath::const_new("render/envis_resample/elapsed_gpu");
pub const DISTRIBUTION_GPU: DiagnosticPath =
    DiagnosticPath::const_new("render/envis_distribution/elapsed_gpu");
pub const POOL_GPU: DiagnosticPath = DiagnosticPath::const_new("render/envis_pool/elapsed_gpu");
pub const LIGHTING_GPU: DiagnosticPath =
    DiagnosticPath::const_new("render/envis_lighting/elapsed_gpu");
pub const RESAMPLING_GPU: DiagnosticPath =
    DiagnosticPath::const_new("render/envis_resampling/elapsed_gpu");

/// The latest GPU times of envis's passes in Bevy's diagnostics into [`EnvisTimings`] (a pass
/// keeps its last value until it runs again: a static map builds once).
pub(crate) fn read_pass_diagnostics(
    store: Option<Res<DiagnosticsStore>>,
    timings: Res<EnvisTimings>,
) {
    let Some(store) = store else { return };
    let ms = |p: &DiagnosticPath| store.get_measurement(p).map(|m| m.value);
    timings.set(|t| {
        for (path, field) in [
            (&RESAMPLE_GPU, &mut t.resample_gpu_ms),
            (&DISTRIBUTION_GPU, &mut t.build_gpu_ms),
            (&POOL_GPU, &mut t.pool_gpu_ms),
            (&LIGHTING_GPU, &mut t.lighting_gpu_ms),
            (&RESAMPLING_GPU, &mut t.resampling_gpu_ms),
        ] {
            if let Some(v) = ms(path) {
                *field = Some(v);
            }
        }
    });
}
