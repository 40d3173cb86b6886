//! The one GPU device of a test binary, shared by the GPU twins' tests (`gpu.rs`) and the lab's
//! (`crates/envis_cli/tests/lab.rs`), which include this file by path.

use super::support;
use envis_wgpu::GpuContext;
use std::sync::OnceLock;

/// One device for the whole binary (device creation on lavapipe costs ~100 ms; tests run in
/// parallel on it). `None` only when `ENVIS_SKIP_GPU=1` asked to skip (see `support`).
pub fn gpu() -> Option<&'static GpuContext> {
    static CTX: OnceLock<Option<GpuContext>> = OnceLock::new();
    CTX.get_or_init(|| match GpuContext::new() {
        Ok(c) => {
            eprintln!(
                "GPU tests on: {} ({:?}, timestamps: {})",
                c.info.name, c.info.backend, c.timestamps
            );
            Some(c)
        }
        Err(e) => {
            support::skip_gpu_or_fail(
                "the GPU tests",
                &format!("no Vulkan device ({e})"),
                support::INSTALL_LAVAPIPE,
            );
            None
        }
    })
    .as_ref()
}
