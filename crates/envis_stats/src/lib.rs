//! Statistics for tests and benchmarks, in the manner of Mitsuba 3's `chi2.py`: one chi-square
//! harness over a sampling domain ([`chi2`]), one harness for unbiasedness checks of estimators
//! ([`unbiased`]), and a Šidák correction across a test's repeated checks so that a test's
//! false-alarm rate is [`FAMILY_ALPHA`] however many checks it makes. Distribution functions come
//! from `statrs` (maintained, with tested special functions) instead of home-made ones.

pub mod chi2;
pub mod unbiased;

pub use chi2::{Chi2Test, Discrete, Domain, FacePlane, Sphere};
pub use unbiased::{MeanCheck, UnbiasedTest};

use statrs::distribution::{ChiSquared, ContinuousCDF, StudentsT};

/// The probability that one test (all of its checks together) fails although every sampler and
/// estimator is right. Mitsuba's chi2 tests use the same 1%.
pub const FAMILY_ALPHA: f64 = 0.01;

/// Šidák's correction: the significance level of each of `m` independent checks that keeps the
/// chance of any false alarm at `alpha`.
pub fn sidak(alpha: f64, m: usize) -> f64 {
    1.0 - (1.0 - alpha).powf(1.0 / m.max(1) as f64)
}

/// Where a failing test writes its tables (histogram, expected counts, checks):
/// `$ENVIS_TEST_OUT` or the system's temporary folder, under `envis-stats/`.
pub fn failure_dir() -> std::path::PathBuf {
    std::env::var_os("ENVIS_TEST_OUT")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(std::env::temp_dir)
        .join("envis-stats")
}

/// Write `text` to `failure_dir()/name` (name made file-safe); returns the path, or what went
/// wrong, for the failure message.
pub(crate) fn write_failure(name: &str, text: &str) -> String {
    let safe: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    let dir = failure_dir();
    let path = dir.join(format!("{safe}.tsv"));
    match std::fs::create_dir_all(&dir).and_then(|_| std::fs::write(&path, text)) {
        Ok(()) => path.display().to_string(),
        Err(e) => format!("(could not write {}: {e})", path.display()),
    }
}

/// Result of a chi-square goodness-of-fit test.
#[derive(Clone, Debug)]
pub struct ChiSquare {
    pub statistic: f64,
    pub dof: usize,
    pub p_value: f64,
    /// Bins that were pooled because their expected count was below the threshold.
    pub pooled_bins: usize,
}

/// Pearson's test of `observed` counts against `expected` counts (same total). Bins with expected
/// count below `min_expected` are pooled into one bin (as Mitsuba's chi2 test does). With exact
/// expectations (`zero_is_failure`), an observation in a bin of zero expectation fails at once
/// (p = 0); with quadrature-estimated expectations such bins are pooled like the other sparse ones.
pub fn chi_square(
    observed: &[f64],
    expected: &[f64],
    min_expected: f64,
    zero_is_failure: bool,
) -> ChiSquare {
    assert_eq!(observed.len(), expected.len());
    let (mut stat, mut dof, mut pooled_o, mut pooled_e, mut pooled) =
        (0.0, 0usize, 0.0, 0.0, 0usize);
    for (&o, &e) in observed.iter().zip(expected) {
        if zero_is_failure && e <= 0.0 && o > 0.0 {
            return ChiSquare {
                statistic: f64::INFINITY,
                dof: 0,
                p_value: 0.0,
                pooled_bins: 0,
            };
        }
        if e < min_expected {
            pooled_o += o;
            pooled_e += e;
            pooled += 1;
        } else {
            stat += (o - e) * (o - e) / e;
            dof += 1;
        }
    }
    if pooled_e > 0.0 {
        stat += (pooled_o - pooled_e) * (pooled_o - pooled_e) / pooled_e;
        dof += 1;
    }
    let dof = dof.saturating_sub(1).max(1);
    ChiSquare {
        statistic: stat,
        dof,
        p_value: chi2_survival(dof as f64, stat),
        pooled_bins: pooled,
    }
}

/// P(X > x) for X ~ chi-square with `dof` degrees of freedom.
pub fn chi2_survival(dof: f64, x: f64) -> f64 {
    ChiSquared::new(dof).map_or(f64::NAN, |d| d.sf(x))
}

/// P(|T| > t) for T ~ Student's t with `dof` degrees of freedom (two-sided).
pub fn student_t_two_sided(dof: f64, t: f64) -> f64 {
    StudentsT::new(0.0, 1.0, dof).map_or(f64::NAN, |d| 2.0 * d.sf(t.abs()))
}

/// Mean and standard error of the mean.
pub fn mean_se(xs: &[f64]) -> (f64, f64) {
    let n = xs.len() as f64;
    let m = xs.iter().sum::<f64>() / n;
    let var = xs.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0).max(1.0);
    (m, (var / n).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn chi2_survival_known_values() {
        // P(chi2_1 > 3.841) = 0.05, P(chi2_10 > 18.307) = 0.05, P(chi2_100 > 124.342) = 0.05
        for &(k, x) in &[(1.0, 3.841_458_8), (10.0, 18.307_038), (100.0, 124.342_11)] {
            assert!((chi2_survival(k, x) - 0.05).abs() < 1e-5, "{k} {x}");
        }
        // P(|T_10| > 2.228) = 0.05, P(|T_39| > 2.7079) = 0.01
        assert!((student_t_two_sided(10.0, 2.228_139) - 0.05).abs() < 1e-5);
        assert!((student_t_two_sided(39.0, 2.707_913) - 0.01).abs() < 1e-5);
    }

    #[test]
    fn sidak_keeps_the_family_rate() {
        let a = sidak(0.01, 100);
        assert!((1.0 - (1.0 - a).powi(100) - 0.01).abs() < 1e-12);
        assert!((sidak(0.05, 1) - 0.05).abs() < 1e-15);
    }
}
