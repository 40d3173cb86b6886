//! Shadow rays in a scene: which objects block them ([`Occluders`]), when a scene needs them at
//! all (the `auto` rule of [`crate::visibility::Visibility`]), and the geometry the GPU traces
//! for them ([`Scene::shadow_bvh`]).

use super::{Scene, Shape, TriMesh, sphere_mesh, square_mesh};
use crate::visibility::{
    FlatBlas, FlatBvh, FlatInstance, ObjectFromWorld, Occluder, Tlas, Visibility, shadow_origin,
};
use glam::Vec3;
use std::sync::Arc;

/// The shapes that block shadow rays (objects with `cast_shadows`) under a top-level BVH,
/// intersected analytically (spheres, planes) or through their mesh's BVH in object space: the
/// same geometry the G-buffer's rays see.
pub struct Occluders<'a> {
    pub shapes: Vec<&'a Shape>,
    tlas: Tlas,
}

impl<'a> Occluders<'a> {
    pub fn new(shapes: Vec<&'a Shape>) -> Self {
        let bounds: Vec<_> = shapes.iter().map(|s| s.bounds()).collect();
        Occluders {
            tlas: Tlas::build(&bounds),
            shapes,
        }
    }

    /// These shapes as the GPU traces them: one BVH per mesh, a tessellated unit sphere and a
    /// two-triangle square placed for every sphere and plane, and the top level over them all. A sphere's triangles lie inside the analytic sphere, so the analytic
    /// G-buffer's points never see their own sphere's triangles above the horizon.
    pub fn flat(&self) -> Result<FlatBvh, String> {
        let (sphere, square) = (
            Arc::new(sphere_mesh(SPHERE_SEGMENTS.0, SPHERE_SEGMENTS.1)),
            Arc::new(square_mesh()),
        );
        let mut meshes: Vec<Arc<TriMesh>> = Vec::new();
        let mut blases: Vec<FlatBlas> = Vec::new();
        let (mut instances, mut bounds) = (Vec::new(), Vec::new());
        for shape in &self.shapes {
            let mesh = match shape {
                Shape::Sphere { .. } => &sphere,
                Shape::Plane { .. } => &square,
                Shape::Mesh(m) => &m.mesh,
            };
            let blas = match meshes.iter().position(|m| Arc::ptr_eq(m, mesh)) {
                Some(i) => i,
                None => {
                    meshes.push(mesh.clone());
                    blases.push(mesh.bvh().flat_blas(&mesh.positions, &mesh.indices)?);
                    blases.len() - 1
                }
            };
            let world = shape.world_from_object();
            if let (Some(b), Some(to_object)) = (blases[blas].bounds, ObjectFromWorld::new(world)) {
                instances.push(FlatInstance { blas, to_object });
                bounds.push(crate::visibility::world_bounds(b, &world));
            }
        }
        FlatBvh::build(&blases, &instances, &Tlas::build(&bounds))
    }
}

impl Occluder for Occluders<'_> {
    fn occluded(&self, p: Vec3, n: Vec3, d: Vec3) -> bool {
        let o = shadow_origin(p, n, d);
        self.tlas
            .any(o, d, f32::INFINITY, |i| match self.shapes[i] {
                Shape::Mesh(m) => m.occluded(o, d, f32::INFINITY),
                s => s.intersect(o, d, f32::INFINITY).is_some(),
            })
    }
}

/// Segments of the sphere the GPU traces in place of an analytic one (as many as the demo's
/// Bevy sphere has around its equator).
const SPHERE_SEGMENTS: (u32, u32) = (64, 32);

impl Shape {
    /// Spheres and planes cannot shadow themselves; a mesh (the torus, any glTF) is not known to
    /// be convex.
    pub fn is_convex(&self) -> bool {
        !matches!(self, Shape::Mesh(_))
    }
}

impl Scene {
    /// The objects that cast shadows.
    pub fn occluders(&self) -> Occluders<'_> {
        Occluders::new(
            self.objects
                .iter()
                .filter(|o| o.spec.cast_shadows)
                .map(|o| &o.shape)
                .collect(),
        )
    }

    /// The shadow-casting objects as the GPU traces them ([`Occluders::flat`]).
    pub fn shadow_bvh(&self) -> Result<FlatBvh, String> {
        self.occluders().flat()
    }

    /// Whether to cast shadow rays under `mode` (`None`: the scene file's `visibility`, else
    /// `auto`), and why, for `--stats`.
    pub fn shadows(&self, mode: Option<Visibility>) -> (bool, String) {
        let mode = mode.or(self.file.sampling.visibility).unwrap_or_default();
        let casters: Vec<&Shape> = self.occluders().shapes;
        match mode {
            Visibility::On => (true, "on (asked for)".into()),
            Visibility::Off => (false, "off (asked for)".into()),
            Visibility::Auto => auto_rule(&casters),
        }
    }
}

/// `auto`: shadows when some object can shadow a visible point: two or more shadow-casting
/// objects, or one that is not known to be convex.
pub fn auto_rule(casters: &[&Shape]) -> (bool, String) {
    match casters {
        [] => (false, "off (auto: no object casts shadows)".into()),
        [one] if one.is_convex() => (
            false,
            "off (auto: one convex object cannot shadow itself)".into(),
        ),
        [_] => (true, "on (auto: a mesh can shadow itself)".into()),
        many => (
            true,
            format!("on (auto: {} shadow-casting objects)", many.len()),
        ),
    }
}
