//! The strategies of the accuracy sweep: the paper's method per pool layout and tiling, the
//! baselines, and uneven light/BRDF splits.

use super::*;

/// The (label, settings) pairs swept at total budget `n`. The `paper-*` rows but `paper-offset`
/// and `paper-blocks` are the paper's method exactly: one shared pool.
pub(super) fn strategies(n: usize) -> Vec<(String, Settings)> {
    let half = Settings {
        light_samples: n / 2,
        brdf_samples: n - n / 2,
        pool_layout: envis::render::PoolLayout::Shared,
        ..Default::default()
    };
    let mut v = paper_rows(half);
    v.extend(tile_rows(half));
    v.extend(baseline_rows(half));
    if n >= 8 {
        v.extend(fraction_rows(n, half));
    }
    v
}

/// The paper's method at an even split `half`: per pool layout, power MIS and integer counts.
fn paper_rows(half: Settings) -> Vec<(String, Settings)> {
    vec![
        ("paper-fractional".to_string(), half),
        (
            "paper-offset".to_string(),
            Settings {
                pool_layout: envis::render::PoolLayout::Offset,
                ..half
            },
        ),
        (
            "paper-blocks".to_string(),
            Settings {
                pool_layout: envis::render::PoolLayout::Blocks,
                ..half
            },
        ),
        (
            "paper-blocks-power".to_string(),
            Settings {
                pool_layout: envis::render::PoolLayout::Blocks,
                heuristic: Heuristic::Power,
                ..half
            },
        ),
        (
            "paper-integer".to_string(),
            Settings {
                counts: Counts::Integer,
                ..half
            },
        ),
    ]
}

/// Sub-face tiles on the default pool layout (`--tiles K`): against paper-blocks (K = 1).
fn tile_rows(half: Settings) -> Vec<(String, Settings)> {
    let mut v = Vec::new();
    for k in crate::bench::tiles::SWEPT {
        v.push((
            crate::bench::tiles::label(k),
            Settings {
                pool_layout: envis::render::PoolLayout::Blocks,
                tiles: k,
                ..half
            },
        ));
    }
    v
}

/// The baselines at an even split `half`: global (power MIS), light alone, BRDF alone.
fn baseline_rows(half: Settings) -> [(String, Settings); 3] {
    [
        (
            "global".to_string(),
            Settings {
                strategy: Strategy::Global,
                heuristic: Heuristic::Power,
                ..half
            },
        ),
        (
            "light".to_string(),
            Settings {
                strategy: Strategy::Light,
                ..half
            },
        ),
        (
            "brdf".to_string(),
            Settings {
                strategy: Strategy::Brdf,
                ..half
            },
        ),
    ]
}

/// paper-fractional and global with a quarter and three quarters of budget `n` on the light.
fn fraction_rows(n: usize, half: Settings) -> Vec<(String, Settings)> {
    let mut v = Vec::new();
    for (tag, nl) in [("L1/4", n / 4), ("L3/4", 3 * n / 4)] {
        let s = Settings {
            light_samples: nl,
            brdf_samples: n - nl,
            ..half
        };
        v.push((format!("paper-fractional {tag}"), s));
        v.push((
            format!("global {tag}"),
            Settings {
                strategy: Strategy::Global,
                heuristic: Heuristic::Power,
                ..s
            },
        ));
    }
    v
}
