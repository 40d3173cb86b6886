//! Deformed casters in the shadow geometry (skinned, morphed or both): each one's BVH over its
//! pose, in world space, built once per entity and refitted to every new pose
//! (`super::super::pose` places the vertices as Bevy's vertex shader does).

use super::*;

/// A deformed caster's BVH over its posed vertices (world space), and what a refit needs.
pub(super) struct PosedBlas {
    pub(super) mesh: AssetId<Mesh>,
    pub(super) blas: Arc<FlatBlas>,
    triangles: Vec<[u32; 3]>,
    order: Vec<u32>,
}

impl PosedBlas {
    /// Refit the BVH to `entity`'s pose now; `false` when the pose cannot be had (then build
    /// anew).
    pub(super) fn refit(
        &mut self,
        mesh: &Mesh,
        (entity, deform): (Entity, Deform),
        poses: &Poses,
        counters: &EnvisCounters,
    ) -> bool {
        let Some(p) = poses.positions(mesh, entity, deform) else {
            return false;
        };
        if !Arc::make_mut(&mut self.blas).refit(&p, &self.triangles, &self.order) {
            return false;
        }
        counters.bump(|c: &Counters| &c.shadow_deformed_refits);
        true
    }
}

/// Deformed casters changed their pose: each such one's BVH refitted to its new pose (the tree
/// kept), every instance placed anew, and the whole geometry uploaded again (the meshes' part
/// changed). `false` when that cannot be done: build anew instead.
pub(super) fn repose(
    scene: &mut ShadowScene,
    geometry: &mut ShadowGeometry,
    (casters, meshes, poses): (&Casters, &Assets<Mesh>, &Poses),
    counters: &EnvisCounters,
) -> bool {
    for (i, &entity) in scene.instances.iter().enumerate() {
        let Ok((_, mesh, _, _, _, deform)) = casters.get(entity) else {
            continue;
        };
        let deform = Deform::new(deform);
        if !deform.is_posed() {
            continue;
        }
        let Some(s) = scene.posed.get_mut(&entity) else {
            return false;
        };
        if !poses.moved(entity, deform) {
            continue;
        }
        let Some(m) = meshes.get(mesh.id()) else {
            return false;
        };
        if !s.refit(m, (entity, deform), poses, counters) {
            return false;
        }
        let Some(b) = s.blas.bounds else { return false };
        scene.object_bounds[i] = b;
        scene.blases[scene.placed[i].blas] = s.blas.clone();
    }
    if !place_instances(scene, casters) {
        return false;
    }
    let Ok(bvh) = FlatBvh::build(&scene.blases, &scene.placed, &scene.tlas) else {
        return false;
    };
    geometry.bvh = bvh;
    (geometry.generation, geometry.placement) = (geometry.generation + 1, geometry.placement + 1);
    true
}

/// A deformed caster's BVH over its pose now, in world space; `None` until a skin's bind poses
/// and joints are there (or when its mesh has no joint attributes: it then casts nothing).
pub(super) fn posed_blas(
    mesh: &Mesh,
    id: AssetId<Mesh>,
    (entity, deform): (Entity, Deform),
    poses: &Poses,
    counters: &EnvisCounters,
) -> Option<PosedBlas> {
    let p = poses.positions(mesh, entity, deform)?;
    let (_, triangles) = mesh_triangles(mesh);
    let bvh = MeshBvh::build(&p, &triangles);
    let blas = bvh.flat_blas(&p, &triangles).unwrap_or_else(|e| {
        error!("envis: a deformed mesh casts no shadow: {e}");
        FlatBlas::default()
    });
    counters.bump(|c: &Counters| &c.shadow_bvh_builds);
    Some(PosedBlas {
        mesh: id,
        blas: Arc::new(blas),
        order: bvh.leaf_order().to_vec(),
        triangles,
    })
}
