//! Two-level ray casting: meshes in object space, each with one bottom-level BVH
//! ([`super::MeshBvh`]) built once, placed any number of times by instances, and a top-level BVH
//! ([`Tlas`], obvhs's BVH2 over the instances' world bounds) that is refitted when instances move.
//! A ray reaching an instance is carried into its object space by [`ObjectFromWorld`]; its
//! direction is not renormalised, so a hit's `t` is the same in both spaces.

use glam::{Affine3A, Vec3};
use glam_obvhs::Vec3A as OVec3A;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::ray::{Ray, RayHit};

/// An axis-aligned box: `(min, max)`.
pub type Bounds = (Vec3, Vec3);

/// Object space from world space: the rows of a 3 × 4 affine matrix, the instance record the GPU
/// reads (`shaders/visibility.wgsl`), with the arithmetic both CPU traversals share.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObjectFromWorld(pub [[f32; 4]; 3]);

impl ObjectFromWorld {
    /// The inverse of `world_from_object`, or `None` when it has none (a zero scale) or is not
    /// finite: such an instance has no volume to block anything.
    pub fn new(world_from_object: Affine3A) -> Option<Self> {
        let inv = world_from_object.inverse();
        let m = inv.matrix3;
        let rows = [0, 1, 2].map(|r| m.row(r).extend(inv.translation[r]).to_array());
        rows.iter()
            .flatten()
            .all(|x| x.is_finite())
            .then_some(ObjectFromWorld(rows))
    }

    pub const IDENTITY: Self = ObjectFromWorld([
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ]);

    #[inline]
    fn row(&self, r: usize) -> (Vec3, f32) {
        let [x, y, z, w] = self.0[r];
        (Vec3::new(x, y, z), w)
    }

    /// A point into object space.
    #[inline]
    pub fn point(&self, p: Vec3) -> Vec3 {
        let [(a, ta), (b, tb), (c, tc)] = [0, 1, 2].map(|r| self.row(r));
        Vec3::new(a.dot(p) + ta, b.dot(p) + tb, c.dot(p) + tc)
    }

    /// A direction into object space (not renormalised: `t` is kept).
    #[inline]
    pub fn vector(&self, d: Vec3) -> Vec3 {
        let [(a, _), (b, _), (c, _)] = [0, 1, 2].map(|r| self.row(r));
        Vec3::new(a.dot(d), b.dot(d), c.dot(d))
    }

    /// An object-space normal into world space (by the inverse transpose, which is this
    /// matrix's transpose), unit length.
    #[inline]
    pub fn normal_to_world(&self, n: Vec3) -> Vec3 {
        let [(a, _), (b, _), (c, _)] = [0, 1, 2].map(|r| self.row(r));
        (a * n.x + b * n.y + c * n.z).normalize_or_zero()
    }
}

/// The world bounds of the box `b` placed by `world_from_object` (its eight corners).
pub fn world_bounds(b: Bounds, world_from_object: &Affine3A) -> Bounds {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for k in 0..8 {
        let c = Vec3::new(
            if k & 1 == 0 { b.0.x } else { b.1.x },
            if k & 2 == 0 { b.0.y } else { b.1.y },
            if k & 4 == 0 { b.0.z } else { b.1.z },
        );
        let w = world_from_object.transform_point3(c);
        lo = lo.min(w);
        hi = hi.max(w);
    }
    (lo, hi)
}

pub(super) fn ovec(v: Vec3) -> OVec3A {
    OVec3A::from_array(v.to_array())
}

fn aabb(b: Bounds) -> Aabb {
    Aabb::new(ovec(b.0), ovec(b.1))
}

/// The top-level BVH: obvhs's BVH2 over instance bounds, one instance per leaf (the GPU layout
/// keeps an instance's BLAS root in its leaf).
#[derive(Clone, Default)]
pub struct Tlas {
    pub(super) bvh: Bvh2,
    instances: usize,
    /// Levels below the root (the any-hit walk's fixed stack needs it below [`STACK`]).
    depth: usize,
}

/// The any-hit walk's stack (small: it is set up for every shadow ray); a deeper top level
/// (only from a build over thousands of instances, or a degenerate one) is walked by obvhs.
const STACK: usize = 32;

impl std::fmt::Debug for Tlas {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Tlas({} instances)", self.instances)
    }
}

impl Tlas {
    /// Build over the world bounds of each instance (instance `i` is `bounds[i]`).
    pub fn build(bounds: &[Bounds]) -> Self {
        if bounds.is_empty() {
            return Tlas::default();
        }
        let boxes: Vec<Aabb> = bounds.iter().map(|b| aabb(*b)).collect();
        let params = obvhs::BvhBuildParams {
            max_prims_per_leaf: 1,
            ..obvhs::BvhBuildParams::medium_build()
        };
        let mut bvh = obvhs::bvh2::builder::build_bvh2(&boxes, params, &mut Default::default());
        bvh.init_primitives_to_nodes_if_uninit();
        Tlas {
            depth: bvh.depth(0),
            bvh,
            instances: bounds.len(),
        }
    }

    /// Instances in it.
    pub fn len(&self) -> usize {
        self.instances
    }

    pub fn is_empty(&self) -> bool {
        self.instances == 0
    }

    /// Move the instances: new bounds for the same instances, the tree kept (its boxes refitted
    /// bottom-up). Returns `false`, changing nothing, when the count differs (then build anew).
    pub fn refit(&mut self, bounds: &[Bounds]) -> bool {
        if bounds.len() != self.instances {
            return false;
        }
        for (i, b) in bounds.iter().enumerate() {
            let node = self.bvh.primitives_to_nodes[i] as usize;
            self.bvh.nodes[node].set_aabb(aabb(*b));
        }
        self.bvh.refit_all();
        true
    }

    /// The closest hit of the ray with `t < t_max`: `hit(instance, t_max so far)` answers an
    /// instance's closest `t`, if any. Returns the instance hit and its answer.
    pub fn closest<H: Copy>(
        &self,
        o: Vec3,
        d: Vec3,
        t_max: f32,
        mut hit: impl FnMut(usize, f32) -> Option<(f32, H)>,
    ) -> Option<(usize, H)> {
        if self.instances == 0 {
            return None;
        }
        let mut best = None;
        let ray = Ray::new(ovec(o), ovec(d), 0.0, t_max);
        self.bvh
            .ray_traverse(ray, &mut RayHit::none(), |ray, slot| {
                let i = self.bvh.primitive_indices[slot] as usize;
                match hit(i, ray.tmax) {
                    Some((t, h)) => {
                        best = Some((i, h));
                        t
                    }
                    None => f32::INFINITY,
                }
            });
        best
    }

    /// Whether `blocked(instance)` holds for some instance whose bounds the ray meets before
    /// `t_max`. A shadow ray's first step, so written out for speed: a fixed stack and obvhs's
    /// slab test (12% more shadow rays per second than obvhs's generic traversal on
    /// `assets/scenes/occluded.toml`).
    pub fn any(
        &self,
        o: Vec3,
        d: Vec3,
        t_max: f32,
        mut blocked: impl FnMut(usize) -> bool,
    ) -> bool {
        if self.instances == 0 {
            return false;
        }
        if self.depth >= STACK {
            let ray = Ray::new(ovec(o), ovec(d), 0.0, t_max);
            return !self.bvh.ray_traverse_miss(ray, |_, slot| {
                if blocked(self.bvh.primitive_indices[slot] as usize) {
                    0.0
                } else {
                    f32::INFINITY
                }
            });
        }
        let inv = super::flat_bvh::inverse(d);
        let mut stack = [0u32; STACK];
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let n = &self.bvh.nodes[stack[sp] as usize];
            let b = n.aabb();
            let (lo, hi) = (Vec3::from(b.min.to_array()), Vec3::from(b.max.to_array()));
            if !super::flat_bvh::slab_hit(lo, hi, o, inv, t_max) {
                continue;
            }
            if n.prim_count > 0 {
                let prims = n.first_index as usize..(n.first_index + n.prim_count) as usize;
                if self.bvh.primitive_indices[prims]
                    .iter()
                    .any(|&i| blocked(i as usize))
                {
                    return true;
                }
            } else {
                stack[sp] = n.first_index + 1;
                stack[sp + 1] = n.first_index;
                sp += 2;
            }
        }
        false
    }
}
