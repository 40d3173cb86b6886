//! `envis bench --suite visibility`: what shadow rays cost on the CPU. For each scene, the frame
//! time with visibility off and on (same process, same G-buffer, same settings), the shadow rays
//! cast and their rate; the BVH build time against triangle count (the bunny, Suzanne, and the
//! bunny merged 100 times into one mesh); and for the bunny placed 100 times (two levels), the
//! one mesh BVH, the top level's build and refit, and the GPU layout's build and rewrite; and a
//! skinned mesh of 10k and 100k triangles posed anew: skinning, refit and layout per frame,
//! against building its BVH anew (the baseline, same process).

use super::{BenchArgs, median};
use envis::envmap::load::{EnvSource, load_env};
use envis::error::Result;
use envis::render::{Extras, render_with};
use envis::scene::{Scene, Shape, TriMesh};
use envis::visibility::MeshBvh;
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

/// The bunny placed 100 times: what each level costs.
#[derive(serde::Serialize)]
struct InstancedRow {
    instances: usize,
    triangles_placed: usize,
    /// The bunny's BVH, built once for all placements.
    mesh_bvh_ms: f64,
    /// The top level over the placements: built anew, and refitted after every instance moved.
    tlas_build_ms: f64,
    tlas_refit_ms: f64,
    /// The GPU layout: both levels laid out, and only the top part rewritten after a move.
    flat_build_ms: f64,
    flat_place_ms: f64,
}

/// A skinned mesh's shadow geometry per new pose (what the Bevy pass does on the CPU each frame
/// a skinned caster's joints move; the upload comes on top).
#[derive(serde::Serialize)]
struct SkinnedRow {
    triangles: usize,
    /// Linear blend skinning of every vertex (two joints).
    skin_ms: f64,
    /// The BVH refitted to the new pose, and the GPU layout built over it.
    refit_ms: f64,
    layout_ms: f64,
    /// All three: the per-frame cost.
    frame_ms: f64,
    /// The baseline: the BVH built anew over the new pose (and laid out).
    rebuild_ms: f64,
    rebuild_over_frame: f64,
}

#[derive(serde::Serialize)]
struct BuildRow {
    mesh: String,
    triangles: usize,
    build_ms: f64,
    ns_per_triangle: f64,
}

pub fn run(a: BenchArgs, dir: PathBuf) -> Result<()> {
    let root = crate::repo_path("assets/scenes");
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
    let grid = bunny_grid_scene(&dir)?;
    let sc = Scene::load(&grid)?;
    scenes.push(scene_row("bunny x100 (instanced)", &sc, w, h, repeat)?);
    let instanced = instanced_row(&sc, repeat.max(3))?;
    let skinned = [(71, 71), (224, 224)]
        .map(|(nu, nv)| skinned_row(nu, nv, repeat.max(3)))
        .into_iter()
        .collect::<Result<Vec<_>>>()?;
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
        "scenes": scenes, "bvh_builds": builds, "instanced": instanced, "skinned": skinned,
    });
    let path = dir.join("bench-visibility.json");
    envis::render::output::write_json(&path, &out)?;
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
    let bunny = envis::scene::load_glb(&models.join("bunny_plain.glb"))?;
    let suzi = envis::scene::load_glb(&models.join("suzi_plain.glb"))?;
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

/// A scene file of 100 bunnies (one glTF file, so one mesh placed 100 times) in a 10 x 10 grid,
/// each turned differently, on a plane, written to `dir`.
pub(super) fn bunny_grid_scene(dir: &Path) -> Result<PathBuf> {
    let models = crate::repo_path("assets/models/bunny_plain.glb");
    let mut text = String::from(
        "[environment]\nsource = \"builtin:sky:15\"\nface_size = 32\n\n[camera]\nposition = [0.0, 6.0, 9.0]\ntarget = [0.0, 0.0, 0.0]\nfov = 45.0\n\n[[object]]\nshape = \"plane\"\nsize = 12.0\nmaterial = { type = \"diffuse\", albedo = 0.6 }\n",
    );
    for i in 0..100 {
        let (x, z) = ((i % 10) as f32 - 4.5, (i / 10) as f32 - 4.5);
        text += &format!(
            "\n[[object]]\nshape = \"gltf\"\npath = {:?}\nposition = [{x}, 0.0, {z}]\nrotation = [0.0, {}, 0.0]\nscale = 0.9\nmaterial = {{ type = \"diffuse\", albedo = 0.8 }}\n",
            models.display().to_string(),
            (i * 37 % 360) as f32
        );
    }
    let path = dir.join("bunny-grid.toml");
    std::fs::create_dir_all(dir)
        .and_then(|_| std::fs::write(&path, text))
        .map_err(|e| envis::error::Error::file(&path, format!("cannot write: {e}")))?;
    Ok(path)
}

/// Time each level of the bunny grid's shadow geometry (`repeat` times, medians).
fn instanced_row(sc: &Scene, repeat: usize) -> Result<InstancedRow> {
    use envis::visibility::Tlas;
    let bunnies = mesh_instances(sc);
    let mesh = &bunnies[0].mesh;
    let mesh_bvh_ms = median_ms(repeat, &mut || {
        let _ = MeshBvh::build(&mesh.positions, &mesh.indices);
    });
    let blas = mesh
        .bvh()
        .flat_blas(&mesh.positions, &mesh.indices)
        .map_err(envis::error::Error::invalid)?;
    let local = blas.bounds.unwrap_or_default();
    // The placements, and the same placements each moved a little (what a frame's refit sees).
    let (placed, bounds) = placements(&bunnies, local, 0.0);
    let (moved, moved_bounds) = placements(&bunnies, local, 0.05);
    let tlas_build_ms = median_ms(repeat, &mut || {
        let _ = Tlas::build(&bounds);
    });
    let mut tlas = Tlas::build(&bounds);
    let tlas_refit_ms = median_ms(repeat, &mut || {
        tlas.refit(&moved_bounds);
    });
    let (flat_build_ms, flat_place_ms) = flat_layout_ms(blas, &placed, &moved, &tlas, repeat)?;
    let row = InstancedRow {
        instances: bunnies.len(),
        triangles_placed: bunnies.len() * mesh.indices.len(),
        mesh_bvh_ms,
        tlas_build_ms,
        tlas_refit_ms,
        flat_build_ms,
        flat_place_ms,
    };
    eprintln!(
        "  bunny x{} (instanced): mesh BVH {:.2} ms once; top level build {:.3} ms, refit {:.3} ms; GPU layout {:.2} ms, rewrite {:.3} ms",
        row.instances, mesh_bvh_ms, tlas_build_ms, tlas_refit_ms, flat_build_ms, flat_place_ms
    );
    Ok(row)
}

/// Median wall time of `repeat` calls of `f`, ms.
fn median_ms(repeat: usize, f: &mut dyn FnMut()) -> f64 {
    median(
        (0..repeat)
            .map(|_| {
                let t0 = Instant::now();
                f();
                t0.elapsed().as_secs_f64() * 1e3
            })
            .collect(),
    )
}

/// The scene's mesh objects, in scene order.
fn mesh_instances(sc: &Scene) -> Vec<&envis::scene::MeshInstance> {
    sc.objects
        .iter()
        .filter_map(|o| match &o.shape {
            Shape::Mesh(m) => Some(m),
            _ => None,
        })
        .collect()
}

/// Each mesh placed (as instance 0 of one BLAS with object bounds `local`), shifted `shift`
/// along x, with its world bounds.
fn placements(
    bunnies: &[&envis::scene::MeshInstance],
    local: envis::visibility::Bounds,
    shift: f32,
) -> (
    Vec<envis::visibility::FlatInstance>,
    Vec<envis::visibility::Bounds>,
) {
    use envis::visibility::{FlatInstance, Layers, ObjectFromWorld, world_bounds};
    bunnies
        .iter()
        .map(|b| {
            let world =
                glam::Affine3A::from_translation(glam::Vec3::X * shift) * b.world_from_object;
            let to_object = ObjectFromWorld::new(world).unwrap_or(b.to_object);
            (
                FlatInstance {
                    blas: 0,
                    to_object,
                    layers: Layers::ALL,
                },
                world_bounds(local, &world),
            )
        })
        .unzip()
}

/// The GPU layout over `placed`: median ms to build both levels, then to rewrite only the top
/// part for `moved`. An error from either is reported after both are timed.
fn flat_layout_ms(
    blas: envis::visibility::FlatBlas,
    placed: &[envis::visibility::FlatInstance],
    moved: &[envis::visibility::FlatInstance],
    tlas: &envis::visibility::Tlas,
    repeat: usize,
) -> Result<(f64, f64)> {
    use envis::visibility::FlatBvh;
    let blases = [blas];
    let mut flat = FlatBvh::default();
    let mut err = None;
    let flat_build_ms = median_ms(
        repeat,
        &mut || match FlatBvh::build(&blases, placed, tlas) {
            Ok(f) => flat = f,
            Err(e) => err = Some(e),
        },
    );
    let flat_place_ms = median_ms(repeat, &mut || {
        if let Err(e) = flat.place(moved, tlas) {
            err = Some(e);
        }
    });
    if let Some(e) = err {
        return Err(envis::error::Error::invalid(e));
    }
    Ok((flat_build_ms, flat_place_ms))
}

/// A sphere of `2 nu nv` triangles skinned to two joints (weights by height, the upper joint
/// bent), posed anew `repeat` times: medians of each step.
fn skinned_row(nu: u32, nv: u32, repeat: usize) -> Result<SkinnedRow> {
    use envis::visibility::skin::skin_points;
    use envis::visibility::{FlatBvh, FlatInstance, Layers, ObjectFromWorld, Tlas};
    use glam::Mat4;
    let mesh = envis::scene::sphere_mesh(nu, nv);
    let (p, tris) = (&mesh.positions, &mesh.indices);
    let index = vec![[0u16, 1, 0, 0]; p.len()];
    let weight: Vec<[f32; 4]> = p
        .iter()
        .map(|v| {
            let w = (0.5 + 0.5 * v.y).clamp(0.0, 1.0);
            [1.0 - w, w, 0.0, 0.0]
        })
        .collect();
    let pose = |k: usize| [Mat4::IDENTITY, Mat4::from_rotation_z(0.02 * k as f32)];
    let bvh = MeshBvh::build(p, tris);
    let mut blas = bvh
        .flat_blas(p, tris)
        .map_err(envis::error::Error::invalid)?;
    let (mut skin, mut refit, mut layout, mut rebuild) = (vec![], vec![], vec![], vec![]);
    let ms = |t0: Instant| t0.elapsed().as_secs_f64() * 1e3;
    for k in 1..=repeat {
        let t0 = Instant::now();
        let posed = skin_points(p, &index, &weight, &pose(k))
            .ok_or_else(|| envis::error::Error::invalid("skinning: bad joints"))?;
        skin.push(ms(t0));
        let t0 = Instant::now();
        blas.refit(&posed, tris, bvh.leaf_order());
        refit.push(ms(t0));
        let t0 = Instant::now();
        let bounds = [blas.bounds.unwrap_or_default()];
        let placed = [FlatInstance {
            blas: 0,
            to_object: ObjectFromWorld::IDENTITY,
            layers: Layers::ALL,
        }];
        let _ = FlatBvh::build(std::slice::from_ref(&blas), &placed, &Tlas::build(&bounds));
        layout.push(ms(t0));
        let t0 = Instant::now();
        let _ = MeshBvh::build(&posed, tris).flat_blas(&posed, tris);
        rebuild.push(ms(t0));
    }
    let (skin_ms, refit_ms, layout_ms) = (median(skin), median(refit), median(layout));
    let frame_ms = skin_ms + refit_ms + layout_ms;
    let rebuild_ms = median(rebuild);
    eprintln!(
        "  skinned {} triangles: skin {skin_ms:.2} + refit {refit_ms:.2} + layout {layout_ms:.2} ms per pose; BVH anew {rebuild_ms:.2} ms",
        tris.len()
    );
    Ok(SkinnedRow {
        triangles: tris.len(),
        skin_ms,
        refit_ms,
        layout_ms,
        frame_ms,
        rebuild_ms,
        rebuild_over_frame: rebuild_ms / frame_ms.max(1e-9),
    })
}
