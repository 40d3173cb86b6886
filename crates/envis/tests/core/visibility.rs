//! Shadow rays on the CPU (the oracle): unbiased against a reference that integrates with
//! visibility, no self-shadowing (acne) and no light leaking at contact, the `auto` rule, and
//! `--stats`.

use super::*;
use envis::render::Extras;
use envis::render::reference::reference_image_with;
use envis::scene::Scene;
use envis::scene::shadows::Occluders;
use envis::visibility::{Occluder, ShadowRays};

use super::support::{CAMERA, PLANE, SPHERE, TORUS, scene_in};

/// A scene file written to a temporary directory and loaded (the file is gone afterwards: the
/// scene is in memory).
fn scene(name: &str, camera: &str, objects: &str) -> Scene {
    scene_in(
        &support::TempDir::new(&format!("vis-{name}")),
        camera,
        objects,
    )
}

/// With occluders (a sphere, the torus, the bunny, each on a plane) the estimators stay unbiased
/// for the integrand with visibility: the mean over seeds matches a reference that casts a
/// shadow ray per quadrature node. The reference resolves
/// visibility only to its sub-texel grid, so its error is bounded by comparing two grids and
/// added to each check's standard error. Checked against a mutation: BRDF samples that ignore
/// visibility fail it (z about 7 in the shadowed quadrant).
#[test]
fn shadows_are_unbiased() {
    let (size, k) = (12usize, 160u32);
    let map = load_env(&EnvSource::Sky { hours: 15.0 }, 8).unwrap().cube;
    let (_, configs) = few_sample_configs();
    let mut test = UnbiasedTest::new("shadows_are_unbiased");
    let bunny = format!(
        "[[object]]\nshape = \"gltf\"\npath = \"{}/assets/models/bunny_plain.glb\"\nposition = [0.0, 0.72, 0.0]\nscale = 0.8\nmaterial = {{ type = \"diffuse\", albedo = 0.8 }}\n",
        support::repo().display()
    );
    for (sname, objects) in [
        ("sphere on a plane", format!("{SPHERE}\n{PLANE}")),
        ("torus on a plane", format!("{TORUS}\n{PLANE}")),
        ("bunny on a plane", format!("{bunny}\n{PLANE}")),
    ] {
        let sc = scene(&sname.replace(' ', "-"), CAMERA, &objects);
        let (gbuf, points) = sc.gbuffer_points(size, size);
        let occ = sc.occluders();
        let shadows = Some((&occ as &dyn Occluder, points.as_slice()));
        let (_, coarse) = reference_image_with(&map, &gbuf, shadows, size, size, 4.0);
        let (_, reference) = reference_image_with(&map, &gbuf, shadows, size, size, 8.0);
        let extras = Extras {
            shadows,
            ..Default::default()
        };
        for (cname, s) in configs {
            let checks = unbiased_checks_with(&map, extras, &gbuf, s, k, size, &reference);
            let coarse_checks = unbiased_checks_with(&map, extras, &gbuf, s, 2, size, &coarse);
            for (c, cc) in checks.into_iter().zip(coarse_checks) {
                // The reference's own error: the change from the coarser grid.
                let quad = (c.reference - cc.reference).abs();
                test.push(MeanCheck {
                    label: format!("{sname} / {cname} / {}", c.label),
                    se: c.se.hypot(quad),
                    ..c
                });
            }
        }
    }
    test.assert();
}

/// Robust ray offsets: a plane and a sphere alone never shadow themselves (no acne: not one
/// blocked sample, the same image as without shadow rays), and at a sphere resting on a plane
/// no light leaks through the contact.
#[test]
fn shadow_rays_have_no_acne_and_no_leaks() {
    let map = load_env(&EnvSource::Sky { hours: 15.0 }, 8).unwrap().cube;
    let s = Settings {
        light_samples: 16,
        brdf_samples: 16,
        ..Default::default()
    };
    for (name, objects) in [("plane", PLANE), ("sphere", SPHERE)] {
        let sc = scene(name, CAMERA, objects);
        let (gbuf, points) = sc.gbuffer_points(24, 24);
        let occ = sc.occluders();
        let extras = Extras {
            shadows: Some((&occ, points.as_slice())),
            ..Default::default()
        };
        let with = envis::render::render_with(&map, extras, &gbuf, 24, 24, &s).unwrap();
        let without = render(&map, &gbuf, 24, 24, &s).unwrap();
        assert!(with.stats.shadow_rays > 0, "{name}: no shadow rays cast");
        assert_eq!(
            with.stats.blocked, 0.0,
            "{name}: the surface shadows itself"
        );
        assert!(
            with.image.data == without.image.data,
            "{name}: shadow rays changed the image"
        );
    }
    let sc = scene("contact", CAMERA, &format!("{SPHERE}\n{PLANE}"));
    let occ: Occluders = sc.occluders();
    // On the plane, a hair from the contact point, straight up: into the sphere.
    for dx in [1e-3f32, 1e-2, 0.1] {
        let p = Vec3::new(dx, 0.0, 0.0);
        assert!(
            occ.occluded(p, Vec3::Y, Vec3::Y),
            "light leaks up at {dx} from the contact"
        );
    }
    // On the sphere just above the contact, pointing down and out: into the plane.
    let n = Vec3::new(0.05, -1.0, 0.0).normalize();
    let p = Vec3::new(0.0, 1.0, 0.0) + n;
    assert!(occ.occluded(p, n, n), "light leaks in under the sphere");
    // In the open, nothing.
    assert!(!occ.occluded(Vec3::new(3.0, 0.0, 0.0), Vec3::Y, Vec3::Y));
}

/// `auto` casts shadow rays only where something can shadow a visible point; a lone convex
/// object renders bit-identically with visibility off; `cast_shadows = false` takes an object out.
#[test]
fn visibility_auto_rule() {
    let cases = [
        ("lone sphere", SPHERE.to_string(), false),
        ("lone plane", PLANE.to_string(), false),
        ("lone torus", TORUS.to_string(), true),
        ("sphere on plane", format!("{SPHERE}\n{PLANE}"), true),
        (
            "sphere casting nothing",
            format!("{}cast_shadows = false\n\n{PLANE}", SPHERE),
            false,
        ),
    ];
    for (name, objects, want) in cases {
        let sc = scene(&name.replace(' ', "-"), CAMERA, &objects);
        let (on, why) = sc.shadows(None);
        assert_eq!(on, want, "{name}: {why}");
        assert!(
            why.starts_with(if want { "on" } else { "off" }),
            "{name}: {why}"
        );
        assert!(!sc.shadows(Some(ShadowRays::Off)).0);
        assert!(sc.shadows(Some(ShadowRays::On)).0);
    }
}

/// The flattened BVH's traversal (the WGSL's CPU twin) answers exactly as obvhs's own.
#[test]
fn flat_bvh_matches_obvhs_traversal() {
    let (mesh, rays) = support::bunny_on_plane_rays();
    let bvh = envis::visibility::MeshBvh::build(&mesh.positions, &mesh.indices);
    let flat = bvh.flatten(&mesh.positions, &mesh.indices).unwrap();
    let mut blocked = 0;
    for (o, d) in rays {
        let want = bvh.occluded(o, d, 1e-4, f32::MAX);
        assert_eq!(flat.occluded(o, d, 1e-4, f32::MAX), want, "ray {o} {d}");
        blocked += want as usize;
    }
    assert!(
        blocked > 2_000 && blocked < 18_000,
        "{blocked} of 20000 rays blocked"
    );
    // A scene with nothing to trace flattens to an empty BVH that blocks nothing (no panic).
    let empty = envis::visibility::MeshBvh::build(&[], &[]);
    let flat = empty.flatten(&[], &[]).unwrap();
    assert!(flat.tlas_nodes() == 0 && !flat.occluded(Vec3::ZERO, Vec3::Y, 0.0, f32::MAX));
}

/// Two levels answer as one: four placements of the bunny (one scaled non-uniformly) and a
/// plane, under a top-level BVH, against the same triangles merged in world space under one
/// BVH. The two two-level traversals (obvhs's per instance, and the flat one the WGSL twins)
/// agree exactly; against the merged triangles, a ray may differ only where it grazes an edge
/// (the transform into object space rounds): at most 0.1%. Then every instance moves and
/// turns, the top level is refitted (not rebuilt) and the records rewritten, and they agree
/// again with the moved triangles merged anew.
#[test]
fn instances_match_world_space_triangles() {
    let (_, rays) = support::bunny_on_plane_rays();
    let check = |flat: &envis::visibility::FlatBvh, at: &support::Instanced, what: &str| {
        let world = &at.world;
        let merged = envis::visibility::MeshBvh::build(&world.positions, &world.indices);
        let (mut differ, mut blocked) = (0, 0);
        for &(o, d) in &rays {
            let got = flat.occluded(o, d, 1e-4, f32::MAX);
            let cpu = at
                .tlas
                .any(o, d, f32::MAX, |i| at.instances[i].occluded(o, d, f32::MAX));
            assert_eq!(got, cpu, "{what}: the two traversals differ on ray {o} {d}");
            let want = merged.occluded(o, d, 1e-4, f32::MAX);
            differ += (got != want) as usize;
            blocked += want as usize;
        }
        eprintln!(
            "{what}: {blocked} of {} rays blocked, {differ} differ",
            rays.len()
        );
        assert!(
            blocked > 4_000 && blocked < 19_000,
            "{what}: {blocked} blocked"
        );
        assert!(differ * 1000 <= rays.len(), "{what}: {differ} rays differ");
    };
    let still = support::instanced_bunnies(0.0);
    assert_eq!((still.flat.instances(), still.flat.tlas_nodes()), (5, 9));
    check(&still.flat, &still, "placed");
    let moved = support::instanced_bunnies(0.35);
    let mut tlas = still.tlas.clone();
    assert!(tlas.refit(&moved.bounds));
    assert!(
        !tlas.clone().refit(&moved.bounds[..4]),
        "a refit needs every instance"
    );
    let mut flat = still.flat.clone();
    flat.place(&moved.placed, &tlas).unwrap();
    let refitted = support::Instanced { tlas, ..moved };
    check(&flat, &refitted, "moved and refitted");
}

/// A refitted BVH (a skinned mesh's new pose) answers as a BVH built anew over the moved
/// vertices, ray by ray: the bunny on its plane, the bunny's vertices bent (each shifted
/// sideways by an amount growing with its height) with the tree of the rest pose kept. Refitted
/// to the rest pose it is the BVH it was, box for box.
#[test]
fn refitted_blas_answers_as_a_new_build() {
    use envis::visibility::{FlatBvh, FlatInstance, Layers, MeshBvh, ObjectFromWorld, Tlas};
    let (mesh, rays) = support::bunny_on_plane_rays();
    let (p, tris) = (&mesh.positions, &mesh.indices);
    let bvh = MeshBvh::build(p, tris);
    let rest = bvh.flat_blas(p, tris).unwrap();
    let mut same = rest.clone();
    assert!(same.refit(p, tris, bvh.leaf_order()));
    assert_eq!((same.nodes, same.bounds), (rest.nodes.clone(), rest.bounds));
    let top = p.iter().map(|v| v.y).fold(f32::MIN, f32::max);
    let bent: Vec<Vec3> = p
        .iter()
        .map(|v| *v + Vec3::new(0.3 * (v.y / top).max(0.0).powi(2), 0.0, 0.0))
        .collect();
    let mut refitted = rest.clone();
    assert!(refitted.refit(&bent, tris, bvh.leaf_order()));
    assert!(!refitted.clone().refit(&bent, tris, &bvh.leaf_order()[1..]));
    let scene = |blas: envis::visibility::FlatBlas| {
        let placed = [FlatInstance {
            blas: 0,
            to_object: ObjectFromWorld::IDENTITY,
            layers: Layers::ALL,
        }];
        let tlas = Tlas::build(&[blas.bounds.unwrap()]);
        FlatBvh::build(&[blas], &placed, &tlas).unwrap()
    };
    let fresh = MeshBvh::build(&bent, tris).flatten(&bent, tris).unwrap();
    let (refitted, old) = (scene(refitted), scene(rest));
    let (mut moved, mut blocked) = (0, 0);
    for &(o, d) in &rays {
        let got = refitted.occluded(o, d, 1e-4, f32::MAX);
        assert_eq!(got, fresh.occluded(o, d, 1e-4, f32::MAX), "ray {o} {d}");
        moved += (got != old.occluded(o, d, 1e-4, f32::MAX)) as usize;
        blocked += got as usize;
    }
    eprintln!("refit: {blocked} rays blocked, {moved} changed by the new pose");
    assert!(moved > 100, "the bend changed only {moved} rays");
}

/// Layers (Bevy's `RenderLayers` as the Bevy pass maps them): a ray cast for a set of layers
/// answers exactly as the scene built of only the instances on those layers, ray by ray. Each
/// instance is on its own layer, the plane on layer 20 (the record's upper half), and the view
/// sees the first bunny and the plane; a view on no layer of theirs sees nothing, and one on
/// every layer answers as the scene without layers.
#[test]
fn layers_keep_only_the_instances_a_view_sees() {
    use envis::visibility::{FlatBvh, FlatInstance, Layers, Tlas};
    let (_, rays) = support::bunny_on_plane_rays();
    let at = support::instanced_bunnies(0.35);
    let layer = |i: usize| Layers(if i == 4 { 1 << 20 } else { 1 << i });
    let placed: Vec<FlatInstance> = (at.placed.iter().enumerate())
        .map(|(i, p)| FlatInstance {
            layers: layer(i),
            ..*p
        })
        .collect();
    let layered = FlatBvh::build(&at.blases, &placed, &at.tlas).unwrap();
    let view = Layers(1 | 1 << 20);
    let seen: Vec<usize> = (0..placed.len()).filter(|&i| layer(i).meet(view)).collect();
    assert_eq!(seen, [0, 4]);
    let only: Vec<FlatInstance> = seen.iter().map(|&i| at.placed[i]).collect();
    let bounds: Vec<_> = seen.iter().map(|&i| at.bounds[i]).collect();
    let subset = FlatBvh::build(&at.blases, &only, &Tlas::build(&bounds)).unwrap();
    let (mut blocked, mut all) = (0, 0);
    for &(o, d) in &rays {
        let got = layered.occluded_on(o, d, 1e-4, f32::MAX, view);
        assert_eq!(got, subset.occluded(o, d, 1e-4, f32::MAX), "ray {o} {d}");
        let every = layered.occluded_on(o, d, 1e-4, f32::MAX, Layers::ALL);
        assert_eq!(every, at.flat.occluded(o, d, 1e-4, f32::MAX), "ray {o} {d}");
        assert!(!layered.occluded_on(o, d, 1e-4, f32::MAX, Layers(1 << 9)));
        (blocked, all) = (blocked + got as usize, all + every as usize);
    }
    eprintln!("layers: {blocked} rays blocked on the view's layers, {all} on all");
    assert!(
        blocked > 1_000 && blocked + 1_000 < all,
        "{blocked} of {all}"
    );
}

/// A pixel's shadow rays set up once ([`Occluder::at_point`]: the shapes its hemisphere can
/// reach, as cones) get the same answer as the full query through the top level, ray by ray:
/// on the occluded scene (spheres, the bunny, a plane), on the showcase (the torus too), and on
/// 40 spheres over a plane (where too many are in reach and the top level answers). Directions
/// are uniform on the sphere, so some leave below the horizon (the full query's path).
/// Checked against a mutation: cones narrowed by 0.002 in cosine give 92 wrong answers here.
#[test]
fn point_culling_matches_full_query() {
    let dir = support::repo();
    let check = |what: &str, occ: &Occluders, at: &[(Vec3, Vec3)]| {
        let mut rng = envis::sampling::rng::Rng::new(7, 0);
        let (mut rays, mut blocked, mut differ, mut culled) = (0usize, 0usize, 0usize, 0usize);
        for &(p, n) in at {
            let point = occ.at_point(p, n);
            culled += point.reach.is_some() as usize;
            for _ in 0..64 {
                let z = 2.0 * rng.next_f32() - 1.0;
                let phi = std::f32::consts::TAU * rng.next_f32();
                let r = (1.0 - z * z).max(0.0).sqrt();
                let d = Vec3::new(r * phi.cos(), z, r * phi.sin());
                let want = occ.occluded(p, n, d);
                differ += (occ.occluded_from(&point, d) != want) as usize;
                blocked += want as usize;
                rays += 1;
            }
        }
        eprintln!(
            "{what}: {rays} rays, {blocked} blocked, {differ} differ; {culled} of {} points cull by cones",
            at.len()
        );
        assert_eq!(
            differ, 0,
            "{what}: culled rays must get the full query's answer"
        );
        assert!(
            blocked * 20 > rays && blocked * 2 < rays,
            "{what}: {blocked} of {rays} blocked"
        );
        culled
    };
    for file in ["assets/scenes/occluded.toml", "assets/scenes/showcase.toml"] {
        let sc = Scene::load(&dir.join(file)).unwrap();
        let (gbuf, points) = sc.gbuffer_points(40, 40);
        let at: Vec<(Vec3, Vec3)> = gbuf
            .iter()
            .zip(&points)
            .filter_map(|(px, &p)| px.as_ref().map(|px| (p, px.n.normalize())))
            .collect();
        let culled = check(file, &sc.occluders(), &at);
        assert!(
            culled * 2 > at.len(),
            "{file}: {culled} of {} points cull",
            at.len()
        );
    }
    // 40 unit spheres in a grid over a plane, seen from points on the plane between them.
    let mut shapes: Vec<envis::scene::Shape> = (0..40)
        .map(|i| envis::scene::Shape::Sphere {
            center: Vec3::new((i % 8) as f32 * 2.5 - 8.75, 1.0, (i / 8) as f32 * 2.5 - 5.0),
            radius: 1.0,
        })
        .collect();
    shapes.push(envis::scene::Shape::Plane {
        center: Vec3::ZERO,
        normal: Vec3::Y,
        u: Vec3::X,
        v: Vec3::Z,
        half: 20.0,
    });
    let occ = Occluders::new(shapes.iter().collect());
    let at: Vec<(Vec3, Vec3)> = (0..200)
        .map(|i| {
            (
                Vec3::new(
                    (i % 20) as f32 * 0.9 - 9.0,
                    0.0,
                    (i / 20) as f32 * 1.1 - 5.5,
                ),
                Vec3::Y,
            )
        })
        .collect();
    assert_eq!(
        check("40 spheres", &occ, &at),
        0,
        "40 spheres are too many to list"
    );
}
