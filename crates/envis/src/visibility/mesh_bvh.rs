//! A BVH over one triangle mesh, traversed with envis's own ray–triangle test, so a ray finds
//! exactly the hit the brute-force loop over every triangle finds. obvhs builds one binary
//! BVH2 (PLOC with SAH reinsertion), laid out twice: flat for the GPU
//! ([`MeshBvh::flat_blas`]), and collapsed to 8-wide nodes for the CPU ([`WideBvh`]), whose
//! leaves hold their triangles as one SSE packet of four ([`Packet`]).

use super::wide_bvh::{Walk, WideBvh};
use glam::Vec3;
use glam_obvhs::Vec3A as OVec3A;
use obvhs::bvh2::Bvh2;
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
    wide: WideBvh,
    /// Each leaf's triangles, four to a packet, in leaf order: a leaf reads them without going
    /// through two index arrays (a shadow ray's cache misses), and tests four at once.
    packets: Vec<Packet>,
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
        // Leaves of at most four triangles: one packet each on the CPU (obvhs's default of
        // eight tested about twice the triangles per shadow ray for the same nodes).
        let params = obvhs::BvhBuildParams {
            max_prims_per_leaf: 4,
            ..obvhs::BvhBuildParams::medium_build()
        };
        let bvh = obvhs::bvh2::builder::build_bvh2_from_tris(&triangles, params, &mut core_time);
        let leaf_triangles: Vec<[Vec3; 3]> = bvh
            .primitive_indices
            .iter()
            .map(|&i| tris[i as usize].map(|k| p[k as usize]))
            .collect();
        let mut packets = Vec::new();
        let wide = WideBvh::collapse(&bvh, |first, count| {
            let start = packets.len() as u32;
            for at in (first..first + count).step_by(LANES) {
                let lanes = (first + count - at).min(LANES as u32);
                packets.push(Packet::new(
                    at,
                    &leaf_triangles[at as usize..][..lanes as usize],
                ));
            }
            (start, packets.len() as u32 - start)
        });
        MeshBvh { wide, bvh, packets }
    }

    /// The triangles' order in the BVH's leaves (what [`Self::flat_blas`] lays out and
    /// [`super::FlatBlas::refit`] rewrites): leaf slot `k` holds triangle `leaf_order()[k]`.
    pub fn leaf_order(&self) -> &[u32] {
        &self.bvh.primitive_indices
    }

    /// The closest hit with `t` in `(t_min, t_max)` of the ray `o + t d`.
    pub fn intersect(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> Option<TriangleHit> {
        let mut best: Option<TriangleHit> = None;
        self.wide.walk((o, d), t_max, |first, count| {
            for packet in &self.packets[first as usize..][..count as usize] {
                let t_best = best.map_or(t_max, |h| h.t);
                let hits = packet.test((o, d), (t_min, t_best));
                // The nearest lane, the first of equals (as the brute-force loop keeps it).
                let mut lanes = hits.mask;
                while lanes != 0 {
                    let k = lanes.trailing_zeros() as usize;
                    lanes &= lanes - 1;
                    if best.is_none_or(|b| hits.t[k] < b.t) {
                        best = Some(TriangleHit {
                            t: hits.t[k],
                            triangle: self.bvh.primitive_indices[(packet.first + k as u32) as usize]
                                as usize,
                            u: hits.u[k],
                            v: hits.v[k],
                        });
                    }
                }
            }
            Walk::Go(best.map_or(t_max, |h| h.t))
        });
        best
    }

    /// Whether any triangle meets the ray with `t` in `(t_min, t_max)`: a shadow ray, which
    /// stops at the first hit instead of looking for the closest.
    pub fn occluded(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> bool {
        self.wide.any((o, d), t_max, |first, count| {
            self.packets[first as usize..][..count as usize]
                .iter()
                .any(|p| p.test((o, d), (t_min, t_max)).mask != 0)
        })
    }
}

/// Triangles tested together.
const LANES: usize = 4;

/// Up to [`LANES`] triangles of one leaf, lane by lane: vertex `a` and the edges `b - a`,
/// `c - a` (unused lanes: all zero, a degenerate triangle no ray meets). Lane `k` is leaf slot
/// `first + k`.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
struct Packet {
    a: [[f32; LANES]; 3],
    e1: [[f32; LANES]; 3],
    e2: [[f32; LANES]; 3],
    first: u32,
}

/// The lanes of a packet a ray meets (bit `k`: lane `k`), and where.
struct PacketHits {
    mask: u32,
    t: [f32; LANES],
    u: [f32; LANES],
    v: [f32; LANES],
}

impl Packet {
    fn new(first: u32, tris: &[[Vec3; 3]]) -> Self {
        let mut p = Packet {
            a: [[0.0; LANES]; 3],
            e1: [[0.0; LANES]; 3],
            e2: [[0.0; LANES]; 3],
            first,
        };
        for (k, &[a, b, c]) in tris.iter().enumerate() {
            let (e1, e2) = (b - a, c - a);
            for axis in 0..3 {
                (p.a[axis][k], p.e1[axis][k], p.e2[axis][k]) = (a[axis], e1[axis], e2[axis]);
            }
        }
        p
    }

    /// [`ray_triangle`] on every lane at once, with `t` in `(t_min, t_max)`: the same
    /// operations in the same order, so the same bits (`mesh_bvh_matches_brute_force`).
    #[inline(always)]
    fn test(&self, ray: (Vec3, Vec3), range: (f32, f32)) -> PacketHits {
        #[cfg(target_arch = "x86_64")]
        {
            self.test_sse(ray, range)
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            self.test_lanes(ray, range)
        }
    }

    /// [`Self::test`] in SSE (every x86-64 CPU has it): four lanes in one register.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn test_sse(&self, (o, d): (Vec3, Vec3), (t_min, t_max): (f32, f32)) -> PacketHits {
        use super::sse::*;
        let (a, e1, e2) = (load3(&self.a), load3(&self.e1), load3(&self.e2));
        let (o, d) = (splat3(o), splat3(d));
        let p = cross(d, e2);
        let det = dot(e1, p);
        let inv = div(splat(1.0), det);
        let s = sub3(o, a);
        let u = mul(dot(s, p), inv);
        let q = cross(s, e1);
        let v = mul(dot(d, q), inv);
        let t = mul(dot(e2, q), inv);
        // `ray_triangle`'s rejections (NaNs fail as there), then the caller's range on `t`.
        let hit = and(
            ge(abs(det), splat(1e-12)),
            and(ge(u, splat(0.0)), le(u, splat(1.0))),
        );
        let hit = and(
            hit,
            and(not_lt(v, splat(0.0)), not_gt(add(u, v), splat(1.0))),
        );
        let hit = and(hit, and(gt(t, splat(t_min)), lt(t, splat(t_max))));
        PacketHits {
            mask: mask(hit),
            t: store(t),
            u: store(u),
            v: store(v),
        }
    }

    /// [`Self::test`] lane by lane, for targets without the SSE copy.
    #[cfg(not(target_arch = "x86_64"))]
    fn test_lanes(&self, (o, d): (Vec3, Vec3), (t_min, t_max): (f32, f32)) -> PacketHits {
        let mut h = PacketHits {
            mask: 0,
            t: [0.0; LANES],
            u: [0.0; LANES],
            v: [0.0; LANES],
        };
        for k in 0..LANES {
            let lane = |m: &[[f32; LANES]; 3]| Vec3::new(m[0][k], m[1][k], m[2][k]);
            let (a, e1, e2) = (lane(&self.a), lane(&self.e1), lane(&self.e2));
            let p = d.cross(e2);
            let det = e1.dot(p);
            let inv = 1.0 / det;
            let s = o - a;
            let u = s.dot(p) * inv;
            let q = s.cross(e1);
            let v = d.dot(q) * inv;
            let t = e2.dot(q) * inv;
            let hit = det.abs() >= 1e-12
                && (0.0..=1.0).contains(&u)
                && !(v < 0.0 || u + v > 1.0)
                && t > t_min
                && t < t_max;
            (h.t[k], h.u[k], h.v[k]) = (t, u, v);
            h.mask |= (hit as u32) << k;
        }
        h
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
