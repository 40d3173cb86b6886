//! What the integration-test binaries share: when a test may skip instead of failing, and where
//! the real data is. A test that cannot run fails, saying how to get what it needs; it skips only
//! when the person running it asked for that (`ENVIS_SKIP_GPU=1`, `ENVIS_SKIP_DATA=1`), and never
//! under CI, so a green run always means the whole suite ran.
#![allow(dead_code)] // each test binary uses its own part of this module

use std::path::{Path, PathBuf};

/// How many `.exr` maps `../shared/data/hdri` holds (see its README): fewer means a partial copy.
pub const REAL_MAP_COUNT: usize = 18;

/// An environment variable set to a true value (`1`, `true`, `yes`, `on`); `CI=false` or `CI=`
/// is not true.
pub fn truthy(var: &str) -> bool {
    std::env::var(var).is_ok_and(|v| {
        matches!(
            v.trim().to_ascii_lowercase().as_str(),
            "1" | "true" | "yes" | "on"
        )
    })
}

/// Running under CI (`CI` set to a true value): nothing may be skipped.
pub fn ci() -> bool {
    truthy("CI")
}

/// `what` cannot run because of `why`. Fails with `install` (how to get the missing piece)
/// unless `ENVIS_SKIP_GPU=1` asks to skip GPU and window tests (outside CI); then says so on
/// stderr, where `cargo test -- --nocapture` shows it.
pub fn skip_gpu_or_fail(what: &str, why: &str, install: &str) {
    if truthy("ENVIS_SKIP_GPU") && !ci() {
        eprintln!("SKIPPING {what} (ENVIS_SKIP_GPU=1): {why}");
    } else {
        panic!(
            "{what} cannot run: {why}. {install} Or set ENVIS_SKIP_GPU=1 to skip GPU and window \
             tests (not honoured under CI)."
        );
    }
}

/// How to get a Vulkan device on a machine without a GPU.
pub const INSTALL_LAVAPIPE: &str = "Install Mesa's CPU Vulkan driver (apt-get install \
    mesa-vulkan-drivers libvulkan1) and run with WGPU_ADAPTER_NAME=llvmpipe.";

/// The shared real maps (`../shared/data/hdri`, all [`REAL_MAP_COUNT`] of them), sorted. A
/// missing or short folder fails, unless `ENVIS_SKIP_DATA=1` (outside CI) asks the tests to use
/// generated maps instead: then `None`, said on stderr.
pub fn real_maps() -> Option<Vec<PathBuf>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/hdri");
    let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map(|rd| {
            rd.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e == "exr"))
                .collect()
        })
        .unwrap_or_default();
    if v.len() < REAL_MAP_COUNT {
        let why = format!(
            "{} holds {} of the {REAL_MAP_COUNT} real maps",
            dir.display(),
            v.len()
        );
        if truthy("ENVIS_SKIP_DATA") && !ci() {
            eprintln!("note (ENVIS_SKIP_DATA=1): {why}; using generated maps instead");
            return None;
        }
        panic!(
            "{why}. Clone envis beside the project's shared/ folder, or set ENVIS_SKIP_DATA=1 to \
             test on generated maps (not honoured under CI)."
        );
    }
    v.sort();
    Some(v)
}

/// A JSON file a test's command wrote (the error names the file).
pub fn read_json(path: &Path) -> serde_json::Value {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_slice(&bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}
