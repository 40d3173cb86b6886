//! The traversal of the flattened BVH (`bvh_occluded` in `shaders/visibility.wgsl`, step for
//! step): the top level over instances, then each instance's mesh in its object space.

use super::{FlatBvh, FlatNode, Layers, STACK_SIZE};
use crate::visibility::instances::ObjectFromWorld;
use crate::visibility::ray_triangle;
use glam::Vec3;

impl FlatBvh {
    /// Whether any triangle meets the ray with `t` in `(t_min, t_max)`, every instance counted
    /// ([`Self::occluded_on`] for [`Layers::ALL`]).
    pub fn occluded(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> bool {
        self.occluded_on(o, d, t_min, t_max, Layers::ALL)
    }

    /// Whether a triangle of an instance on one of `layers` meets the ray with `t` in
    /// `(t_min, t_max)`: the traversal of `bvh_occluded` in `shaders/visibility.wgsl`, step for
    /// step: the top level, and at each instance leaf on those layers its mesh, the ray carried
    /// into object space.
    pub fn occluded_on(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32, layers: Layers) -> bool {
        if self.top.nodes.is_empty() {
            return false;
        }
        self.walk(0, o, d, t_max, |n| {
            if !Layers::from_record(self.triangle(n.first + 1)).meet(layers) {
                return false;
            }
            let m = ObjectFromWorld(self.triangle(n.first));
            self.blas_occluded(n.count, m.point(o), m.vector(d), t_min, t_max)
        })
    }

    /// [`Self::occluded`] within one mesh from its `root`, the ray in its object space
    /// (`blas_occluded` in the WGSL).
    fn blas_occluded(&self, root: u32, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> bool {
        self.walk(root, o, d, t_max, |n| {
            (n.first..n.first + n.count).any(|k| {
                let [a, b, c] = self.triangle(k).map(|v| Vec3::new(v[0], v[1], v[2]));
                ray_triangle(o, d, a, b, c).is_some_and(|(t, _, _)| t > t_min && t < t_max)
            })
        })
    }

    /// The stack walk both levels share (the WGSL writes it out twice): from `root`, every node
    /// whose box the ray meets before `t_max`, inner nodes' children pushed second child first,
    /// until `leaf` answers `true` for a leaf.
    #[inline(always)]
    fn walk(
        &self,
        root: u32,
        o: Vec3,
        d: Vec3,
        t_max: f32,
        mut leaf: impl FnMut(FlatNode) -> bool,
    ) -> bool {
        let inv = inverse(d);
        let mut stack = [0u32; STACK_SIZE];
        stack[0] = root;
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let n = self.node(stack[sp]);
            if !slab(&n, o, inv, t_max) {
                continue;
            }
            if n.count > 0 {
                if leaf(n) {
                    return true;
                }
            } else if sp + 2 <= STACK_SIZE {
                stack[sp] = n.first + 1;
                stack[sp + 1] = n.first;
                sp += 2;
            }
        }
        false
    }
}

/// obvhs's `safe_inverse`: `1 / x`, or `±1 / EPSILON` for `|x| <= EPSILON`.
#[inline]
fn safe_inverse(x: f32) -> f32 {
    if x.abs() <= f32::EPSILON {
        x.signum() / f32::EPSILON
    } else {
        1.0 / x
    }
}

/// `1 / d` per component, finite where a component is 0 (obvhs's convention).
#[inline]
pub fn inverse(d: Vec3) -> Vec3 {
    Vec3::new(safe_inverse(d.x), safe_inverse(d.y), safe_inverse(d.z))
}

/// The ray meets the node's box before `t_max` (obvhs's slab test).
#[inline]
fn slab(n: &FlatNode, o: Vec3, inv: Vec3, t_max: f32) -> bool {
    slab_hit(Vec3::from(n.min), Vec3::from(n.max), o, inv, t_max)
}

/// The ray `o + t d` (`inv` = 1 / `d`) meets the box `[lo, hi]` at some `t` in `[0, t_max)`.
#[inline]
pub fn slab_hit(lo: Vec3, hi: Vec3, o: Vec3, inv: Vec3, t_max: f32) -> bool {
    let t1 = (lo - o) * inv;
    let t2 = (hi - o) * inv;
    let (near, far) = (t1.min(t2).max_element(), t1.max(t2).min_element());
    far >= near && far >= 0.0 && near < t_max
}

/// A flattened BVH as the scene's occluder: the CPU twin of the GPU's shadow rays (the same
/// origin offset, `t_min` 1e-4, no `t_max`).
impl crate::visibility::Occluder for FlatBvh {
    fn occluded(&self, p: Vec3, n: Vec3, d: Vec3) -> bool {
        self.occluded(crate::visibility::shadow_origin(p, n, d), d, 1e-4, f32::MAX)
    }
}
