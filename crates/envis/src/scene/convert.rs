//! What a scene file's specs mean in the core's terms: its `[sampling]` table as [`Settings`],
//! an object's material as a [`Material`].

use super::{MaterialSpec, SamplingSpec, err};
use crate::error::Result;
use crate::render::Settings;
use crate::sampling::{Lobe, Material};
use glam::Vec3;
use std::path::Path;

/// The core's settings of a `[sampling]` table (defaults for what it leaves out), with the
/// distribution's `face_size` of the `[environment]` table.
pub(super) fn sampling_settings(
    path: &Path,
    s: &SamplingSpec,
    face_size: usize,
) -> Result<Settings> {
    let mut out = Settings {
        face_size,
        ..Default::default()
    };
    if let Some(v) = s.light_samples {
        out.light_samples = v;
    }
    if let Some(v) = s.brdf_samples {
        out.brdf_samples = v;
    }
    out.strategy = s.strategy.unwrap_or(out.strategy);
    out.counts = s.counts.unwrap_or(out.counts);
    out.heuristic = s.heuristic.unwrap_or(out.heuristic);
    out.seed = s.seed.unwrap_or(0);
    out.pool_size = s.pool_size.unwrap_or(0);
    out.pool_layout = match (s.pool_layout, s.pixel_offset) {
        (Some(l), _) => l,
        (None, Some(true)) => crate::render::PoolLayout::Offset,
        (None, _) => out.pool_layout,
    };
    out.pool_blocks = s.pool_blocks.unwrap_or(out.pool_blocks);
    out.material_budget = s.material_budget.unwrap_or(false);
    out.tiles = s.tiles.unwrap_or(out.tiles);
    out.tile_counts = s.tile_counts.unwrap_or(out.tile_counts);
    out.shadows = s.shadows.unwrap_or_default();
    out.validate()
        .map_err(|e| err(path, format!("[sampling]: {e}")))?;
    Ok(out)
}

/// The core material of a spec (clamped into the supported ranges).
pub fn material(m: &MaterialSpec) -> std::result::Result<Material, String> {
    let a = m.albedo.rgb();
    if !a.is_finite() || a.min_element() < 0.0 {
        return Err(format!("albedo {a} must be finite and >= 0"));
    }
    Ok(match m.kind.as_str() {
        "diffuse" => Material {
            kd: a,
            ks: Vec3::ZERO,
            lobe: Lobe::None,
        },
        "phong" => Material {
            kd: Vec3::ZERO,
            ks: a,
            lobe: Lobe::Phong {
                exponent: m
                    .exponent
                    .unwrap_or(150.0)
                    .clamp(0.0, crate::sampling::brdf::MAX_EXPONENT),
            },
        },
        "ggx" => Material {
            kd: Vec3::ZERO,
            ks: a,
            lobe: Lobe::Ggx {
                alpha: m
                    .alpha
                    .unwrap_or(0.2)
                    .clamp(crate::sampling::brdf::MIN_ALPHA, 1.0),
            },
        },
        "mix" => {
            let s = m.specular.unwrap_or(0.5).clamp(0.0, 1.0);
            Material {
                kd: a * (1.0 - s),
                ks: a * s,
                lobe: Lobe::Ggx {
                    alpha: m
                        .alpha
                        .unwrap_or(0.2)
                        .clamp(crate::sampling::brdf::MIN_ALPHA, 1.0),
                },
            }
        }
        other => return Err(format!("unknown type '{other}' (diffuse, phong, ggx, mix)")),
    })
}
