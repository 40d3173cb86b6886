//! What restarts accumulation in the scene: [`SceneRevision`], bumped by
//! [`track_scene_changes`] whenever a change would change the image (the camera, settings and
//! image are in each view's own accumulation key, `sampling.rs`).

use bevy::camera::visibility::RenderLayers;
use bevy::mesh::morph::{MeshMorphWeights, MorphWeights};
use bevy::prelude::*;
use bevy::render::extract_resource::ExtractResource;

/// Counts changes to the scene (materials, meshes, transforms of meshes, which meshes are drawn
/// and cast shadows), extracted to the render world: accumulation restarts when it changes.
#[derive(Resource, Clone, Copy, Default, ExtractResource)]
pub struct SceneRevision(pub u64);

/// A mesh entity now draws another mesh or material, was hidden or shown, or put on other
/// layers. (Bevy writes `InheritedVisibility` only when it changes, so a still scene triggers
/// none of these.)
type MeshSwapped = (
    With<Mesh3d>,
    Or<(
        Changed<Mesh3d>,
        Changed<MeshMaterial3d<StandardMaterial>>,
        Changed<MeshMaterial3d<super::EnvisMaterial>>,
        Changed<InheritedVisibility>,
        Changed<RenderLayers>,
    )>,
);

/// Meshes that moved; skinned meshes and the transforms that changed (their joints' among
/// them); morph weights that changed, on a mesh or on the entity its weights refer to.
type Moves<'w, 's> = (
    Query<'w, 's, (), (With<Mesh3d>, Changed<GlobalTransform>)>,
    Query<'w, 's, &'static bevy::mesh::skinning::SkinnedMesh, With<Mesh3d>>,
    Query<'w, 's, (), Changed<GlobalTransform>>,
    Query<'w, 's, (), Or<(Changed<MeshMorphWeights>, Changed<MorphWeights>)>>,
);

/// Bump [`SceneRevision`] when a material or mesh asset changed, a mesh moved, appeared, went
/// away, was hidden or shown, took another mesh or material handle or other layers, started
/// or stopped casting shadows, a skinned mesh's joints moved or morph weights changed.
#[allow(
    clippy::too_many_arguments,
    reason = "a Bevy system's parameters are the data it touches"
)]
pub fn track_scene_changes(
    mut standard: MessageReader<AssetEvent<StandardMaterial>>,
    mut envis: MessageReader<AssetEvent<super::EnvisMaterial>>,
    mut meshes: MessageReader<AssetEvent<Mesh>>,
    (moved, skins, transformed, reweighted): Moves,
    swapped: Query<(), MeshSwapped>,
    (opted_out, mut opted_in, mut unlayered): (
        Query<(), Added<bevy::light::NotShadowCaster>>,
        RemovedComponents<bevy::light::NotShadowCaster>,
        RemovedComponents<RenderLayers>,
    ),
    mut removed: RemovedComponents<Mesh3d>,
    mut revision: ResMut<SceneRevision>,
) {
    let changed = standard.read().count() + envis.read().count() + meshes.read().count() > 0
        || !moved.is_empty()
        || (skins.iter()).any(|s| s.joints.iter().any(|&j| transformed.contains(j)))
        || !reweighted.is_empty()
        || !swapped.is_empty()
        || !opted_out.is_empty()
        || opted_in.read().count() > 0
        || unlayered.read().count() > 0
        || removed.read().count() > 0;
    if changed {
        revision.0 += 1;
    }
}
