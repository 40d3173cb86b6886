//! GPU stages against their CPU twins, on a real Vulkan device (Mesa lavapipe in CI:
//! `WGPU_ADAPTER_NAME=llvmpipe`). Each stage is compared in isolation — the CPU twin of a stage
//! runs on exactly the GPU's input — and then the whole frame against the CPU renderer and the
//! f64 reference. A missing device fails the tests, unless `ENVIS_SKIP_GPU=1` (outside CI).

use envis::envmap::load::{EnvSource, load_env};
use envis::envmap::*;
use envis::render::reference::reference_image;
use envis::render::{
    FrameData, GPixel, PoolLayout, Settings, Strategy, pool_seed, render, sphere_gbuffer,
};
use envis::sampling::*;
use envis_stats::{MeanCheck, UnbiasedTest};
use envis_wgpu::{EnvSampler, GpuContext, GpuGPixel, Shader, render_gpu};
use glam::Vec3;
use std::path::PathBuf;

#[path = "gpu/device.rs"]
mod device;
#[path = "../../envis/tests/support/mod.rs"]
mod support;
use device::gpu;
use support::{mean_lum, rel};

fn real_map_paths() -> Vec<PathBuf> {
    support::real_maps().unwrap_or_default()
}

/// A map that is zero but for one texel of 1e6 (plus a dim floor so other faces are not empty).
fn single_texel_map(n: usize, face: usize, col: usize, row: usize) -> CubeMap {
    let mut m = CubeMap::new(n);
    for t in &mut m.data {
        *t = Vec3::splat(1e-3);
    }
    let i = m.index(face, col, row);
    m.data[i] = Vec3::splat(1e6);
    m
}

/// Test maps for the stage comparisons: the built-in sky, two real maps, a lone 1e6 texel.
fn stage_maps(n: usize) -> Vec<(String, CubeMap)> {
    let mut v = vec![(
        "builtin:sky:9".to_string(),
        load_env(&EnvSource::Sky { hours: 9.0 }, n).unwrap().cube,
    )];
    let real = real_map_paths();
    for p in real.iter().step_by(real.len().max(2) / 2).take(2) {
        v.push((
            p.display().to_string(),
            load_env(&EnvSource::File(p.clone()), n).unwrap().cube,
        ));
    }
    v.push((
        "single 1e6 texel".into(),
        single_texel_map(n, 4, n / 3, n - 2),
    ));
    v
}

/// Build on the GPU (a pool of `blocks` blocks of `m` per face) and read every table back.
fn gpu_build(
    ctx: &GpuContext,
    map: &CubeMap,
    m: usize,
    blocks: usize,
    seed: u32,
) -> envis_wgpu::GpuTables {
    gpu_build_tiled(ctx, map, 1, m, blocks, seed)
}

/// [`gpu_build`] with `tiles x tiles` tiles per face.
fn gpu_build_tiled(
    ctx: &GpuContext,
    map: &CubeMap,
    tiles: usize,
    m: usize,
    blocks: usize,
    seed: u32,
) -> envis_wgpu::GpuTables {
    let s = Settings {
        light_samples: m,
        brdf_samples: 0,
        tiles,
        pool_layout: PoolLayout::Blocks,
        pool_blocks: blocks,
        ..Default::default()
    };
    let mut s = EnvSampler::for_settings(ctx, map.size, &s).unwrap();
    s.set_blocks(blocks).unwrap();
    s.upload(&ctx.queue, map);
    ctx.wait(s.run(ctx, seed)).unwrap();
    s.read_tables(ctx).unwrap()
}

#[path = "gpu/twins.rs"]
mod twins;

#[path = "gpu/shading.rs"]
mod shading;

#[path = "gpu/functions.rs"]
mod functions;

#[path = "gpu/stability.rs"]
mod stability;

#[path = "gpu/visibility.rs"]
mod visibility;
