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
use crate::envmap::{face_ab_to_dvec, texel_solid_angle, CubeMap, Image};
use crate::sampling::{Lobe, Material};
use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::PI;

/// f64 BRDF value `f(o, i)` (no cosine) for unit `n`, `o`, `i`.
pub fn eval_brdf_f64(m: &Material, n: DVec3, o: DVec3, i: DVec3) -> DVec3 {
    let (no, ni) = (n.dot(o), n.dot(i));
    if no <= 0.0 || ni <= 0.0 {
        return DVec3::ZERO;
    }
    let mut v = m.kd.as_dvec3() / PI;
    match m.lobe {
        Lobe::None => {}
        Lobe::Phong { exponent } => {
            let e = exponent as f64;
            let r = 2.0 * no * n - o;
            let c = r.dot(i);
            if c > 0.0 {
                v += m.ks.as_dvec3() * ((e + 2.0) / (2.0 * PI) * c.powf(e));
            }
        }
        Lobe::Ggx { alpha } => {
            let a2 = (alpha as f64) * (alpha as f64);
            let h = (o + i).normalize();
            let nh = n.dot(h);
            if nh > 0.0 {
                let sin2 = (1.0 - nh * nh).max(0.0);
                let t = sin2 + a2 * nh * nh;
                let d = a2 / (PI * t * t);
                let lambda = |z: f64| ((1.0 + a2 * (1.0 - z * z) / (z * z)).sqrt() - 1.0) / 2.0;
                let g2 = 1.0 / (1.0 + lambda(no) + lambda(ni));
                v += m.ks.as_dvec3() * (d * g2 / (4.0 * no * ni));
            }
        }
    }
    v
}

/// Sub-texel resolution `k` for a face of `n` texels and a material.
pub fn subdivision(n: usize, m: &Material, refine: f64) -> usize {
    let texel = 2.0 / n as f64; // radians at the face centre
    let k = (refine * 6.0 * texel / m.lobe_width() as f64).ceil() as usize;
    k.clamp(2, 48)
}

/// Reference radiance of one G-buffer pixel.
pub fn reference_pixel(map: &CubeMap, px: &GPixel, refine: f64) -> DVec3 {
    let n = px.n.as_dvec3().normalize_or_zero();
    let o = px.o.as_dvec3().normalize_or_zero();
    if n == DVec3::ZERO || o == DVec3::ZERO || n.dot(o) <= 0.0 {
        return DVec3::ZERO;
    }
    let size = map.size;
    let h = 2.0 / size as f64;
    let k0 = subdivision(size, &px.material, refine);
    let mut sum = DVec3::ZERO;
    for f in 0..6 {
        for r in 0..size {
            for c in 0..size {
                let l = map.texel(f, c, r);
                if l.max_element() <= 0.0 {
                    continue;
                }
                let (a0, b0) = (-1.0 + c as f64 * h, -1.0 + r as f64 * h);
                let corners = [(a0, b0), (a0 + h, b0), (a0, b0 + h), (a0 + h, b0 + h)];
                let cos: Vec<f64> = corners.iter().map(|&(a, b)| n.dot(face_ab_to_dvec(f, a, b))).collect();
                if cos.iter().all(|&x| x <= 0.0) {
                    continue;
                }
                let k = if cos.iter().any(|&x| x <= 0.0) { (k0 * 4).min(96) } else { k0 };
                let mut acc = DVec3::ZERO;
                let mut wsum = 0.0;
                for sy in 0..k {
                    for sx in 0..k {
                        let a = a0 + (sx as f64 + 0.5) / k as f64 * h;
                        let b = b0 + (sy as f64 + 0.5) / k as f64 * h;
                        let q = 1.0 + a * a + b * b;
                        let w = 1.0 / (q * q.sqrt());
                        wsum += w;
                        let d = face_ab_to_dvec(f, a, b) / q.sqrt();
                        let ct = n.dot(d);
                        if ct > 0.0 {
                            acc += eval_brdf_f64(&px.material, n, o, d) * (ct * w);
                        }
                    }
                }
                sum += l.as_dvec3() * acc * (texel_solid_angle(c, r, size) / wsum);
            }
        }
    }
    sum
}

/// Reference image of a G-buffer (f64 internally, stored as f32 RGB).
pub fn reference_image(map: &CubeMap, gbuf: &[Option<GPixel>], width: usize, height: usize, refine: f64) -> (Image, Vec<DVec3>) {
    let px: Vec<DVec3> = gbuf.par_iter().map(|p| p.as_ref().map_or(DVec3::ZERO, |p| reference_pixel(map, p, refine))).collect();
    let img = Image { width, height, data: px.iter().map(|c| c.as_vec3()).collect() };
    (img, px)
}
