//! Skinned meshes' shadow geometry: the pose Bevy draws, on the CPU. Bevy's skinning
//! (`skinning.wgsl`, `skin_model`) replaces a skinned mesh's model matrix by the weighted sum of
//! its joints' matrices (joint `GlobalTransform` x inverse bind pose), so its vertices land in
//! world space directly; [`skinned_positions`] does the same sum per vertex (the core's
//! `visibility::skin`), and the shadow BVH of such a mesh is built once per entity in world space
//! and refitted to each new pose ([`crate::visibility::FlatBlas::refit`]).

use bevy::ecs::system::SystemParam;
use bevy::light::NotShadowCaster;
use bevy::mesh::VertexAttributeValues;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::prelude::*;

/// What the shadow geometry reads of the skinned casters' poses.
#[derive(SystemParam)]
pub struct Poses<'w, 's> {
    skins: Query<'w, 's, &'static SkinnedMesh, (With<Mesh3d>, Without<NotShadowCaster>)>,
    moved: Query<'w, 's, (), Changed<GlobalTransform>>,
    transforms: Query<'w, 's, &'static GlobalTransform>,
    bindposes: Res<'w, Assets<SkinnedMeshInverseBindposes>>,
    loaded: MessageReader<'w, 's, AssetEvent<SkinnedMeshInverseBindposes>>,
}

impl Poses<'_, '_> {
    /// Whether a shadow-casting skinned mesh has a joint that moved since the last look.
    pub fn any_moved(&self) -> bool {
        self.skins.iter().any(|s| self.moved(s))
    }

    /// Whether bind poses were added or changed since the last look (a skinned caster waiting
    /// for them can be built).
    pub fn bindposes_loaded(&mut self) -> bool {
        self.loaded.read().count() > 0
    }

    /// Whether `skin`'s joints moved since the last look.
    pub fn moved(&self, skin: &SkinnedMesh) -> bool {
        skin.joints.iter().any(|&j| self.moved.contains(j))
    }

    /// `skin`'s joint matrices now ([`joint_matrices`]).
    pub fn joints(&self, skin: &SkinnedMesh) -> Option<Vec<Mat4>> {
        joint_matrices(skin, &self.bindposes, &self.transforms)
    }
}

/// Each joint's matrix as Bevy's skinning uses it (`GlobalTransform` x inverse bind pose), or
/// `None` while the bind poses are not loaded or a joint has no transform.
pub fn joint_matrices(
    skin: &SkinnedMesh,
    bindposes: &Assets<SkinnedMeshInverseBindposes>,
    transforms: &Query<&GlobalTransform>,
) -> Option<Vec<Mat4>> {
    let inverse = bindposes.get(&skin.inverse_bindposes)?;
    (skin.joints.iter().zip(inverse.iter()))
        .map(|(&joint, ib)| Some(transforms.get(joint).ok()?.to_matrix() * *ib))
        .collect()
}

/// The world-space positions of `mesh` skinned by `joints` (Bevy's `skin_model`:
/// [`crate::visibility::skin::skin_points`]); `None` for a mesh without float positions, joint
/// indices and weights, or with a joint index past `joints`.
pub fn skinned_positions(mesh: &Mesh, joints: &[Mat4]) -> Option<Vec<Vec3>> {
    let p = mesh.attribute(Mesh::ATTRIBUTE_POSITION)?.as_float3()?;
    let Some(VertexAttributeValues::Uint16x4(index)) = mesh.attribute(Mesh::ATTRIBUTE_JOINT_INDEX)
    else {
        return None;
    };
    let Some(VertexAttributeValues::Float32x4(weight)) =
        mesh.attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT)
    else {
        return None;
    };
    let p: Vec<Vec3> = p.iter().map(|&v| Vec3::from(v)).collect();
    crate::visibility::skin::skin_points(&p, index, weight, joints)
}
