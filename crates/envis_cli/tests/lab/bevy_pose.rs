//! Deformed meshes in envis's shadows: skinned (`SkinnedMesh`) and morphed (`MeshMorphWeights`)
//! casters cast the pose Bevy draws, refitted, not rebuilt, when it changes.

use super::bevy_plugin::white_furnace_material;
use super::bevy_shadows::top_down_camera;
use super::gpu;
use bevy::asset::RenderAssetUsages;
use bevy::mesh::morph::{MeshMorphWeights, MorphAttributes, MorphWeights};
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;
use bevy_envis::sampling::SceneRevision;
use envis::envmap::luminance;
use envis::visibility::ShadowRays;
use envis_cli::headless::HeadlessApp;

/// The top-down views' size in pixels (a 6 x 6 square of ground).
const SIZE: u32 = 48;

/// Mean luminance of the ground ring [r0, r1) around (x0, 0) in a [`top_down_camera`] image (its
/// x runs along -X).
fn disc(img: &[Vec3], x0: f32, (r0, r1): (f32, f32)) -> f32 {
    let px: Vec<f32> = (0..img.len())
        .filter(|&i| {
            let c = |v: u32| -3.0 + 6.0 * (v as f32 + 0.5) / SIZE as f32;
            let (x, z) = (-c(i as u32 % SIZE), c(i as u32 / SIZE));
            (r0..r1).contains(&(x - x0).hypot(z))
        })
        .map(|i| luminance(img[i]))
        .collect();
    px.iter().sum::<f32>() / px.len() as f32
}

/// The ground just outside the edge of a 1 x 1 plate centred over (x0, 0).
fn ring(img: &[Vec3], x0: f32) -> f32 {
    disc(img, x0, (0.72, 0.85))
}

/// A 1 x 1 plate at height 0.15, facing up, centred over (x0, 0): positions, normals, UVs and
/// indices (both triangles face +Y).
fn plate(x0: f32) -> Mesh {
    let corners = [[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]];
    let corners: Vec<[f32; 3]> = corners.iter().map(|[x, z]| [x0 + x, 0.15, *z]).collect();
    Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::all())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, corners)
        .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, vec![[0.0, 1.0, 0.0]; 4])
        .with_inserted_attribute(Mesh::ATTRIBUTE_UV_0, vec![[0.0, 0.0]; 4])
        .with_inserted_indices(Indices::U16(vec![0, 2, 1, 0, 3, 2]))
}

/// The plate over the origin, every vertex weighted wholly to one joint, built in code: it is
/// drawn (and must cast its shadow) where that joint puts it, whatever the mesh entity's own
/// transform.
fn skinned_plate(h: &mut HeadlessApp) -> (Mesh3d, SkinnedMesh, Entity) {
    let mesh = plate(0.0)
        .with_inserted_attribute(
            Mesh::ATTRIBUTE_JOINT_INDEX,
            VertexAttributeValues::Uint16x4(vec![[0, 0, 0, 0]; 4]),
        )
        .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, vec![[1.0, 0.0, 0.0, 0.0]; 4]);
    let bindposes = h.add::<SkinnedMeshInverseBindposes>(vec![Mat4::IDENTITY]);
    let joint = h.app.world_mut().spawn(Transform::default()).id();
    let skin = SkinnedMesh {
        inverse_bindposes: bindposes,
        joints: vec![joint],
    };
    (Mesh3d(h.add::<Mesh>(mesh)), skin, joint)
}

/// A plane of the given material under a [`top_down_camera`] with shadow rays; the target.
fn ground(h: &mut HeadlessApp, mat: &Handle<StandardMaterial>) -> (Handle<Mesh>, Handle<Image>) {
    let plane = h.add::<Mesh>(Plane3d::default().mesh().size(6.0, 6.0));
    let world = h.app.world_mut();
    world.spawn((Mesh3d(plane.clone()), MeshMaterial3d(mat.clone())));
    (plane, top_down_camera(h, ShadowRays::On, SIZE, 3.0))
}

fn revision(h: &HeadlessApp) -> u64 {
    h.app.world().resource::<SceneRevision>().0
}

fn builds(h: &HeadlessApp) -> u64 {
    h.counters().get(|c| &c.shadow_bvh_builds)
}

/// A skinned mesh casts the pose Bevy draws: a plate skinned to one joint, on a plane, seen from
/// above. Its shadow is where the joint puts it (not where the bind pose and the entity's own
/// transform would: at the origin), and follows the joint when it moves; the plate's BVH is
/// built once and then refitted, not rebuilt; the new pose restarts accumulation. The joint
/// moves in the frame another caster is spawned (a structure change), which must not hide the
/// new pose.
#[test]
fn bevy_skinned_mesh_casts_its_pose() {
    let Some(_) = gpu() else { return };
    let mut h = HeadlessApp::new();
    let mat = h.add::<StandardMaterial>(white_furnace_material());
    let (mesh, skin, joint) = skinned_plate(&mut h);
    let world = h.app.world_mut();
    world
        .entity_mut(joint)
        .insert(Transform::from_xyz(-1.8, 0.0, 0.0));
    world.spawn((mesh, skin, MeshMaterial3d(mat.clone()), Transform::IDENTITY));
    let (plane, target) = ground(&mut h, &mat);
    let before = h.capture(&target).unwrap();
    assert_eq!(builds(&h), 2, "the plate's and the plane's BVHs");
    let still = revision(&h);
    h.update();
    assert_eq!(revision(&h), still, "a still pose restarts accumulation");
    let world = h.app.world_mut();
    world
        .entity_mut(joint)
        .insert(Transform::from_xyz(1.8, 0.0, 0.0));
    // A small placement of the plane's mesh in a far corner (no new mesh BVH).
    world.spawn((
        Mesh3d(plane),
        MeshMaterial3d(mat),
        Transform::from_xyz(2.8, 0.01, -2.8).with_scale(Vec3::splat(0.02)),
    ));
    h.update();
    assert!(
        revision(&h) > still,
        "a new pose does not restart accumulation"
    );
    let after = h.capture(&target).unwrap();
    let (left, right) = (
        (ring(&before, -1.8), ring(&before, 1.8)),
        (ring(&after, -1.8), ring(&after, 1.8)),
    );
    // The ground under the bind pose (the plate is not drawn there: it is visible).
    let origin = disc(&before, 0.0, (0.0, 0.5));
    eprintln!("skinned plate rings (left, right): {left:?} then {right:?}; origin {origin}");
    // The low plate darkens the ring just outside it by 5.6% (lavapipe); the two open rings
    // differ by 0.35% (noise).
    assert!(
        left.0 < 0.97 * left.1,
        "no shadow under the posed plate: {left:?}"
    );
    assert!(
        (origin - left.1).abs() < 0.01 * left.1,
        "a shadow at the bind pose: {origin} vs open ground {}",
        left.1
    );
    assert!(
        right.1 < 0.97 * right.0,
        "the shadow did not follow the joint: {right:?}"
    );
    assert_eq!(builds(&h), 2, "a new pose rebuilt a BVH");
    assert!(h.counters().get(|c| &c.shadow_deformed_refits) >= 1);
}

/// A mesh with morph targets casts the pose Bevy draws: a plate over x = -1.8 whose one target
/// moves it by +3.6 along X. With weight 0 its shadow is at -1.8; given weights (by value) of
/// 1 it moves to +1.8; referring then to another entity's `MorphWeights` (as glTF animation
/// does) and setting those to 0.5 puts it over the origin. Each change restarts accumulation
/// and refits the plate's BVH; none rebuilds it.
#[test]
fn bevy_morphed_mesh_casts_its_pose() {
    let Some(_) = gpu() else { return };
    let mut h = HeadlessApp::new();
    let mat = h.add::<StandardMaterial>(white_furnace_material());
    let mut mesh = plate(-1.8);
    let shift = MorphAttributes::new(Vec3::new(3.6, 0.0, 0.0), Vec3::ZERO, Vec3::ZERO);
    mesh.set_morph_targets(vec![shift; 4]);
    let mesh = h.add::<Mesh>(mesh);
    let weights = MeshMorphWeights::Value { weights: vec![0.0] };
    let world = h.app.world_mut();
    let plate = (world.spawn((Mesh3d(mesh), weights, MeshMaterial3d(mat.clone())))).id();
    let target = ground(&mut h, &mat).1;
    let images = [h.capture(&target).unwrap()];
    assert_eq!(builds(&h), 2, "the plate's and the plane's BVHs");
    let mut revision_before = revision(&h);
    let mut pose = |h: &mut HeadlessApp, change: &dyn Fn(&mut World)| {
        change(h.app.world_mut());
        h.update();
        let r = revision(h);
        assert!(
            r > revision_before,
            "a new pose does not restart accumulation"
        );
        revision_before = r;
        h.capture(&target).unwrap()
    };
    let by_value = |w: &mut World| {
        let weights = MeshMorphWeights::Value { weights: vec![1.0] };
        w.entity_mut(plate).insert(weights);
    };
    let shared = |w: &mut World| {
        let source = w.spawn(MorphWeights::new(vec![1.0], None).unwrap()).id();
        w.entity_mut(plate)
            .insert(MeshMorphWeights::Reference(source));
    };
    let images = [&images[0], &pose(&mut h, &by_value), &pose(&mut h, &shared)];
    let half = |w: &mut World| {
        let mut q = w.query::<&mut MorphWeights>();
        q.single_mut(w).unwrap().weights_mut()[0] = 0.5;
    };
    let middle = pose(&mut h, &half);
    let rings = |img: &[Vec3]| [ring(img, -1.8), ring(img, 0.0), ring(img, 1.8)];
    let [rest, one, shared_one] = images.map(|i| rings(i));
    let middle = rings(&middle);
    eprintln!("morphed plate rings (-1.8, 0, 1.8): {rest:?} {one:?} {shared_one:?} {middle:?}");
    assert!(
        shadowed_at(rest, 0),
        "weight 0: no shadow at -1.8: {rest:?}"
    );
    assert!(shadowed_at(one, 2), "weight 1: no shadow at +1.8: {one:?}");
    assert!(
        shadowed_at(shared_one, 2),
        "shared weight 1: no shadow at +1.8: {shared_one:?}"
    );
    assert!(
        shadowed_at(middle, 1),
        "weight 0.5: no shadow at 0: {middle:?}"
    );
    assert_eq!(builds(&h), 2, "a new pose rebuilt a BVH");
    assert!(h.counters().get(|c| &c.shadow_deformed_refits) >= 2);
}

/// A glTF with a skin and a morph target, through Bevy's own glTF loader and scene spawning
/// (`assets/models/skinned_plate.glb`, from `tests/corpus/make_glb.py`): a plate skinned to a
/// joint node at x = -1.8, whose one target moves it by +3.6 along X (weight 0). Its shadow is
/// at -1.8; with the mesh node's `MorphWeights` set to 1 (what an animation would write) it is
/// at +1.8 (morphed, then skinned); with the joint then moved to -3.6, over the origin.
#[test]
fn bevy_gltf_skin_and_morph_target_cast_their_pose() {
    use bevy::world_serialization::WorldAssetRoot;
    let Some(_) = gpu() else { return };
    let mut h = HeadlessApp::new();
    let mat = h.add::<StandardMaterial>(white_furnace_material());
    let target = ground(&mut h, &mat).1;
    let assets = h.app.world().resource::<AssetServer>().clone();
    let scene = assets.load(GltfAssetLabel::Scene(0).from_asset("models/skinned_plate.glb"));
    h.app.world_mut().spawn(WorldAssetRoot(scene));
    // The file loads on Bevy's IO threads; the scene is spawned the frame after.
    let mut skinned = h.app.world_mut().query::<&SkinnedMesh>();
    for _ in 0..400 {
        if skinned.iter(h.app.world()).next().is_some() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
        h.update();
    }
    let world = h.app.world_mut();
    let joint = world
        .query::<(Entity, &Name)>()
        .iter(world)
        .find(|(_, n)| n.as_str() == "joint");
    let joint = joint.expect("the glTF scene was not spawned in 4 s").0;
    let rest = h.capture(&target).unwrap();
    let weights = |w: &mut World| {
        let mut q = w.query::<&mut MorphWeights>();
        q.single_mut(w)
            .expect("no MorphWeights on the glTF's mesh node")
            .weights_mut()[0] = 1.0;
    };
    weights(h.app.world_mut());
    h.update();
    let morphed = h.capture(&target).unwrap();
    let world = h.app.world_mut();
    world
        .entity_mut(joint)
        .insert(Transform::from_xyz(-3.6, 0.0, 0.0));
    h.update();
    let moved = h.capture(&target).unwrap();
    let rings = |img: &[Vec3]| [ring(img, -1.8), ring(img, 0.0), ring(img, 1.8)];
    let [rest, morphed, moved] = [&rest, &morphed, &moved].map(|i| rings(i));
    eprintln!("glTF plate rings (-1.8, 0, 1.8): {rest:?} {morphed:?} {moved:?}");
    assert!(
        shadowed_at(rest, 0),
        "rest pose: no shadow at -1.8: {rest:?}"
    );
    assert!(
        shadowed_at(morphed, 2),
        "weight 1: no shadow at +1.8: {morphed:?}"
    );
    assert!(
        shadowed_at(moved, 1),
        "joint at -3.6: no shadow at 0: {moved:?}"
    );
    assert_eq!(builds(&h), 2, "a new pose rebuilt a BVH");
}

/// Whether ring `k` of three is darker than both others by 2% (the plate's shadow is there).
/// On lavapipe the plate darkens its ring by 3.3% (over the origin) to 5.6% (at x = 1.8); open
/// rings differ by 0.35%.
fn shadowed_at(r: [f32; 3], k: usize) -> bool {
    let open = (0..3)
        .filter(|&j| j != k)
        .map(|j| r[j])
        .fold(f32::MAX, f32::min);
    r[k] < 0.98 * open
}
