//! The `u32` codes by which the core's enums cross to WGSL, defined once: each enum's
//! [`GpuCode::gpu_code`] here, and the WGSL's `const NAME: u32` twins checked against them by
//! `every_wgsl_code_matches_its_rust_twin` (WGSL cannot import Rust constants, so a test is the
//! only link). A new variant without its WGSL constant, or a WGSL constant of a known family
//! without its variant, fails that test.

use envis::envmap::resample::SourceLayout;
use envis::render::{Overlay, PoolLayout, Strategy};
use envis::sampling::{Counts, Heuristic, Lobe, TileCounts};

/// The code by which a value of the core's enums crosses to WGSL (its `const NAME: u32` twin).
pub trait GpuCode: Copy {
    /// The value's code in the WGSL.
    fn gpu_code(self) -> u32;
}

impl GpuCode for Strategy {
    /// `STRATEGY_*` in `shade.wgsl`.
    fn gpu_code(self) -> u32 {
        match self {
            Strategy::Paper => 0,
            Strategy::Light => 1,
            Strategy::Brdf => 2,
            Strategy::Global => 3,
        }
    }
}

impl GpuCode for PoolLayout {
    /// `POOL_*` in `shade.wgsl`.
    fn gpu_code(self) -> u32 {
        match self {
            PoolLayout::Shared => 0,
            PoolLayout::Offset => 1,
            PoolLayout::Blocks => 2,
        }
    }
}

impl GpuCode for Counts {
    /// `COUNTS_*` in `sampling.wgsl`.
    fn gpu_code(self) -> u32 {
        match self {
            Counts::Fractional => 0,
            Counts::Integer => 1,
        }
    }
}

impl GpuCode for Heuristic {
    /// `MIS_*` in `sampling.wgsl`.
    fn gpu_code(self) -> u32 {
        match self {
            Heuristic::Balance => 0,
            Heuristic::Power => 1,
        }
    }
}

impl GpuCode for TileCounts {
    /// `TILE_COUNTS_*` in `shade.wgsl`.
    fn gpu_code(self) -> u32 {
        match self {
            TileCounts::Tile => 0,
            TileCounts::Face => 1,
        }
    }
}

impl GpuCode for SourceLayout {
    /// `SOURCE_*` in `image_source.wgsl`.
    fn gpu_code(self) -> u32 {
        match self {
            SourceLayout::LatLong => 0,
            SourceLayout::Cube => 1,
        }
    }
}

impl GpuCode for Overlay {
    /// `OVERLAY_*` in `lighting.wgsl`.
    fn gpu_code(self) -> u32 {
        match self {
            Overlay::None => 0,
            Overlay::EffectiveSamples => 1,
            Overlay::Wasted => 2,
            Overlay::CountsDifference => 3,
            Overlay::History => 4,
        }
    }
}

impl GpuCode for Lobe {
    /// `LOBE_*` in `sampling.wgsl`: the lobe's kind (its parameter travels beside it).
    fn gpu_code(self) -> u32 {
        match self {
            Lobe::None => 0,
            Lobe::Phong { .. } => 1,
            Lobe::Ggx { .. } => 2,
            Lobe::GgxSchlick { .. } => 3,
        }
    }
}

/// The lobe's parameter as the GPU carries it beside its [`GpuCode::gpu_code`]: the Phong
/// exponent or the GGX alpha (0 for no lobe).
pub const fn lobe_param(lobe: Lobe) -> f32 {
    match lobe {
        Lobe::None => 0.0,
        Lobe::Phong { exponent } => exponent,
        Lobe::Ggx { alpha } | Lobe::GgxSchlick { alpha } => alpha,
    }
}

/// The lobe of a GPU code and parameter (an unknown code is no lobe).
pub const fn lobe_from_gpu(code: u32, param: f32) -> Lobe {
    match code {
        1 => Lobe::Phong { exponent: param },
        2 => Lobe::Ggx { alpha: param },
        3 => Lobe::GgxSchlick { alpha: param },
        _ => Lobe::None,
    }
}

use std::collections::BTreeMap;

/// Every `const NAME: u32 = Nu;` of a WGSL source (the tests check the WGSL's codes with it).
#[doc(hidden)]
pub fn wgsl_u32_consts(src: &str) -> BTreeMap<String, u32> {
    src.lines()
        .filter_map(|l| {
            let rest = l.trim_start().strip_prefix("const ")?;
            let (name, value) = rest.split_once(": u32 =")?;
            let v = value.trim().trim_end_matches(';').trim_end_matches('u');
            Some((name.trim().to_string(), v.parse().ok()?))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The WGSL name of each variant's code, per family prefix.
    fn core_codes() -> Vec<(&'static str, Vec<(&'static str, u32)>)> {
        vec![
            (
                "STRATEGY_",
                vec![
                    ("PAPER", Strategy::Paper.gpu_code()),
                    ("LIGHT", Strategy::Light.gpu_code()),
                    ("BRDF", Strategy::Brdf.gpu_code()),
                    ("GLOBAL", Strategy::Global.gpu_code()),
                ],
            ),
            (
                "POOL_",
                vec![
                    ("SHARED", PoolLayout::Shared.gpu_code()),
                    ("OFFSET", PoolLayout::Offset.gpu_code()),
                    ("BLOCKS", PoolLayout::Blocks.gpu_code()),
                ],
            ),
            (
                "COUNTS_",
                vec![
                    ("FRACTIONAL", Counts::Fractional.gpu_code()),
                    ("INTEGER", Counts::Integer.gpu_code()),
                ],
            ),
            (
                "MIS_",
                vec![
                    ("BALANCE", Heuristic::Balance.gpu_code()),
                    ("POWER", Heuristic::Power.gpu_code()),
                ],
            ),
            (
                "TILE_COUNTS_",
                vec![
                    ("TILE", TileCounts::Tile.gpu_code()),
                    ("FACE", TileCounts::Face.gpu_code()),
                ],
            ),
            (
                "SOURCE_",
                vec![
                    ("LATLONG", SourceLayout::LatLong.gpu_code()),
                    ("CUBE", SourceLayout::Cube.gpu_code()),
                ],
            ),
            (
                "OVERLAY_",
                vec![
                    ("NONE", Overlay::None.gpu_code()),
                    ("EFFECTIVE_SAMPLES", Overlay::EffectiveSamples.gpu_code()),
                    ("WASTED", Overlay::Wasted.gpu_code()),
                    ("COUNTS_DIFFERENCE", Overlay::CountsDifference.gpu_code()),
                    ("HISTORY", Overlay::History.gpu_code()),
                ],
            ),
            (
                "LOBE_",
                vec![
                    ("NONE", Lobe::None.gpu_code()),
                    ("PHONG", Lobe::Phong { exponent: 1.0 }.gpu_code()),
                    ("GGX", Lobe::Ggx { alpha: 1.0 }.gpu_code()),
                    ("GGX_SCHLICK", Lobe::GgxSchlick { alpha: 1.0 }.gpu_code()),
                ],
            ),
        ]
    }

    /// Families match both ways: every variant has its WGSL constant with its code, and every
    /// WGSL constant of the family is a variant.
    fn check_families(wgsl: &BTreeMap<String, u32>, families: &[(&str, Vec<(&str, u32)>)]) {
        for (prefix, variants) in families {
            for (name, code) in variants {
                let full = format!("{prefix}{name}");
                assert_eq!(wgsl.get(&full), Some(code), "WGSL {full}");
            }
            for name in wgsl.keys().filter(|k| k.starts_with(prefix)) {
                // TILE_COUNTS_ also starts with no other family's prefix; a longer family wins.
                let own = families
                    .iter()
                    .filter(|(p, _)| name.starts_with(p))
                    .max_by_key(|(p, _)| p.len())
                    .is_some_and(|(p, _)| p == prefix);
                let known = variants
                    .iter()
                    .any(|(v, _)| name == &format!("{prefix}{v}"));
                assert!(!own || known, "WGSL {name} has no Rust variant");
            }
        }
    }

    /// The `u32` constants that are no enum's code, each with its Rust twin where it has one.
    fn plain_constants() -> Vec<(&'static str, Option<u32>)> {
        vec![
            ("BVH_STACK_SIZE", Some(envis::visibility::STACK_SIZE as u32)),
            // The scan's workgroup size, used only inside scan.wgsl.
            ("WG", None),
            // Bevy's deferred conventions, checked in bevy_envis (lighting.wgsl needs Bevy's values).
            ("PBR_LIGHTING_PASS_ID", None),
            ("DEFERRED_FLAGS_UNLIT_BIT", None),
            ("ENVIS_LIGHTING_PASS_ID", None),
        ]
    }

    /// All of envis's WGSL `u32` constants, from every module.
    fn all_wgsl_consts() -> BTreeMap<String, u32> {
        use crate::shaders::*;
        let mut all = BTreeMap::new();
        for src in [
            COMMON,
            SAMPLING,
            DISTRIBUTION,
            SHADE,
            SCAN,
            CDF,
            GLOBAL,
            GLOBAL_LAYOUT,
            SHADE_COMPUTE,
            LIGHTING,
            GBUFFER,
            GATHER,
            IMAGE_SOURCE,
            RESAMPLE,
            VISIBILITY,
            TRACE_RAYS,
        ] {
            for (k, v) in wgsl_u32_consts(src) {
                let old = all.insert(k.clone(), v);
                assert!(
                    old.is_none_or(|o| o == v),
                    "WGSL {k} defined twice, differently"
                );
            }
        }
        all
    }

    #[test]
    fn every_wgsl_code_matches_its_rust_twin() {
        let wgsl = all_wgsl_consts();
        let families = core_codes();
        check_families(&wgsl, &families);
        let plain = plain_constants();
        for (name, value) in &wgsl {
            let family = families.iter().any(|(p, _)| name.starts_with(p));
            let listed = plain.iter().find(|(n, _)| n == name);
            assert!(
                family || listed.is_some(),
                "WGSL {name} is in no table here"
            );
            if let Some((_, Some(v))) = listed {
                assert_eq!(value, v, "WGSL {name}");
            }
        }
    }

    #[test]
    fn lobes_round_trip_through_their_gpu_form() {
        for lobe in [
            Lobe::None,
            Lobe::Phong { exponent: 37.5 },
            Lobe::Ggx { alpha: 0.25 },
            Lobe::GgxSchlick { alpha: 0.5 },
        ] {
            assert_eq!(
                crate::codes::lobe_from_gpu(lobe.gpu_code(), crate::codes::lobe_param(lobe)),
                lobe
            );
        }
    }
}
