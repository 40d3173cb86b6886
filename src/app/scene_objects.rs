//! Scene objects in the Bevy world: a [`crate::scene::Scene`] (a TOML scene file) spawned as
//! meshes with envis materials, shared by the demo and the headless app.

use super::EnvisMaterial;
use crate::scene::{Scene, Shape};
use bevy::prelude::*;

/// One object of the scene and its material (the panel edits it; `handle` is its
/// `StandardMaterial`).
#[derive(Component)]
pub struct SceneObject {
    pub name: String,
    pub material: EnvisMaterial,
    pub handle: Handle<StandardMaterial>,
}

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

/// The envis material that writes `m` into the G-buffer.
pub fn envis_material(m: &crate::sampling::Material) -> EnvisMaterial {
    use crate::sampling::Lobe;
    match m.lobe {
        Lobe::None => EnvisMaterial::Lambert { albedo: m.kd },
        Lobe::Phong { exponent } => EnvisMaterial::Phong {
            albedo: m.ks + m.kd,
            exponent,
        },
        Lobe::Ggx { alpha } if m.kd.max_element() <= 0.0 => EnvisMaterial::Ggx {
            albedo: m.ks,
            alpha,
        },
        Lobe::Ggx { alpha } => {
            let all = m.kd + m.ks;
            let lum = crate::envmap::luminance;
            EnvisMaterial::Mix {
                albedo: all,
                specular: lum(m.ks) / lum(all).max(1e-6),
                alpha,
            }
        }
    }
}

/// A Bevy mesh of world-space triangles.
pub fn bevy_mesh(m: &crate::scene::TriMesh) -> Mesh {
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

/// Spawn one object: its mesh, the `StandardMaterial` its envis material is written through, and
/// the [`SceneObject`] that lets the panel edit it.
pub fn spawn_object(
    commands: &mut Commands,
    materials: &mut Assets<StandardMaterial>,
    name: &str,
    mesh: Handle<Mesh>,
    material: EnvisMaterial,
    transform: Transform,
) {
    let handle = materials.add(material.standard());
    commands.spawn((
        Mesh3d(mesh),
        MeshMaterial3d(handle.clone()),
        transform,
        SceneObject {
            name: name.into(),
            material,
            handle,
        },
    ));
}

/// Spawn every object of `sc` (spheres and planes as Bevy primitives, tori and glTF meshes as the
/// same world-space triangles the CPU ray caster uses) and return its camera.
pub fn spawn_scene_objects(
    commands: &mut Commands,
    meshes: &mut Assets<Mesh>,
    materials: &mut Assets<StandardMaterial>,
    sc: &Scene,
) -> SceneCamera {
    for o in &sc.objects {
        let material = envis_material(&o.material);
        let (mesh, transform) = match &o.shape {
            Shape::Sphere { center, radius } => (
                meshes.add(Sphere::new(*radius).mesh().ico(6).expect("icosphere")),
                Transform::from_translation(*center),
            ),
            Shape::Plane {
                center,
                normal,
                u,
                half,
                ..
            } => {
                let rot = Quat::from_mat3(&Mat3::from_cols(*u, *normal, u.cross(*normal)));
                (
                    meshes.add(Plane3d::default().mesh().size(2.0 * half, 2.0 * half)),
                    Transform::from_translation(*center).with_rotation(rot),
                )
            }
            Shape::Mesh(m) => (meshes.add(bevy_mesh(m)), Transform::IDENTITY),
        };
        spawn_object(commands, materials, &o.name, mesh, material, transform);
    }
    let c = &sc.file.camera;
    SceneCamera {
        eye: Vec3::from(c.position),
        target: Vec3::from(c.target),
        fov: c.fov.clamp(1.0, 170.0).to_radians(),
    }
}
