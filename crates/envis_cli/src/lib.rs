//! The lab behind the `envis` binary: what the command line runs, and what the tests share.
//!
//! - [`bench`](mod@bench): `envis bench`, speed and accuracy measured as ratios against baselines run in
//!   the same process, with plots.
//! - [`sequence`]: `envis sequence`, an animated scene frame by frame on the CPU oracle, the
//!   WGSL passes (`envis_wgpu`) or Bevy (`bevy_envis`).
//! - [`headless`]: a windowless Bevy app with float render targets read back (captures, the
//!   Bevy backend of `render` and `sequence`, the Bevy tests).
//! - [`demo`]: the interactive demo (egui panel, sample-debug view), `envis` with no subcommand.
//!
//! A game depends on `bevy_envis` alone and compiles none of this.

pub mod bench;
pub mod demo;
pub mod headless;
pub mod sequence;

/// A path under the workspace's root (`assets/...`), where the lab's default scenes, maps and
/// models are: the binary is run from a checkout of the repository.
pub fn repo_path(relative: &str) -> std::path::PathBuf {
    std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join(relative)
}
