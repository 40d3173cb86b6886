//! The two-level BVH as the GPU reads it: obvhs's BVH2 nodes flattened to plain arrays (32
//! bytes a node), the top level over instances first, then every mesh's BVH in object space with
//! its triangles in leaf order. The traversal `shaders/visibility.wgsl` runs is written here in the
//! same order and arithmetic: the CPU twin of the WGSL, and the layout the GPU buffers are
//! uploaded from.

use super::MeshBvh;
use super::instances::{Bounds, ObjectFromWorld, Tlas};
use glam::Vec3;

mod traverse;
pub use traverse::{inverse, slab_hit};

/// Most nodes a traversal keeps on its stack (the WGSL's array size); a deeper BVH is refused.
pub const STACK_SIZE: usize = 64;

/// One node: inner (`count == 0`, children at `first` and `first + 1`) or leaf. A mesh leaf
/// holds `count` triangles from `first`; a top-level leaf holds one instance, whose record is
/// `triangles[first]` (its transform) and `triangles[first + 1]` (its layers), and `count` is
/// the root of its mesh's BVH (never 0: node 0 is the top-level root).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "bytemuck", derive(bytemuck::Pod, bytemuck::Zeroable))]
pub struct FlatNode {
    pub min: [f32; 3],
    pub first: u32,
    pub max: [f32; 3],
    pub count: u32,
}

/// One mesh's BVH, flattened with indices local to it (object space).
#[derive(Clone, Debug, Default)]
pub struct FlatBlas {
    pub nodes: Vec<FlatNode>,
    pub triangles: Vec<[[f32; 4]; 3]>,
    /// The root's box (object space); `None` for a mesh with no triangles.
    pub bounds: Option<Bounds>,
}

/// One placement of a mesh: which [`FlatBlas`], the transform into its object space, and the
/// layers it casts shadows on (a ray cast for `layers` meets it only when the two share a bit).
#[derive(Clone, Copy, Debug)]
pub struct FlatInstance {
    pub blas: usize,
    pub to_object: ObjectFromWorld,
    pub layers: Layers,
}

/// A set of up to 32 layers, one bit each (the app maps Bevy's `RenderLayers` onto it): an
/// instance casts shadows for a view when their sets meet.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layers(pub u32);

impl Layers {
    /// Every layer: what the CLI's scenes use (they have no layers), and a view that sees all.
    pub const ALL: Layers = Layers(u32::MAX);

    /// Whether the two sets share a layer.
    #[inline]
    pub fn meet(self, other: Layers) -> bool {
        self.0 & other.0 != 0
    }

    /// The instance record's second entry: the set as two exact 16-bit halves in floats (the
    /// triangle buffer holds floats, and a float's bits need not survive every GPU's loads).
    fn record(self) -> [[f32; 4]; 3] {
        let (lo, hi) = ((self.0 & 0xffff) as f32, (self.0 >> 16) as f32);
        [[lo, hi, 0.0, 0.0], [0.0; 4], [0.0; 4]]
    }

    /// The inverse of [`Self::record`] (`instance_layers` in the WGSL).
    fn from_record(r: [[f32; 4]; 3]) -> Layers {
        Layers(r[0][0] as u32 | (r[0][1] as u32) << 16)
    }
}

/// Entries of the triangle array an instance's record takes: its transform, then its layers.
const RECORD_ENTRIES: usize = 2;

/// A scene's shadow geometry, ready to upload: as the GPU reads it, one node array (the top
/// level's nodes, then every mesh's) and one triangle array (the instance records, then every
/// mesh's triangles), here kept in two parts so that moving instances rewrites only the first.
#[derive(Clone, Debug, Default)]
pub struct FlatBvh {
    pub top: FlatTop,
    pub meshes: std::sync::Arc<FlatMeshes>,
}

/// The part instances move: the top level and the instance records (per instance, the rows of
/// its [`ObjectFromWorld`], then its [`Layers`]). Its size depends only on the number of
/// instances.
#[derive(Clone, Debug, Default)]
pub struct FlatTop {
    pub nodes: Vec<FlatNode>,
    pub records: Vec<[[f32; 4]; 3]>,
}

/// Every mesh's nodes and triangles (vertices as `[x, y, z, 0]`, object space), with indices
/// into the whole arrays (after the [`FlatTop`] of as many instances).
#[derive(Clone, Debug, Default)]
pub struct FlatMeshes {
    pub nodes: Vec<FlatNode>,
    pub triangles: Vec<[[f32; 4]; 3]>,
    /// Where each mesh's root node is (the top-level leaves point at them).
    roots: Vec<u32>,
}

impl MeshBvh {
    /// This BVH over `tris` of vertices `p`, laid out flat, or why the GPU could not traverse
    /// it (deeper than [`STACK_SIZE`]).
    pub fn flat_blas(&self, p: &[Vec3], tris: &[[u32; 3]]) -> Result<FlatBlas, String> {
        if self.bvh.nodes.is_empty() || tris.is_empty() {
            return Ok(FlatBlas::default()); // nothing to trace (obvhs's depth needs a root)
        }
        let depth = self.bvh.depth(0);
        if depth >= STACK_SIZE {
            return Err(format!(
                "a BVH {depth} levels deep is beyond the GPU traversal's stack of {STACK_SIZE}"
            ));
        }
        let nodes = self.bvh.nodes.iter().map(flat_node).collect();
        let triangles = self
            .bvh
            .primitive_indices
            .iter()
            .map(|&i| tris[i as usize].map(|k| p[k as usize].extend(0.0).to_array()))
            .collect();
        let root = self.bvh.nodes[0].aabb();
        let bounds = Some((
            Vec3::from(root.min.to_array()),
            Vec3::from(root.max.to_array()),
        ));
        Ok(FlatBlas {
            nodes,
            triangles,
            bounds,
        })
    }

    /// One mesh in world space as the whole scene: [`Self::flat_blas`] under one instance with
    /// the identity transform.
    pub fn flatten(&self, p: &[Vec3], tris: &[[u32; 3]]) -> Result<FlatBvh, String> {
        let blas = self.flat_blas(p, tris)?;
        let bounds: Vec<Bounds> = blas.bounds.into_iter().collect();
        let instances: Vec<FlatInstance> = bounds
            .iter()
            .map(|_| FlatInstance {
                blas: 0,
                to_object: ObjectFromWorld::IDENTITY,
                layers: Layers::ALL,
            })
            .collect();
        FlatBvh::build(&[blas], &instances, &Tlas::build(&bounds))
    }
}

impl FlatBlas {
    /// The same tree over moved vertices `p` (a deforming mesh: a skinned pose): each leaf's
    /// triangles rewritten from `tris` in the BVH's leaf order `order` ([`MeshBvh::leaf_order`]),
    /// and every box refitted bottom-up. Traced, it answers as the tree it was; only its quality
    /// (box overlap) may degrade as the shape moves away from the one it was built for. `false`,
    /// changing nothing, when `order` or an index does not fit.
    pub fn refit(&mut self, p: &[Vec3], tris: &[[u32; 3]], order: &[u32]) -> bool {
        let fits = order.len() == self.triangles.len()
            && order.iter().all(|&i| {
                tris.get(i as usize)
                    .is_some_and(|t| t.iter().all(|&k| (k as usize) < p.len()))
            });
        if !fits || self.nodes.is_empty() {
            return fits;
        }
        for (slot, &i) in self.triangles.iter_mut().zip(order) {
            *slot = tris[i as usize].map(|k| p[k as usize].extend(0.0).to_array());
        }
        self.bounds = Some(self.refit_node(0));
        true
    }

    /// Node `i`'s box from its triangles or children (recursion as deep as the tree, which
    /// [`MeshBvh::flat_blas`] keeps below [`STACK_SIZE`]).
    fn refit_node(&mut self, i: usize) -> Bounds {
        let n = self.nodes[i];
        let b = if n.count > 0 {
            let tris = &self.triangles[n.first as usize..(n.first + n.count) as usize];
            let mut b = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
            for v in tris.iter().flatten() {
                let v = Vec3::new(v[0], v[1], v[2]);
                b = (b.0.min(v), b.1.max(v));
            }
            b
        } else {
            let (l, r) = (
                self.refit_node(n.first as usize),
                self.refit_node(n.first as usize + 1),
            );
            (l.0.min(r.0), l.1.max(r.1))
        };
        (self.nodes[i].min, self.nodes[i].max) = (b.0.to_array(), b.1.to_array());
        b
    }
}

fn flat_node(n: &obvhs::bvh2::node::Bvh2Node) -> FlatNode {
    FlatNode {
        min: n.aabb().min.to_array(),
        first: n.first_index,
        max: n.aabb().max.to_array(),
        count: n.prim_count,
    }
}

impl FlatBvh {
    /// The scene of `instances` of `blases`, under the top level `tlas` built over the instances'
    /// world bounds (in the same order). Instances of an empty mesh must be left out.
    pub fn build(
        blases: &[impl std::borrow::Borrow<FlatBlas>],
        instances: &[FlatInstance],
        tlas: &Tlas,
    ) -> Result<FlatBvh, String> {
        let top_nodes = tlas.bvh.nodes.len() as u32;
        let top_records = (RECORD_ENTRIES * instances.len()) as u32;
        let mut meshes = FlatMeshes::default();
        for b in blases.iter().map(|b| b.borrow()) {
            let node0 = top_nodes + meshes.nodes.len() as u32;
            let tri0 = top_records + meshes.triangles.len() as u32;
            meshes.roots.push(node0);
            meshes.nodes.extend(b.nodes.iter().map(|n| FlatNode {
                first: n.first + if n.count > 0 { tri0 } else { node0 },
                ..*n
            }));
            meshes.triangles.extend(&b.triangles);
        }
        let meshes = std::sync::Arc::new(meshes);
        let top = meshes.top(instances, tlas)?;
        Ok(FlatBvh { top, meshes })
    }

    /// Move the instances (after `tlas` was refitted to their new bounds): rewrite the top part.
    pub fn place(&mut self, instances: &[FlatInstance], tlas: &Tlas) -> Result<(), String> {
        if instances.len() != self.instances() || tlas.bvh.nodes.len() != self.tlas_nodes() {
            return Err("the instances changed: build anew".into());
        }
        self.top = self.meshes.top(instances, tlas)?;
        Ok(())
    }

    /// Nodes in the top level (0: nothing to trace).
    pub fn tlas_nodes(&self) -> usize {
        self.top.nodes.len()
    }

    pub fn instances(&self) -> usize {
        self.top.records.len() / RECORD_ENTRIES
    }

    /// Node `i` of the whole node array.
    #[inline]
    fn node(&self, i: u32) -> FlatNode {
        let top = self.top.nodes.len();
        match (i as usize).checked_sub(top) {
            None => self.top.nodes[i as usize],
            Some(k) => self.meshes.nodes[k],
        }
    }

    /// Entry `i` of the whole triangle array (a record or a triangle).
    #[inline]
    fn triangle(&self, i: u32) -> [[f32; 4]; 3] {
        match (i as usize).checked_sub(self.top.records.len()) {
            None => self.top.records[i as usize],
            Some(k) => self.meshes.triangles[k],
        }
    }
}

impl FlatMeshes {
    /// The top part for `instances` under `tlas`.
    fn top(&self, instances: &[FlatInstance], tlas: &Tlas) -> Result<FlatTop, String> {
        if tlas.len() != instances.len() {
            return Err(format!(
                "{} instances under a top level over {}",
                instances.len(),
                tlas.len()
            ));
        }
        let mut nodes = Vec::with_capacity(tlas.bvh.nodes.len());
        for n in &tlas.bvh.nodes {
            let mut f = flat_node(n);
            if n.is_leaf() {
                if n.prim_count != 1 {
                    return Err(format!("a top-level leaf with {} instances", n.prim_count));
                }
                let i = tlas.bvh.primitive_indices[n.first_index as usize] as usize;
                let root = instances
                    .get(i)
                    .and_then(|inst| self.roots.get(inst.blas))
                    .ok_or_else(|| format!("instance {i} has no mesh"))?;
                (f.first, f.count) = ((RECORD_ENTRIES * i) as u32, *root);
            }
            nodes.push(f);
        }
        let records = instances
            .iter()
            .flat_map(|i| [i.to_object.0, i.layers.record()])
            .collect();
        Ok(FlatTop { nodes, records })
    }
}
