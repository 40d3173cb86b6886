//! Shadow rays in a scene: which objects block them ([`Occluders`]), and when a scene needs them
//! at all (the `auto` rule of [`crate::visibility::Visibility`]).

use super::{Scene, Shape};
use crate::visibility::{Occluder, Visibility, shadow_origin};
use glam::Vec3;

/// The shapes that block shadow rays (objects with `cast_shadows`), intersected analytically
/// (spheres, planes) or through their BVH (meshes): the same geometry the G-buffer's rays see.
pub struct Occluders<'a>(pub Vec<&'a Shape>);

impl Occluder for Occluders<'_> {
    fn occluded(&self, p: Vec3, n: Vec3, d: Vec3) -> bool {
        let o = shadow_origin(p, n, d);
        self.0.iter().any(|s| match s {
            Shape::Mesh(m) => m.occluded(o, d, f32::INFINITY),
            _ => s.intersect(o, d, f32::INFINITY).is_some(),
        })
    }
}

impl Shape {
    /// Spheres and planes cannot shadow themselves; a mesh (the torus, any glTF) is not known to
    /// be convex.
    pub fn is_convex(&self) -> bool {
        !matches!(self, Shape::Mesh(_))
    }
}

impl Scene {
    /// The objects that cast shadows.
    /// Analytic shapes come first: they are cheaper than a mesh's BVH and end most blocked rays.
    pub fn occluders(&self) -> Occluders<'_> {
        let mut shapes: Vec<&Shape> = self
            .objects
            .iter()
            .filter(|o| o.spec.cast_shadows)
            .map(|o| &o.shape)
            .collect();
        shapes.sort_by_key(|s| matches!(s, Shape::Mesh(_)));
        Occluders(shapes)
    }

    /// Whether to cast shadow rays under `mode` (`None`: the scene file's `visibility`, else
    /// `auto`), and why, for `--stats`.
    pub fn shadows(&self, mode: Option<Visibility>) -> (bool, String) {
        let mode = mode.or(self.file.sampling.visibility).unwrap_or_default();
        let casters: Vec<&Shape> = self.occluders().0;
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
