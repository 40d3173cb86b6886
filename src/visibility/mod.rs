//! Visibility: ray casts against the scene's geometry through bounding volume hierarchies built
//! with `obvhs`. Today: one BVH per triangle mesh ([`MeshBvh`]), used by the CPU G-buffer's ray
//! cast; the shadow rays of issue 13 (two-level instances, the WGSL twin) build on it.
//!
//! `obvhs` works in glam 0.33 (its range is 0.33–0.34) while envis (with Bevy) uses glam 0.32: vectors cross the boundary
//! as plain `[f32; 3]` arrays, here and nowhere else.

mod mesh_bvh;

pub use mesh_bvh::{MeshBvh, TriangleHit, ray_triangle};
