//! The BVH as the GPU reads it: obvhs's BVH2 nodes flattened to plain arrays (32 bytes a node)
//! and the triangles reordered into leaf order, with the traversal `shaders/visibility.wgsl`
//! runs written here in the same order and arithmetic: the CPU twin of the WGSL, and the layout
//! the GPU buffers are uploaded from.

use super::{MeshBvh, ray_triangle};
use glam::Vec3;

/// Most nodes a traversal keeps on its stack (the WGSL's array size); a deeper BVH is refused.
pub const STACK_SIZE: usize = 64;

/// One node: inner (`count == 0`, children at `first` and `first + 1`) or leaf (`count`
/// triangles from `first`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "gpu", derive(bytemuck::Pod, bytemuck::Zeroable))]
pub struct FlatNode {
    pub min: [f32; 3],
    pub first: u32,
    pub max: [f32; 3],
    pub count: u32,
}

/// A BVH over a triangle soup, ready to upload.
#[derive(Clone, Debug, Default)]
pub struct FlatBvh {
    pub nodes: Vec<FlatNode>,
    /// Triangle `i` of the leaves is `triangles[i]` (vertices as `[x, y, z, 0]`).
    pub triangles: Vec<[[f32; 4]; 3]>,
}

impl MeshBvh {
    /// The flat layout of this BVH over `tris` of vertices `p`, or why the GPU could not
    /// traverse it (deeper than [`STACK_SIZE`]).
    pub fn flatten(&self, p: &[Vec3], tris: &[[u32; 3]]) -> Result<FlatBvh, String> {
        if self.bvh.nodes.is_empty() || tris.is_empty() {
            return Ok(FlatBvh::default()); // nothing to trace (obvhs's depth needs a root)
        }
        let depth = self.bvh.depth(0);
        if depth >= STACK_SIZE {
            return Err(format!(
                "a BVH {depth} levels deep is beyond the GPU traversal's stack of {STACK_SIZE}"
            ));
        }
        let nodes = self
            .bvh
            .nodes
            .iter()
            .map(|n| FlatNode {
                min: n.aabb().min.to_array(),
                first: n.first_index,
                max: n.aabb().max.to_array(),
                count: n.prim_count,
            })
            .collect();
        let triangles = self
            .bvh
            .primitive_indices
            .iter()
            .map(|&i| tris[i as usize].map(|k| p[k as usize].extend(0.0).to_array()))
            .collect();
        Ok(FlatBvh { nodes, triangles })
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

impl FlatBvh {
    /// Whether any triangle meets the ray with `t` in `(t_min, t_max)`: the traversal of
    /// `bvh_occluded` in `shaders/visibility.wgsl`, step for step.
    pub fn occluded(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let inv = Vec3::new(safe_inverse(d.x), safe_inverse(d.y), safe_inverse(d.z));
        let mut stack = [0u32; STACK_SIZE];
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let n = self.nodes[stack[sp] as usize];
            if !slab(&n, o, inv, t_max) {
                continue;
            }
            if n.count > 0 {
                for k in n.first..n.first + n.count {
                    let [a, b, c] = self.triangles[k as usize].map(|v| Vec3::new(v[0], v[1], v[2]));
                    if let Some((t, _, _)) = ray_triangle(o, d, a, b, c)
                        && t > t_min
                        && t < t_max
                    {
                        return true;
                    }
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

/// The ray meets the node's box before `t_max` (obvhs's slab test).
#[inline]
fn slab(n: &FlatNode, o: Vec3, inv: Vec3, t_max: f32) -> bool {
    let t1 = (Vec3::from(n.min) - o) * inv;
    let t2 = (Vec3::from(n.max) - o) * inv;
    let (near, far) = (t1.min(t2).max_element(), t1.max(t2).min_element());
    far >= near && far >= 0.0 && near < t_max
}

/// A flattened BVH as the scene's occluder: the CPU twin of the GPU's shadow rays (the same
/// origin offset, `t_min` 1e-4, no `t_max`).
impl super::Occluder for FlatBvh {
    fn occluded(&self, p: Vec3, n: Vec3, d: Vec3) -> bool {
        self.occluded(super::shadow_origin(p, n, d), d, 1e-4, f32::MAX)
    }
}
