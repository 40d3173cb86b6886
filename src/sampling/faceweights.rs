//! Per-pixel face weighting (the seed's "dynamic sample distribution").
//!
//! `C_f = sum over the 4 corners of max(0, <n, corner>)`, `F_f = C_f / sum C_f`,
//! `mu_f = F_f I_f / sum(F_f I_f)`, `N_f = mu_f N_L`. A face whose four corners all have
//! `cos <= 0` gets `C_f = 0` and is skipped: that is exact, since `<n, p>` is linear over the planar
//! face and so is `<= 0` on all of it. Conversely any face with a point of positive cosine has a
//! corner of positive cosine, so `mu_f > 0` wherever the integrand can be non-zero: light
//! sampling alone is unbiased.

use glam::Vec3;

/// The 8 unit cube-corner directions `(+-1, +-1, +-1) / sqrt(3)`, index bits (x, y, z): bit set = negative.
pub fn corner(i: usize) -> Vec3 {
    let s = |bit: usize| if i & bit != 0 { -1.0 } else { 1.0 };
    Vec3::new(s(1), s(2), s(4)) / 3f32.sqrt()
}

/// The four corner indices of each face (+X, -X, +Y, -Y, +Z, -Z).
pub const FACE_CORNERS: [[usize; 4]; 6] = [
    [0, 2, 4, 6], // x > 0: bit 1 clear
    [1, 3, 5, 7], // x < 0
    [0, 1, 4, 5], // y > 0: bit 2 clear
    [2, 3, 6, 7], // y < 0
    [0, 1, 2, 3], // z > 0: bit 4 clear
    [4, 5, 6, 7], // z < 0
];

/// How the per-face counts `N_f` become samples.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, clap::ValueEnum,
)]
// Reflected for the Bevy camera component (`app::EnvironmentSampling`); the core stays Bevy-free.
#[cfg_attr(feature = "app", derive(bevy::reflect::Reflect))]
#[serde(rename_all = "lowercase")]
pub enum Counts {
    /// floor(N_f) samples of weight 1 plus one of weight frac(N_f), divided by N_f: unbiased, no popping.
    Fractional,
    /// round(N_f) samples, each weighted as if N_f were drawn (1 / (N_L mu_f p_f)): biased by a
    /// factor round(N_f) / N_f per face, and pops when round(N_f) changes. Exists to show that.
    Integer,
}

crate::vocab::display_as_value_enum!(Counts);

/// Face weights of one pixel.
#[derive(Clone, Copy, Debug, Default)]
pub struct FaceWeights {
    /// Pseudo form factors `F_f`.
    pub form: [f32; 6],
    /// `mu_f`.
    pub mu: [f32; 6],
}

/// `C_f` for normal `n` (need not be unit: only signs and ratios matter).
#[inline]
pub fn corner_cosines(n: Vec3) -> [f32; 6] {
    let cos: [f32; 8] = std::array::from_fn(|i| n.dot(corner(i)).max(0.0));
    std::array::from_fn(|f| FACE_CORNERS[f].iter().map(|&c| cos[c]).sum())
}

/// `F_f` and `mu_f` for normal `n` and face energies `I_f`. With `use_cosine == false` this is
/// the `light` baseline (`mu_f = I_f / sum I_f`). All-zero when nothing can contribute.
pub fn face_weights(n: Vec3, energy: &[f64; 6], use_cosine: bool) -> FaceWeights {
    let c = if use_cosine {
        corner_cosines(n)
    } else {
        [1.0; 6]
    };
    let csum: f32 = c.iter().sum();
    let mut w = FaceWeights::default();
    if csum <= 0.0 {
        return w;
    }
    let form: [f32; 6] = std::array::from_fn(|f| c[f] / csum);
    let fi: [f64; 6] = std::array::from_fn(|f| form[f] as f64 * energy[f]);
    let total: f64 = fi.iter().sum();
    w.form = form;
    if total > 0.0 {
        w.mu = std::array::from_fn(|f| (fi[f] / total) as f32);
    }
    w
}

/// Which pool samples a face uses, and with what weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaceCount {
    /// Samples taken from the pool: floor(N_f) (+1 if frac > 0) or round(N_f), at most M.
    pub taken: usize,
    /// Weight of the last taken sample (frac for fractional counts; 1 otherwise).
    pub last_weight: f32,
    /// The count the estimator divides by, i.e. the sampling density is `density * p_f(w)`.
    pub density: f32,
}

/// Turn `N_f = mu_f N_L` into taken samples, clamped to the pool size `m` (clamping only changes
/// the count that is divided by, so it stays unbiased in fractional mode).
#[inline]
pub fn face_count(n_f: f32, m: usize, counts: Counts) -> FaceCount {
    let n_f = if n_f.is_finite() {
        n_f.clamp(0.0, m as f32)
    } else {
        0.0
    };
    if n_f <= 0.0 {
        return FaceCount {
            taken: 0,
            last_weight: 0.0,
            density: 0.0,
        };
    }
    match counts {
        Counts::Fractional => {
            let whole = n_f.floor();
            let frac = n_f - whole;
            if frac > 0.0 {
                FaceCount {
                    taken: whole as usize + 1,
                    last_weight: frac,
                    density: n_f,
                }
            } else {
                FaceCount {
                    taken: whole as usize,
                    last_weight: 1.0,
                    density: n_f,
                }
            }
        }
        Counts::Integer => FaceCount {
            taken: (n_f.round() as usize).min(m),
            last_weight: 1.0,
            density: n_f,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corners_belong_to_their_faces() {
        let axes = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
        for f in 0..6 {
            for &c in &FACE_CORNERS[f] {
                assert!((corner(c).dot(axes[f]) - 1.0 / 3f32.sqrt()).abs() < 1e-6);
            }
        }
    }

    #[test]
    fn fractional_weights_sum_to_n_f() {
        for &n in &[0.3f32, 1.0, 2.5, 7.999_999, 8.0] {
            let c = face_count(n, 8, Counts::Fractional);
            let sum = (c.taken.saturating_sub(1)) as f32 + c.last_weight;
            assert!((sum - n).abs() < 1e-5, "{n}: {c:?}");
        }
    }
}
