//! The top level of the shadow BVH: built anew over every visible caster when casters come, go
//! or change (each new mesh's BVH built once), refitted when they only move.

use super::mesh::mesh_blas;
use super::posed::{PosedBlas, posed_blas};
use super::{Casters, ShadowGeometry, ShadowScene, layers_of};
use crate::pose::{Deform, Poses};
use crate::{Counters, EnvisCounters};
use bevy::math::Affine3A;
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use envis::visibility::{
    Bounds, FlatBlas, FlatBvh, FlatInstance, ObjectFromWorld, Tlas, world_bounds,
};
use std::sync::Arc;

/// The top level's parts, gathered caster by caster while it is built.
#[derive(Default)]
struct TopLevelParts {
    /// Each mesh's index in `blases` (its BVH is placed once for every instance of it).
    used: HashMap<AssetId<Mesh>, usize>,
    blases: Vec<Arc<FlatBlas>>,
    instances: Vec<Entity>,
    placed: Vec<FlatInstance>,
    object_bounds: Vec<Bounds>,
    bounds: Vec<Bounds>,
    posed: HashMap<Entity, PosedBlas>,
    triangles: usize,
}

impl TopLevelParts {
    /// The index in `blases` of a caster's BVH: a deformed caster's own, else its mesh's (added
    /// with the mesh's first instance).
    fn blas_index(&mut self, id: AssetId<Mesh>, posed: bool, blas: &Arc<FlatBlas>) -> usize {
        if posed {
            self.blases.push(blas.clone());
            self.blases.len() - 1
        } else {
            *self.used.entry(id).or_insert_with(|| {
                self.blases.push(blas.clone());
                self.blases.len() - 1
            })
        }
    }
}

/// Build the top level over every visible caster whose mesh is loaded (and each new mesh's BVH).
pub(super) fn rebuild(
    scene: &mut ShadowScene,
    geometry: &mut ShadowGeometry,
    casters: &Casters,
    (meshes, poses): (&Assets<Mesh>, &Poses),
    counters: &EnvisCounters,
) {
    let mut parts = TopLevelParts::default();
    scene.waiting = false;
    for (entity, mesh, transform, visible, render_layers, deform) in casters {
        let deform = Deform::new(deform);
        let id = mesh.id();
        if !visible.get() {
            continue;
        }
        let Some(m) = meshes.get(id) else {
            scene.waiting = true;
            continue;
        };
        let (blas, to_object, world) = if deform.is_posed() {
            let pose = (entity, deform);
            let Some(blas) =
                posed_caster_blas(scene, &mut parts.posed, (m, id), pose, poses, counters)
            else {
                scene.waiting = true; // its bind poses or joints are not there yet
                continue;
            };
            (blas, Some(ObjectFromWorld::IDENTITY), Affine3A::IDENTITY)
        } else {
            let blas = mesh_caster_blas(scene, (m, id), counters);
            let to_object = ObjectFromWorld::new(transform.affine());
            (blas, to_object, transform.affine())
        };
        let Some((b, to_object)) = blas.bounds.zip(to_object) else {
            continue; // no triangles, or a zero scale
        };
        let k = parts.blas_index(id, deform.is_posed(), &blas);
        parts.triangles += blas.triangles.len();
        parts.instances.push(entity);
        parts.placed.push(FlatInstance {
            blas: k,
            to_object,
            layers: layers_of(render_layers),
        });
        parts.object_bounds.push(b);
        parts.bounds.push(world_bounds(b, &world));
    }
    install(scene, geometry, parts, counters);
}

/// A deformed caster's own BVH, in world space, kept if its mesh is the same; `None` while its
/// bind poses or joints are not there yet. Kept or new, it goes into `posed`.
fn posed_caster_blas(
    scene: &mut ShadowScene,
    posed: &mut HashMap<Entity, PosedBlas>,
    (m, id): (&Mesh, AssetId<Mesh>),
    pose: (Entity, Deform),
    poses: &Poses,
    counters: &EnvisCounters,
) -> Option<Arc<FlatBlas>> {
    let (entity, deform) = pose;
    // A kept one is refitted when its pose changed this frame too (a pose change in the frame
    // of a structure change is not seen by `repose`).
    let old = scene.posed.remove(&entity).filter(|s| s.mesh == id);
    let old = old.and_then(|mut s| {
        (!poses.moved(entity, deform) || s.refit(m, pose, poses, counters)).then_some(s)
    });
    let s = old.or_else(|| posed_blas(m, id, pose, poses, counters))?;
    let blas = s.blas.clone();
    posed.insert(entity, s);
    Some(blas)
}

/// A mesh's BVH, in object space: built once, the first time a caster places the mesh.
fn mesh_caster_blas(
    scene: &mut ShadowScene,
    (m, id): (&Mesh, AssetId<Mesh>),
    counters: &EnvisCounters,
) -> Arc<FlatBlas> {
    scene
        .meshes
        .entry(id)
        .or_insert_with(|| {
            counters.bump(|c: &Counters| &c.shadow_bvh_builds);
            Arc::new(mesh_blas(m))
        })
        .clone()
}

/// The gathered parts become the scene's: meshes no caster uses are dropped, the top level is
/// built over the instances' world bounds and the geometry's new generation flattened.
fn install(
    scene: &mut ShadowScene,
    geometry: &mut ShadowGeometry,
    parts: TopLevelParts,
    counters: &EnvisCounters,
) {
    let TopLevelParts {
        used,
        blases,
        instances,
        placed,
        object_bounds,
        bounds,
        posed,
        triangles,
    } = parts;
    scene.meshes.retain(|id, _| used.contains_key(id));
    scene.posed = posed;
    let tlas = Tlas::build(&bounds);
    let bvh = FlatBvh::build(&blases, &placed, &tlas).unwrap_or_else(|e| {
        error!("envis: no shadows: {e}");
        FlatBvh::default()
    });
    (scene.instances, scene.placed, scene.blases) = (instances, placed, blases);
    (scene.object_bounds, scene.tlas) = (object_bounds, tlas);
    *geometry = ShadowGeometry {
        generation: geometry.generation + 1,
        placement: geometry.placement + 1,
        bvh,
        triangles,
    };
    counters.bump(|c: &Counters| &c.shadow_tlas_builds);
}

/// Instances moved: their new transforms into the records, the top level refitted. `false`
/// when that cannot be done (an instance is gone or lost its inverse): build anew instead.
pub(super) fn refit(
    scene: &mut ShadowScene,
    geometry: &mut ShadowGeometry,
    casters: &Casters,
) -> bool {
    if !place_instances(scene, casters) {
        return false;
    }
    if geometry.bvh.place(&scene.placed, &scene.tlas).is_err() {
        return false;
    }
    geometry.placement += 1;
    true
}

/// Every instance's record and world bounds from its transform now (a deformed one stays in
/// world space, with its BVH's bounds), and the top level refitted to them.
pub(super) fn place_instances(scene: &mut ShadowScene, casters: &Casters) -> bool {
    let mut bounds: Vec<Bounds> = Vec::with_capacity(scene.instances.len());
    for (i, &entity) in scene.instances.iter().enumerate() {
        let Ok((_, _, transform, _, _, deform)) = casters.get(entity) else {
            return false;
        };
        if Deform::new(deform).is_posed() {
            bounds.push(scene.object_bounds[i]);
            continue;
        }
        let Some(to_object) = ObjectFromWorld::new(transform.affine()) else {
            return false;
        };
        scene.placed[i].to_object = to_object;
        bounds.push(world_bounds(scene.object_bounds[i], &transform.affine()));
    }
    scene.tlas.refit(&bounds)
}
