//! Scene objects in the Bevy world: a [`envis::scene::Scene`] (a TOML scene file) spawned as
//! meshes with envis materials, shared by the demo and the headless app.

use super::{EnvisBrdf, EnvisMaterial};
use bevy::prelude::*;
use envis::scene::{Scene, Shape};

/// One object of the scene and its BRDF (the panel edits it; `handle` is its material asset).
#[derive(Component)]
pub struct SceneObject {
    pub name: String,
    pub material: EnvisBrdf,
    pub handle: Handle<EnvisMaterial>,
}

/// Which of the scene file's objects an entity is (its index in `Scene::objects`): what
/// `envis sequence --backend gpu` moves.
#[derive(Component, Clone, Copy, Debug)]
pub struct SceneIndex(pub usize);

/// The scene file's camera.
pub struct SceneCamera {
    pub eye: Vec3,
    pub target: Vec3,
    /// Vertical field of view, radians.
    pub fov: f32,
}

impl SceneCamera {
    pub fn transform(&self) -> Transform {
        Transform::from_translation(self.eye).looking_at(self.target, Vec3::Y)
    }
}

/// A Bevy mesh of world-space triangles.
pub fn bevy_mesh(m: &envis::scene::TriMesh) -> Mesh {
    use bevy::asset::RenderAssetUsages;
    use bevy::mesh::{Indices, PrimitiveTopology};
    Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    )
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_POSITION,
        m.positions.iter().map(|p| p.to_array()).collect::<Vec<_>>(),
    )
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_NORMAL,
        m.normals.iter().map(|p| p.to_array()).collect::<Vec<_>>(),
    )
    .with_inserted_indices(Indices::U32(m.indices.iter().flatten().copied().collect()))
}

/// Spawn one object: its mesh, its [`EnvisMaterial`], and the [`SceneObject`] that lets the
/// panel edit it.
pub fn spawn_object(
    commands: &mut Commands,
    materials: &mut Assets<EnvisMaterial>,
    name: &str,
    mesh: Handle<Mesh>,
    material: EnvisBrdf,
    transform: Transform,
) -> Entity {
    let handle = materials.add(EnvisMaterial::from(material));
    commands
        .spawn((
            Mesh3d(mesh),
            MeshMaterial3d(handle.clone()),
            transform,
            SceneObject {
                name: name.into(),
                material,
                handle,
            },
        ))
        .id()
}

/// Spawn every object of `sc` (spheres and planes as Bevy primitives, tori and glTF meshes as the
/// same world-space triangles the CPU ray caster uses) and return its camera.
pub fn spawn_scene_objects(
    commands: &mut Commands,
    meshes: &mut Assets<Mesh>,
    materials: &mut Assets<EnvisMaterial>,
    sc: &Scene,
) -> SceneCamera {
    for (i, o) in sc.objects.iter().enumerate() {
        let material = EnvisBrdf::from_material(&o.material);
        let mesh = meshes.add(match &o.shape {
            Shape::Sphere { radius, .. } => Sphere::new(*radius).mesh().ico(6).expect("icosphere"),
            Shape::Plane { half, .. } => Plane3d::default()
                .mesh()
                .size(2.0 * half, 2.0 * half)
                .into(),
            Shape::Mesh(m) => bevy_mesh(&m.mesh),
        });
        let transform = object_transform(&o.shape);
        let e = spawn_object(commands, materials, &o.name, mesh, material, transform);
        commands.entity(e).insert(SceneIndex(i));
    }
    scene_camera(sc)
}

/// Where an object of the scene file is: spheres and planes as Bevy's primitives are placed,
/// meshes by their world-from-object transform.
pub fn object_transform(shape: &Shape) -> Transform {
    match shape {
        Shape::Sphere { center, .. } => Transform::from_translation(*center),
        Shape::Plane {
            center, normal, u, ..
        } => {
            let rot = Quat::from_mat3(&Mat3::from_cols(*u, *normal, u.cross(*normal)));
            Transform::from_translation(*center).with_rotation(rot)
        }
        Shape::Mesh(m) => Transform::from_matrix(Mat4::from(m.world_from_object)),
    }
}

/// The scene file's camera.
pub fn scene_camera(sc: &Scene) -> SceneCamera {
    let c = &sc.file.camera;
    SceneCamera {
        eye: Vec3::from(c.position),
        target: Vec3::from(c.target),
        fov: c.fov.clamp(1.0, 170.0).to_radians(),
    }
}
