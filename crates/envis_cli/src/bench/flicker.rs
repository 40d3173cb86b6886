//! Suite `flicker`: how much one frame's image mean moves from seed to seed on a white furnace,
//! for the pool layouts envis has today. Every pixel shading from the same per-frame pool makes
//! the error coherent across the image: in a live view, whole-image flicker. This measures the
//! pool layouts of issue 14 part 1: the paper's shared pool, a random per-pixel start offset into
//! pools of `N_L`, 4 `N_L` and 16 `N_L` samples per face, `K` = 4, 16, 64 independent blocks of
//! `N_L` (one per pixel), and the `global` baseline (independent samples per pixel).
//!
//! The furnace: a constant map of radiance 1 (faces `--face-size`), a diffuse sphere of albedo 1
//! (`--size`), `N_L + N_B` samples; the exact image is 1 everywhere. Per layout, over `--repeat`
//! seeds (at least 24): the relative SD of the image mean, the per-pixel relMSE, and the median
//! frame time (build + shade) as a ratio to the shared layout's, measured in the same process.

use super::{BenchArgs, median};
use envis::envmap::CubeMap;
use envis::error::Result;
use envis::render::{self, PoolLayout, Settings, Strategy};
use envis::sampling::Material;
use glam::Vec3;
use std::path::Path;

/// One layout's figures.
#[derive(serde::Serialize)]
struct Row {
    layout: String,
    strategy: Strategy,
    pool_per_face: usize,
    pool_layout: PoolLayout,
    pool_blocks: usize,
    image_mean_rel_sd: f64,
    relmse: f64,
    frame_ms: f64,
    frame_time_ratio: f64,
}

/// The layouts measured: (name, settings on top of the base).
fn layouts(base: Settings) -> Vec<(String, Settings)> {
    let nl = base.light_samples.max(1);
    let shared = Settings {
        pool_layout: PoolLayout::Shared,
        ..base
    };
    let mut v = vec![("shared (the paper's)".to_string(), shared)];
    for mult in [1, 4, 16] {
        v.push((
            format!("offset, pool {mult} N_L"),
            Settings {
                pool_layout: PoolLayout::Offset,
                pool_size: mult * nl,
                ..base
            },
        ));
    }
    for k in [4, 16, 64] {
        v.push((
            format!("blocks, {k} pools of N_L"),
            Settings {
                pool_layout: PoolLayout::Blocks,
                pool_blocks: k,
                ..base
            },
        ));
    }
    v.push((
        "global (independent per pixel)".into(),
        Settings {
            strategy: Strategy::Global,
            ..base
        },
    ));
    v
}

pub fn run(a: BenchArgs, dir: &Path) -> Result<()> {
    let (size, seeds) = (a.size, a.repeat.max(24));
    let map = CubeMap::from_fn(a.face_size, |_| Vec3::ONE);
    let gbuf = render::sphere_gbuffer(size, size, Material::diffuse(1.0));
    let idx: Vec<usize> = (0..gbuf.len()).filter(|&i| gbuf[i].is_some()).collect();
    let base = Settings {
        light_samples: a.light_samples,
        brdf_samples: a.brdf_samples,
        ..Default::default()
    };
    let mut rows: Vec<Row> = Vec::new();
    for (name, s) in layouts(base) {
        let (mut means, mut times, mut relmse) = (Vec::new(), Vec::new(), 0.0);
        for seed in 0..seeds {
            let s = Settings {
                seed: seed as u32,
                ..s
            };
            let t0 = std::time::Instant::now();
            let out = render::render(&map, &gbuf, size, size, &s)?;
            times.push(t0.elapsed().as_secs_f64() * 1e3);
            let lum = |i: usize| envis::envmap::luminance_f64(out.image.data[i].as_dvec3());
            means.push(idx.iter().map(|&i| lum(i)).sum::<f64>() / idx.len() as f64);
            relmse += idx.iter().map(|&i| (lum(i) - 1.0).powi(2)).sum::<f64>();
        }
        let (mean, se) = envis_stats::mean_se(&means);
        let frame_ms = median(times);
        let shared_ms = rows.first().map_or(frame_ms, |r| r.frame_ms);
        let row = Row {
            layout: name,
            strategy: s.strategy,
            pool_per_face: s.pool_per_face(),
            pool_layout: s.pool_layout,
            pool_blocks: s.pool_block_count(),
            image_mean_rel_sd: se * (seeds as f64).sqrt() / mean,
            relmse: relmse / (seeds * idx.len()) as f64,
            frame_ms,
            frame_time_ratio: frame_ms / shared_ms,
        };
        eprintln!(
            "  {:32} image-mean SD {:5.2}%  relMSE {:.3e}  frame {:.2} ms ({:.2}x)",
            row.layout,
            100.0 * row.image_mean_rel_sd,
            row.relmse,
            row.frame_ms,
            row.frame_time_ratio
        );
        rows.push(row);
    }
    let report = serde_json::json!({
        "suite": "flicker", "map": "constant 1 (white furnace)", "material": "diffuse, albedo 1",
        "face_size": a.face_size, "size": size, "light_samples": a.light_samples,
        "brdf_samples": a.brdf_samples, "seeds": seeds, "rows": rows,
    });
    let path = dir.join("bench-flicker.json");
    envis::render::output::write_json(&path, &report)?;
    eprintln!("wrote {}", path.display());
    Ok(())
}
