//! A `Mesh` asset's triangles, and its BVH in object space as the GPU reads it.

use super::*;

/// The BVH of `mesh` in object space, flattened (triangle lists with float positions; anything
/// else, or a mesh whose data lives only in the render world, has no triangles).
pub(super) fn mesh_blas(mesh: &Mesh) -> FlatBlas {
    let (positions, tris) = mesh_triangles(mesh);
    MeshBvh::build(&positions, &tris)
        .flat_blas(&positions, &tris)
        .unwrap_or_else(|e| {
            error!("envis: a mesh casts no shadow: {e}");
            FlatBlas::default()
        })
}

pub(super) fn mesh_triangles(mesh: &Mesh) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    if mesh.primitive_topology() != PrimitiveTopology::TriangleList {
        return Default::default();
    }
    let Ok(Some(p)) = mesh.try_attribute_option(Mesh::ATTRIBUTE_POSITION) else {
        return Default::default();
    };
    let Some(p) = p.as_float3() else {
        return Default::default();
    };
    let positions: Vec<Vec3> = p.iter().map(|v| Vec3::from(*v)).collect();
    let n = p.len() as u32;
    let index: Vec<u32> = match mesh.try_indices_option() {
        Ok(Some(Indices::U16(v))) => v.iter().map(|&i| i as u32).collect(),
        Ok(Some(Indices::U32(v))) => v.clone(),
        _ => (0..n).collect(),
    };
    let tris = index
        .chunks_exact(3)
        .filter(|t| t.iter().all(|&i| i < n))
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    (positions, tris)
}
