//! Scene geometry: the mesh BVH against brute force, and scene files load, render and report
//! errors.

use super::*;

/// The mesh BVH (obvhs) finds what the brute-force loop over every triangle finds: for 20,000
/// random rays at the bunny and the torus, the same hit or miss and the same distance; the
/// normal too, except where a ray meets two triangles at the same distance (an edge), where
/// either triangle is right: those are counted and must be rare.
#[test]
fn mesh_bvh_matches_brute_force() {
    let root = support::repo();
    let bunny = envis::scene::load_glb(&root.join("assets/models/bunny_plain.glb")).unwrap();
    let torus = envis::scene::torus_mesh(1.0, 0.3, 48, 24);
    let mut r = Rng::new(13, 17);
    for (name, mesh) in [("bunny", &bunny), ("torus", &torus)] {
        let (lo, hi) = mesh.positions.iter().fold(
            (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        let (centre, radius) = (0.5 * (lo + hi), 0.5 * (hi - lo).length());
        let (mut hits, mut edge) = (0, 0);
        let n = 10_000;
        for _ in 0..n {
            // From a sphere around the mesh towards a point inside its box.
            let o = centre + random_dir(&mut r) * 2.0 * radius;
            let target = lo + (hi - lo) * Vec3::new(r.next_f32(), r.next_f32(), r.next_f32());
            let d = (target - o).normalize();
            let (a, b) = (
                mesh.intersect(o, d, f32::MAX),
                mesh.intersect_brute(o, d, f32::MAX),
            );
            match (a, b) {
                (None, None) => {}
                (Some((ta, na)), Some((tb, nb))) => {
                    hits += 1;
                    assert_eq!(ta, tb, "{name}: ray {o} {d}");
                    edge += (na != nb) as u32;
                }
                _ => panic!("{name}: BVH {a:?} vs brute force {b:?} for ray {o} {d}"),
            }
            // The shadow-ray query (any hit) agrees with the closest hit.
            assert_eq!(
                mesh.occluded(o, d, f32::MAX),
                b.is_some(),
                "{name}: any-hit"
            );
        }
        assert!(hits > n / 4, "{name}: only {hits} of {n} rays hit");
        assert!(
            edge * 1000 <= n,
            "{name}: {edge} of {n} rays differ in the normal"
        );
    }
}

/// A scene file's `[sampling]` keys are the settings type's field names (`heuristic`,
/// `pool_size`, `shadows`, as `EnvironmentSampling` names them); the names files used before
/// (`mis`, `pool`, `visibility`) still read the same.
#[test]
fn sampling_keys_are_the_settings_field_names() {
    let dir = tempdir();
    let scene = |name: &str, sampling: &str| {
        let p = dir.join(format!("{name}.toml"));
        let text = format!(
            "[environment]\nsource = \"builtin:sky\"\nface_size = 16\n[sampling]\n{sampling}\n\
             [[object]]\nshape = \"sphere\"\nmaterial = {{ type = \"diffuse\", albedo = 0.8 }}\n"
        );
        std::fs::write(&p, text).unwrap();
        envis::scene::Scene::load(&p).unwrap()
    };
    let new = scene(
        "new",
        "heuristic = \"power\"\npool_size = 7\nshadows = \"on\"",
    );
    let old = scene("old", "mis = \"power\"\npool = 7\nvisibility = \"on\"");
    assert_eq!(new.settings, old.settings);
    assert_eq!(new.settings.heuristic, Heuristic::Power);
    assert_eq!(new.settings.pool_size, 7);
    assert_eq!(new.settings.face_size, 16);
    assert_eq!(new.settings.shadows, envis::visibility::ShadowRays::On);
    assert!(new.shadows(None).0);
}
