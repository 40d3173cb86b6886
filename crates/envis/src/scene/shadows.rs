//! Shadow rays in a scene: which objects block them ([`Occluders`]), when a scene needs them at
//! all (the `auto` rule of [`crate::visibility::ShadowRays`]), and the geometry the GPU traces
//! for them ([`Scene::shadow_bvh`]).

use super::{Scene, Shape, TriMesh, sphere_mesh, square_mesh};
use crate::visibility::{
    Bounds, FlatBlas, FlatBvh, FlatInstance, Hull, Layers, ObjectFromWorld, Occluder, Reach,
    ShadowPoint, ShadowRays, Tlas, inverse, shadow_origin, slab_hit,
};
use glam::Vec3;
use std::sync::Arc;

/// The shapes that block shadow rays (objects with `cast_shadows`) under a top-level BVH,
/// intersected analytically (spheres, planes) or through their mesh's BVH in object space: the
/// same geometry the G-buffer's rays see.
pub struct Occluders<'a> {
    pub shapes: Vec<&'a Shape>,
    tlas: Tlas,
    /// Where each shape lies `(shape, hull)`, for a point's [`Reach`].
    hulls: Vec<(u32, Hull)>,
    /// Each shape's box, as the top level holds it.
    bounds: Vec<Bounds>,
}

impl<'a> Occluders<'a> {
    pub fn new(shapes: Vec<&'a Shape>) -> Self {
        let bounds: Vec<_> = shapes.iter().map(|s| s.bounds()).collect();
        Occluders {
            tlas: Tlas::build(&bounds),
            hulls: shapes
                .iter()
                .zip(&bounds)
                .enumerate()
                .map(|(i, (s, b))| (i as u32, hull(s, *b)))
                .collect(),
            bounds,
            shapes,
        }
    }

    /// Whether shape `i` blocks the ray from `o` (in world space; `local` in the shape's own
    /// space, for a mesh) towards `d`: the exact test both paths of [`Occluder`] end in.
    #[inline(always)]
    fn blocks(&self, i: usize, o: Vec3, local: Vec3, d: Vec3) -> bool {
        match self.shapes[i] {
            Shape::Mesh(m) => m.mesh.occluded(local, m.to_object.vector(d), f32::INFINITY),
            s => s.intersect(o, d, f32::INFINITY).is_some(),
        }
    }

    /// Where the world point `o` lies in shape `i`'s own space (a mesh's; others use `o`).
    fn local(&self, i: usize, o: Vec3) -> Vec3 {
        match self.shapes[i] {
            Shape::Mesh(m) => m.to_object.point(o),
            _ => o,
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
                instances.push(FlatInstance {
                    blas,
                    to_object,
                    layers: Layers::ALL,
                });
                bounds.push(crate::visibility::world_bounds(b, &world));
            }
        }
        FlatBvh::build(&blases, &instances, &Tlas::build(&bounds))
    }
}

impl Occluder for Occluders<'_> {
    fn occluded(&self, p: Vec3, n: Vec3, d: Vec3) -> bool {
        let o = shadow_origin(p, n, d);
        self.tlas.any(o, d, f32::INFINITY, |i| {
            self.blocks(i, o, self.local(i, o), d)
        })
    }

    fn at_point(&self, p: Vec3, n: Vec3) -> ShadowPoint {
        let mut at = ShadowPoint::new(p, n);
        let o = at.origin;
        at.reach = Reach::new(o, n, self.hulls.iter().copied(), |i| self.local(i, o));
        at
    }

    /// Through the point's [`Reach`]: only the shapes whose cone (or half-space) holds `d`, in the order the
    /// shapes are listed. The answer is [`Self::occluded`]'s (any hit is a hit, whichever shape
    /// gives it first).
    fn occluded_from(&self, at: &ShadowPoint, d: Vec3) -> bool {
        match &at.reach {
            Some(r) if at.n.dot(d) >= 0.0 => {
                let mut mask = r.hits(d);
                while mask != 0 {
                    let k = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    let i = r.object[k] as usize;
                    // A mesh's walk costs far more than a box: its box first, as the top level
                    // would test it (a sphere's or a plane's own test is as cheap).
                    if let Shape::Mesh(_) = self.shapes[i] {
                        let (lo, hi) = self.bounds[i];
                        if !slab_hit(lo, hi, at.origin, inverse(d), f32::INFINITY) {
                            continue;
                        }
                    }
                    if self.blocks(i, at.origin, r.local_origin[k], d) {
                        return true;
                    }
                }
                false
            }
            _ => self.occluded(at.p, at.n, d),
        }
    }
}

/// Where shape `s` of bounds `b` lies for a point's [`Reach`]: a plane on its plane, a sphere in
/// itself (padded as its box is), a mesh in its box's sphere.
fn hull(s: &Shape, b: Bounds) -> Hull {
    match s {
        Shape::Plane { center, normal, .. } => Hull::Flat {
            point: *center,
            normal: *normal,
        },
        Shape::Sphere { center, .. } => Hull::Ball(*center, 0.5 * (b.1.x - b.0.x)),
        Shape::Mesh(_) => Hull::Ball(0.5 * (b.0 + b.1), 0.5 * (b.1 - b.0).length()),
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
    pub fn shadows(&self, mode: Option<ShadowRays>) -> (bool, String) {
        let mode = mode.or(self.file.sampling.shadows).unwrap_or_default();
        let casters: Vec<&Shape> = self.occluders().shapes;
        match mode {
            ShadowRays::On => (true, "on (asked for)".into()),
            ShadowRays::Off => (false, "off (asked for)".into()),
            ShadowRays::Auto => auto_rule(&casters),
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
