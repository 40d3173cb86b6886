//! Per-face sample counts: how `N_f = mu_f N_L` becomes taken pool samples and their weights,
//! fractional (unbiased, no popping) or integer (the paper's toggle; `docs/method.md`, step 6).

/// How the per-face counts `N_f` become samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
// Reflected for the Bevy camera component (`bevy_envis::EnvironmentSampling`, feature `bevy`).
#[cfg_attr(feature = "bevy", derive(bevy_reflect::Reflect))]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Counts {
    /// floor(N_f) samples of weight 1 plus one of weight frac(N_f), divided by N_f: unbiased, no popping.
    Fractional,
    /// round(N_f) samples, each weighted as if N_f were drawn (1 / (N_L mu_f p_f)): biased by a
    /// factor round(N_f) / N_f per face, and pops when round(N_f) changes. Exists to show that.
    Integer,
}

crate::display_as_serde_name!(Counts);

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
    fn fractional_weights_sum_to_n_f() {
        for &n in &[0.3f32, 1.0, 2.5, 7.999_999, 8.0] {
            let c = face_count(n, 8, Counts::Fractional);
            let sum = (c.taken.saturating_sub(1)) as f32 + c.last_weight;
            assert!((sum - n).abs() < 1e-5, "{n}: {c:?}");
        }
    }
}
