//! Skinned casters in the shadow geometry: each one's BVH over its pose, in world space, built
//! once per entity and refitted to every new pose (`super::super::skinning` skins the vertices).

use super::*;

/// A skinned caster's BVH over its posed vertices (world space), and what a refit needs.
pub(super) struct SkinnedBlas {
    pub(super) mesh: AssetId<Mesh>,
    pub(super) blas: Arc<FlatBlas>,
    triangles: Vec<[u32; 3]>,
    order: Vec<u32>,
}

impl SkinnedBlas {
    /// Refit the BVH to `skin`'s pose now; `false` when the pose cannot be had (then build
    /// anew).
    pub(super) fn refit(
        &mut self,
        mesh: &Mesh,
        skin: &SkinnedMesh,
        poses: &Poses,
        counters: &EnvisCounters,
    ) -> bool {
        let Some(p) = poses.joints(skin).and_then(|j| skinned_positions(mesh, &j)) else {
            return false;
        };
        if !Arc::make_mut(&mut self.blas).refit(&p, &self.triangles, &self.order) {
            return false;
        }
        counters.bump(|c: &Counters| &c.shadow_skin_refits);
        true
    }
}

/// Skinned casters' joints moved: each moved one's BVH refitted to its new pose (the tree
/// kept), every instance placed anew, and the whole geometry uploaded again (the meshes' part
/// changed). `false` when that cannot be done: build anew instead.
pub(super) fn repose(
    scene: &mut ShadowScene,
    geometry: &mut ShadowGeometry,
    (casters, meshes, poses): (&Casters, &Assets<Mesh>, &Poses),
    counters: &EnvisCounters,
) -> bool {
    for (i, &entity) in scene.instances.iter().enumerate() {
        let Ok((_, mesh, _, _, _, Some(skin))) = casters.get(entity) else {
            continue;
        };
        let Some(s) = scene.skinned.get_mut(&entity) else {
            return false;
        };
        if !poses.moved(skin) {
            continue;
        }
        let Some(m) = meshes.get(mesh.id()) else {
            return false;
        };
        if !s.refit(m, skin, poses, counters) {
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

/// A skinned caster's BVH over its pose now, in world space; `None` until its bind poses and
/// joints are there (or when its mesh has no joint attributes: it then casts nothing).
pub(super) fn skinned_blas(
    mesh: &Mesh,
    id: AssetId<Mesh>,
    skin: &SkinnedMesh,
    poses: &Poses,
    counters: &EnvisCounters,
) -> Option<SkinnedBlas> {
    let p = skinned_positions(mesh, &poses.joints(skin)?)?;
    let (_, triangles) = mesh_triangles(mesh);
    let bvh = MeshBvh::build(&p, &triangles);
    let blas = bvh.flat_blas(&p, &triangles).unwrap_or_else(|e| {
        error!("envis: a skinned mesh casts no shadow: {e}");
        FlatBlas::default()
    });
    counters.bump(|c: &Counters| &c.shadow_bvh_builds);
    Some(SkinnedBlas {
        mesh: id,
        blas: Arc::new(blas),
        order: bvh.leaf_order().to_vec(),
        triangles,
    })
}
