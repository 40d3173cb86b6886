//! Small statistics helpers shared by tests and benchmarks: Pearson's chi-square test with
//! pooling of sparse bins, and the chi-square survival function (regularised upper incomplete gamma).

/// ln Gamma(x) for x > 0 (Lanczos, g = 7, n = 9).
pub fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        return (std::f64::consts::PI / (std::f64::consts::PI * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let t = x + 7.5;
    let mut a = C[0];
    for (i, &c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised upper incomplete gamma Q(a, x) (series for x < a + 1, continued fraction otherwise).
pub fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let lg = ln_gamma(a);
    if x < a + 1.0 {
        let (mut sum, mut term, mut ap) = (1.0 / a, 1.0 / a, a);
        for _ in 0..10_000 {
            ap += 1.0;
            term *= x / ap;
            sum += term;
            if term.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        1.0 - sum * (-x + a * x.ln() - lg).exp()
    } else {
        // Lentz's method for the continued fraction.
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        (-x + a * x.ln() - lg).exp() * h
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
        p_value: gamma_q(dof as f64 / 2.0, stat / 2.0),
        pooled_bins: pooled,
    }
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
            assert!((gamma_q(k / 2.0, x / 2.0) - 0.05).abs() < 1e-5, "{k} {x}");
        }
    }
}
