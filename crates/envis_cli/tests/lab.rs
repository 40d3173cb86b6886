//! The lab's tests: the `envis` binary (commands, bench suites, sequences on the CPU, the WGSL
//! passes and Bevy), and everything that runs Bevy (the plugins through a headless app, the
//! examples, the demo under Xvfb). One binary, so Bevy is linked once.

use envis::envmap::load::{EnvSource, load_env};
use envis::envmap::*;
use envis::render::reference::reference_image;
use envis::render::{GPixel, Settings, render, sphere_gbuffer};
use envis::sampling::rng::Rng;
use envis::sampling::*;
use envis_stats::{Chi2Test, FacePlane, MeanCheck, UnbiasedTest};
use glam::{DVec3, Vec3};
use std::path::Path;

#[path = "../../envis_wgpu/tests/gpu/device.rs"]
mod device;
#[path = "../../envis/tests/support/mod.rs"]
mod support;
use device::gpu;
use support::{mean_lum, rel, rng_vec2, tempdir};

// Helpers

/// `envis bench --suite SUITE_AND_ARGS --out DIR`, which must succeed; returns `DIR/json`.
fn bench_json(dir: &Path, suite_and_args: &[&str], json: &str) -> serde_json::Value {
    let mut args = vec!["bench", "--suite"];
    args.extend_from_slice(suite_and_args);
    args.extend_from_slice(&["--out", dir.to_str().unwrap()]);
    let r = envis_cmd(&args);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    support::read_json(&dir.join(json))
}

fn envis_cmd(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_envis"))
        .args(args)
        .output()
        .unwrap()
}

#[path = "lab/core_cli.rs"]
mod core_cli;

#[path = "lab/core_bench.rs"]
mod core_bench;

#[path = "lab/core_scenes.rs"]
mod core_scenes;

#[path = "lab/core_resampling.rs"]
mod core_resampling;

#[path = "lab/gpu_resampling.rs"]
mod gpu_resampling;

#[path = "lab/gpu_cli.rs"]
mod gpu_cli;

#[path = "lab/bevy_app.rs"]
mod bevy_app;

#[path = "lab/bevy_plugin.rs"]
mod bevy_plugin;

#[path = "lab/bevy_images.rs"]
mod bevy_images;

#[path = "lab/bevy_shadows.rs"]
mod bevy_shadows;

#[path = "lab/bevy_pose.rs"]
mod bevy_pose;

#[path = "lab/bevy_resampling.rs"]
mod bevy_resampling;

#[path = "lab/bevy_post.rs"]
mod bevy_post;

#[path = "lab/bevy_ready.rs"]
mod bevy_ready;

#[path = "lab/examples.rs"]
mod examples;

#[path = "lab/demo.rs"]
mod demo;
