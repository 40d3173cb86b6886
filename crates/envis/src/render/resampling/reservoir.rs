//! One pixel's reservoir (weighted reservoir sampling, Chao's algorithm) and the sink that
//! streams the paper's light and BRDF samples into it as resampling candidates.

use crate::envmap::luminance;
use crate::render::estimator::Sink;
use crate::sampling::rng::Rng;
use glam::Vec3;

/// What a pixel keeps of its candidates: one selected direction, and the weights that make the
/// selection an unbiased estimator (`rgb * ucw` estimates the pixel's integral).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Reservoir {
    /// The selected direction (world space). Meaningless where `ucw` is 0.
    pub dir: Vec3,
    /// `W`, the unbiased contribution weight: an estimate of `1 / p(dir)`. 0: nothing selected,
    /// or the selected direction is blocked from the pixel's surface.
    pub ucw: f32,
    /// `M`, the confidence: the candidate batches (frames of candidates) behind the reservoir.
    pub m: f32,
    /// `p̂(dir)` at the reservoir's own pixel and frame: the luminance of `rgb`.
    pub target: f32,
    /// The unshadowed integrand at `dir` (BRDF x radiance x cosine), at the pixel and frame.
    pub rgb: Vec3,
    /// Whether `dir` is known to be unblocked from the pixel's surface (a shadow ray was cast,
    /// or nothing occludes). A reservoir found blocked has `ucw = 0`.
    pub visible: bool,
    /// The bright part's candidates here found it partly blocked (one seen, another not): a
    /// penumbra, where the next frame draws more of them ([`bright_light_samples`]). Carried
    /// through the combinations from the canonical pixel's candidates.
    ///
    /// [`bright_light_samples`]: super::bright_light_samples
    pub penumbra: bool,
}

impl Reservoir {
    /// The pixel's estimate: the integrand at the selected direction times its weight. The
    /// caller has made sure the direction is visible (or set `ucw` to 0).
    pub fn estimate(&self) -> Vec3 {
        self.rgb * self.ucw
    }

    /// Whether it holds a sample that can contribute.
    pub fn is_live(&self) -> bool {
        self.ucw > 0.0
    }
}

/// Streams candidates into a reservoir: each candidate of contribution `fl * scale` gets the
/// resampling weight `p̂ * scale / cos`, where `p̂ = lum(fl) * cos` is the target, so the weight
/// is the luminance of its contribution to the paper's MIS estimate. That estimate is unbiased,
/// so resampling it is (streaming RIS over an unbiased sum of weighted samples).
pub struct CandidateSink {
    rng: Rng,
    w_sum: f32,
    chosen: Option<(Vec3, Vec3, f32)>,
    /// Candidates offered (weights > 0 or not).
    pub offered: u32,
}

impl CandidateSink {
    pub fn new(rng: Rng) -> Self {
        CandidateSink {
            rng,
            w_sum: 0.0,
            chosen: None,
            offered: 0,
        }
    }

    /// The reservoir of the candidates seen, with confidence 1 (one batch). Visibility is not
    /// known yet.
    pub fn finish(self) -> Reservoir {
        match self.chosen {
            Some((dir, rgb, target)) if target > 0.0 && self.w_sum > 0.0 => Reservoir {
                dir,
                ucw: self.w_sum / target,
                m: 1.0,
                target,
                rgb,
                visible: false,
                penumbra: false,
            },
            _ => Reservoir {
                m: 1.0,
                ..Default::default()
            },
        }
    }
}

impl Sink for CandidateSink {
    #[inline]
    fn add(&mut self, dir: Vec3, fl: Vec3, cos: f32, scale: f32) {
        self.offered += 1;
        let y = luminance(fl);
        let w = y * scale;
        if !(w > 0.0 && w.is_finite()) {
            return;
        }
        self.w_sum += w;
        // Select with probability w / w_sum (the first live candidate always).
        if self.rng.next_f32() * self.w_sum < w {
            self.chosen = Some((dir, fl * cos, y * cos));
        }
    }
}
