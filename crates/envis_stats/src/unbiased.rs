//! The unbiasedness harness: an estimator run with `k` seeds gives a mean and a standard error
//! per region; each region's mean is compared with the reference by a two-sided Student's t test
//! (`k - 1` degrees of freedom: the error is itself estimated), and all the checks of one test
//! are held together to [`FAMILY_ALPHA`] by a Šidák correction. Running many checks at a fixed
//! `|z| > 3` would raise about one false alarm per fresh set of seeds; this does not.

use super::{FAMILY_ALPHA, mean_se, sidak, student_t_two_sided, write_failure};

/// One region's mean over seeds against its reference.
#[derive(Clone, Debug)]
pub struct MeanCheck {
    pub label: String,
    pub mean: f64,
    pub se: f64,
    /// Seeds the mean is over.
    pub seeds: usize,
    pub reference: f64,
}

impl MeanCheck {
    /// From per-seed values.
    pub fn from_values(label: impl Into<String>, values: &[f64], reference: f64) -> Self {
        let (mean, se) = mean_se(values);
        MeanCheck {
            label: label.into(),
            mean,
            se,
            seeds: values.len(),
            reference,
        }
    }

    /// The deviation in standard errors, after allowing 1e-6 relative for f32 rounding (a
    /// deterministic difference no seed count removes).
    pub fn z(&self) -> f64 {
        let dev = ((self.mean - self.reference).abs() - 1e-6 * self.reference.abs()).max(0.0);
        if dev == 0.0 {
            0.0
        } else if self.se > 0.0 {
            dev / self.se
        } else {
            f64::INFINITY
        }
    }

    /// Two-sided p-value of the deviation.
    pub fn p_value(&self) -> f64 {
        let z = self.z();
        if z == 0.0 {
            1.0
        } else if z.is_infinite() {
            0.0
        } else {
            student_t_two_sided((self.seeds.max(2) - 1) as f64, z)
        }
    }
}

/// The checks of one test, held together to [`FAMILY_ALPHA`].
#[derive(Default)]
pub struct UnbiasedTest {
    pub name: String,
    pub checks: Vec<MeanCheck>,
}

impl UnbiasedTest {
    pub fn new(name: impl Into<String>) -> Self {
        UnbiasedTest {
            name: name.into(),
            checks: Vec::new(),
        }
    }

    pub fn push(&mut self, c: MeanCheck) {
        self.checks.push(c);
    }

    /// The significance level each check is held to.
    pub fn alpha(&self) -> f64 {
        sidak(FAMILY_ALPHA, self.checks.len())
    }

    /// The checks that fail at the corrected level.
    pub fn failures(&self) -> Vec<&MeanCheck> {
        let a = self.alpha();
        self.checks.iter().filter(|c| c.p_value() < a).collect()
    }

    /// Panic if any check fails; a failure first writes every check to a table.
    pub fn assert(&self) {
        assert!(
            !self.checks.is_empty(),
            "{}: no checks were made",
            self.name
        );
        let bad = self.failures();
        let worst = self.checks.iter().map(MeanCheck::z).fold(0.0, f64::max);
        eprintln!(
            "{}: {} checks, worst |t| = {worst:.2}, each held to p >= {:.2e}",
            self.name,
            self.checks.len(),
            self.alpha()
        );
        if bad.is_empty() {
            return;
        }
        let mut t = String::from("label\tmean\tse\tseeds\treference\tt\tp\n");
        for c in &self.checks {
            t += &format!(
                "{}\t{}\t{}\t{}\t{}\t{:.3}\t{:.3e}\n",
                c.label,
                c.mean,
                c.se,
                c.seeds,
                c.reference,
                c.z(),
                c.p_value()
            );
        }
        let path = write_failure(&self.name, &t);
        let lines: Vec<String> = bad
            .iter()
            .map(|c| {
                format!(
                    "{}: mean {:.6} ref {:.6} se {:.2e} t {:.2} p {:.2e}",
                    c.label,
                    c.mean,
                    c.reference,
                    c.se,
                    c.z(),
                    c.p_value()
                )
            })
            .collect();
        panic!(
            "{}: {} of {} checks biased at the Šidák-corrected level {:.2e} (family {FAMILY_ALPHA}); \
             all checks in {path}:\n{}",
            self.name,
            bad.len(),
            self.checks.len(),
            self.alpha(),
            lines.join("\n")
        );
    }
}
