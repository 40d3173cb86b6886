//! Deformed meshes' shadow geometry: the pose Bevy draws, on the CPU. Bevy's vertex shader
//! (`mesh.wgsl`) first moves each vertex by its morph targets' weighted displacements
//! (`morph_vertex`), then, for a skinned mesh, replaces the model matrix by the weighted sum of
//! its joints' matrices (`skin_model`: joint `GlobalTransform` x inverse bind pose), so a skinned
//! mesh's vertices land in world space directly. [`posed_positions`] does the same per vertex
//! (the core's `visibility::morph` and `visibility::skin`); the shadow BVH of such a mesh is
//! built once per entity in world space and refitted to each new pose
//! ([`envis::visibility::FlatBlas::refit`]). A mesh with morph targets and no skin is posed in
//! world space too, through its own transform, so moving it refits its BVH as well.

use bevy::ecs::system::SystemParam;
use bevy::light::NotShadowCaster;
use bevy::math::Affine3A;
use bevy::mesh::VertexAttributeValues;
use bevy::mesh::morph::{MeshMorphWeights, MorphWeights};
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::prelude::*;

/// What deforms a mesh entity as Bevy draws it: its skin, its morph weights, or both. Neither
/// means it is drawn as its mesh asset through its transform.
#[derive(Clone, Copy, Default)]
pub struct Deform<'a> {
    pub skin: Option<&'a SkinnedMesh>,
    pub morph: Option<&'a MeshMorphWeights>,
}

impl<'a> Deform<'a> {
    pub fn new((skin, morph): (Option<&'a SkinnedMesh>, Option<&'a MeshMorphWeights>)) -> Self {
        Deform { skin, morph }
    }

    /// Whether the entity is posed on its own (its shadow BVH is its own, in world space).
    pub fn is_posed(&self) -> bool {
        self.skin.is_some() || self.morph.is_some()
    }
}

/// The deforming components of a mesh entity, as a query reads them (see [`Deform::new`]).
pub type DeformQuery = (
    Option<&'static SkinnedMesh>,
    Option<&'static MeshMorphWeights>,
);

/// A shadow-casting mesh entity that is skinned or morphed.
type PosedCaster = (
    With<Mesh3d>,
    Without<NotShadowCaster>,
    Or<(With<SkinnedMesh>, With<MeshMorphWeights>)>,
);

/// What the shadow geometry reads of the deformed casters' poses.
#[derive(SystemParam)]
pub struct Poses<'w, 's> {
    posed: Query<'w, 's, (Entity, DeformQuery), PosedCaster>,
    moved: Query<'w, 's, (), Changed<GlobalTransform>>,
    transforms: Query<'w, 's, &'static GlobalTransform>,
    reweighted: Query<'w, 's, (), Changed<MeshMorphWeights>>,
    weights: Query<'w, 's, Ref<'static, MorphWeights>>,
    bindposes: Res<'w, Assets<SkinnedMeshInverseBindposes>>,
    loaded: MessageReader<'w, 's, AssetEvent<SkinnedMeshInverseBindposes>>,
}

impl Poses<'_, '_> {
    /// Whether a shadow-casting deformed mesh changed its pose since the last look.
    pub fn any_moved(&self) -> bool {
        (self.posed.iter()).any(|(entity, d)| self.moved(entity, Deform::new(d)))
    }

    /// Whether bind poses were added or changed since the last look (a skinned caster waiting
    /// for them can be built).
    pub fn bindposes_loaded(&mut self) -> bool {
        self.loaded.read().count() > 0
    }

    /// Whether `entity`'s pose changed since the last look: a joint moved, its morph weights
    /// changed, or (posed through its own transform: morphed, not skinned) it moved.
    pub fn moved(&self, entity: Entity, deform: Deform) -> bool {
        let joints = deform.skin.is_some_and(|s| {
            // A skinned mesh's own transform is not drawn: only its joints place it.
            s.joints.iter().any(|&j| self.moved.contains(j))
        });
        let weights = deform.morph.is_some_and(|m| {
            self.reweighted.contains(entity)
                || matches!(m, MeshMorphWeights::Reference(w)
                    if self.weights.get(*w).is_ok_and(|w| w.is_changed()))
        });
        let own = deform.skin.is_none() && deform.morph.is_some() && self.moved.contains(entity);
        joints || weights || own
    }

    /// `entity`'s vertices in world space as Bevy draws them ([`posed_positions`]); `None`
    /// while a skin's bind poses are not loaded or a joint has no transform, or for a mesh
    /// without float positions (or a skinned one without joint attributes).
    pub fn positions(&self, mesh: &Mesh, entity: Entity, deform: Deform) -> Option<Vec<Vec3>> {
        let joints = match deform.skin {
            Some(skin) => Some(joint_matrices(skin, &self.bindposes, &self.transforms)?),
            None => None,
        };
        let weights = deform.morph.and_then(|m| match m {
            MeshMorphWeights::Value { weights } => Some(weights.as_slice()),
            MeshMorphWeights::Reference(w) => {
                self.weights.get(*w).ok().map(|w| w.into_inner().weights())
            }
        });
        let placed = self.transforms.get(entity).ok()?.affine();
        posed_positions(mesh, joints.as_deref(), weights, &placed)
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

/// The world-space positions of `mesh` as Bevy's vertex shader places them: moved by its morph
/// targets' displacements times `weights` (none: the mesh's own positions;
/// [`envis::visibility::morph::morph_points`]), then skinned by `joints`
/// ([`envis::visibility::skin::skin_points`]) or, without a skin, placed by `world_from_object`.
/// `None` for a mesh without float positions, a skinned one without joint indices and weights or
/// with a joint index past `joints`, or morph targets that do not match the vertex count.
pub fn posed_positions(
    mesh: &Mesh,
    joints: Option<&[Mat4]>,
    weights: Option<&[f32]>,
    world_from_object: &Affine3A,
) -> Option<Vec<Vec3>> {
    let p = mesh.attribute(Mesh::ATTRIBUTE_POSITION)?.as_float3()?;
    let mut p: Vec<Vec3> = p.iter().map(|&v| Vec3::from(v)).collect();
    if let (Some(w), Ok(targets)) = (weights, mesh.try_morph_targets()) {
        let d: Vec<Vec3> = targets.iter().map(|t| t.position).collect();
        p = envis::visibility::morph::morph_points(&p, &d, w)?;
    }
    let Some(joints) = joints else {
        return Some(
            p.iter()
                .map(|&v| world_from_object.transform_point3(v))
                .collect(),
        );
    };
    let Some(VertexAttributeValues::Uint16x4(index)) = mesh.attribute(Mesh::ATTRIBUTE_JOINT_INDEX)
    else {
        return None;
    };
    let Some(VertexAttributeValues::Float32x4(weight)) =
        mesh.attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT)
    else {
        return None;
    };
    envis::visibility::skin::skin_points(&p, index, weight, joints)
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy::asset::RenderAssetUsages;
    use bevy::mesh::PrimitiveTopology;
    use bevy::mesh::morph::MorphAttributes;

    /// One vertex at the origin, one morph target lifting it by 1 along +Y, skinned wholly to a
    /// joint that rotates a quarter turn about +Z: Bevy morphs first, then skins, so the lifted
    /// vertex lands on -X (skinning first would leave it on +Y). Without a skin, the entity's
    /// own transform places it; without weights, the mesh's own position is used.
    #[test]
    fn morph_targets_apply_before_skinning() {
        let mut mesh = Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::all())
            .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0, 0.0, 0.0]])
            .with_inserted_attribute(
                Mesh::ATTRIBUTE_JOINT_INDEX,
                VertexAttributeValues::Uint16x4(vec![[0; 4]]),
            )
            .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, vec![[1.0, 0.0, 0.0, 0.0]]);
        mesh.set_morph_targets(vec![MorphAttributes::new(Vec3::Y, Vec3::ZERO, Vec3::ZERO)]);
        let quarter = [Mat4::from_rotation_z(std::f32::consts::FRAC_PI_2)];
        let moved = Affine3A::from_translation(Vec3::Z);
        let close = |a: Option<Vec<Vec3>>, b: Vec3| a.is_some_and(|a| (a[0] - b).length() < 1e-6);
        let skinned = posed_positions(&mesh, Some(&quarter), Some(&[1.0]), &moved);
        assert!(close(skinned.clone(), -Vec3::X), "{skinned:?}");
        let unskinned = posed_positions(&mesh, None, Some(&[0.5]), &moved);
        assert!(
            close(unskinned.clone(), Vec3::new(0.0, 0.5, 1.0)),
            "{unskinned:?}"
        );
        let rest = posed_positions(&mesh, None, None, &moved);
        assert!(close(rest.clone(), Vec3::Z), "{rest:?}");
    }
}
