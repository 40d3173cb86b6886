//! Scene objects built from their specs: each object's shape, with its meshes loaded once per
//! asset however often they are placed.

use super::{MeshInstance, ObjectSpec, Shape, TriMesh, err, load_glb, torus_mesh};
use crate::error::Result;
use glam::{Affine3A, EulerRot, Mat3, Quat, Vec3};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The meshes a scene file has loaded, one per asset (a glTF file, a torus's radii), however
/// often it is placed.
#[derive(Default)]
pub(super) struct MeshCache(HashMap<String, Arc<TriMesh>>);

impl MeshCache {
    pub(super) fn get(
        &mut self,
        key: String,
        load: impl FnOnce() -> Result<TriMesh>,
    ) -> Result<Arc<TriMesh>> {
        if let Some(m) = self.0.get(&key) {
            return Ok(m.clone());
        }
        let m = Arc::new(load()?);
        self.0.insert(key, m.clone());
        Ok(m)
    }
}

/// The shape of scene object `o` (`at(field)` names a field in an error), its meshes from
/// `meshes`, its paths resolved by `resolve`.
pub(super) fn object_shape(
    o: &ObjectSpec,
    at: &dyn Fn(&str) -> String,
    path: &Path,
    resolve: &dyn Fn(&str) -> PathBuf,
    meshes: &mut MeshCache,
) -> Result<Shape> {
    let (rot, pos, world) = object_pose(o, at, path)?;
    // A scale too small for f32 to invert (1e-39) is refused, not placed.
    let place = |mesh| {
        MeshInstance::new(mesh, world)
            .map(Shape::Mesh)
            .ok_or_else(|| {
                err(
                    path,
                    format!("{}: {} cannot be inverted", at("scale"), o.scale),
                )
            })
    };
    Ok(match o.shape.as_str() {
        "sphere" => Shape::Sphere {
            center: pos,
            radius: o.radius.unwrap_or(1.0) * o.scale,
        },
        "plane" => plane_shape(pos, rot, 0.5 * o.size.unwrap_or(10.0) * o.scale),
        "torus" => {
            let (major, minor) = (
                o.major_radius.unwrap_or(0.9),
                o.minor_radius.unwrap_or(0.45),
            );
            place(meshes.get(format!("torus {major} {minor}"), || {
                Ok(torus_mesh(major, minor, 64, 32))
            })?)?
        }
        "gltf" => {
            let p = o
                .path
                .as_deref()
                .ok_or_else(|| err(path, format!("{}: a gltf object needs a path", at("path"))))?;
            let file = resolve(p);
            place(meshes.get(format!("gltf {}", file.display()), || load_glb(&file))?)?
        }
        other => {
            return Err(err(
                path,
                format!(
                    "{}: unknown shape '{other}' (sphere, plane, torus, gltf)",
                    at("shape")
                ),
            ));
        }
    })
}

/// Object `o`'s rotation, position and object-to-world transform; its scale must be > 0.
fn object_pose(
    o: &ObjectSpec,
    at: &dyn Fn(&str) -> String,
    path: &Path,
) -> Result<(Quat, Vec3, Affine3A)> {
    let rot = Quat::from_euler(
        EulerRot::XYZ,
        o.rotation[0].to_radians(),
        o.rotation[1].to_radians(),
        o.rotation[2].to_radians(),
    );
    let pos = Vec3::from(o.position);
    if !(o.scale.is_finite() && o.scale > 0.0) {
        return Err(err(path, format!("{}: must be > 0", at("scale"))));
    }
    let world = Affine3A::from_scale_rotation_translation(Vec3::splat(o.scale), rot, pos);
    Ok((rot, pos, world))
}

/// A square of half side `half` centred at `center`, its normal the rotated +Y.
fn plane_shape(center: Vec3, rot: Quat, half: f32) -> Shape {
    let m = Mat3::from_quat(rot);
    Shape::Plane {
        center,
        normal: m * Vec3::Y,
        u: m * Vec3::X,
        v: m * Vec3::Z,
        half,
    }
}
