//! Lat-long -> cube and cube -> cube resampling that preserves energy (the integral of radiance
//! over solid angle).
//! - Lat-long shrinking (area / box filter): every source texel is split into `k x k` sub-rects of
//!   exact solid angle and its energy `L dOmega` is splatted into the cube texel each sub-rect's
//!   centre falls in; cube texel = energy / its exact solid angle. No source texel is ever skipped
//!   (small texels near the poles included), and the total energy is preserved to rounding.
//! - Growing: each target texel is the solid-angle-weighted mean of `s x s` bilinear sub-points.

use super::{CubeMap, Image, dir_to_face_uv, dir_to_latlong, face_ab_to_vec};
use glam::Vec3;
use rayon::prelude::*;

/// Fill a cube map of `size` from `fetch(direction)`, averaging `s x s` sub-points per texel
/// weighted by the cube-face Jacobian `(1 + a^2 + b^2)^(-3/2)` (solid angle per unit face area).
pub fn cube_from_fetch(size: usize, s: usize, fetch: impl Fn(Vec3) -> Vec3 + Sync) -> CubeMap {
    let mut cube = CubeMap::new(size);
    let n = size;
    let h = 2.0 / n as f32;
    cube.data.par_iter_mut().enumerate().for_each(|(i, t)| {
        let face = i / (n * n);
        let row = (i / n) % n;
        let col = i % n;
        let mut sum = Vec3::ZERO;
        let mut wsum = 0.0f32;
        for sy in 0..s {
            for sx in 0..s {
                let a = -1.0 + (col as f32 + (sx as f32 + 0.5) / s as f32) * h;
                let b = -1.0 + (row as f32 + (sy as f32 + 0.5) / s as f32) * h;
                let q = 1.0 + a * a + b * b;
                let w = 1.0 / (q * q.sqrt());
                sum += w * fetch(face_ab_to_vec(face, a, b).normalize());
                wsum += w;
            }
        }
        *t = sum / wsum;
    });
    cube
}

/// Resample a (sanitized) 2:1 lat-long image into a cube map of `size` x `size` faces.
pub fn latlong_to_cube(img: &Image, size: usize) -> CubeMap {
    // Source texels (along the equator) per target texel: (2 pi / W) vs (pi / 2 / N).
    let ratio = img.width as f32 / (4.0 * size as f32);
    if ratio > 1.0 {
        // Sub-rects small enough that even the smallest cube texels (at face corners, ~0.44x the
        // centre's side) receive several.
        let k = ((4.0 / ratio).ceil() as usize).clamp(2, 8);
        latlong_splat(img, size, k)
    } else {
        cube_from_fetch(size, 2, |d| latlong_bilinear(img, d))
    }
}

/// Area-filtered lat-long -> cube by splatting `k x k` exact-solid-angle sub-rects per source texel.
pub fn latlong_splat(img: &Image, size: usize, k: usize) -> CubeMap {
    use glam::DVec3;
    use std::f64::consts::PI;
    let (w, h) = (img.width, img.height);
    let n = size;
    let mut energy = vec![DVec3::ZERO; 6 * n * n];
    let dphi = 2.0 * PI / (w * k) as f64;
    for y in 0..h {
        for sy in 0..k {
            let t0 = PI * (y as f64 + sy as f64 / k as f64) / h as f64;
            let t1 = PI * (y as f64 + (sy + 1) as f64 / k as f64) / h as f64;
            let domega = (t0.cos() - t1.cos()) * dphi;
            let v = ((y as f64 + (sy as f64 + 0.5) / k as f64) / h as f64) as f32;
            for x in 0..w {
                let c = img.get(x, y);
                if c == Vec3::ZERO {
                    continue;
                }
                for sx in 0..k {
                    let u = ((x as f64 + (sx as f64 + 0.5) / k as f64) / w as f64) as f32;
                    let (f, u2, v2) = dir_to_face_uv(super::latlong_to_dir(u, v));
                    let (col, row) = super::uv_to_texel(u2, v2, n);
                    energy[(f * n + row) * n + col] += c.as_dvec3() * domega;
                }
            }
        }
    }
    let mut cube = CubeMap::new(n);
    for (i, t) in cube.data.iter_mut().enumerate() {
        *t = (energy[i] / super::texel_solid_angle(i % n, (i / n) % n, n)).as_vec3();
    }
    cube
}

/// Resample a cube map to another face size.
pub fn resize_cube(src: &CubeMap, size: usize) -> CubeMap {
    if size == src.size {
        return src.clone();
    }
    let ratio = src.size as f32 / size as f32;
    if ratio > 1.0 {
        let s = ((ratio).ceil() as usize).clamp(1, 32);
        cube_from_fetch(size, s, |d| src.lookup(d))
    } else {
        cube_from_fetch(size, 2, |d| cube_bilinear(src, d))
    }
}

/// Bilinear lat-long lookup in direction `d` (wraps in `u`, clamps in `v`).
pub fn latlong_bilinear(img: &Image, d: Vec3) -> Vec3 {
    let (u, v) = dir_to_latlong(d);
    let x = u * img.width as f32 - 0.5;
    let y = (v * img.height as f32 - 0.5).clamp(0.0, (img.height - 1) as f32);
    let x0 = x.floor();
    let y0 = y.floor();
    let (fx, fy) = (x - x0, y - y0);
    let w = img.width as isize;
    let xi0 = (x0 as isize).rem_euclid(w) as usize;
    let xi1 = (x0 as isize + 1).rem_euclid(w) as usize;
    let yi0 = y0 as usize;
    let yi1 = (yi0 + 1).min(img.height - 1);
    let top = img.get(xi0, yi0) * (1.0 - fx) + img.get(xi1, yi0) * fx;
    let bot = img.get(xi0, yi1) * (1.0 - fx) + img.get(xi1, yi1) * fx;
    top * (1.0 - fy) + bot * fy
}

/// Bilinear lookup within the face that `d` falls in (clamped at face edges).
pub fn cube_bilinear(src: &CubeMap, d: Vec3) -> Vec3 {
    let n = src.size;
    let (f, u, v) = dir_to_face_uv(d);
    let x = (u * n as f32 - 0.5).clamp(0.0, (n - 1) as f32);
    let y = (v * n as f32 - 0.5).clamp(0.0, (n - 1) as f32);
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(n - 1), (y0 + 1).min(n - 1));
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    let top = src.texel(f, x0, y0) * (1.0 - fx) + src.texel(f, x1, y0) * fx;
    let bot = src.texel(f, x0, y1) * (1.0 - fx) + src.texel(f, x1, y1) * fx;
    top * (1.0 - fy) + bot * fy
}

/// Integral of a lat-long image's radiance over the sphere (f64), for energy checks.
pub fn latlong_integral(img: &Image) -> glam::DVec3 {
    let (w, h) = (img.width, img.height);
    let mut s = glam::DVec3::ZERO;
    for y in 0..h {
        let t0 = std::f64::consts::PI * y as f64 / h as f64;
        let t1 = std::f64::consts::PI * (y + 1) as f64 / h as f64;
        let omega = (t0.cos() - t1.cos()) * 2.0 * std::f64::consts::PI / w as f64;
        for x in 0..w {
            s += img.get(x, y).as_dvec3() * omega;
        }
    }
    s
}

/// Most sub-points per axis of [`SourceLayout::subpoints`]: enough for two per source texel up to
/// a lat-long 64 x `n` texels wide (4096 for faces of 64). Beyond, a source texel can fall
/// between sub-points; its coarse texel may then miss it (see `docs/bevy.md`).
pub const MAX_SUBPOINTS: u32 = 32;

/// How a GPU environment image is laid out (see `shaders/image_source.wgsl`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SourceLayout {
    /// One 2:1 layer in Mitsuba's lat-long convention.
    LatLong,
    /// Six square layers, `+X -X +Y -Y +Z -Z`, in Bevy's (left-handed) cube convention: world
    /// direction `d` is read at `(d.x, d.y, -d.z)`.
    Cube,
}

impl SourceLayout {
    /// The layout of a texture with this size and layer count, or why it is not an environment.
    pub fn detect(width: u32, height: u32, layers: u32) -> Result<Self, String> {
        match layers {
            1 if width == 2 * height && height > 0 => Ok(SourceLayout::LatLong),
            6 if width == height && width > 0 => Ok(SourceLayout::Cube),
            1 => Err(format!(
                "a {width}x{height} image is not a 2:1 lat-long environment"
            )),
            6 => Err(format!(
                "a cube image needs square layers, this one is {width}x{height}"
            )),
            n => Err(format!(
                "an environment image has 1 (lat-long) or 6 (cube) layers, this one has {n}"
            )),
        }
    }

    /// Sub-points per axis that the GPU resample takes per target texel for a source whose
    /// layers are `width` texels wide and a target face of `n`: about two per source texel along
    /// each axis (a face spans a quarter of a lat-long row, or a whole cube layer), 2 to
    /// [`MAX_SUBPOINTS`].
    /// A cube image of exactly the target's size is copied texel for texel (one sub-point at each
    /// texel centre, where the bilinear lookup is exact).
    pub fn subpoints(self, width: u32, n: u32) -> u32 {
        if self == SourceLayout::Cube && width == n {
            return 1;
        }
        let span = match self {
            SourceLayout::LatLong => width as f32 / 4.0,
            SourceLayout::Cube => width as f32,
        };
        ((2.0 * span / n.max(1) as f32).ceil() as u32).clamp(2, MAX_SUBPOINTS)
    }
}

/// An environment image as the GPU reads it (CPU twin of `shaders/image_source.wgsl`): texels
/// are sanitised (non-finite and negative to 0) before bilinear filtering.
pub enum SourceImage {
    LatLong(Image),
    /// Bevy's layers in order, each `size x size` (a [`CubeMap`] holding the layers as faces).
    Cube(CubeMap),
}

impl SourceImage {
    /// Sanitise a copy of the texels, as every GPU fetch does.
    pub fn new_latlong(mut img: Image) -> Self {
        img.sanitize();
        SourceImage::LatLong(img)
    }
    pub fn new_cube(mut layers: CubeMap) -> Self {
        layers.sanitize();
        SourceImage::Cube(layers)
    }

    pub fn layout(&self) -> SourceLayout {
        match self {
            SourceImage::LatLong(_) => SourceLayout::LatLong,
            SourceImage::Cube(_) => SourceLayout::Cube,
        }
    }

    /// Width of one layer in texels.
    pub fn width(&self) -> usize {
        match self {
            SourceImage::LatLong(img) => img.width,
            SourceImage::Cube(c) => c.size,
        }
    }

    /// Bilinear radiance in (environment-space) direction `d`.
    pub fn radiance(&self, d: Vec3) -> Vec3 {
        match self {
            SourceImage::LatLong(img) => latlong_bilinear(img, d),
            SourceImage::Cube(c) => cube_bilinear(c, Vec3::new(d.x, d.y, -d.z)),
        }
    }

    /// The radiance of the texel direction `d` falls in (no filtering): what the Bevy pass gives
    /// light and BRDF samples (twin of `source_nearest` in `shaders/image_source.wgsl`). Point
    /// sampling keeps each sample's radiance inside the texel whose density drew it; a filtered
    /// lookup would spread a small sun into neighbours of low density (unbiased, but heavy-tailed).
    pub fn radiance_nearest(&self, d: Vec3) -> Vec3 {
        match self {
            SourceImage::LatLong(img) => {
                let (u, v) = dir_to_latlong(d);
                let x = ((u * img.width as f32) as usize).min(img.width - 1);
                let y = ((v * img.height as f32) as usize).min(img.height - 1);
                img.get(x, y)
            }
            SourceImage::Cube(c) => c.lookup(Vec3::new(d.x, d.y, -d.z)),
        }
    }

    /// The sampler's texel table of face size `n`: twin of `shaders/resample.wgsl`.
    pub fn to_cube(&self, n: usize) -> CubeMap {
        let s = self.layout().subpoints(self.width() as u32, n as u32) as usize;
        cube_from_fetch(n, s, |d| self.radiance(d))
    }
}

/// A cube map as the six layers of a Bevy cube image (a [`CubeMap`] holding them as faces):
/// layer `L` at `(a, b)` holds the map in direction `face_ab_to_vec(L, a, b)` with `z` negated
/// (Bevy's cubes are left-handed). A mirror, so each layer texel is exactly one map texel;
/// [`SourceImage::Cube`] reads it back.
pub fn bevy_cube_layers(map: &CubeMap) -> CubeMap {
    let n = map.size;
    let mut out = CubeMap::new(n);
    for (i, t) in out.data.iter_mut().enumerate() {
        let (layer, row, col) = (i / (n * n), (i / n) % n, i % n);
        let a = (2 * col + 1) as f32 / n as f32 - 1.0;
        let b = (2 * row + 1) as f32 / n as f32 - 1.0;
        let s = face_ab_to_vec(layer, a, b);
        let hit = super::dir_to_texel(Vec3::new(s.x, s.y, -s.z), n);
        *t = map.texel(hit.face, hit.col, hit.row);
    }
    out
}
