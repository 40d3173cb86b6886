//! The accuracy sweep's verdict on sub-face tiles (`--tiles K`, issue 14 part 2): for each
//! material and budget, the error of `K x K` tiles against whole faces (`paper-blocks`, `K = 1`)
//! at equal time, and the wasted light-sample fraction over the real maps.

use super::accuracy::{Config, Point, mean, pooled};
use std::fmt::Write as _;

/// Tiles per face side swept beside `K = 1`.
pub const SWEPT: [usize; 2] = [2, 4];

/// The sweep's label of `k x k` tiles on the default pool layout.
pub fn label(k: usize) -> String {
    format!("paper-blocks-tiles{k}")
}

/// The strategy a `K` is measured as (`K = 1`: whole faces).
fn strategy(k: usize) -> String {
    if k == 1 {
        "paper-blocks".into()
    } else {
        label(k)
    }
}

/// The relMSE of `curve` (points `(time, relMSE)`) at time `t`, interpolated linearly in log-log
/// between the neighbouring points, and extrapolated from the nearest segment outside them.
pub fn error_at_time(curve: &[(f64, f64)], t: f64) -> f64 {
    let mut c: Vec<(f64, f64)> = curve
        .iter()
        .filter(|(t, e)| *t > 0.0 && *e > 0.0)
        .map(|&(t, e)| (t.ln(), e.ln()))
        .collect();
    c.sort_by(|a, b| a.0.total_cmp(&b.0));
    match c.len() {
        0 => f64::NAN,
        1 => c[0].1.exp(),
        len => {
            let x = t.ln();
            let i = c.partition_point(|p| p.0 < x).clamp(1, len - 1);
            let ((x0, y0), (x1, y1)) = (c[i - 1], c[i]);
            let s = if x1 > x0 { (y1 - y0) / (x1 - x0) } else { 0.0 };
            (y0 + s * (x - x0)).exp()
        }
    }
}

/// The "Tiles" section of `accuracy-vs-time.md`.
pub fn report(md: &mut String, cfg: &Config, pts: &[Point]) {
    let ks: Vec<usize> = std::iter::once(1).chain(SWEPT).collect();
    let _ = writeln!(
        md,
        "## Sub-face tiles (`--tiles K`) against whole faces\n\nEach K on the default pool layout (16 blocks). Per material and budget N: relMSE (time in ms), geometric mean over environments, and for K > 1 the ratio of its relMSE to K = 1's at the same time (K = 1's error-vs-time curve interpolated log-log at K's time; below 1: K is better per unit time).\n"
    );
    let mut verdict = vec![(0usize, 0usize, 1.0f64); ks.len()];
    for (mname, _) in &cfg.materials {
        material_table(md, cfg, &pooled(pts, mname), mname, &ks, &mut verdict);
    }
    for (i, &k) in ks.iter().enumerate().skip(1) {
        let (met, cases, worst) = verdict[i];
        let _ = writeln!(
            md,
            "K = {k}: on or below K = 1's error-vs-time curve in **{met} of {cases}** (material, N) cases; worst ratio ×{worst:.2}."
        );
    }
    wasted_line(md, cfg, pts, &ks);
}

/// Per K: the (material, N) cases on or below K = 1's error-vs-time curve, the cases compared,
/// and the worst ratio.
type Verdict = (usize, usize, f64);

/// A point's time, ms: the build and the shading.
fn time(p: &Point) -> f64 {
    p.build_ms + p.shade_ms
}

/// One material's table (`pool`: its points pooled over environments): a row per budget, a
/// column per K; each K > 1 is compared with K = 1 at equal time and tallied into `verdict`.
fn material_table(
    md: &mut String,
    cfg: &Config,
    pool: &[Point],
    mname: &str,
    ks: &[usize],
    verdict: &mut [Verdict],
) {
    let get = |k: usize, n: usize| {
        pool.iter()
            .find(|p| p.strategy == strategy(k) && p.budget == n)
    };
    let base: Vec<(f64, f64)> = cfg
        .budgets
        .iter()
        .filter_map(|&n| get(1, n).map(|p| (time(p), p.relmse)))
        .collect();
    let _ = writeln!(
        md,
        "**{mname}**\n\n| N | {} |\n|---:|{}",
        ks.iter()
            .map(|k| format!("K = {k}"))
            .collect::<Vec<_>>()
            .join(" | "),
        "---:|".repeat(ks.len())
    );
    for &n in &cfg.budgets {
        let _ = write!(md, "| {n} |");
        for (i, &k) in ks.iter().enumerate() {
            let Some(p) = get(k, n) else {
                md.push_str(" — |");
                continue;
            };
            let _ = write!(md, " {:.3e} ({:.2})", p.relmse, time(p));
            if k > 1 {
                let r = p.relmse / error_at_time(&base, time(p));
                let _ = write!(md, " ×{r:.2}");
                let v = &mut verdict[i];
                v.0 += (r <= 1.0) as usize;
                v.1 += 1;
                v.2 = v.2.max(r);
            }
            md.push_str(" |");
        }
        md.push('\n');
    }
    md.push('\n');
}

/// The mean wasted light-sample fraction per K, over the real maps (the files; the built-in
/// skies excluded).
fn wasted_line(md: &mut String, cfg: &Config, pts: &[Point], ks: &[usize]) {
    let files: Vec<&String> = cfg
        .envs
        .iter()
        .filter(|e| !e.starts_with("builtin"))
        .collect();
    let wasted = |k: usize| {
        100.0
            * mean(
                pts.iter()
                    .filter(|p| p.strategy == strategy(k) && files.contains(&&p.env))
                    .map(|p| p.wasted),
            )
    };
    let _ = writeln!(
        md,
        "\nMean wasted (negative-cosine) light-sample fraction over the {} map files, all materials and budgets: {}.\n",
        files.len(),
        ks.iter()
            .map(|&k| format!("K = {k}: **{:.1}%**", wasted(k)))
            .collect::<Vec<_>>()
            .join(", ")
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_at_time_interpolates_log_log() {
        // relMSE proportional to 1 / time: a straight line in log-log.
        let curve = [(1.0, 1.0), (4.0, 0.25), (16.0, 0.0625)];
        for t in [0.5, 1.0, 2.0, 8.0, 32.0] {
            assert!((error_at_time(&curve, t) - 1.0 / t).abs() < 1e-12, "t {t}");
        }
        assert!(error_at_time(&[], 1.0).is_nan());
        assert_eq!(error_at_time(&[(2.0, 0.5)], 9.0), 0.5);
    }
}
