//! The CPU's layout of a mesh BVH: obvhs's BVH2 collapsed to 8-wide nodes whose children's
//! boxes are full-precision `f32`, one array per axis and side.
//!
//! Why not obvhs's own 8-wide CWBVH: its child boxes are quantised to a byte per side, and a
//! shadow ray spends most of each node decoding them back to floats. Counted with callgrind on
//! `assets/scenes/occluded.toml` (128², the bunny's shadow rays): a walk of the CWBVH took about
//! 1,900 instructions, one of this layout (SSE slab tests, leaves as triangle packets) about
//! 900, with the same answers. obvhs still builds the tree (PLOC with SAH reinsertion); this
//! file only lays it out, as `flat_bvh.rs` does for the GPU.
//!
//! The boxes are the BVH2's, padded outwards by a relative 2^-20, so rounding in a slab test can
//! never drop a triangle a ray meets: every answer is the triangle test's, as with the
//! brute-force loop (`envis/tests/core/scenes.rs`, `mesh_bvh_matches_brute_force`).

use super::flat_bvh::inverse;
use glam::Vec3;
use obvhs::bvh2::Bvh2;

/// Children per node.
const WIDTH: usize = 8;

/// A node's children: lane `k` is child `k`. An inner child's `count` is 0 and `index` its node;
/// a leaf's is what the caller of [`WideBvh::collapse`] gave for it (for a mesh: its first
/// triangle packet and how many). Unused lanes have an empty box
/// (`lo = +inf`, `hi = -inf`), which no ray meets.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
struct Node {
    /// `bounds[side][axis][lane]`: side 0 the box's minimum, side 1 its maximum.
    bounds: [[[f32; WIDTH]; 3]; 2],
    index: [u32; WIDTH],
    count: [u32; WIDTH],
}

impl Node {
    const EMPTY: Node = Node {
        bounds: [[[f32::INFINITY; WIDTH]; 3], [[f32::NEG_INFINITY; WIDTH]; 3]],
        index: [0; WIDTH],
        count: [0; WIDTH],
    };

    /// The lanes whose box the ray `r` meets at some `t` in `[0, t_max]`, as a bit mask.
    #[inline(always)]
    fn hits(&self, r: &SlabRay, t_max: f32) -> u32 {
        #[cfg(target_arch = "x86_64")]
        {
            self.hits_sse(r, t_max)
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            self.hits_lanes(r, t_max)
        }
    }

    /// [`Self::hits`], four lanes at a time in SSE (every x86-64 CPU has it).
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn hits_sse(&self, r: &SlabRay, t_max: f32) -> u32 {
        use super::sse::*;
        let b = &self.bounds;
        let (o, inv) = (splat3(r.o), splat3(r.inv));
        let (zero, t_max) = (splat(0.0), splat(t_max));
        let mut mask = 0;
        for half in 0..2 {
            let lanes = |side: usize, axis: usize| -> &[f32; 4] {
                b[side][axis][4 * half..][..4].try_into().unwrap()
            };
            let t =
                |side: usize, axis: usize| mul(sub(load(lanes(side, axis)), o[axis]), inv[axis]);
            let [nx, ny, nz] = r.near;
            let near = max(max(t(nx, 0), t(ny, 1)), max(t(nz, 2), zero));
            let far = min(min(t(1 - nx, 0), t(1 - ny, 1)), min(t(1 - nz, 2), t_max));
            mask |= super::sse::mask(le(near, far)) << (4 * half);
        }
        mask
    }

    /// [`Self::hits`] lane by lane, for targets without the SSE copy.
    #[cfg(not(target_arch = "x86_64"))]
    fn hits_lanes(&self, r: &SlabRay, t_max: f32) -> u32 {
        let [nx, ny, nz] = r.near;
        let b = &self.bounds;
        let mut mask = 0u32;
        for k in 0..WIDTH {
            let tx0 = (b[nx][0][k] - r.o.x) * r.inv.x;
            let tx1 = (b[1 - nx][0][k] - r.o.x) * r.inv.x;
            let ty0 = (b[ny][1][k] - r.o.y) * r.inv.y;
            let ty1 = (b[1 - ny][1][k] - r.o.y) * r.inv.y;
            let tz0 = (b[nz][2][k] - r.o.z) * r.inv.z;
            let tz1 = (b[1 - nz][2][k] - r.o.z) * r.inv.z;
            let near = max(max(tx0, ty0), max(tz0, 0.0));
            let far = min(min(tx1, ty1), min(tz1, t_max));
            mask |= ((near <= far) as u32) << k;
        }
        mask
    }
}

// `f32::max` and `min` order NaNs, which costs a blend per call; no NaN reaches the slab tests
// (finite `1 / d`, boxes of finite or infinite bounds whose differences from a finite origin are
// never `inf - inf`), and these are SSE's `maxps` / `minps`.
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn max(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn min(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

/// A ray as the slab tests read it: origin, `1 / d` (finite) and, per axis, the side of a box
/// it enters by (1 where `d` is negative on that axis).
struct SlabRay {
    o: Vec3,
    inv: Vec3,
    near: [usize; 3],
}

impl SlabRay {
    fn new(o: Vec3, d: Vec3) -> Self {
        let inv = inverse(d);
        SlabRay {
            o,
            inv,
            near: inv.to_array().map(|v| (v < 0.0) as usize),
        }
    }
}

/// The deepest stack a walk needs before it falls back to a growable one: enough for any tree
/// obvhs builds over meshes of millions of triangles (each level adds at most seven entries).
const STACK: usize = 128;

/// A mesh's BVH as 8-wide nodes (the root is node 0; none for an empty mesh).
#[derive(Clone, Debug, Default)]
pub struct WideBvh {
    nodes: Vec<Node>,
}

impl WideBvh {
    /// `bvh` (obvhs's BVH2, leaves holding ranges of `bvh.primitive_indices`) collapsed: each
    /// wide node takes a BVH2 node's two children and keeps opening its largest inner child
    /// (by surface area) until it has eight, so a leaf's triangles stay the BVH2 leaf's range.
    /// `leaf(first, count)` turns each leaf's range into the `(index, count)` (count > 0) that
    /// the walk will hand back for it.
    pub fn collapse(bvh: &Bvh2, mut leaf: impl FnMut(u32, u32) -> (u32, u32)) -> Self {
        // An empty mesh has no tree (obvhs may still give a root, a leaf of nothing).
        let Some(root) = bvh
            .nodes
            .first()
            .filter(|_| !bvh.primitive_indices.is_empty())
        else {
            return WideBvh::default();
        };
        let mut nodes = vec![Node::EMPTY];
        // (wide node to fill, BVH2 nodes it holds).
        let mut todo = vec![(
            0usize,
            if root.is_leaf() {
                vec![0]
            } else {
                children(bvh, 0)
            },
        )];
        while let Some((at, mut kids)) = todo.pop() {
            while kids.len() < WIDTH {
                let widest = kids
                    .iter()
                    .enumerate()
                    .filter(|(_, k)| !bvh.nodes[**k].is_leaf())
                    .max_by(|a, b| half_area(bvh, *a.1).total_cmp(&half_area(bvh, *b.1)));
                let Some((slot, &open)) = widest else { break };
                kids.swap_remove(slot);
                kids.extend(children(bvh, open));
            }
            for (k, &kid) in kids.iter().enumerate() {
                let n = &bvh.nodes[kid];
                let (lo, hi) = padded(n);
                for axis in 0..3 {
                    nodes[at].bounds[0][axis][k] = lo[axis];
                    nodes[at].bounds[1][axis][k] = hi[axis];
                }
                if n.is_leaf() {
                    let (index, count) = leaf(n.first_index, n.prim_count);
                    debug_assert!(count > 0, "a leaf's count must tell it from an inner node");
                    (nodes[at].index[k], nodes[at].count[k]) = (index, count);
                } else {
                    nodes[at].index[k] = nodes.len() as u32;
                    nodes.push(Node::EMPTY);
                    todo.push((nodes.len() - 1, children(bvh, kid)));
                }
            }
        }
        WideBvh { nodes }
    }

    /// Whether `leaf_hit(index, count)` (one leaf, as `collapse` was told) says the ray
    /// `(o, d)` is blocked within `t_max`, for some leaf whose box the ray meets: a shadow
    /// ray, which stops at the first leaf that answers yes.
    #[inline(always)]
    pub fn any(
        &self,
        (o, d): (Vec3, Vec3),
        t_max: f32,
        mut leaf_hit: impl FnMut(u32, u32) -> bool,
    ) -> bool {
        let mut blocked = false;
        self.walk((o, d), t_max, |first, count| {
            blocked = leaf_hit(first, count);
            if blocked { Walk::Stop } else { Walk::Go(t_max) }
        });
        blocked
    }

    /// The walk every query shares: each leaf the ray meets within the current `t_max` is
    /// passed to `leaf` (its index and count), which says whether to go on and with
    /// what `t_max` (a closest-hit query shortens it as it finds hits).
    #[inline(always)]
    pub fn walk(&self, (o, d): (Vec3, Vec3), t_max: f32, mut leaf: impl FnMut(u32, u32) -> Walk) {
        if self.nodes.is_empty() {
            return;
        }
        let ray = SlabRay::new(o, d);
        let mut t_max = t_max;
        // Not zeroed: only slots below `sp` are read, and all were written.
        let mut stack = [std::mem::MaybeUninit::<u32>::uninit(); STACK];
        stack[0].write(0);
        let mut spill: Vec<u32> = Vec::new();
        let mut sp = 1usize;
        loop {
            let node = if sp > 0 {
                sp -= 1;
                // SAFETY: slots below `sp` were written by the pushes (or the root's) above.
                unsafe { stack[sp].assume_init() }
            } else if let Some(n) = spill.pop() {
                n
            } else {
                return;
            };
            let node = &self.nodes[node as usize];
            let mut mask = node.hits(&ray, t_max);
            while mask != 0 {
                let k = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                match node.count[k] {
                    0 if sp < STACK => {
                        stack[sp].write(node.index[k]);
                        sp += 1;
                    }
                    0 => spill.push(node.index[k]),
                    count => match leaf(node.index[k], count) {
                        Walk::Stop => return,
                        Walk::Go(t) => t_max = t,
                    },
                }
            }
        }
    }
}

/// What a walk does after a leaf.
pub enum Walk {
    Stop,
    /// Go on, meeting boxes only up to this distance.
    Go(f32),
}

fn children(bvh: &Bvh2, i: usize) -> Vec<usize> {
    let first = bvh.nodes[i].first_index as usize;
    vec![first, first + 1]
}

fn half_area(bvh: &Bvh2, i: usize) -> f32 {
    bvh.nodes[i].aabb().half_area()
}

/// A BVH2 node's box, pushed out by 2^-20 of its largest coordinate (and at least 2^-40), so a
/// slab test's rounding keeps every triangle inside it reachable.
fn padded(n: &obvhs::bvh2::node::Bvh2Node) -> ([f32; 3], [f32; 3]) {
    let (lo, hi) = (n.aabb().min.to_array(), n.aabb().max.to_array());
    let size = lo.iter().chain(&hi).fold(0.0f32, |m, v| m.max(v.abs()));
    let pad = (size * 2f32.powi(-20)).max(2f32.powi(-40));
    (lo.map(|v| v - pad), hi.map(|v| v + pad))
}
