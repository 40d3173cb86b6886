//! A scene's geometry: analytic spheres and planes, and triangle meshes kept in object space
//! ([`TriMesh`], one per mesh asset, with its BVH built once) placed by [`MeshInstance`]s. Rays
//! reach a mesh through its instance's [`ObjectFromWorld`], so a hundred placements of the bunny
//! share one BVH.

use crate::visibility::{Bounds, MeshBvh, ObjectFromWorld, world_bounds};
use glam::{Affine3A, Vec3};
use std::sync::Arc;

#[derive(Clone, Debug)]
pub enum Shape {
    Sphere {
        center: Vec3,
        radius: f32,
    },
    /// A square of side `2 half` on the plane through `center` with normal `normal`.
    Plane {
        center: Vec3,
        normal: Vec3,
        u: Vec3,
        v: Vec3,
        half: f32,
    },
    /// A placed triangle mesh.
    Mesh(MeshInstance),
}

/// Triangles with per-vertex normals, in object space.
#[derive(Clone, Debug, Default)]
pub struct TriMesh {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub indices: Vec<[u32; 3]>,
    /// Built on the first ray cast (the mesh is complete by then); the mesh must not change
    /// after that.
    bvh: std::sync::OnceLock<MeshBvh>,
}

/// A mesh placed in the world: `world_from_object` and its inverse, which carries rays in.
#[derive(Clone, Debug)]
pub struct MeshInstance {
    pub mesh: Arc<TriMesh>,
    pub world_from_object: Affine3A,
    pub to_object: ObjectFromWorld,
}

impl MeshInstance {
    /// `None` when the transform has no inverse (a zero scale).
    pub fn new(mesh: Arc<TriMesh>, world_from_object: Affine3A) -> Option<Self> {
        Some(MeshInstance {
            to_object: ObjectFromWorld::new(world_from_object)?,
            mesh,
            world_from_object,
        })
    }

    /// The closest hit with `1e-4 < t < t_max`: distance and world-space normal.
    pub fn intersect(&self, o: Vec3, d: Vec3, t_max: f32) -> Option<(f32, Vec3)> {
        let m = &self.to_object;
        let (t, n) = self.mesh.intersect(m.point(o), m.vector(d), t_max)?;
        Some((t, m.normal_to_world(n)))
    }

    /// Whether anything meets the ray with `1e-4 < t < t_max`.
    pub fn occluded(&self, o: Vec3, d: Vec3, t_max: f32) -> bool {
        let m = &self.to_object;
        self.mesh.occluded(m.point(o), m.vector(d), t_max)
    }

    /// [`Self::intersect`] by testing every triangle (the reference for the BVHs).
    pub fn intersect_brute(&self, o: Vec3, d: Vec3, t_max: f32) -> Option<(f32, Vec3)> {
        let m = &self.to_object;
        let (t, n) = self.mesh.intersect_brute(m.point(o), m.vector(d), t_max)?;
        Some((t, m.normal_to_world(n)))
    }

    /// The mesh's vertices in world space.
    pub fn world_positions(&self) -> Vec<Vec3> {
        let a = &self.world_from_object;
        self.mesh
            .positions
            .iter()
            .map(|p| a.transform_point3(*p))
            .collect()
    }
}

impl Shape {
    /// Nearest intersection with `t` in `(1e-4, t_max)`: distance and geometric / shading normal.
    pub fn intersect(&self, o: Vec3, d: Vec3, t_max: f32) -> Option<(f32, Vec3)> {
        match self {
            Shape::Sphere { center, radius } => {
                let oc = o - *center;
                let b = oc.dot(d);
                let c = oc.length_squared() - radius * radius;
                let disc = b * b - c;
                if disc < 0.0 {
                    return None;
                }
                let s = disc.sqrt();
                let t = if -b - s > 1e-4 { -b - s } else { -b + s };
                (t > 1e-4 && t < t_max).then(|| (t, (o + d * t - *center) / *radius))
            }
            Shape::Plane {
                center,
                normal,
                u,
                v,
                half,
            } => {
                let den = normal.dot(d);
                let h = normal.dot(*center - o);
                // `t = h / den > 1e-4` needs `h` and `den` of one sign: most shadow rays leave a
                // plane's front away from it, and stop here without a division.
                if den.abs() < 1e-9 || h * den <= 0.0 {
                    return None;
                }
                let t = h / den;
                if !(t > 1e-4 && t < t_max) {
                    return None;
                }
                let p = o + d * t - *center;
                (p.dot(*u).abs() <= *half && p.dot(*v).abs() <= *half).then_some((t, *normal))
            }
            Shape::Mesh(m) => m.intersect(o, d, t_max),
        }
    }

    /// World bounds, padded a little (a plane's box would be flat).
    pub fn bounds(&self) -> Bounds {
        let (lo, hi) = match self {
            Shape::Sphere { center, radius } => (*center - *radius, *center + *radius),
            Shape::Plane {
                center, u, v, half, ..
            } => {
                let e = (u.abs() + v.abs()) * *half;
                (*center - e, *center + e)
            }
            Shape::Mesh(m) => match m.mesh.bounds() {
                Some(b) => world_bounds(b, &m.world_from_object),
                None => return (Vec3::ZERO, Vec3::ZERO),
            },
        };
        let pad = 1e-4 * lo.abs().max(hi.abs()).max_element().max(1.0);
        (lo - pad, hi + pad)
    }

    /// Where the object is placed, object space to world: a unit sphere, the square
    /// `[-1, 1]^2` of the XZ plane, or the mesh's own space (the GPU traces the first two as
    /// [`sphere_mesh`] and [`square_mesh`]).
    pub fn world_from_object(&self) -> Affine3A {
        match self {
            Shape::Sphere { center, radius } => Affine3A::from_scale_rotation_translation(
                Vec3::splat(*radius),
                Default::default(),
                *center,
            ),
            Shape::Plane {
                center,
                normal,
                u,
                v,
                half,
            } => Affine3A::from_cols(
                (*u * *half).into(),
                (*normal).into(),
                (*v * *half).into(),
                (*center).into(),
            ),
            Shape::Mesh(m) => m.world_from_object,
        }
    }
}

impl TriMesh {
    /// The closest hit with `1e-4 < t < t_max` and its interpolated normal, through the mesh's
    /// BVH (built on first use).
    pub fn intersect(&self, o: Vec3, d: Vec3, t_max: f32) -> Option<(f32, Vec3)> {
        let h = self.bvh().intersect(o, d, 1e-4, t_max)?;
        Some((h.t, self.normal_at(h.triangle, h.u, h.v)))
    }

    /// Whether anything meets the ray with `1e-4 < t < t_max` (any hit, through the BVH).
    pub fn occluded(&self, o: Vec3, d: Vec3, t_max: f32) -> bool {
        self.bvh().occluded(o, d, 1e-4, t_max)
    }

    /// The mesh's BVH, built on first use.
    pub fn bvh(&self) -> &MeshBvh {
        self.bvh
            .get_or_init(|| MeshBvh::build(&self.positions, &self.indices))
    }

    /// [`Self::intersect`] by testing every triangle in order (after a bounding-sphere test):
    /// the reference the BVH is tested against.
    pub fn intersect_brute(&self, o: Vec3, d: Vec3, t_max: f32) -> Option<(f32, Vec3)> {
        let (lo, hi) = self.bounds()?;
        let (c, r) = (0.5 * (lo + hi), 0.5 * (hi - lo).length() + 1e-4);
        let oc = o - c;
        let b = oc.dot(d);
        let dd = d.length_squared();
        if b * b - dd * (oc.length_squared() - r * r) < 0.0 {
            return None;
        }
        let mut best: Option<(f32, usize, f32, f32)> = None;
        for (i, tri) in self.indices.iter().enumerate() {
            let [a, bb, cc] = tri.map(|i| self.positions[i as usize]);
            if let Some((t, u, v)) = crate::visibility::ray_triangle(o, d, a, bb, cc)
                && t > 1e-4
                && t < best.map_or(t_max, |b| b.0)
            {
                best = Some((t, i, u, v));
            }
        }
        best.map(|(t, i, u, v)| (t, self.normal_at(i, u, v)))
    }

    /// The interpolated normal of triangle `i` at barycentrics `(u, v)` (the face normal where
    /// the vertex normals cancel).
    fn normal_at(&self, i: usize, u: f32, v: f32) -> Vec3 {
        let tri = self.indices[i];
        let [a, b, c] = tri.map(|k| self.positions[k as usize]);
        let [na, nb, nc] = tri.map(|k| self.normals[k as usize]);
        (na * (1.0 - u - v) + nb * u + nc * v)
            .normalize_or((b - a).cross(c - a).normalize_or_zero())
    }

    /// The box around the vertices; `None` without any.
    pub fn bounds(&self) -> Option<Bounds> {
        if self.positions.is_empty() {
            return None;
        }
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for p in &self.positions {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        Some((lo, hi))
    }

    /// Triangles of `nu x nv` quads on a surface `at(s, t)` (periodic in both, `s, t` in
    /// `[0, 1)`) giving a point and its normal.
    fn grid(nu: u32, nv: u32, at: impl Fn(f32, f32) -> (Vec3, Vec3)) -> TriMesh {
        let mut m = TriMesh::default();
        for i in 0..nu {
            for j in 0..nv {
                let (p, n) = at(i as f32 / nu as f32, j as f32 / nv as f32);
                m.positions.push(p);
                m.normals.push(n);
            }
        }
        let idx = |i: u32, j: u32| (i % nu) * nv + (j % nv);
        for i in 0..nu {
            for j in 0..nv {
                let (a, b, c, d) = (idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1));
                m.indices.push([a, c, b]);
                m.indices.push([a, d, c]);
            }
        }
        m
    }
}

/// A torus around +Y: `major` ring radius, `minor` tube radius, `nu x nv` quads.
pub fn torus_mesh(major: f32, minor: f32, nu: u32, nv: u32) -> TriMesh {
    TriMesh::grid(nu, nv, |s, t| {
        let (a, b) = (s * std::f32::consts::TAU, t * std::f32::consts::TAU);
        let ring = Vec3::new(a.cos(), 0.0, a.sin());
        let n = ring * b.cos() + Vec3::Y * b.sin();
        (ring * major + n * minor, n)
    })
}

/// The unit sphere as `nu` segments around +Y by `nv` rings, vertices on the sphere (so the
/// triangles lie inside it: a point of the analytic sphere never sees them above its horizon).
pub fn sphere_mesh(nu: u32, nv: u32) -> TriMesh {
    let mut m = TriMesh::default();
    for i in 0..nu {
        let a = i as f32 / nu as f32 * std::f32::consts::TAU;
        for j in 0..=nv {
            let b = j as f32 / nv as f32 * std::f32::consts::PI;
            let n = Vec3::new(b.sin() * a.cos(), b.cos(), b.sin() * a.sin());
            m.positions.push(n);
            m.normals.push(n);
        }
    }
    let idx = |i: u32, j: u32| (i % nu) * (nv + 1) + j;
    for i in 0..nu {
        for j in 0..nv {
            let (a, b, c, d) = (idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1));
            m.indices.push([a, c, b]);
            m.indices.push([a, d, c]);
        }
    }
    m
}

/// The square `[-1, 1]^2` of the XZ plane, facing +Y, as two triangles.
pub fn square_mesh() -> TriMesh {
    let mut m = TriMesh::default();
    for (x, z) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        m.positions.push(Vec3::new(x, 0.0, z));
        m.normals.push(Vec3::Y);
    }
    m.indices = vec![[0, 2, 1], [0, 3, 2]];
    m
}
