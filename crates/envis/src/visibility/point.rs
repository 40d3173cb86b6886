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
//! A flat shape (a plane's square) gets a half-space of directions instead of a cone: only rays
//! heading towards its plane can meet it. Its bounding sphere is large and holds the points
//! that lie on or just above it (the ground's own pixels), whose cone would let every ray
//! through to the exact test.
//!
//! The culling is exact (a direction outside a cone misses everything inside the sphere, one
//! heading away from a plane misses it, and a hemisphere cannot reach a sphere behind its
//! tangent plane), with a margin far larger than f32 rounding, so a ray gets the same answer as
//! through the top level: tested ray by ray in `envis/tests/core/visibility.rs`.

use glam::Vec3;

/// The most cones one point's hemisphere can reach for [`Reach`] to list them; past that the
/// top-level BVH is the better filter (a ray would test more cones than it walks boxes).
pub const MAX_REACH: usize = 16;

/// Slack on a cone's cosine: f32 rounding of a direction and of the cone's axis and cosine is
/// about 1e-7; this keeps every ray that could touch the sphere inside its cone.
const COS_MARGIN: f32 = 1e-5;

/// Where a shape lies, as [`Reach`] culls it.
#[derive(Clone, Copy, Debug)]
pub enum Hull {
    /// Inside the sphere of this centre and radius: reached only through a cone.
    Ball(Vec3, f32),
    /// On the plane through `point` with unit normal `normal`: reached only by directions
    /// towards that plane.
    Flat { point: Vec3, normal: Vec3 },
}

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
    /// The shapes `(object, hull)` that a ray from `origin` into the hemisphere of `n` can
    /// reach; `local(object)` is where `origin` lies in that object's space. `None` when more
    /// than [`MAX_REACH`] can be reached.
    pub fn new(
        origin: Vec3,
        n: Vec3,
        hulls: impl IntoIterator<Item = (u32, Hull)>,
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
        for (object, hull) in hulls {
            let Some((axis, cos)) = cone(origin, n, hull) else {
                continue;
            };
            if r.len == MAX_REACH {
                return None;
            }
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
            mask |= self.group_hits(g, d) << (4 * g);
        }
        mask
    }

    /// [`Self::hits`] for slots `4 g .. 4 g + 4`, in SSE (every x86-64 CPU has it).
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn group_hits(&self, g: usize, d: Vec3) -> u32 {
        use super::sse::*;
        let lanes = |a: &[f32; MAX_REACH]| load(a[4 * g..][..4].try_into().unwrap());
        let axis = [
            lanes(&self.axis_x),
            lanes(&self.axis_y),
            lanes(&self.axis_z),
        ];
        mask(ge(dot(axis, splat3(d)), lanes(&self.cos)))
    }

    /// [`Self::hits`] for slots `4 g .. 4 g + 4`, lane by lane.
    #[cfg(not(target_arch = "x86_64"))]
    #[inline(always)]
    fn group_hits(&self, g: usize, d: Vec3) -> u32 {
        let mut m = 0u32;
        for j in 0..4 {
            let k = 4 * g + j;
            let dot = self.axis_x[k] * d.x + self.axis_y[k] * d.y + self.axis_z[k] * d.z;
            m |= ((dot >= self.cos[k]) as u32) << j;
        }
        m
    }
}

/// The directions `d` from `origin` that can reach `hull`, as `d . axis >= cos`; `None` when
/// none of the hemisphere of `n` can.
fn cone(origin: Vec3, n: Vec3, hull: Hull) -> Option<(Vec3, f32)> {
    match hull {
        Hull::Ball(c, radius) => {
            let oc = c - origin;
            // Wholly behind the tangent plane: no direction of the hemisphere gets there.
            if n.dot(oc) < -radius {
                return None;
            }
            let dist2 = oc.length_squared();
            if dist2 <= radius * radius {
                // The origin is inside the sphere: every direction can hit.
                return Some((Vec3::X, -2.0));
            }
            let axis = oc / dist2.sqrt();
            Some((axis, (1.0 - radius * radius / dist2).sqrt() - COS_MARGIN))
        }
        Hull::Flat { point, normal } => {
            // The plane's own test meets it at `t = h / (normal . d) > 0` only: `d` on `h`'s side.
            let h = normal.dot(point - origin);
            (h != 0.0).then(|| (normal * h.signum(), -COS_MARGIN))
        }
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
