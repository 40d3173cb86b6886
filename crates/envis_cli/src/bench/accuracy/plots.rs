//! The accuracy sweep's charts: error against time and against samples, wasted samples.

use super::*;

const MAIN: [(&str, &str); 10] = [
    ("paper-fractional", "#d62728"),
    ("paper-offset", "#8c564b"),
    ("paper-blocks", "#17becf"),
    ("paper-blocks-power", "#bcbd22"),
    ("paper-blocks-tiles2", "#e377c2"),
    ("paper-blocks-tiles4", "#7f7f7f"),
    ("paper-integer", "#ff9896"),
    ("global", "#1f77b4"),
    ("light", "#2ca02c"),
    ("brdf", "#9467bd"),
];

/// One series per main strategy through its budgets, `(x, y)` picked from the pooled points.
fn strategy_series(
    pool: &[Point],
    x: impl Fn(&Point) -> f64,
    y: impl Fn(&Point) -> f64,
) -> Vec<Series> {
    MAIN.iter()
        .map(|(name, color)| {
            let mut line: Vec<&Point> = pool.iter().filter(|p| p.strategy == *name).collect();
            line.sort_by_key(|p| p.budget);
            Series {
                name: name.to_string(),
                color,
                points: line.iter().map(|p| (x(p), y(p))).collect(),
                dashed: false,
            }
        })
        .collect()
}

/// An error-vs-time plot (log-log) of one material: one line per main strategy through its
/// budgets (geometric means over environments), the Pareto front dashed.
pub fn plot_error_vs_time(pts: &[Point], material: &str) -> Chart {
    let pool = pooled(pts, material);
    let t = |p: &Point| p.build_ms + p.shade_ms;
    let mut series = strategy_series(&pool, t, |p| p.relmse);
    let front = pareto_front(&pool)
        .into_iter()
        .map(|i| (t(&pool[i]), pool[i].relmse))
        .collect();
    series.push(Series {
        name: "Pareto front (all)".into(),
        color: "#000000",
        points: front,
        dashed: true,
    });
    let title = format!("{material}: relMSE vs time (geometric mean over environments)");
    Chart {
        title,
        xlabel: "time per frame, ms (build + shade, CPU)",
        ylabel: "relMSE",
        xlog: true,
        ylog: true,
        series,
    }
}

/// Error against the sample budget N = N_L + N_B (log-log) for one material.
pub fn plot_error_vs_samples(pts: &[Point], material: &str) -> Chart {
    let pool = pooled(pts, material);
    let title = format!("{material}: relMSE vs samples per pixel");
    Chart {
        title,
        xlabel: "samples per pixel, N = N_L + N_B",
        ylabel: "relMSE",
        xlog: true,
        ylog: true,
        series: strategy_series(&pool, |p| p.budget as f64, |p| p.relmse),
    }
}

/// The fraction of light samples wasted on negative cosines, against the budget, per strategy
/// (mean over materials and environments).
pub fn plot_wasted(pts: &[Point]) -> Chart {
    let keys: std::collections::BTreeSet<(String, usize)> =
        pts.iter().map(|p| (p.strategy.clone(), p.budget)).collect();
    let pool: Vec<Point> = keys
        .into_iter()
        .map(|(st, n)| {
            let sel: Vec<&Point> = pts
                .iter()
                .filter(|p| p.strategy == st && p.budget == n)
                .collect();
            Point {
                wasted: mean(sel.iter().map(|p| p.wasted)),
                ..sel[0].clone()
            }
        })
        .filter(|p| p.strategy != "brdf")
        .collect();
    let series = strategy_series(&pool, |p| p.budget as f64, |p| 100.0 * p.wasted)
        .into_iter()
        .filter(|s| !s.points.is_empty())
        .collect();
    Chart {
        title: "Light samples wasted on negative cosines (mean over materials and maps)".into(),
        xlabel: "samples per pixel, N = N_L + N_B",
        ylabel: "wasted light samples, %",
        xlog: true,
        ylog: false,
        series,
    }
}

/// File stem of a material's plots: `accuracy-<material>` with spaces and dots made dashes.
pub fn plot_stem(material: &str) -> String {
    format!("accuracy-{}", material.replace([' ', '.'], "-"))
}
