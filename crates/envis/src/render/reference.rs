//! The converged reference, in f64: for every pixel, quadrature over every cube texel,
//! `L(p, o) = sum_t L_t * sum_{s in t} f(o, w_s) max(0, <n, w_s>) dOmega_s`, with `k x k` sub-texel
//! midpoints whose solid angles are rescaled to sum to the texel's exact solid angle. `k` grows
//! with the texel size relative to the narrowest BRDF lobe (sub-texel supersampling for glossy
//! lobes), and texels that straddle the horizon get 4x more. Texels whose four corners are all at
//! or below the horizon are skipped (exact: the cosine is linear over the face plane).
//!
//! The BRDFs are evaluated here with their own f64 formulas — the oracle shares no arithmetic
//! with the f32 run-time code it checks.

use super::scene::GPixel;
use crate::envmap::{CubeMap, Image, face_ab_to_dvec, texel_solid_angle};
use crate::sampling::{Lobe, Material};
use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::PI;

/// f64 BRDF value `f(o, i)` (no cosine) for unit `n`, `o`, `i`.
pub fn eval_brdf_f64(m: &Material, n: DVec3, o: DVec3, i: DVec3) -> DVec3 {
    BrdfF64::new(m, n, o).eval(i)
}

/// [`eval_brdf_f64`] with everything that depends only on the pixel (`n`, `o`, the material)
/// computed once: the quadrature calls it for every sub-texel sample of every texel.
struct BrdfF64 {
    m: Material,
    n: DVec3,
    o: DVec3,
    no: f64,
    /// Phong: the mirror direction; GGX: unused.
    r: DVec3,
    /// GGX: alpha^2 and Smith's lambda of the view direction.
    a2: f64,
    lambda_o: f64,
}

impl BrdfF64 {
    fn new(m: &Material, n: DVec3, o: DVec3) -> Self {
        let no = n.dot(o);
        let (mut r, mut a2, mut lambda_o) = (DVec3::ZERO, 0.0, 0.0);
        match m.lobe {
            Lobe::None => {}
            Lobe::Phong { .. } => r = 2.0 * no * n - o,
            Lobe::Ggx { alpha } | Lobe::GgxSchlick { alpha } => {
                a2 = (alpha as f64) * (alpha as f64);
                lambda_o = ggx_lambda(a2, no);
            }
        }
        BrdfF64 {
            m: *m,
            n,
            o,
            no,
            r,
            a2,
            lambda_o,
        }
    }

    #[inline]
    fn eval(&self, i: DVec3) -> DVec3 {
        let (m, n, no) = (&self.m, self.n, self.no);
        let ni = n.dot(i);
        if no <= 0.0 || ni <= 0.0 {
            return DVec3::ZERO;
        }
        let mut v = m.kd.as_dvec3() / PI;
        match m.lobe {
            Lobe::None => {}
            Lobe::Phong { exponent } => {
                let e = exponent as f64;
                let c = self.r.dot(i);
                if c > 0.0 {
                    v += m.ks.as_dvec3() * ((e + 2.0) / (2.0 * PI) * c.powf(e));
                }
            }
            Lobe::Ggx { .. } | Lobe::GgxSchlick { .. } => {
                let a2 = self.a2;
                let h = (self.o + i).normalize();
                let nh = n.dot(h);
                if nh > 0.0 {
                    let sin2 = (1.0 - nh * nh).max(0.0);
                    let t = sin2 + a2 * nh * nh;
                    let d = a2 / (PI * t * t);
                    let g2 = 1.0 / (1.0 + self.lambda_o + ggx_lambda(a2, ni));
                    v += self.fresnel(h) * (d * g2 / (4.0 * no * ni));
                }
            }
        }
        v
    }
}

impl BrdfF64 {
    /// The glossy lobe's Fresnel factor at half vector `h`: `ks`, or Schlick's with Bevy's f90.
    fn fresnel(&self, h: DVec3) -> DVec3 {
        let f0 = self.m.ks.as_dvec3();
        if !matches!(self.m.lobe, Lobe::GgxSchlick { .. }) {
            return f0;
        }
        let f90 = crate::sampling::brdf::bevy_f90(self.m.ks) as f64;
        f0 + (DVec3::splat(f90) - f0) * (1.0 - self.o.dot(h)).clamp(0.0, 1.0).powi(5)
    }
}

/// Smith's lambda for GGX: `(sqrt(1 + a^2 tan^2) - 1) / 2` with `tan^2 = (1 - z^2) / z^2`.
#[inline]
fn ggx_lambda(a2: f64, z: f64) -> f64 {
    ((1.0 + a2 * (1.0 - z * z) / (z * z)).sqrt() - 1.0) / 2.0
}

/// Sub-texel resolution `k` for a face of `n` texels and a material.
pub fn subdivision(n: usize, m: &Material, refine: f64) -> usize {
    let texel = 2.0 / n as f64; // radians at the face centre
    let k = (refine * 6.0 * texel / m.lobe_width() as f64).ceil() as usize;
    k.clamp(2, 48)
}

/// Sub-texel resolution for texels that straddle the horizon.
fn horizon_subdivision(k0: usize) -> usize {
    (k0 * 4).min(96)
}

/// What the quadrature needs per texel, independent of the pixel: exact solid angles, the
/// directions of the texel corners, and (when it fits in 64 MiB) the unit directions and weights
/// of the `k x k` sub-texel midpoints with each texel's weight sum.
pub struct Quadrature {
    size: usize,
    k: usize,
    omega: Vec<f64>,
    /// Per face, `(size + 1)^2` corner directions (not normalised; only their sign against `n` is used).
    corners: Vec<DVec3>,
    /// Per texel, `k^2` (direction, weight); empty when too large.
    samples: Vec<(DVec3, f64)>,
    /// Per texel, the sum of its `k^2` weights.
    wsum: Vec<f64>,
}

impl Quadrature {
    /// Tables for a map of face size `size` at sub-texel resolution `k`, for a whole image:
    /// with the sub-texel table when it fits (see [`Quadrature::for_one_pixel`]).
    pub fn new(size: usize, k: usize) -> Self {
        Self::build(size, k, true)
    }

    /// The cheap tables only (solid angles, corners): for a single pixel, where building the
    /// sub-texel table would cost more than it saves.
    pub fn for_one_pixel(size: usize, k: usize) -> Self {
        Self::build(size, k, false)
    }

    fn build(size: usize, k: usize, with_samples: bool) -> Self {
        let h = 2.0 / size as f64;
        let omega = (0..size * size)
            .map(|i| texel_solid_angle(i % size, i / size, size))
            .collect();
        let corners = (0..6 * (size + 1) * (size + 1))
            .map(|i| {
                let (f, j) = (i / ((size + 1) * (size + 1)), i % ((size + 1) * (size + 1)));
                face_ab_to_dvec(
                    f,
                    -1.0 + (j % (size + 1)) as f64 * h,
                    -1.0 + (j / (size + 1)) as f64 * h,
                )
            })
            .collect();
        let fits = with_samples
            && 6 * size * size * k * k * std::mem::size_of::<(DVec3, f64)>() <= 64 << 20;
        let (samples, wsum) = if fits {
            let per_texel: Vec<Vec<(DVec3, f64)>> = (0..6 * size * size)
                .into_par_iter()
                .map(|t| subsamples(t / (size * size), t % size, (t / size) % size, h, k))
                .collect();
            let wsum = per_texel
                .iter()
                .map(|sub| sub.iter().map(|s| s.1).sum())
                .collect();
            (per_texel.into_iter().flatten().collect(), wsum)
        } else {
            (Vec::new(), Vec::new())
        };
        Quadrature {
            size,
            k,
            omega,
            corners,
            samples,
            wsum,
        }
    }
}

/// The `k x k` midpoints of texel `(c, r)` of face `f`: unit direction and `1 / q^(3/2)` weight.
fn subsamples(f: usize, c: usize, r: usize, h: f64, k: usize) -> Vec<(DVec3, f64)> {
    let (a0, b0) = (-1.0 + c as f64 * h, -1.0 + r as f64 * h);
    let mut out = Vec::with_capacity(k * k);
    for sy in 0..k {
        for sx in 0..k {
            let a = a0 + (sx as f64 + 0.5) / k as f64 * h;
            let b = b0 + (sy as f64 + 0.5) / k as f64 * h;
            let q = 1.0 + a * a + b * b;
            out.push((face_ab_to_dvec(f, a, b) / q.sqrt(), 1.0 / (q * q.sqrt())));
        }
    }
    out
}

/// Reference radiance of one G-buffer pixel.
pub fn reference_pixel(map: &CubeMap, px: &GPixel, refine: f64) -> DVec3 {
    let q = Quadrature::for_one_pixel(map.size, subdivision(map.size, &px.material, refine));
    reference_pixel_with(map, px, &q)
}

/// [`reference_pixel`] with tables built once for the image (`q.k` must be this pixel's
/// [`subdivision`]).
pub fn reference_pixel_with(map: &CubeMap, px: &GPixel, q: &Quadrature) -> DVec3 {
    reference_pixel_visible(map, px, q, |_| true)
}

/// [`reference_pixel_with`] with visibility: every quadrature node above the horizon counts only
/// when `visible(direction)` (a shadow ray per node).
pub fn reference_pixel_visible(
    map: &CubeMap,
    px: &GPixel,
    q: &Quadrature,
    visible: impl Fn(DVec3) -> bool,
) -> DVec3 {
    let n = px.n.as_dvec3().normalize_or_zero();
    let o = px.o.as_dvec3().normalize_or_zero();
    if n == DVec3::ZERO || o == DVec3::ZERO || n.dot(o) <= 0.0 {
        return DVec3::ZERO;
    }
    let size = map.size;
    assert_eq!(q.size, size);
    let brdf = BrdfF64::new(&px.material, n, o);
    let side = size + 1;
    let mut sum = DVec3::ZERO;
    for f in 0..6 {
        for r in 0..size {
            for c in 0..size {
                let l = map.texel(f, c, r);
                if l.max_element() <= 0.0 {
                    continue;
                }
                let at = |dc: usize, dr: usize| {
                    n.dot(q.corners[f * side * side + (r + dr) * side + c + dc])
                };
                let cos = [at(0, 0), at(1, 0), at(0, 1), at(1, 1)];
                if cos.iter().all(|&x| x <= 0.0) {
                    continue;
                }
                let mut acc = DVec3::ZERO;
                let mut add = |d: DVec3, w: f64| {
                    let ct = n.dot(d);
                    if ct > 0.0 && visible(d) {
                        acc += brdf.eval(d) * (ct * w);
                    }
                };
                let horizon = cos.iter().any(|&x| x <= 0.0);
                let wsum = texel_nodes(q, (f, c, r), horizon, &mut add);
                sum += l.as_dvec3() * acc * (q.omega[r * size + c] / wsum);
            }
        }
    }
    sum
}

/// Feed texel (`f`, `c`, `r`)'s quadrature nodes to `add` (direction, weight); their weight
/// sum. Horizon texels (and maps too large for the table) take midpoints on the fly, finer.
fn texel_nodes(
    q: &Quadrature,
    (f, c, r): (usize, usize, usize),
    horizon: bool,
    add: &mut impl FnMut(DVec3, f64),
) -> f64 {
    let (k0, size) = (q.k, q.size);
    if horizon || q.samples.is_empty() {
        let k = if horizon { horizon_subdivision(k0) } else { k0 };
        let mut wsum = 0.0;
        for (d, w) in subsamples(f, c, r, 2.0 / size as f64, k) {
            wsum += w;
            add(d, w);
        }
        wsum
    } else {
        let t = (f * size + r) * size + c;
        for &(d, w) in &q.samples[t * k0 * k0..(t + 1) * k0 * k0] {
            add(d, w);
        }
        q.wsum[t]
    }
}

/// Reference image of a G-buffer (f64 internally, stored as f32 RGB).
pub fn reference_image(
    map: &CubeMap,
    gbuf: &[Option<GPixel>],
    width: usize,
    height: usize,
    refine: f64,
) -> (Image, Vec<DVec3>) {
    reference_image_with(map, gbuf, None, width, height, refine)
}

/// [`reference_image`] with visibility: the scene's `occluder`, and each pixel's surface point
/// (laid out as the G-buffer). One shadow ray per quadrature node: the visibility boundary is
/// resolved to the sub-texel grid, so compare two `refine`s to bound the quadrature error.
pub fn reference_image_with(
    map: &CubeMap,
    gbuf: &[Option<GPixel>],
    shadows: Option<(&dyn crate::visibility::Occluder, &[glam::Vec3])>,
    width: usize,
    height: usize,
    refine: f64,
) -> (Image, Vec<DVec3>) {
    // One table per sub-texel resolution in use (one per material).
    let mut tables: std::collections::HashMap<usize, Quadrature> = Default::default();
    for p in gbuf.iter().flatten() {
        let k = subdivision(map.size, &p.material, refine);
        tables
            .entry(k)
            .or_insert_with(|| Quadrature::new(map.size, k));
    }
    let px: Vec<DVec3> = gbuf
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            p.as_ref().map_or(DVec3::ZERO, |p| {
                let q = &tables[&subdivision(map.size, &p.material, refine)];
                match shadows {
                    None => reference_pixel_with(map, p, q),
                    Some((occ, points)) => reference_pixel_visible(map, p, q, |d| {
                        !occ.occluded(points[i], p.n.normalize_or_zero(), d.as_vec3())
                    }),
                }
            })
        })
        .collect();
    let img = Image {
        width,
        height,
        data: px.iter().map(|c| c.as_vec3()).collect(),
    };
    (img, px)
}
