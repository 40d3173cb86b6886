//! What a render reports: per-pixel sample accounting and the image-wide statistics `--stats`
//! writes.

use super::Settings;

/// Per-pixel sample accounting (the paper's red / green / yellow).
#[derive(Clone, Copy, Debug, Default)]
pub struct PixelStats {
    /// Light samples available to the pixel (6 K^2 M for the pool, N_L for `global`).
    pub available: u32,
    /// Light samples used with a positive cosine (and not blocked).
    pub green: u32,
    /// Light samples used with a non-positive cosine (wasted).
    pub yellow: u32,
    /// Light samples used with a positive cosine but blocked by the scene (the debug view's blue).
    pub blocked: u32,
    /// BRDF samples drawn.
    pub brdf: u32,
    /// Shadow rays cast (light and BRDF samples), 0 with visibility off.
    pub shadow_rays: u32,
}

impl PixelStats {
    /// Light samples the face weights discarded.
    pub fn red(&self) -> u32 {
        self.available
            .saturating_sub(self.green + self.yellow + self.blocked)
    }
}

/// Statistics of a render, written by `--stats`.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct RenderStats {
    pub width: usize,
    pub height: usize,
    pub strategy: String,
    pub counts: String,
    pub mis: String,
    pub light_samples: usize,
    pub brdf_samples: usize,
    /// M, the pool samples per face (per tile, with tiles) one pixel draws from (one block's
    /// with `blocks`).
    pub pool_per_face: usize,
    pub seed: u32,
    /// `shared`, `offset` or `blocks`, and the pool's blocks (1 unless `blocks`).
    pub pool_layout: String,
    pub pool_blocks: usize,
    /// `K`: tiles per face side (1: the paper's whole faces).
    pub tiles: usize,
    /// `face` or `tile` ([`crate::sampling::TileCounts`]).
    pub tile_counts: String,
    pub material_budget: bool,
    /// Distribution (CDF tables, face energies) + light-sample pool build, milliseconds.
    pub build_ms: f64,
    /// Shading of all pixels, milliseconds.
    pub shade_ms: f64,
    /// Pixels with geometry.
    pub shaded_pixels: u64,
    /// Light samples used + BRDF samples drawn, over all pixels.
    pub samples_evaluated: u64,
    /// BRDF samples drawn, over all pixels (0 for a diffuse scene with `material_budget`).
    pub brdf_samples_drawn: u64,
    /// Samples evaluated per second of shading.
    pub samples_per_second: f64,
    /// Mean over shaded pixels of the fraction of available light samples discarded by face weighting.
    pub red: f64,
    /// ... used with a positive cosine.
    pub green: f64,
    /// ... used with a non-positive cosine.
    pub yellow: f64,
    /// ... used with a positive cosine but blocked by the scene.
    pub blocked: f64,
    /// Mean over shaded pixels of yellow / (green + yellow).
    pub wasted: f64,
    /// Shadow rays: `on` or `off`, and why (`--visibility`, the `auto` rule).
    pub visibility: String,
    /// Shadow rays cast over all pixels (0 with visibility off).
    pub shadow_rays: u64,
    /// NaN / Inf / negative texels clamped when loading the map.
    pub clamped_texels: crate::envmap::SanitizeReport,
}

impl RenderStats {
    /// Statistics header of a render with settings `s` (timings and counts still empty).
    pub fn for_settings(width: usize, height: usize, s: &Settings, pool_per_face: usize) -> Self {
        RenderStats {
            width,
            height,
            strategy: s.strategy.to_string(),
            counts: s.counts.to_string(),
            mis: s.heuristic.to_string(),
            light_samples: s.light_samples,
            brdf_samples: s.brdf_samples,
            pool_per_face,
            seed: s.seed,
            pool_layout: s.pool_layout.to_string(),
            pool_blocks: s.pool_block_count(),
            tiles: s.tiles,
            tile_counts: s.tile_counts.to_string(),
            material_budget: s.material_budget,
            ..Default::default()
        }
    }

    /// Fill the sample counts and red / green / yellow fractions from per-pixel statistics
    /// (`None` = no geometry); `shade_ms` must be set.
    pub fn accumulate(&mut self, per_pixel: &[Option<PixelStats>]) {
        let (mut red, mut green, mut yellow, mut wasted) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        let mut blocked = 0.0f64;
        for st in per_pixel.iter().flatten() {
            self.shaded_pixels += 1;
            self.samples_evaluated += (st.green + st.yellow + st.blocked + st.brdf) as u64;
            self.brdf_samples_drawn += st.brdf as u64;
            self.shadow_rays += st.shadow_rays as u64;
            if st.available > 0 {
                let a = st.available as f64;
                red += st.red() as f64 / a;
                green += st.green as f64 / a;
                yellow += st.yellow as f64 / a;
                blocked += st.blocked as f64 / a;
            }
            if st.green + st.yellow > 0 {
                wasted += st.yellow as f64 / (st.green + st.yellow) as f64;
            }
        }
        let np = self.shaded_pixels.max(1) as f64;
        (self.red, self.green, self.yellow, self.wasted) =
            (red / np, green / np, yellow / np, wasted / np);
        self.blocked = blocked / np;
        self.samples_per_second = self.samples_evaluated as f64 / (self.shade_ms / 1e3).max(1e-9);
    }
}
