//! The map's bright part (a sun) in the Bevy pass, resampled apart from the rest as the CPU
//! oracle does (`render::resampling::Split`). The split is a CPU step over the map, made from
//! the camera's map on the CPU ([`CpuEnvMaps`]: the envis stream's frame, or the texels of
//! a user's image). Once per map change, per view: the map resampled to the sampling face size
//! by the CPU twin of the texel table (`SourceImage::to_cube`, which `gpu_resample_matches_cpu`
//! ties to the GPU's), split, and its rest built into a sampler of the view's own (the camera's
//! shared one is built on the whole map, whose light samples would land in the sun, where the
//! rest is zero). Every frame: that sampler's pool drawn with the frame's seed, and the split
//! tables written into the frame's split buffer in place of `gather_split`'s whole map. A
//! camera whose map has no CPU copy keeps the whole map (`split_bright: false`).

use super::cpu_maps::CpuEnvMaps;
use bevy::prelude::*;
use envis::envmap::CubeMap;
use envis::render::resampling::{BrightLight, Split, map_agreement};
use envis::sampling::TileGrid;
use envis_wgpu::EnvSampler;
use envis_wgpu::resampling::{split_tables, storage_init};
use std::sync::Arc;

/// A view's split of its map, and the sampler built on its rest.
pub(super) struct BrightSplit {
    /// (`CpuEnvMap::revision`, face size) of the map the tables hold.
    map_key: (u64, usize),
    /// Per texel the rest's radiance and the bright part's with its probability
    /// (`split_tables`), written into each frame's split buffer.
    tables: Vec<[f32; 4]>,
    pub cdf: wgpu::Buffer,
    pub ids: wgpu::Buffer,
    pub count: u32,
    pub bright: Arc<BrightLight>,
    pub sampler: EnvSampler,
    /// The rest of the map (what [`map_agreement`] compares when the map changes).
    rest: Arc<CubeMap>,
    /// How far this frame's map agrees with the previous frame's as light: [`map_agreement`]
    /// of the two rests in the frame the map changed, 1 while it stays, 0 where the frame
    /// before had no split (its history was made under the whole map).
    pub map_agreement: f32,
}

/// What the sampler is built for: face size, tiles, pool slots, blocks, `global` table.
type SamplerShape = (usize, usize, usize, usize, bool);

fn shape(s: &EnvSampler) -> SamplerShape {
    (s.n, s.tiles, s.m, s.blocks, s.has_global())
}

/// Prepare `split`, this frame's split for a view lit by `image` whose camera samples with
/// `like` (its shared sampler: face size, tiles, pool), its pool drawn with `pool_seed`; left
/// `None` (the whole map) where the image has no CPU copy or the sampler cannot be made.
pub(super) fn view_split(
    split: &mut Option<BrightSplit>,
    (maps, image): (Option<&CpuEnvMaps>, AssetId<Image>),
    like: &EnvSampler,
    pool_seed: u32,
    (device, queue, enc): (&wgpu::Device, &wgpu::Queue, &mut wgpu::CommandEncoder),
) {
    let old = split.take();
    let Some((revision, map)) = maps.and_then(|m| m.map(image)) else {
        return;
    };
    let map_key = (revision, like.n);
    let fresh = match old {
        Some(s) if shape(&s.sampler) == shape(like) && s.map_key == map_key => BrightSplit {
            map_agreement: 1.0,
            ..s
        },
        old => {
            // (Made here only when the map or the sampler changed: the stream's frame is
            // resampled to the face size now; a face size not yet made from a user's image is
            // being made on the async pool.)
            let Some(cube) = map.cube(like.n) else {
                return;
            };
            let old_rest = old.as_ref().map(|s| s.rest.clone());
            let sampler = match old {
                Some(s) if shape(&s.sampler) == shape(like) => s.sampler,
                _ => match new_sampler(device, queue, like) {
                    Some(s) => s,
                    None => return,
                },
            };
            let mut s = build(device, queue, &cube, map_key, sampler);
            s.sampler.encode_distribution(enc, None);
            // Without a split the frame before, that frame's history was made under the whole
            // map (a new version of it was being read, or its first texels): another rest,
            // which the CPU cannot compare, so the history is dropped. Kept, a new image would
            // be followed at a twentieth a frame (the carousel before the map agreement,
            // docs/temporal.md).
            s.map_agreement = old_rest.map_or(0.0, |r| map_agreement(&r, &s.rest));
            s
        }
    };
    fresh.sampler.set_seed(queue, pool_seed);
    fresh.sampler.encode_pool(enc, None);
    *split = Some(fresh);
}

/// A sampler shaped as `like`; `None`, with a warning once, where the device refuses.
fn new_sampler(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    like: &EnvSampler,
) -> Option<EnvSampler> {
    let grid = TileGrid::new(like.n, like.tiles);
    // The shared sampler's compiled build: nothing is compiled on the frame path.
    let pipelines = like.build_pipelines();
    let made = EnvSampler::with_pipelines(device, queue, pipelines, grid, like.m, false);
    let made = made.and_then(|mut s| {
        s.set_blocks(like.blocks)?;
        if like.has_global() {
            s.enable_global(device, queue)?;
        }
        Ok(s)
    });
    made.map_err(|e| bevy::log::warn_once!("envis resampling: no bright part ({e})"))
        .ok()
}

/// Split `map` at the sampler's face size and upload the rest and the bright part's tables.
fn build(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    cube: &CubeMap,
    map_key: (u64, usize),
    sampler: EnvSampler,
) -> BrightSplit {
    let split = Split::new(cube);
    sampler.upload(queue, &split.rest);
    let (tables, cdf, ids) = split_tables(&split);
    BrightSplit {
        map_key,
        cdf: storage_init(device, "envis bright cdf", &cdf),
        ids: storage_init(device, "envis bright texels", &ids),
        count: ids.len() as u32,
        tables,
        bright: Arc::new(split.bright),
        sampler,
        rest: Arc::new(split.rest),
        map_agreement: 1.0,
    }
}

impl BrightSplit {
    /// Write the split tables into this frame's split buffer.
    pub(super) fn write(&self, queue: &wgpu::Queue, split: &wgpu::Buffer) {
        queue.write_buffer(split, 0, bytemuck::cast_slice(&self.tables));
    }
}
