//! `EnvironmentShadowsPlugin`: shadow rays in the Bevy pass. The main world gathers the meshes
//! that cast shadows (every visible `Mesh3d` without `NotShadowCaster`), in world space, into
//! one BVH (`obvhs`, flattened as the GPU reads it: `visibility::FlatBvh`) whenever a mesh is
//! added, moved, changed or removed; the render world uploads it to two storage buffers, and the
//! lighting pass traverses it (`shaders/visibility.wgsl`) for every light and BRDF sample of a
//! camera whose `EnvironmentSampling::shadows` is on. The geometry traced is the geometry
//! rasterised (a tessellated sphere is traced as its triangles).

use super::components::EnvironmentSampling;
use super::{Counters, EnvisCounters};
use crate::visibility::{FlatBvh, MeshBvh, Visibility};
use bevy::light::NotShadowCaster;
use bevy::mesh::{Indices, PrimitiveTopology};
use bevy::prelude::*;
use bevy::render::extract_resource::{ExtractResource, ExtractResourcePlugin};
use bevy::render::renderer::RenderDevice;
use bevy::render::{Render, RenderApp, RenderSystems};
use std::sync::Arc;

/// The shadow-casting geometry of the main world, flattened (extracted to the render world).
#[derive(Resource, Clone, Default, ExtractResource)]
pub struct ShadowGeometry {
    /// Changes exactly when the geometry does.
    pub generation: u64,
    pub bvh: Arc<FlatBvh>,
    /// Triangles in it.
    pub triangles: usize,
}

impl ShadowGeometry {
    /// Whether a camera asking for `mode` casts shadow rays: `auto` does when there is any
    /// shadow-casting triangle (a Bevy mesh is not known to be convex).
    pub fn enabled(&self, mode: Visibility) -> bool {
        match mode {
            Visibility::On => true,
            Visibility::Off => false,
            Visibility::Auto => self.triangles > 0,
        }
    }
}

/// The geometry on the GPU (render world).
#[derive(Resource)]
pub struct GpuShadowGeometry {
    pub generation: u64,
    pub nodes: wgpu::Buffer,
    pub triangles: wgpu::Buffer,
    pub node_count: u32,
}

pub struct EnvironmentShadowsPlugin;

impl Plugin for EnvironmentShadowsPlugin {
    fn build(&self, app: &mut App) {
        super::share_resources(app);
        app.init_resource::<ShadowGeometry>()
            .add_plugins(ExtractResourcePlugin::<ShadowGeometry>::default())
            .add_systems(
                PostUpdate,
                gather_shadow_geometry
                    .after(bevy::transform::TransformSystems::Propagate)
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
        &'static Mesh3d,
        &'static GlobalTransform,
        &'static InheritedVisibility,
    ),
    Without<NotShadowCaster>,
>;

/// A mesh moved, was swapped, or was shown or hidden.
type CasterChanged = Or<(
    Changed<GlobalTransform>,
    Changed<Mesh3d>,
    Changed<InheritedVisibility>,
)>;

/// Rebuild the BVH when a shadow-casting mesh came, went, moved or changed (and only then, and
/// only while some camera samples the environment).
#[allow(
    clippy::too_many_arguments,
    reason = "a Bevy system's parameters are the data it touches"
)]
pub fn gather_shadow_geometry(
    cameras: Query<(), With<EnvironmentSampling>>,
    new_cameras: Query<(), Added<EnvironmentSampling>>,
    casters: Casters,
    changed: Query<(), (With<Mesh3d>, CasterChanged)>,
    mut removed: RemovedComponents<Mesh3d>,
    // Meshes that started or stopped casting shadows.
    (opted_out, mut opted_in): (
        Query<(), Added<NotShadowCaster>>,
        RemovedComponents<NotShadowCaster>,
    ),
    mut events: MessageReader<AssetEvent<Mesh>>,
    meshes: Res<Assets<Mesh>>,
    mut geometry: ResMut<ShadowGeometry>,
    counters: Res<EnvisCounters>,
) {
    // A first envis camera in a scene that has not changed since needs the geometry too.
    let dirty = !changed.is_empty()
        | (!new_cameras.is_empty() && geometry.generation == 0)
        | !opted_out.is_empty()
        | (opted_in.read().count() > 0)
        | (removed.read().count() > 0)
        | (events.read().count() > 0);
    if !dirty || cameras.is_empty() {
        return;
    }
    let (mut positions, mut tris) = (Vec::new(), Vec::new());
    for (mesh, transform, visible) in &casters {
        if visible.get()
            && let Some(m) = meshes.get(&mesh.0)
        {
            append_triangles(m, &transform.affine(), &mut positions, &mut tris);
        }
    }
    let bvh = MeshBvh::build(&positions, &tris);
    let flat = match bvh.flatten(&positions, &tris) {
        Ok(f) => f,
        Err(e) => {
            error!("envis: no shadows: {e}");
            FlatBvh::default()
        }
    };
    *geometry = ShadowGeometry {
        generation: geometry.generation + 1,
        bvh: Arc::new(flat),
        triangles: tris.len(),
    };
    counters.bump(|c: &Counters| &c.shadow_bvh_builds);
}

/// The triangles of `mesh` in world space (triangle lists with float positions; anything else,
/// or a mesh whose data lives only in the render world, adds nothing).
fn append_triangles(
    mesh: &Mesh,
    world: &bevy::math::Affine3A,
    positions: &mut Vec<Vec3>,
    tris: &mut Vec<[u32; 3]>,
) {
    if mesh.primitive_topology() != PrimitiveTopology::TriangleList {
        return;
    }
    let Ok(Some(p)) = mesh.try_attribute_option(Mesh::ATTRIBUTE_POSITION) else {
        return;
    };
    let Some(p) = p.as_float3() else { return };
    let base = positions.len() as u32;
    positions.extend(p.iter().map(|v| world.transform_point3(Vec3::from(*v))));
    let n = p.len() as u32;
    let index: Vec<u32> = match mesh.try_indices_option() {
        Ok(Some(Indices::U16(v))) => v.iter().map(|&i| i as u32).collect(),
        Ok(Some(Indices::U32(v))) => v.clone(),
        _ => (0..n).collect(),
    };
    tris.extend(
        index
            .chunks_exact(3)
            .filter(|t| t.iter().all(|&i| i < n))
            .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
    );
}

/// Upload the geometry when its generation changed.
pub fn upload_shadow_geometry(
    mut commands: Commands,
    geometry: Option<Res<ShadowGeometry>>,
    gpu: Option<Res<GpuShadowGeometry>>,
    device: Res<RenderDevice>,
) {
    let Some(geometry) = geometry else { return };
    if gpu.is_some_and(|g| g.generation == geometry.generation) {
        return;
    }
    let (nodes, triangles) =
        crate::gpu::visibility::upload_bvh(device.wgpu_device(), &geometry.bvh);
    commands.insert_resource(GpuShadowGeometry {
        generation: geometry.generation,
        nodes,
        triangles,
        node_count: geometry.bvh.nodes.len() as u32,
    });
}
