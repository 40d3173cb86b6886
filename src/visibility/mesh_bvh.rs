//! A BVH over one triangle mesh, traversed with envis's own ray–triangle test, so a ray finds
//! exactly the hit the brute-force loop over every triangle finds. Two of obvhs's layouts, both
//! PLOC builds with SAH reinsertion: the binary BVH2, which is what the GPU traverses
//! ([`MeshBvh::flat_blas`]), and the compressed 8-wide CWBVH, which the CPU traverses (its
//! SIMD node tests make a shadow ray about twice as fast as through the BVH2 here).

use glam::Vec3;
use glam_obvhs::Vec3A as OVec3A;
use obvhs::bvh2::Bvh2;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;

/// The closest hit of a ray: distance, triangle index and barycentrics `(u, v)` of vertices 1, 2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    pub t: f32,
    pub triangle: usize,
    pub u: f32,
    pub v: f32,
}

/// The BVH of one mesh (its triangles as given: positions `p`, index triples `tris`).
#[derive(Clone)]
pub struct MeshBvh {
    pub(super) bvh: Bvh2,
    cw: CwBvh,
    /// The triangles' vertices in the CWBVH's leaf order: a leaf reads them without going
    /// through two index arrays (a shadow ray's cache misses).
    leaf_triangles: Vec<[Vec3; 3]>,
}

impl std::fmt::Debug for MeshBvh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "MeshBvh({} nodes)", self.bvh.nodes.len())
    }
}

fn ovec(v: Vec3) -> OVec3A {
    OVec3A::from_array(v.to_array())
}

impl MeshBvh {
    /// Build over the triangles `tris` of vertices `p` (indices must be in range).
    pub fn build(p: &[Vec3], tris: &[[u32; 3]]) -> Self {
        let triangles: Vec<Triangle> = tris
            .iter()
            .map(|t| {
                let [v0, v1, v2] = t.map(|i| ovec(p[i as usize]));
                Triangle { v0, v1, v2 }
            })
            .collect();
        let mut core_time = std::time::Duration::ZERO;
        let params = obvhs::BvhBuildParams::medium_build();
        let bvh = obvhs::bvh2::builder::build_bvh2_from_tris(&triangles, params, &mut core_time);
        let cw = obvhs::cwbvh::builder::build_cwbvh_from_tris(&triangles, params, &mut core_time);
        let leaf_triangles = cw
            .primitive_indices
            .iter()
            .map(|&i| tris[i as usize].map(|k| p[k as usize]))
            .collect();
        MeshBvh {
            bvh,
            cw,
            leaf_triangles,
        }
    }

    /// The closest hit with `t` in `(t_min, t_max)` of the ray `o + t d`.
    pub fn intersect(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> Option<TriangleHit> {
        if self.leaf_triangles.is_empty() {
            return None;
        }
        let ray = Ray::new(ovec(o), ovec(d), t_min, t_max);
        let mut hit = RayHit::none();
        let mut best = None;
        self.cw.ray_traverse(ray, &mut hit, |ray, slot| {
            match self.slot_hit((o, d), (t_min, ray.tmax), slot) {
                Some(h) => {
                    best = Some(h);
                    h.t
                }
                None => f32::INFINITY,
            }
        });
        best
    }

    /// Whether any triangle meets the ray with `t` in `(t_min, t_max)`: a shadow ray, which
    /// stops at the first hit instead of looking for the closest.
    pub fn occluded(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> bool {
        if self.leaf_triangles.is_empty() {
            return false;
        }
        let ray = Ray::new(ovec(o), ovec(d), t_min, t_max);
        !self.cw.ray_traverse_miss(ray, |ray, slot| {
            self.slot_hit((o, d), (t_min, ray.tmax), slot)
                .map_or(f32::INFINITY, |h| h.t)
        })
    }

    /// The hit of ray `(o, d)` on the triangle in CWBVH primitive slot `slot`, with `t` in
    /// `(t_min, t_max)`: what both traversals test at a leaf.
    #[inline(always)]
    fn slot_hit(
        &self,
        (o, d): (Vec3, Vec3),
        (t_min, t_max): (f32, f32),
        slot: usize,
    ) -> Option<TriangleHit> {
        let [a, b, c] = self.leaf_triangles[slot];
        match ray_triangle(o, d, a, b, c) {
            Some((t, u, v)) if t > t_min && t < t_max => Some(TriangleHit {
                t,
                triangle: self.cw.primitive_indices[slot] as usize,
                u,
                v,
            }),
            _ => None,
        }
    }
}

/// Möller–Trumbore: `(t, u, v)` where the ray meets triangle `(a, b, c)`, any `t`.
#[inline]
pub fn ray_triangle(o: Vec3, d: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Option<(f32, f32, f32)> {
    let (e1, e2) = (b - a, c - a);
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-12 {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    Some((e2.dot(q) * inv, u, v))
}
