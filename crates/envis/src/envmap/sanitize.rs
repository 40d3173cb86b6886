//! Bad texels (NaN, Inf, negative, overflowing): clamped and counted, never passed on.

use glam::Vec3;

/// Per-map report of texels that were not finite and non-negative: they are clamped to zero and
/// counted here, and never reach a distribution.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct SanitizeReport {
    /// Texels with at least one NaN channel.
    pub nan: u64,
    /// Texels with an infinite channel (and no NaN).
    pub inf: u64,
    /// Texels with a finite negative channel (and no NaN or Inf).
    pub negative: u64,
    /// Texels with a finite channel above [`MAX_RADIANCE`] (clamped to it): such values would
    /// overflow f32 in luminance, filtering or CDF sums.
    pub huge: u64,
}

/// Largest radiance kept; finite values above it are clamped to it (and counted).
pub const MAX_RADIANCE: f32 = 1e30;

impl SanitizeReport {
    pub fn total(&self) -> u64 {
        self.nan + self.inf + self.negative + self.huge
    }
    pub fn add(&mut self, o: SanitizeReport) {
        self.nan += o.nan;
        self.inf += o.inf;
        self.negative += o.negative;
        self.huge += o.huge;
    }
}

impl std::fmt::Display for SanitizeReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} NaN, {} Inf, {} negative texels clamped to 0",
            self.nan, self.inf, self.negative
        )?;
        if self.huge > 0 {
            write!(
                f,
                ", {} texels above {MAX_RADIANCE:e} clamped to it",
                self.huge
            )?;
        }
        Ok(())
    }
}

/// Clamp one RGB texel: every channel that is NaN, infinite or negative becomes 0, and a finite
/// channel above [`MAX_RADIANCE`] becomes `MAX_RADIANCE`. Counts the texel once, under its first
/// problem in the order NaN, Inf, negative, huge.
#[inline]
pub fn sanitize_texel(c: Vec3, report: &mut SanitizeReport) -> Vec3 {
    let a = c.to_array();
    if a.iter().any(|x| x.is_nan()) {
        report.nan += 1;
    } else if a.iter().any(|x| x.is_infinite()) {
        report.inf += 1;
    } else if a.iter().any(|&x| x < 0.0) {
        report.negative += 1;
    } else if a.iter().any(|&x| x > MAX_RADIANCE) {
        report.huge += 1;
    } else {
        return c;
    }
    Vec3::from_array(a.map(|x| {
        if x.is_finite() && x > 0.0 {
            x.min(MAX_RADIANCE)
        } else {
            0.0
        }
    }))
}
