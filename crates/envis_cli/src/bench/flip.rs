//! FLIP, the perceptual image-difference evaluator of Andersson et al. ("FLIP: A Difference
//! Evaluator for Alternating Images", HPG 2020), and HDR-FLIP ("Visualizing Errors in Rendered
//! High Dynamic Range Images", EG 2021), written from the papers' formulas for the accuracy
//! sweep. Checked against NVIDIA's `flip-evaluator` package (envis_cli/tests/lab/core_bench.rs, values from
//! `docs/bench/flip_reference.py`).
//!
//! LDR-FLIP of two sRGB images in `[0,1]`:
//! - colour: YCxCz opponent space, spatial filtering by the contrast-sensitivity Gaussians of
//!   each channel (edge pixels replicated), clamp to the RGB cube, CIELAB with the Hunt
//!   adjustment, HyAB distance, raised to 0.7 and remapped to `[0, 1]`;
//! - features: edge (first-derivative-of-Gaussian) and point (second-derivative) detectors on
//!   the normalised achromatic channel, `dF = sqrt(max(|dedge|, |dpoint|) / sqrt 2)`;
//! - per pixel `dE = dC^(1 - dF)`.
//!
//! HDR-FLIP: exposures from `log2(x_max / Y_max)` to `log2(x_max / median Y)` of the reference
//! (`x_max`: where the ACES curve reaches 0.85), at least 2, about one stop apart; each pair is
//! exposed, tone mapped (ACES), sRGB encoded and compared by LDR-FLIP; the map is the per-pixel
//! maximum. All kernels are separable, so the cost is linear in the kernel radius.

// The colour constants keep every digit FLIP publishes, so they can be checked against the paper.
#![allow(clippy::excessive_precision)]

use glam::Vec3;

/// Pixels per degree of the default observer: a 0.7 m wide 4K monitor seen from 0.7 m.
pub fn default_ppd() -> f32 {
    0.7 * (3840.0 / 0.7) * (std::f32::consts::PI / 180.0)
}

/// D65 white point in XYZ and its inverse (as FLIP uses them).
const WHITE: Vec3 = Vec3::new(0.950428545, 1.0, 1.088900371);
const INV_WHITE: Vec3 = Vec3::new(1.052156925, 1.0, 0.918357670);

/// ACES (Narkowicz fit, with FLIP's 0.6 pre-exposure folded in): `y = (k0 x^2 + k1 x + k2) / (k3 x^2 + k4 x + k5)`.
const ACES: [f32; 6] = [
    0.6 * 0.6 * 2.51,
    0.6 * 0.03,
    0.0,
    0.6 * 0.6 * 2.43,
    0.6 * 0.59,
    0.14,
];

#[inline]
fn srgb_to_linear(x: f32) -> f32 {
    if x > 0.04045 {
        ((x + 0.055) / 1.055).powf(2.4)
    } else {
        x / 12.92
    }
}
#[inline]
fn linear_to_srgb(x: f32) -> f32 {
    if x > 0.0031308 {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    } else {
        12.92 * x
    }
}
#[inline]
fn rgb_to_xyz(c: Vec3) -> Vec3 {
    Vec3::new(
        (10135552.0 / 24577794.0) * c.x
            + (8788810.0 / 24577794.0) * c.y
            + (4435075.0 / 24577794.0) * c.z,
        (2613072.0 / 12288897.0) * c.x
            + (8788810.0 / 12288897.0) * c.y
            + (887015.0 / 12288897.0) * c.z,
        (1425312.0 / 73733382.0) * c.x
            + (8788810.0 / 73733382.0) * c.y
            + (70074185.0 / 73733382.0) * c.z,
    )
}
#[inline]
fn xyz_to_rgb(c: Vec3) -> Vec3 {
    Vec3::new(
        3.241003275 * c.x - 1.537398934 * c.y - 0.498615861 * c.z,
        -0.969224334 * c.x + 1.875930071 * c.y + 0.041554224 * c.z,
        0.055639423 * c.x - 0.204011202 * c.y + 1.057148933 * c.z,
    )
}
/// XYZ -> YCxCz (linear opponent space).
#[inline]
fn xyz_to_ycxcz(c: Vec3) -> Vec3 {
    let c = c * INV_WHITE;
    Vec3::new(116.0 * c.y - 16.0, 500.0 * (c.x - c.y), 200.0 * (c.y - c.z))
}
#[inline]
fn ycxcz_to_xyz(c: Vec3) -> Vec3 {
    let y = (c.x + 16.0) / 116.0;
    Vec3::new(y + c.y / 500.0, y, y - c.z / 200.0) * WHITE
}
/// XYZ -> CIELAB with the Hunt adjustment (`a, b` scaled by `0.01 L`).
#[inline]
fn xyz_to_hunt_lab(c: Vec3) -> Vec3 {
    let c = c * INV_WHITE;
    const D: f32 = 6.0 / 29.0;
    let f = |t: f32| {
        if t > D * D * D {
            t.cbrt()
        } else {
            t / (3.0 * D * D) + 4.0 / 29.0
        }
    };
    let (fx, fy, fz) = (f(c.x), f(c.y), f(c.z));
    let l = 116.0 * fy - 16.0;
    Vec3::new(
        l,
        0.01 * l * 500.0 * (fx - fy),
        0.01 * l * 200.0 * (fy - fz),
    )
}
/// HyAB distance: `|dL| + ||(da, db)||`.
#[inline]
fn hyab(a: Vec3, b: Vec3) -> f32 {
    let d = a - b;
    d.x.abs() + (d.y * d.y + d.z * d.z).sqrt()
}

/// A 1D kernel pair whose outer product is the 2D kernel (`k2d(x, y) = kx[x] * ky[y]`).
struct Separable {
    kx: Vec<f32>,
    ky: Vec<f32>,
}

/// Correlate one channel with a sum of separable kernels, replicating edge pixels.
fn filter(src: &[f32], w: usize, h: usize, terms: &[Separable]) -> Vec<f32> {
    let mut out = vec![0.0f32; w * h];
    for t in terms {
        let rows = correlate_1d(src, w, h, &t.kx, (1, 0));
        for (o, v) in out.iter_mut().zip(correlate_1d(&rows, w, h, &t.ky, (0, 1))) {
            *o += v;
        }
    }
    out
}

/// Correlate with a centred 1D kernel along `step` = (1, 0) (rows) or (0, 1) (columns).
fn correlate_1d(src: &[f32], w: usize, h: usize, k: &[f32], step: (isize, isize)) -> Vec<f32> {
    let r = (k.len() / 2) as isize;
    let mut out = vec![0.0f32; w * h];
    for y in 0..h as isize {
        for x in 0..w as isize {
            let mut s = 0.0;
            for (i, kv) in k.iter().enumerate() {
                let d = i as isize - r;
                let (xx, yy) = (
                    (x + d * step.0).clamp(0, w as isize - 1),
                    (y + d * step.1).clamp(0, h as isize - 1),
                );
                s += kv * src[yy as usize * w + xx as usize];
            }
            out[y as usize * w + x as usize] = s;
        }
    }
    out
}

/// Contrast-sensitivity filter of one opponent channel: `a1 sqrt(pi/b1) exp(-pi^2 r^2/b1) +
/// a2 sqrt(pi/b2) exp(-pi^2 r^2/b2)` (r in degrees), normalised to sum 1; the radius covers 3
/// standard deviations of the widest Gaussian of all three channels.
fn csf_filter(ppd: f32, (a1, b1, a2, b2): (f32, f32, f32, f32)) -> Vec<Separable> {
    const MAX_B: f32 = 0.04;
    let r = (3.0 * (MAX_B / (2.0 * std::f32::consts::PI.powi(2))).sqrt() * ppd).ceil() as isize;
    let pi2 = std::f32::consts::PI.powi(2);
    let gauss = |b: f32| -> Vec<f32> {
        (-r..=r)
            .map(|i| (-pi2 * (i as f32 / ppd).powi(2) / b).exp())
            .collect()
    };
    let (g1, g2) = (gauss(b1), gauss(b2));
    let (s1, s2) = (g1.iter().sum::<f32>(), g2.iter().sum::<f32>());
    let (c1, c2) = (
        a1 * (std::f32::consts::PI / b1).sqrt(),
        a2 * (std::f32::consts::PI / b2).sqrt(),
    );
    let total = c1 * s1 * s1 + c2 * s2 * s2;
    let mut terms = vec![Separable {
        kx: g1.iter().map(|g| g * c1 / total).collect(),
        ky: g1,
    }];
    if a2 != 0.0 {
        terms.push(Separable {
            kx: g2.iter().map(|g| g * c2 / total).collect(),
            ky: g2,
        });
    }
    terms
}

/// Edge (`point = false`) or point detector along x: `-x g(x)` or `(x^2/s^2 - 1) g(x)` times
/// `g(y)`, positive weights normalised to sum 1 and negative ones to -1 (the sign depends on x
/// only, so the normalisation keeps the kernel separable).
fn feature_filter(ppd: f32, point: bool) -> Separable {
    let sd = 0.5 * 0.082 * ppd;
    let r = (3.0 * sd).ceil() as isize;
    let g: Vec<f32> = (-r..=r)
        .map(|i| (-((i * i) as f32) / (2.0 * sd * sd)).exp())
        .collect();
    let f: Vec<f32> = (-r..=r)
        .zip(&g)
        .map(|(i, g)| {
            if point {
                ((i * i) as f32 / (sd * sd) - 1.0) * g
            } else {
                -(i as f32) * g
            }
        })
        .collect();
    let gs: f32 = g.iter().sum();
    let pos: f32 = f.iter().filter(|v| **v > 0.0).sum::<f32>() * gs;
    let neg: f32 = -f.iter().filter(|v| **v < 0.0).sum::<f32>() * gs;
    Separable {
        kx: f
            .iter()
            .map(|v| if *v < 0.0 { v / neg } else { v / pos })
            .collect(),
        ky: g,
    }
}

/// LDR-FLIP's kernels at one viewing distance: the contrast-sensitivity filters of the three
/// opponent channels, and the edge and point detectors along x and (transposed) along y.
struct Kernels {
    csf: [Vec<Separable>; 3],
    edge: Separable,
    point: Separable,
    edge_t: Separable,
    point_t: Separable,
}

/// One image as LDR-FLIP compares it: per pixel, the filtered Hunt-adjusted Lab colour and the
/// edge and point feature magnitudes.
struct Prepared {
    lab: Vec<Vec3>,
    edges: Vec<f32>,
    points: Vec<f32>,
}

impl Kernels {
    /// The kernels for `ppd` pixels per degree.
    fn new(ppd: f32) -> Self {
        let csf = [
            csf_filter(ppd, (1.0, 0.0047, 0.0, 1e-5)),
            csf_filter(ppd, (1.0, 0.0053, 0.0, 1e-5)),
            csf_filter(ppd, (34.1, 0.04, 13.5, 0.025)),
        ];
        let (edge, point) = (feature_filter(ppd, false), feature_filter(ppd, true));
        let transpose = |s: &Separable| Separable {
            kx: s.ky.clone(),
            ky: s.kx.clone(),
        };
        let (edge_t, point_t) = (transpose(&edge), transpose(&point));
        Self {
            csf,
            edge,
            point,
            edge_t,
            point_t,
        }
    }

    /// An sRGB image (`w x h`) in opponent space, filtered for the colour comparison and the
    /// feature detectors.
    fn prepare(&self, img: &[Vec3], w: usize, h: usize) -> Prepared {
        let opp: Vec<Vec3> = img
            .iter()
            .map(|c| xyz_to_ycxcz(rgb_to_xyz(c.to_array().map(srgb_to_linear).into())))
            .collect();
        let lab = self.filtered_lab(&opp, w, h);
        let y: Vec<f32> = opp.iter().map(|c| (c.x + 16.0) / 116.0).collect();
        let along = |k: &Separable| filter(&y, w, h, std::slice::from_ref(k));
        let edges = magnitude(&along(&self.edge), &along(&self.edge_t));
        let points = magnitude(&along(&self.point), &along(&self.point_t));
        Prepared { lab, edges, points }
    }

    /// Each opponent channel filtered by its contrast sensitivity, then clamped to the RGB cube
    /// and converted to Hunt-adjusted Lab.
    fn filtered_lab(&self, opp: &[Vec3], w: usize, h: usize) -> Vec<Vec3> {
        let channel = |k: usize| -> Vec<f32> { opp.iter().map(|c| c[k]).collect() };
        let filtered: Vec<Vec<f32>> = (0..3)
            .map(|k| filter(&channel(k), w, h, &self.csf[k]))
            .collect();
        (0..w * h)
            .map(|i| {
                let rgb = xyz_to_rgb(ycxcz_to_xyz(Vec3::new(
                    filtered[0][i],
                    filtered[1][i],
                    filtered[2][i],
                )))
                .clamp(Vec3::ZERO, Vec3::ONE);
                xyz_to_hunt_lab(rgb_to_xyz(rgb))
            })
            .collect()
    }
}

/// Per-pixel length of the 2D vector `(a, b)`.
fn magnitude(a: &[f32], b: &[f32]) -> Vec<f32> {
    a.iter()
        .zip(b)
        .map(|(a, b)| (a * a + b * b).sqrt())
        .collect()
}

/// Per-pixel LDR-FLIP of two sRGB-encoded images (values in `[0, 1]`, row-major `w x h`).
pub fn ldr_flip(reference: &[Vec3], test: &[Vec3], w: usize, h: usize, ppd: f32) -> Vec<f32> {
    assert_eq!(reference.len(), w * h);
    assert_eq!(test.len(), w * h);
    let kernels = Kernels::new(ppd);
    let r = kernels.prepare(reference, w, h);
    let t = kernels.prepare(test, w, h);
    flip_error(&r, &t)
}

/// Per pixel, `dE = dC^(1 - dF)`: the remapped HyAB colour difference and the feature difference
/// of the prepared reference `r` and test `t`.
fn flip_error(r: &Prepared, t: &Prepared) -> Vec<f32> {
    const QC: f32 = 0.7;
    const PC: f32 = 0.4;
    const PT: f32 = 0.95;
    let cmax = hyab(
        xyz_to_hunt_lab(rgb_to_xyz(Vec3::Y)),
        xyz_to_hunt_lab(rgb_to_xyz(Vec3::Z)),
    )
    .powf(QC);
    let pccmax = PC * cmax;
    (0..r.lab.len())
        .map(|i| {
            let e = hyab(r.lab[i], t.lab[i]).powf(QC);
            let dc = if e < pccmax {
                (PT / pccmax) * e
            } else {
                PT + ((e - pccmax) / (cmax - pccmax)) * (1.0 - PT)
            };
            let df = ((r.edges[i] - t.edges[i])
                .abs()
                .max((r.points[i] - t.points[i]).abs())
                / std::f32::consts::SQRT_2)
                .sqrt();
            dc.powf(1.0 - df)
        })
        .collect()
}

/// ACES tone curve (inputs clamped to `>= 0`, output clamped to `[0, 1]`).
#[inline]
fn aces(x: f32) -> f32 {
    let x = x.max(0.0);
    let [k0, k1, k2, k3, k4, k5] = ACES;
    let den = k3 * x * x + k4 * x + k5;
    if !den.is_finite() {
        return 1.0;
    }
    ((k0 * x * x + k1 * x + k2) / den).clamp(0.0, 1.0)
}

/// Exposure range of HDR-FLIP for a reference image: `(start, stop, count)`.
pub fn exposure_range(reference: &[Vec3]) -> (f32, f32, usize) {
    // x where the ACES curve reaches t = 0.85 (the root of a quadratic).
    let t = 0.85f32;
    let [k0, k1, k2, k3, k4, k5] = ACES;
    let c0 = (k1 - k4 * t) / (k0 - k3 * t);
    let c1 = (k2 - k5 * t) / (k0 - k3 * t);
    let x_max = -0.5 * c0 + (0.25 * c0 * c0 - c1).sqrt();
    let mut lum: Vec<f32> = reference
        .iter()
        .map(|c| 0.2126 * c.x.max(0.0) + 0.7152 * c.y.max(0.0) + 0.0722 * c.z.max(0.0))
        .collect();
    lum.sort_by(f32::total_cmp);
    let y_hi = lum.last().copied().unwrap_or(0.0);
    if y_hi <= 0.0 || !y_hi.is_finite() {
        return (0.0, 0.0, 2);
    }
    // Median with linear interpolation between the two middle values (numpy's 50th percentile).
    let pos = 0.5 * (lum.len() - 1) as f32;
    let (lo, frac) = (pos.floor() as usize, pos.fract());
    let y_med = lum[lo] + frac * (lum[(lo + 1).min(lum.len() - 1)] - lum[lo]);
    let start = (x_max / y_hi).log2();
    // A reference that is black in more than half its pixels has no median exposure: one
    // exposure step past the start is then the range (FLIP itself would diverge).
    let stop = if y_med > 0.0 {
        (x_max / y_med).log2()
    } else {
        start + 1.0
    };
    (start, stop, ((stop - start).ceil() as usize).max(2))
}

/// HDR-FLIP of linear RGB images: per-pixel error map and its mean.
pub fn hdr_flip(reference: &[Vec3], test: &[Vec3], w: usize, h: usize) -> (Vec<f32>, f32) {
    let (start, stop, count) = exposure_range(reference);
    let step = (stop - start) / (count - 1).max(1) as f32;
    let ppd = default_ppd();
    // The exposures are independent: one task each, then the per-pixel maximum.
    use rayon::prelude::*;
    let map = (0..count)
        .into_par_iter()
        .map(|k| {
            let scale = (start + k as f32 * step).exp2();
            let ldr = |img: &[Vec3]| -> Vec<Vec3> {
                img.iter()
                    .map(|c| {
                        (*c * scale)
                            .to_array()
                            .map(|x| linear_to_srgb(aces(x)))
                            .into()
                    })
                    .collect()
            };
            ldr_flip(&ldr(reference), &ldr(test), w, h, ppd)
        })
        .reduce(
            || vec![0.0f32; w * h],
            |a, b| a.iter().zip(&b).map(|(a, b)| a.max(*b)).collect(),
        );
    let mean = map.iter().map(|&e| e as f64).sum::<f64>() / map.len().max(1) as f64;
    (map, mean as f32)
}
