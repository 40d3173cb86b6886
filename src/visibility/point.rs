//! One surface point's shadow rays, set up once for all of them.
//!
//! A pixel casts up to `N_L + N_B` shadow rays, all from the same origin (the point pushed off
//! its surface, [`super::shadow_origin`]) and all into the hemisphere of its normal. What they
//! share is worked out once per pixel ([`ShadowPoint`]): which objects that hemisphere can reach
//! at all ([`Reach`]: each object's bounding sphere seen from the origin as a cone, those wholly
//! behind the tangent plane dropped), and where the origin lies in each object's own space. A
//! ray then tests a handful of cones (a dot product each) instead of walking the top-level BVH,
//! and runs an object's exact test only when its direction falls in that object's cone.
//!
//! The culling is exact (a direction outside a cone misses everything inside the sphere, and a
//! hemisphere cannot reach a sphere behind its tangent plane), with a margin far larger than
//! f32 rounding, so a ray gets the same answer as through the top level: tested ray by ray in
//! `tests/core/visibility.rs`.

use glam::Vec3;

/// The most cones one point's hemisphere can reach for [`Reach`] to list them; past that the
/// top-level BVH is the better filter (a ray would test more cones than it walks boxes).
pub const MAX_REACH: usize = 16;

/// Slack on a cone's cosine: f32 rounding of a direction and of the cone's axis and cosine is
/// about 1e-7; this keeps every ray that could touch the sphere inside its cone.
const COS_MARGIN: f32 = 1e-5;

/// The cones a point's hemisphere can reach: object `object[k]` lies in the sphere of slot `k`,
/// which only a unit direction `d` with `d . axis[k] >= cos[k]` can reach. Structure of arrays,
/// tested in groups of four; unused slots have `cos > 1` and never pass.
#[derive(Clone, Copy, Debug)]
pub struct Reach {
    len: usize,
    pub object: [u32; MAX_REACH],
    axis_x: [f32; MAX_REACH],
    axis_y: [f32; MAX_REACH],
    axis_z: [f32; MAX_REACH],
    cos: [f32; MAX_REACH],
    /// The ray origin in each slot's object's own space (filled by the caller, [`Reach::new`]).
    pub local_origin: [Vec3; MAX_REACH],
}

impl Reach {
    /// The spheres `(object, centre, radius)` that a ray from `origin` into the hemisphere of
    /// `n` can reach; `local(object)` is where `origin` lies in that object's space. `None` when
    /// more than [`MAX_REACH`] can be reached.
    pub fn new(
        origin: Vec3,
        n: Vec3,
        spheres: impl IntoIterator<Item = (u32, Vec3, f32)>,
        mut local: impl FnMut(usize) -> Vec3,
    ) -> Option<Self> {
        let mut r = Reach {
            len: 0,
            object: [0; MAX_REACH],
            axis_x: [0.0; MAX_REACH],
            axis_y: [0.0; MAX_REACH],
            axis_z: [0.0; MAX_REACH],
            cos: [2.0; MAX_REACH],
            local_origin: [Vec3::ZERO; MAX_REACH],
        };
        for (object, c, radius) in spheres {
            let oc = c - origin;
            // Wholly behind the tangent plane: no direction of the hemisphere gets there.
            if n.dot(oc) < -radius {
                continue;
            }
            if r.len == MAX_REACH {
                return None;
            }
            let dist2 = oc.length_squared();
            let (axis, cos) = if dist2 > radius * radius {
                let axis = oc / dist2.sqrt();
                (axis, (1.0 - radius * radius / dist2).sqrt() - COS_MARGIN)
            } else {
                // The origin is inside the sphere: every direction can hit.
                (Vec3::X, -2.0)
            };
            let k = r.len;
            r.object[k] = object;
            (r.axis_x[k], r.axis_y[k], r.axis_z[k], r.cos[k]) = (axis.x, axis.y, axis.z, cos);
            r.local_origin[k] = local(object as usize);
            r.len += 1;
        }
        Some(r)
    }

    /// How many slots are used.
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The slots whose cone holds the unit direction `d`, as a bit mask (bit `k`: slot `k`).
    #[inline(always)]
    pub fn hits(&self, d: Vec3) -> u32 {
        let mut mask = 0u32;
        for g in 0..self.len.div_ceil(4) {
            let mut m = 0u32;
            for j in 0..4 {
                let k = 4 * g + j;
                let dot = self.axis_x[k] * d.x + self.axis_y[k] * d.y + self.axis_z[k] * d.z;
                m |= ((dot >= self.cos[k]) as u32) << j;
            }
            mask |= m << (4 * g);
        }
        mask
    }
}

/// What a point's shadow rays share: the point, its normal, the origin of its rays on the
/// normal's side, and (where the occluder sets one up) the objects they can reach.
#[derive(Clone, Copy, Debug)]
pub struct ShadowPoint {
    pub p: Vec3,
    pub n: Vec3,
    /// [`super::shadow_origin`] for directions with `n . d >= 0`.
    pub origin: Vec3,
    /// `None`: no per-point culling (ask the occluder's full query).
    pub reach: Option<Reach>,
}

impl ShadowPoint {
    /// The point alone, with no culling set up.
    pub fn new(p: Vec3, n: Vec3) -> Self {
        ShadowPoint {
            p,
            n,
            origin: super::shadow_origin(p, n, n),
            reach: None,
        }
    }
}
