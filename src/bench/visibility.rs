//! `envis bench --suite visibility`: what shadow rays cost on the CPU. For each scene, the frame
//! time with visibility off and on (same process, same G-buffer, same settings), the shadow rays
//! cast and their rate; and the BVH build time against triangle count (the bunny, Suzanne, and
//! the bunny merged 100 times).

use super::{BenchArgs, median};
use crate::envmap::load::{EnvSource, load_env};
use crate::error::Result;
use crate::render::{Extras, render_with};
use crate::scene::{Scene, Shape, TriMesh};
use crate::visibility::MeshBvh;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(serde::Serialize)]
struct SceneRow {
    scene: String,
    triangles: usize,
    visibility_auto: String,
    /// Median frame (shading) time, ms: no shadow rays, and a shadow ray per sample.
    off_ms: f64,
    on_ms: f64,
    on_over_off: f64,
    shadow_rays_per_frame: u64,
    /// Shadow rays per second, counting all the on-frame's extra time as ray time.
    shadow_rays_per_second: f64,
    blocked_fraction: f64,
}

#[derive(serde::Serialize)]
struct BuildRow {
    mesh: String,
    triangles: usize,
    build_ms: f64,
    ns_per_triangle: f64,
}

pub fn run(a: BenchArgs, dir: PathBuf) -> Result<()> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
    let (w, h) = if a.quick {
        (96, 60)
    } else {
        (a.size, a.height.unwrap_or(a.size * 10 / 16))
    };
    let repeat = if a.quick { 1 } else { a.repeat.max(1) };
    let mut scenes = Vec::new();
    for name in ["diffuse-static.toml", "showcase.toml"] {
        let sc = Scene::load(&root.join(name))?;
        scenes.push(scene_row(name, &sc, w, h, repeat)?);
    }
    let mut builds = Vec::new();
    for (name, mesh) in meshes(&root)? {
        let t: Vec<f64> = (0..repeat.max(3))
            .map(|_| {
                let t0 = Instant::now();
                let _ = MeshBvh::build(&mesh.positions, &mesh.indices);
                t0.elapsed().as_secs_f64() * 1e3
            })
            .collect();
        let ms = median(t);
        let n = mesh.indices.len();
        eprintln!("  BVH build {name}: {n} triangles in {ms:.2} ms");
        builds.push(BuildRow {
            mesh: name,
            triangles: n,
            build_ms: ms,
            ns_per_triangle: ms * 1e6 / n.max(1) as f64,
        });
    }
    let out = serde_json::json!({
        "width": w, "height": h, "threads": rayon::current_num_threads(),
        "scenes": scenes, "bvh_builds": builds,
    });
    let path = dir.join("bench-visibility.json");
    crate::render::output::write_json(&path, &out)?;
    eprintln!("wrote {}", path.display());
    Ok(())
}

/// One scene rendered `repeat` times with visibility off, then on.
fn scene_row(name: &str, sc: &Scene, w: usize, h: usize, repeat: usize) -> Result<SceneRow> {
    let src: EnvSource = sc.environment.parse()?;
    let map = load_env(&src, sc.file.environment.face_size)?.cube;
    let (gbuf, points) = sc.gbuffer_points(w, h);
    let occ = sc.occluders();
    let mut times = [Vec::new(), Vec::new()];
    let mut last = None;
    for (k, on) in [false, true].into_iter().enumerate() {
        let extras = Extras {
            shadows: on.then_some((&occ as _, points.as_slice())),
            ..Default::default()
        };
        for _ in 0..repeat {
            let out = render_with(&map, extras, &gbuf, w, h, &sc.settings)?;
            times[k].push(out.stats.shade_ms);
            last = Some(out.stats);
        }
    }
    let stats = last.expect("rendered");
    let [off, on] = times.map(median);
    let rays = stats.shadow_rays;
    let triangles = sc
        .objects
        .iter()
        .map(|o| match &o.shape {
            Shape::Mesh(m) => m.mesh.indices.len(),
            _ => 0,
        })
        .sum();
    let row = SceneRow {
        scene: name.into(),
        triangles,
        visibility_auto: sc.shadows(None).1,
        off_ms: off,
        on_ms: on,
        on_over_off: on / off.max(1e-9),
        shadow_rays_per_frame: rays,
        shadow_rays_per_second: rays as f64 / ((on - off).max(1e-6) / 1e3),
        blocked_fraction: stats.blocked,
    };
    eprintln!(
        "  {name}: shading {off:.1} ms without shadow rays, {on:.1} ms with ({:.2}x); {rays} rays, {:.1} M rays/s",
        row.on_over_off,
        row.shadow_rays_per_second / 1e6
    );
    Ok(row)
}

/// The meshes whose BVH build is timed.
fn meshes(root: &Path) -> Result<Vec<(String, TriMesh)>> {
    let models = root.parent().unwrap_or(root).join("models");
    let bunny = crate::scene::load_glb(&models.join("bunny_plain.glb"))?;
    let suzi = crate::scene::load_glb(&models.join("suzi_plain.glb"))?;
    let mut many = TriMesh::default();
    for i in 0..100 {
        let offset = glam::Vec3::new((i % 10) as f32, 0.0, (i / 10) as f32) * 0.3;
        let base = many.positions.len() as u32;
        many.positions
            .extend(bunny.positions.iter().map(|p| *p + offset));
        many.indices
            .extend(bunny.indices.iter().map(|t| t.map(|v| v + base)));
    }
    Ok(vec![
        ("bunny".into(), bunny),
        ("suzanne".into(), suzi),
        ("bunny x100 (merged)".into(), many),
    ])
}
