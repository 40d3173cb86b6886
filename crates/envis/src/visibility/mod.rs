//! Visibility: ray casts against the scene's geometry through bounding volume hierarchies built
//! with `obvhs`, in two levels: one BVH per triangle mesh in object space ([`MeshBvh`], built
//! once per mesh) and a top level over the placed instances ([`Tlas`], refitted when they move).
//! They serve the CPU G-buffer's ray cast and the shadow rays of the estimator ([`Occluder`]);
//! [`FlatBvh`] is both levels laid out for the GPU, with its CPU twin traversal.
//!
//! `obvhs` works in glam 0.33 (its range is 0.33–0.34) while envis (with Bevy) uses glam 0.32: vectors cross the boundary
//! as plain `[f32; 3]` arrays, here and nowhere else.

mod flat_bvh;
mod instances;
mod mesh_bvh;
pub mod morph;
mod point;
pub mod skin;
#[cfg(target_arch = "x86_64")]
mod sse;
mod wide_bvh;

pub use flat_bvh::{
    FlatBlas, FlatBvh, FlatInstance, FlatMeshes, FlatNode, FlatTop, Layers, STACK_SIZE,
};
pub use flat_bvh::{inverse, slab_hit};
pub use instances::{Bounds, ObjectFromWorld, Tlas, world_bounds};
pub use mesh_bvh::{MeshBvh, TriangleHit, ray_triangle};
pub use point::{Hull, MAX_REACH, Reach, ShadowPoint};

use glam::Vec3;

/// Answers the estimator's one question about the scene: is direction `d` blocked, seen from
/// the surface point `p` with shading normal `n`? A sample the answer blocks contributes nothing;
/// its density is unchanged, so the estimate stays unbiased for the integrand with visibility.
pub trait Occluder: Sync {
    fn occluded(&self, p: Vec3, n: Vec3, d: Vec3) -> bool;

    /// What every shadow ray from `p` (normal `n`) shares, set up once per pixel for
    /// [`Self::occluded_from`]. By default only the point: no culling.
    fn at_point(&self, p: Vec3, n: Vec3) -> ShadowPoint {
        ShadowPoint::new(p, n)
    }

    /// [`Self::occluded`] for the point `at` was set up for: the same answer, sooner.
    fn occluded_from(&self, at: &ShadowPoint, d: Vec3) -> bool {
        self.occluded(at.p, at.n, d)
    }
}

/// Whether shadow rays are cast (`--visibility`, a scene file's `[sampling] visibility`,
/// `EnvironmentSampling::shadows`). Named so that it does not clash with Bevy's `Visibility`
/// in a Bevy user's `use bevy::prelude::*; use bevy_envis::prelude::*;`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
// Reflected for the Bevy camera component (`bevy_envis::EnvironmentSampling`, feature `bevy`).
#[cfg_attr(feature = "bevy", derive(bevy_reflect::Reflect))]
pub enum ShadowRays {
    /// On when some object can shadow a visible point: two or more shadow-casting objects, or
    /// one that is not known to be convex; off for a lone convex object.
    #[default]
    Auto,
    On,
    Off,
}
crate::display_as_serde_name!(ShadowRays);

/// How far a shadow ray starts from its surface, along the normal: relative to the point's
/// distance from the origin (f32 positions carry about 1e-7 of it in error), with a floor.
/// Large enough that no surface shadows itself (no acne), small enough that a ray leaving a
/// plane next to a resting sphere's contact point still hits the sphere (no leak); both are
/// tested.
#[inline]
pub fn ray_offset(p: Vec3) -> f32 {
    1e-4 * p.abs().max_element().max(1.0)
}

/// The origin of a shadow ray from `p` (normal `n`) towards `d`: pushed off the surface on the
/// side `d` leaves by.
#[inline]
pub fn shadow_origin(p: Vec3, n: Vec3, d: Vec3) -> Vec3 {
    let side = if n.dot(d) >= 0.0 { 1.0 } else { -1.0 };
    p + n * (side * ray_offset(p))
}
