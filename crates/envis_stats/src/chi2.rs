//! The chi-square harness for samplers (after Mitsuba 3's `chi2.py`): a [`Domain`] says how
//! samples fall into bins and how a pdf integrates over a bin; [`Chi2Test`] draws the samples,
//! integrates the pdf per bin, pools sparse bins, and checks the p-value against [`FAMILY_ALPHA`]
//! Šidák-corrected over the test's checks. A failure writes the histogram and expected table.
//!
//! A sampler may fail to produce a sample (`None`: below the horizon, an empty face). Such
//! samples go to one extra "lost" bin whose expected count is what the pdf does not integrate to.

use super::{ChiSquare, FAMILY_ALPHA, chi_square, sidak, write_failure};
use envis::envmap::{dir_to_face_ab, face_ab_to_vec, face_rect_solid_angle};
use envis::sampling::warp::Frame;
use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// Where samples live, how they are binned, and how a density integrates over a bin.
pub trait Domain: Sync {
    type Point: Copy;
    /// Number of bins (without the lost bin).
    fn bins(&self) -> usize;
    /// The bin of a sample, or `None` when it lies outside the binned region.
    fn bin_of(&self, p: Self::Point) -> Option<usize>;
    /// Integral of `pdf` over bin `i`, in the measure the pdf is written in.
    fn integrate(&self, i: usize, pdf: &(dyn Fn(Self::Point) -> f64 + Sync)) -> f64;
    /// Whether [`integrate`](Domain::integrate) is exact (a sample in a bin of zero expectation
    /// then fails at once) or a quadrature (such bins are pooled like other sparse ones).
    fn exact(&self) -> bool {
        false
    }
}

/// A discrete domain of `n` outcomes (texels, faces): the "pdf" is a probability mass.
pub struct Discrete(pub usize);

impl Domain for Discrete {
    type Point = usize;
    fn bins(&self) -> usize {
        self.0
    }
    fn bin_of(&self, p: usize) -> Option<usize> {
        (p < self.0).then_some(p)
    }
    fn integrate(&self, i: usize, pmf: &(dyn Fn(usize) -> f64 + Sync)) -> f64 {
        pmf(i)
    }
    fn exact(&self) -> bool {
        true
    }
}

/// The unit sphere around `axis`, in `nt` bins of `sqrt(theta / pi)` (fine near the axis, where
/// lobes are narrow) by `np` bins of phi; each bin integrated by `q x q` midpoints of the
/// solid-angle pdf.
pub struct Sphere {
    frame: Frame,
    nt: usize,
    np: usize,
    q: usize,
}

impl Sphere {
    pub fn new(axis: Vec3) -> Self {
        Sphere {
            frame: Frame::new(axis.normalize()),
            nt: 24,
            np: 48,
            q: 16,
        }
    }
}

impl Domain for Sphere {
    type Point = Vec3;
    fn bins(&self) -> usize {
        self.nt * self.np
    }
    fn bin_of(&self, d: Vec3) -> Option<usize> {
        use std::f32::consts::PI;
        let l = self.frame.to_local(d);
        let t = (l.z.clamp(-1.0, 1.0).acos() / PI).sqrt();
        let phi = l.y.atan2(l.x).rem_euclid(2.0 * PI);
        let it = ((t * self.nt as f32) as usize).min(self.nt - 1);
        let ip = ((phi / (2.0 * PI) * self.np as f32) as usize).min(self.np - 1);
        Some(it * self.np + ip)
    }
    fn integrate(&self, i: usize, pdf: &(dyn Fn(Vec3) -> f64 + Sync)) -> f64 {
        use std::f64::consts::PI;
        let (it, ip, q) = (i / self.np, i % self.np, self.q);
        let mut m = 0.0;
        for a in 0..q {
            for b in 0..q {
                let t = (it as f64 + (a as f64 + 0.5) / q as f64) / self.nt as f64;
                let theta = PI * t * t;
                let dtheta = 2.0 * PI * t / (self.nt * q) as f64;
                let phi = 2.0 * PI * (ip as f64 + (b as f64 + 0.5) / q as f64) / self.np as f64;
                let dphi = 2.0 * PI / (self.np * q) as f64;
                let l = DVec3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                );
                let d = self.frame.to_world(l.as_vec3()).normalize();
                m += pdf(d) * theta.sin() * dtheta * dphi;
            }
        }
        m
    }
}

/// One cube face in `n x n` bins of its face coordinates (a, b), each integrated by `q x q`
/// sub-rectangles of exact solid angle: a solid-angle pdf only fits here if its cube-face
/// Jacobian is right. Directions on other faces are outside.
pub struct FacePlane {
    pub face: usize,
    pub n: usize,
    pub q: usize,
}

impl Domain for FacePlane {
    type Point = Vec3;
    fn bins(&self) -> usize {
        self.n * self.n
    }
    fn bin_of(&self, d: Vec3) -> Option<usize> {
        let (g, a, b) = dir_to_face_ab(d);
        let cell = |t: f32| (((t + 1.0) * 0.5 * self.n as f32) as usize).min(self.n - 1);
        (g == self.face).then(|| cell(b) * self.n + cell(a))
    }
    fn integrate(&self, i: usize, pdf: &(dyn Fn(Vec3) -> f64 + Sync)) -> f64 {
        let h = 2.0 / (self.n * self.q) as f64;
        let (bx, by) = (i % self.n, i / self.n);
        let mut m = 0.0;
        for y in by * self.q..(by + 1) * self.q {
            for x in bx * self.q..(bx + 1) * self.q {
                let (a0, b0) = (-1.0 + x as f64 * h, -1.0 + y as f64 * h);
                let d = face_ab_to_vec(self.face, (a0 + h / 2.0) as f32, (b0 + h / 2.0) as f32);
                m += pdf(d) * face_rect_solid_angle(a0, b0, a0 + h, b0 + h);
            }
        }
        m
    }
}

/// One chi-square check of a sampler against its pdf.
pub struct Chi2Test<D: Domain> {
    /// Names the check in messages and in the failure table's file name.
    pub name: String,
    pub domain: D,
    pub samples: usize,
    /// How many checks the calling test makes in all (the Šidák correction's `m`).
    pub checks: usize,
    /// Bins expecting fewer samples are pooled into one (Mitsuba: 5).
    pub min_expected: f64,
}

/// What a [`Chi2Test`] saw.
pub struct Chi2Outcome {
    pub name: String,
    pub result: ChiSquare,
    /// The corrected significance level the p-value is held to.
    pub alpha: f64,
    /// Observed and expected counts per bin; the last entry is the lost bin.
    pub observed: Vec<f64>,
    pub expected: Vec<f64>,
}

impl<D: Domain> Chi2Test<D> {
    pub fn new(name: impl Into<String>, domain: D, samples: usize, checks: usize) -> Self {
        Chi2Test {
            name: name.into(),
            domain,
            samples,
            checks,
            min_expected: 5.0,
        }
    }

    /// Draw `samples` points from `sample` and compare their histogram with `pdf` integrated per
    /// bin.
    pub fn run(
        &self,
        mut sample: impl FnMut() -> Option<D::Point>,
        pdf: impl Fn(D::Point) -> f64 + Sync,
    ) -> Chi2Outcome {
        let nb = self.domain.bins();
        let mut observed = vec![0.0f64; nb + 1];
        for _ in 0..self.samples {
            let bin = sample().and_then(|p| self.domain.bin_of(p));
            observed[bin.unwrap_or(nb)] += 1.0;
        }
        let n = self.samples as f64;
        let mut expected: Vec<f64> = (0..nb)
            .into_par_iter()
            .map(|i| self.domain.integrate(i, &pdf) * n)
            .collect();
        let inside: f64 = expected.iter().sum();
        expected.push((n - inside).max(0.0));
        let result = chi_square(&observed, &expected, self.min_expected, self.domain.exact());
        Chi2Outcome {
            name: self.name.clone(),
            result,
            alpha: sidak(FAMILY_ALPHA, self.checks),
            observed,
            expected,
        }
    }
}

impl Chi2Outcome {
    pub fn passed(&self) -> bool {
        self.result.p_value >= self.alpha
    }

    /// Panic unless the check passed; a failure first writes the histogram and expected table.
    pub fn assert(&self) {
        if self.passed() {
            return;
        }
        let mut t = String::from("bin\tobserved\texpected\n");
        for (i, (o, e)) in self.observed.iter().zip(&self.expected).enumerate() {
            let label = if i + 1 == self.observed.len() {
                "lost".to_string()
            } else {
                i.to_string()
            };
            t += &format!("{label}\t{o}\t{e:.3}\n");
        }
        let path = write_failure(&self.name, &t);
        panic!(
            "chi-square test '{}' rejected the sampler: p = {:.3e} < {:.3e} (Šidák-corrected \
             {FAMILY_ALPHA}), statistic {:.1}, {} dof, {} pooled bins; tables in {path}",
            self.name,
            self.result.p_value,
            self.alpha,
            self.result.statistic,
            self.result.dof,
            self.result.pooled_bins
        );
    }
}
