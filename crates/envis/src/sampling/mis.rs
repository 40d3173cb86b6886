//! Multiple importance sampling weights in the multi-sample form (Veach 1997): each technique's
//! *effective density* is its sample count times its pdf, `n_L(w) = N_f p_f(w)` for the light
//! pool and `n_B(w) = N_B p_B(w)` for the BRDF.

/// MIS heuristic.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
// Reflected for the Bevy camera component (`bevy_envis::EnvironmentSampling`, feature `bevy`).
#[cfg_attr(feature = "bevy", derive(bevy_reflect::Reflect))]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Heuristic {
    /// `w_a = n_a / (n_a + n_b)`.
    Balance,
    /// `w_a = n_a^2 / (n_a^2 + n_b^2)`.
    Power,
}

crate::display_as_serde_name!(Heuristic);

/// Weight of technique `a` with effective density `na` against `nb`. Returns 1 when `nb == 0`
/// and 0 when `na == 0` (so a technique that cannot produce `w` never takes weight for it).
#[inline]
pub fn weight(h: Heuristic, na: f32, nb: f32) -> f32 {
    if na <= 0.0 {
        return 0.0;
    }
    if nb <= 0.0 {
        return 1.0;
    }
    match h {
        Heuristic::Balance => na / (na + nb),
        Heuristic::Power => {
            // Divide through by the larger density to keep the squares in range.
            let m = na.max(nb);
            let (a, b) = (na / m, nb / m);
            a * a / (a * a + b * b)
        }
    }
}

/// `weight(h, na, nb) / na` with one division: balance `1 / (na + nb)`, power `na / (na^2 + nb^2)`.
/// This is the factor a sample of technique `a` (effective density `na > 0`) is multiplied by.
#[inline]
pub fn weight_over_density(h: Heuristic, na: f32, nb: f32) -> f32 {
    match h {
        Heuristic::Balance => 1.0 / (na + nb),
        Heuristic::Power => {
            let m = na.max(nb);
            let (a, b) = (na / m, nb / m);
            a / (m * (a * a + b * b))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn weight_over_density_matches() {
        for h in [Heuristic::Balance, Heuristic::Power] {
            for &(a, b) in &[(1.0f32, 2.0f32), (3.0, 0.0), (1e-10, 1e10), (5e3, 2.0)] {
                let x = weight_over_density(h, a, b);
                let y = weight(h, a, b) / a;
                assert!(
                    (x - y).abs() <= 1e-5 * y.abs().max(1e-35),
                    "{h:?} {a} {b}: {x} vs {y}"
                );
            }
        }
    }
    #[test]
    fn weights_partition_unity() {
        for h in [Heuristic::Balance, Heuristic::Power] {
            for &(a, b) in &[(1.0f32, 2.0f32), (1e30, 1e-30), (3.0, 3.0)] {
                assert!((weight(h, a, b) + weight(h, b, a) - 1.0).abs() < 1e-6);
            }
        }
    }
}
