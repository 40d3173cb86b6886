//! Triangle meshes from binary glTF (`.glb`), read with the maintained `gltf` crate: every
//! triangle primitive of every mesh instanced in the default scene, with the node transforms
//! applied. A crafted file cannot make envis allocate or index beyond it: each accessor is checked
//! against its buffer view and the binary chunk, and against the size caps below, before a byte
//! is read (the crate trusts accessor counts and offsets, and would overflow or panic on some).
//! The crate is in the tree already through Bevy, so no second glTF reader is built.

use super::{TriMesh, err};
use crate::error::Result;
use glam::{Mat3, Mat4, Vec3};
use gltf::accessor::{DataType, Dimensions};
use std::path::Path;

/// Vertices and triangles a mesh file may bring in all (a 16M-triangle mesh is ~600 MB in
/// memory): beyond, the file is refused with an error instead of exhausting memory.
pub const MAX_VERTICES: usize = 1 << 24;
pub const MAX_TRIANGLES: usize = 1 << 24;
/// Node nesting deeper than this is refused (a cycle in a crafted file would never end).
const MAX_DEPTH: usize = 64;

/// Load the meshes of a binary glTF file. Missing normals are computed (area-weighted vertex
/// normals); primitives other than triangle lists are skipped. Errors name the file.
pub fn load_glb(path: &Path) -> Result<TriMesh> {
    let bytes = std::fs::read(path).map_err(|e| err(path, format!("cannot open: {e}")))?;
    parse_glb(&bytes).map_err(|m| err(path, format!("not a usable binary glTF: {m}")))
}

/// [`load_glb`] on bytes in memory; the error says what is wrong. A panic inside the `gltf`
/// crate on some crafted input we do not foresee becomes this file's error, not the program's
/// end (the checks below exist so that none is expected).
pub fn parse_glb(bytes: &[u8]) -> std::result::Result<TriMesh, String> {
    std::panic::catch_unwind(|| parse_checked(bytes))
        .unwrap_or_else(|_| Err("the glTF reader failed on this file".into()))
}

fn parse_checked(bytes: &[u8]) -> std::result::Result<TriMesh, String> {
    check_header(bytes)?;
    // The crate's validation indexes each primitive's POSITION accessor before checking that it
    // exists: check that first, then validate.
    let raw = gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| e.to_string())?;
    check_position_indices(raw.document.as_json())?;
    let blob = raw.blob.unwrap_or_default();
    let doc = gltf::Document::from_json(raw.document.into_json()).map_err(|e| e.to_string())?;
    let mut mesh = TriMesh::default();
    match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => {
            for node in scene.nodes() {
                add_node(&mut mesh, &node, Mat4::IDENTITY, &blob, 0)?;
            }
        }
        // No scene: every mesh once, untransformed.
        None => {
            for m in doc.meshes() {
                add_mesh(&mut mesh, &m, Mat4::IDENTITY, &blob)?;
            }
        }
    }
    if mesh.indices.is_empty() {
        return Err("no triangles".into());
    }
    Ok(mesh)
}

/// Every primitive's POSITION accessor index is in range.
fn check_position_indices(root: &gltf::json::Root) -> std::result::Result<(), String> {
    let n = root.accessors.len();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            for (sem, acc) in &prim.attributes {
                if acc.value() >= n {
                    return Err(format!(
                        "mesh {m} primitive {p}: attribute {sem:?} names accessor {} of {n}",
                        acc.value()
                    ));
                }
            }
        }
    }
    Ok(())
}

/// The GLB header, checked before the crate reads it (it subtracts the header size from the
/// declared length without checking).
fn check_header(bytes: &[u8]) -> std::result::Result<(), String> {
    let word = |o: usize| {
        bytes
            .get(o..o + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    if bytes.get(0..4) != Some(b"glTF") {
        return Err("missing the glTF header".into());
    }
    match (word(4), word(8)) {
        (Some(2), Some(len)) if (12..=bytes.len() as u64).contains(&(len as u64)) => Ok(()),
        (Some(2), _) => Err("the header's length does not match the file".into()),
        _ => Err("not glTF version 2".into()),
    }
}

fn add_node(
    mesh: &mut TriMesh,
    node: &gltf::Node,
    parent: Mat4,
    blob: &[u8],
    depth: usize,
) -> std::result::Result<(), String> {
    if depth > MAX_DEPTH {
        return Err(format!("nodes nested deeper than {MAX_DEPTH} (a cycle?)"));
    }
    let m = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
    if !m.is_finite() {
        return Err(format!("node {}: a non-finite transform", node.index()));
    }
    if let Some(me) = node.mesh() {
        add_mesh(mesh, &me, m, blob)?;
    }
    for child in node.children() {
        add_node(mesh, &child, m, blob, depth + 1)?;
    }
    Ok(())
}

fn add_mesh(
    out: &mut TriMesh,
    mesh: &gltf::Mesh,
    m: Mat4,
    blob: &[u8],
) -> std::result::Result<(), String> {
    // Normals transform by the inverse transpose (non-uniform scale keeps them perpendicular).
    let nm = Mat3::from_mat4(m).inverse().transpose();
    for prim in mesh.primitives() {
        if prim.mode() != gltf::mesh::Mode::Triangles {
            continue;
        }
        let at = |what: &str| format!("mesh {} primitive {}: {what}", mesh.index(), prim.index());
        let has_normals = check_primitive(&prim, blob).map_err(|e| at(&e))?;
        let reader = prim.reader(|b| (b.index() == 0).then_some(blob));
        let positions: Vec<Vec3> = reader
            .read_positions()
            .ok_or_else(|| at("POSITION unreadable"))?
            .map(Vec3::from_array)
            .collect();
        let base = out.positions.len();
        let n = positions.len();
        if base + n > MAX_VERTICES {
            return Err(format!("more than {MAX_VERTICES} vertices"));
        }
        let flat: Vec<u32> = match reader.read_indices() {
            Some(ix) => ix.into_u32().collect(),
            None => (0..n as u32).collect(),
        };
        if flat.iter().any(|&i| i as usize >= n) || !flat.len().is_multiple_of(3) {
            return Err(at("indices do not match the positions"));
        }
        if out.indices.len() + flat.len() / 3 > MAX_TRIANGLES {
            return Err(format!("more than {MAX_TRIANGLES} triangles"));
        }
        let tris: Vec<[u32; 3]> = flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        let normals: Vec<Vec3> = match reader.read_normals() {
            Some(it) if has_normals => it.map(Vec3::from_array).collect(),
            _ => vertex_normals(&positions, &tris),
        };
        if normals.len() != n {
            return Err(at("NORMAL and POSITION counts differ"));
        }
        out.positions
            .extend(positions.iter().map(|&p| m.transform_point3(p)));
        out.normals
            .extend(normals.iter().map(|&v| (nm * v).normalize_or(Vec3::Y)));
        out.indices
            .extend(tris.iter().map(|t| t.map(|i| i + base as u32)));
    }
    Ok(())
}

/// Check a primitive's accessors against the binary chunk before reading them: positions
/// (required), normals, indices. Whether it has normals.
fn check_primitive(prim: &gltf::Primitive, blob: &[u8]) -> std::result::Result<bool, String> {
    let pos_acc = prim.get(&gltf::Semantic::Positions).ok_or("no POSITION")?;
    check_accessor(&pos_acc, DataType::F32, Dimensions::Vec3, blob)?;
    let normals_acc = prim.get(&gltf::Semantic::Normals);
    if let Some(a) = &normals_acc {
        check_accessor(a, DataType::F32, Dimensions::Vec3, blob)?;
    }
    if let Some(a) = prim.indices() {
        check_index_accessor(&a, blob)?;
    }
    Ok(normals_acc.is_some())
}

/// An accessor of the expected type whose every element lies inside its buffer view, and the
/// view inside the binary chunk; counts within the caps.
fn check_accessor(
    a: &gltf::Accessor,
    ty: DataType,
    dims: Dimensions,
    blob: &[u8],
) -> std::result::Result<(), String> {
    if a.data_type() != ty || a.dimensions() != dims {
        return Err(format!(
            "accessor {}: {:?} {:?}, expected {ty:?} {dims:?}",
            a.index(),
            a.data_type(),
            a.dimensions()
        ));
    }
    check_accessor_bounds(a, blob)
}

fn check_index_accessor(a: &gltf::Accessor, blob: &[u8]) -> std::result::Result<(), String> {
    if a.dimensions() != Dimensions::Scalar
        || !matches!(a.data_type(), DataType::U8 | DataType::U16 | DataType::U32)
    {
        return Err(format!(
            "index accessor {}: not unsigned scalars",
            a.index()
        ));
    }
    check_accessor_bounds(a, blob)
}

fn check_accessor_bounds(a: &gltf::Accessor, blob: &[u8]) -> std::result::Result<(), String> {
    let bad = |m: &str| Err(format!("accessor {}: {m}", a.index()));
    if a.sparse().is_some() {
        return bad("sparse accessors are not supported");
    }
    let count = a.count();
    if count == 0 || count > 3 * MAX_TRIANGLES.max(MAX_VERTICES) {
        return bad(&format!("count {count} out of range"));
    }
    let Some(view) = a.view() else {
        return bad("no buffer view");
    };
    if view.buffer().index() != 0 || !matches!(view.buffer().source(), gltf::buffer::Source::Bin) {
        return bad("data outside the file's binary chunk (only self-contained .glb is read)");
    }
    let elem = a.size();
    let stride = view.stride().unwrap_or(elem);
    let end = (count - 1)
        .checked_mul(stride.max(elem))
        .and_then(|x| x.checked_add(a.offset()))
        .and_then(|x| x.checked_add(elem));
    let view_end = view.offset().checked_add(view.length());
    match (end, view_end) {
        (Some(e), Some(ve)) if e <= view.length() && ve <= blob.len() => Ok(()),
        _ => bad("reaches beyond its buffer view or the binary chunk"),
    }
}

/// Area-weighted vertex normals, for a mesh that brings none.
fn vertex_normals(p: &[Vec3], tris: &[[u32; 3]]) -> Vec<Vec3> {
    let mut n = vec![Vec3::ZERO; p.len()];
    for t in tris {
        let [a, b, c] = t.map(|i| p[i as usize]);
        let f = (b - a).cross(c - a);
        for &i in t {
            n[i as usize] += f;
        }
    }
    n
}
