//! `EnvisShadowsPlugin`: shadow rays in the Bevy pass. The main world keeps one BVH per
//! shadow-casting mesh asset, in object space, built once (`visibility::MeshBvh`, flattened as
//! the GPU reads it), and a top-level BVH over the placed meshes (every visible `Mesh3d` without
//! `NotShadowCaster`, through its `GlobalTransform`). When meshes come, go or change, the top
//! level is built anew and everything uploaded; when they only move, the top level is refitted
//! and only it and the instance records are rewritten. The lighting pass traverses both levels
//! (`shaders/visibility.wgsl`) for every light and BRDF sample of a camera whose
//! `EnvironmentSampling::shadows` is on. The geometry traced is the geometry rasterised (a
//! tessellated sphere is traced as its triangles).
//!
//! Skinned meshes (`SkinnedMesh`) and meshes with morph targets (`MeshMorphWeights`) cast the
//! pose Bevy draws: their vertices morphed and skinned on the CPU as Bevy's vertex shader does
//! (`super::pose`), their BVH built once per entity in world space and refitted, not rebuilt,
//! whenever a joint moves or a weight changes.
//!
//! `RenderLayers`: a mesh casts shadows only for the cameras that see one of its layers, as Bevy
//! draws it only for them. Each instance record keeps its layers and each camera's rays are cast
//! for its own ([`Layers`], 32 bits: layer `l` is bit `l mod 32`, so layers 32 apart share a bit
//! and a mesh on layer 33 casts for a camera on layer 1).

use super::components::EnvironmentSampling;
use super::pose::{Deform, DeformQuery, Poses};
use super::{Counters, EnvisCounters};
use bevy::camera::visibility::RenderLayers;
use bevy::light::NotShadowCaster;
use bevy::mesh::{Indices, PrimitiveTopology};
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use bevy::render::extract_resource::{ExtractResource, ExtractResourcePlugin};
use bevy::render::renderer::{RenderDevice, RenderQueue};
use bevy::render::{Render, RenderApp, RenderSystems};
use envis::visibility::{
    Bounds, FlatBlas, FlatBvh, FlatInstance, Layers, MeshBvh, ShadowRays, Tlas,
};
use std::sync::Arc;

mod mesh;
mod posed;
mod top_level;
use mesh::mesh_triangles;
use posed::{PosedBlas, repose};
use top_level::{place_instances, rebuild, refit};

/// The shadow-casting geometry of the main world, flattened (extracted to the render world).
#[derive(Resource, Clone, Default, ExtractResource)]
pub struct ShadowGeometry {
    /// Changes when meshes or the set of instances change (everything is uploaded).
    pub generation: u64,
    /// Changes when instances moved (the top part is rewritten).
    pub placement: u64,
    pub bvh: FlatBvh,
    /// Triangles placed (a mesh counts once per instance).
    pub triangles: usize,
}

impl ShadowGeometry {
    /// Whether a camera asking for `mode` casts shadow rays: `auto` does when there is any
    /// shadow-casting triangle (a Bevy mesh is not known to be convex).
    pub fn enabled(&self, mode: ShadowRays) -> bool {
        match mode {
            ShadowRays::On => true,
            ShadowRays::Off => false,
            ShadowRays::Auto => self.triangles > 0,
        }
    }
}

/// The main world's side: each mesh asset's flattened BVH, and the instances in the order the
/// top level was built over them.
#[derive(Resource, Default)]
pub struct ShadowScene {
    meshes: HashMap<AssetId<Mesh>, Arc<FlatBlas>>,
    /// Deformed (skinned or morphed) casters' BVHs, in world space, one per entity.
    posed: HashMap<Entity, PosedBlas>,
    instances: Vec<Entity>,
    placed: Vec<FlatInstance>,
    /// The BVHs the instances place (`placed[i].blas` indexes them).
    blases: Vec<Arc<FlatBlas>>,
    /// Each instance's mesh bounds (object space; world space for a deformed one).
    object_bounds: Vec<Bounds>,
    tlas: Tlas,
    /// A visible caster's mesh was not loaded at the last build: a mesh that loads since may be
    /// it.
    waiting: bool,
}

/// The geometry on the GPU (render world).
#[derive(Resource)]
pub struct GpuShadowGeometry {
    pub generation: u64,
    pub placement: u64,
    pub nodes: wgpu::Buffer,
    pub triangles: wgpu::Buffer,
    pub node_count: u32,
}

pub struct EnvisShadowsPlugin;

impl Plugin for EnvisShadowsPlugin {
    fn build(&self, app: &mut App) {
        super::share_resources(app);
        app.init_resource::<ShadowGeometry>()
            .init_resource::<ShadowScene>()
            .add_plugins(ExtractResourcePlugin::<ShadowGeometry>::default())
            .add_systems(
                PostUpdate,
                // After this frame's transforms and visibility are known: a mesh spawned this
                // frame is then built once, visible, not once hidden and again next frame. And
                // after Bevy marks the `Mesh3d`s of modified mesh assets changed (its order to
                // this system was free), so that the mark is seen in the frame it is made.
                gather_shadow_geometry
                    .after(bevy::mesh::mark_3d_meshes_as_changed_if_their_assets_changed)
                    .after(bevy::transform::TransformSystems::Propagate)
                    .after(bevy::camera::visibility::VisibilitySystems::VisibilityPropagate)
                    .after(bevy::asset::AssetEventSystems),
            );
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render_app.add_systems(
                Render,
                upload_shadow_geometry.in_set(RenderSystems::Prepare),
            );
        }
    }
}

type Casters<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        &'static Mesh3d,
        &'static GlobalTransform,
        &'static InheritedVisibility,
        Option<&'static RenderLayers>,
        DeformQuery,
    ),
    Without<NotShadowCaster>,
>;

/// A mesh was swapped, shown or hidden, or put on other layers.
type CasterChanged = Or<(
    Changed<Mesh3d>,
    Changed<InheritedVisibility>,
    Changed<RenderLayers>,
)>;

/// The [`Layers`] of an entity's or a camera's `RenderLayers` (none: Bevy's default, layer 0).
pub fn layers_of(render_layers: Option<&RenderLayers>) -> Layers {
    let layers = render_layers.unwrap_or(bevy::camera::visibility::DEFAULT_LAYERS);
    Layers(layers.iter().fold(0, |bits, l| bits | 1 << (l % 32)))
}

/// A shadow-casting mesh moved.
type CasterMoved = (Without<NotShadowCaster>, Changed<GlobalTransform>);

/// What changed since the last look.
#[derive(Clone, Copy, PartialEq, Debug)]
enum Change {
    None,
    /// Instances moved: refit the top level.
    Moved,
    /// A deformed caster's pose changed: refit its BVH (and the top level).
    Posed,
    /// Meshes or instances came, went or changed: build the top level anew.
    Structure,
}

/// Keep the geometry up to date, only while some camera samples the environment: build a
/// mesh's BVH once, the top level when instances come or go, and refit it when they move.
#[allow(
    clippy::too_many_arguments,
    reason = "a Bevy system's parameters are the data it touches"
)]
pub fn gather_shadow_geometry(
    cameras: Query<(), With<EnvironmentSampling>>,
    new_cameras: Query<(), Added<EnvironmentSampling>>,
    casters: Casters,
    changed: Query<(), (With<Mesh3d>, CasterChanged)>,
    moved: Query<(), (With<Mesh3d>, CasterMoved)>,
    mut removed: RemovedComponents<Mesh3d>,
    // Meshes that started or stopped casting shadows, or went back to the default layer.
    (opted_out, mut opted_in, mut unlayered): (
        Query<(), Added<NotShadowCaster>>,
        RemovedComponents<NotShadowCaster>,
        RemovedComponents<RenderLayers>,
    ),
    mut events: MessageReader<AssetEvent<Mesh>>,
    (meshes, mut poses): (Res<Assets<Mesh>>, Poses),
    (mut scene, mut geometry): (ResMut<ShadowScene>, ResMut<ShadowGeometry>),
    counters: Res<EnvisCounters>,
) {
    let assets_changed = forget_changed_meshes(&mut events, &mut scene);
    // A first envis camera in a scene that has not changed since needs the geometry too.
    let structure = !changed.is_empty()
        | (!new_cameras.is_empty() && geometry.generation == 0)
        | !opted_out.is_empty()
        | (opted_in.read().count() > 0)
        | (unlayered.read().count() > 0)
        | (removed.read().count() > 0)
        | (poses.bindposes_loaded() && scene.waiting)
        | assets_changed;
    // A skinned caster still waiting for its bind poses is built when it moves.
    let posed = poses.any_moved();
    let change = Change::of(
        structure || (posed && scene.waiting),
        posed,
        !moved.is_empty(),
    );
    if change == Change::None || cameras.is_empty() {
        return;
    }
    update_geometry(
        change,
        (&mut scene, &mut geometry),
        &casters,
        (&meshes, &poses),
        &counters,
    );
}

/// Drop the kept BVHs of modified or removed meshes; whether an event concerns the shadow
/// geometry (such a mesh, or a new mesh while a caster waits for its mesh).
fn forget_changed_meshes(
    events: &mut MessageReader<AssetEvent<Mesh>>,
    // A `ResMut`: the scene is marked changed only when a modified or removed mesh's event
    // comes (its kept BVH is dropped through it), as in the single system before.
    scene: &mut ResMut<ShadowScene>,
) -> bool {
    // Only the meshes that cast shadows matter (a mesh modified every frame elsewhere, or one
    // with NotShadowCaster, costs nothing), and new ones while a caster waits for its mesh.
    let mut assets_changed = false;
    for e in events.read() {
        match e {
            AssetEvent::Modified { id } | AssetEvent::Removed { id } => {
                let posed = scene.posed.values().any(|s| s.mesh == *id);
                scene.posed.retain(|_, s| s.mesh != *id);
                assets_changed |= scene.meshes.remove(id).is_some() | posed;
            }
            AssetEvent::Added { .. } | AssetEvent::LoadedWithDependencies { .. } => {
                assets_changed |= scene.waiting;
            }
            _ => {}
        }
    }
    assets_changed
}

impl Change {
    /// The change to act on: a structure change wins over a pose change, which wins over moves.
    fn of(structure: bool, posed: bool, moved: bool) -> Change {
        match (structure, posed, moved) {
            (true, ..) => Change::Structure,
            (false, true, _) => Change::Posed,
            (false, false, true) => Change::Moved,
            (false, false, false) => Change::None,
        }
    }
}

/// Refit the top level for a move, or the deformed casters' BVHs for a pose change; build it
/// anew for a structure change, or when a refit cannot be done.
fn update_geometry(
    change: Change,
    (scene, geometry): (&mut ShadowScene, &mut ShadowGeometry),
    casters: &Casters,
    (meshes, poses): (&Assets<Mesh>, &Poses),
    counters: &EnvisCounters,
) {
    let done = match change {
        Change::Moved => refit(scene, geometry, casters),
        Change::Posed => repose(scene, geometry, (casters, meshes, poses), counters),
        _ => false,
    };
    if done {
        counters.bump(|c: &Counters| &c.shadow_tlas_refits);
        return;
    }
    rebuild(scene, geometry, casters, (meshes, poses), counters);
}

/// Upload the geometry when it changed: everything for a new generation, the top part when
/// instances only moved.
pub fn upload_shadow_geometry(
    mut commands: Commands,
    geometry: Option<Res<ShadowGeometry>>,
    gpu: Option<ResMut<GpuShadowGeometry>>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
) {
    let Some(geometry) = geometry else { return };
    match gpu {
        Some(mut g) if g.generation == geometry.generation => {
            if g.placement != geometry.placement {
                envis_wgpu::visibility::write_top(
                    &queue,
                    (&g.nodes, &g.triangles),
                    &geometry.bvh.top,
                );
                g.placement = geometry.placement;
            }
        }
        _ => {
            let (nodes, triangles) =
                envis_wgpu::visibility::upload_bvh(device.wgpu_device(), &geometry.bvh);
            commands.insert_resource(GpuShadowGeometry {
                generation: geometry.generation,
                placement: geometry.placement,
                nodes,
                triangles,
                node_count: geometry.bvh.tlas_nodes() as u32,
            });
        }
    }
}
