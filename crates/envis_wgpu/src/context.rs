//! A headless wgpu device for the GPU backend and the GPU tests.

use envis::error::{Error, Result};

/// Device, queue and what was chosen. `WGPU_ADAPTER_NAME` (a case-insensitive substring, e.g.
/// `llvmpipe` for Mesa lavapipe) picks the adapter; otherwise wgpu's default choice.
pub struct GpuContext {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    /// Timestamp queries inside compute passes are available.
    pub timestamps: bool,
}

/// Drive a future whose work wgpu completes on its own (adapter and device requests on native
/// backends resolve without an executor), polling until it is ready.
pub fn block_on<F: std::future::Future>(fut: F) -> F::Output {
    let mut fut = std::pin::pin!(fut);
    let waker = std::task::Waker::noop();
    let mut cx = std::task::Context::from_waker(waker);
    loop {
        if let std::task::Poll::Ready(v) = fut.as_mut().poll(&mut cx) {
            return v;
        }
        std::thread::yield_now();
    }
}

/// The adapter `WGPU_ADAPTER_NAME` names (a case-insensitive substring), or wgpu's default.
/// The error says how to get a Vulkan device on a machine without a GPU.
fn pick_adapter(instance: &wgpu::Instance) -> Result<wgpu::Adapter> {
    let wanted = std::env::var("WGPU_ADAPTER_NAME")
        .ok()
        .filter(|s| !s.is_empty())
        .map(|s| s.to_lowercase());
    match &wanted {
        Some(name) => {
            let all = block_on(instance.enumerate_adapters(wgpu::Backends::all()));
            let names: Vec<String> = all.iter().map(|a| a.get_info().name).collect();
            let found = all
                .into_iter()
                .find(|a| a.get_info().name.to_lowercase().contains(name.as_str()));
            found.ok_or_else(|| {
                let names = if names.is_empty() {
                    "none".into()
                } else {
                    names.join(", ")
                };
                Error::invalid(format!(
                    "WGPU_ADAPTER_NAME={name}: no such GPU adapter (found: {names}){NO_GPU_HINT}"
                ))
            })
        }
        None => block_on(instance.request_adapter(&wgpu::RequestAdapterOptions::default()))
            .map_err(|e| Error::invalid(format!("no GPU adapter ({e}){NO_GPU_HINT}"))),
    }
}

/// What to do without a GPU, appended to adapter errors.
const NO_GPU_HINT: &str = "; without a GPU, `apt-get install mesa-vulkan-drivers` gives a CPU \
    Vulkan device (run with WGPU_ADAPTER_NAME=llvmpipe), or use `envis render` (CPU)";

/// Whether a GPU adapter is there, without creating a device: a one-line error before a Bevy app
/// starts (Bevy would panic instead).
pub fn check_adapter() -> Result<wgpu::AdapterInfo> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
    pick_adapter(&instance).map(|a| a.get_info())
}

impl GpuContext {
    pub fn new() -> Result<Self> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
        let adapter = pick_adapter(&instance)?;
        let info = adapter.get_info();
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let features = if timestamps {
            wgpu::Features::TIMESTAMP_QUERY
        } else {
            wgpu::Features::empty()
        };
        // Everything the adapter offers: 2048^2 faces need storage bindings above WebGPU's 128 MiB.
        let limits = adapter.limits();
        let (device, queue) = block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("envis"),
            required_features: features,
            required_limits: limits,
            ..Default::default()
        }))
        .map_err(|e| Error::invalid(format!("GPU device request failed on {}: {e}", info.name)))?;
        Ok(GpuContext {
            device,
            queue,
            info,
            timestamps,
        })
    }

    /// Block until the given submission has finished.
    pub fn wait(&self, index: wgpu::SubmissionIndex) -> Result<()> {
        self.device
            .poll(wgpu::PollType::Wait {
                submission_index: Some(index),
                timeout: None,
            })
            .map(|_| ())
            .map_err(|e| Error::invalid(format!("GPU wait failed: {e}")))
    }

    /// Copy `size` bytes of `src` (from `offset`) to the CPU.
    pub fn read_buffer(&self, src: &wgpu::Buffer, offset: u64, size: u64) -> Result<Vec<u8>> {
        Ok(self.read_many(&[(src, offset, size)])?.remove(0))
    }

    /// Copy several buffer ranges `(buffer, offset, size)` to the CPU with one staging buffer,
    /// one submission and one wait (each round trip to the device costs latency, which adds up
    /// on a software driver).
    pub fn read_many(&self, parts: &[(&wgpu::Buffer, u64, u64)]) -> Result<Vec<Vec<u8>>> {
        let align = |x: u64| x.div_ceil(8) * 8;
        let total: u64 = parts.iter().map(|p| align(p.2)).sum::<u64>().max(8);
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("envis readback"),
            size: total,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = self.device.create_command_encoder(&Default::default());
        let mut at = 0;
        for &(src, offset, size) in parts {
            enc.copy_buffer_to_buffer(src, offset, &staging, at, size);
            at += align(size);
        }
        let idx = self.queue.submit([enc.finish()]);
        let (tx, rx) = std::sync::mpsc::channel();
        staging.slice(..).map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.wait(idx)?;
        rx.recv()
            .map_err(|_| Error::invalid("GPU readback: map callback dropped"))?
            .map_err(|e| Error::invalid(format!("GPU readback failed: {e}")))?;
        let data = staging.slice(..).get_mapped_range().to_vec();
        staging.unmap();
        let mut out = Vec::with_capacity(parts.len());
        let mut at = 0usize;
        for p in parts {
            out.push(data[at..at + p.2 as usize].to_vec());
            at += align(p.2) as usize;
        }
        Ok(out)
    }

    /// Read back a buffer of plain values.
    pub fn read<T: bytemuck::Pod>(
        &self,
        src: &wgpu::Buffer,
        first: usize,
        count: usize,
    ) -> Result<Vec<T>> {
        let sz = std::mem::size_of::<T>() as u64;
        let bytes = self.read_buffer(src, first as u64 * sz, count as u64 * sz)?;
        Ok(bytemuck::pod_collect_to_vec(&bytes))
    }
}
