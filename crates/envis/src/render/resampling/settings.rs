//! How a frame resamples: the reuse a sequence does (`--resampling`), its settings (the
//! defaults are `EnvironmentResampling`'s), and the faults the mutation tests inject.

/// Which reuse a sequence does (`--resampling`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum ResamplingMode {
    /// No resampling: every frame is today's estimator (every sample shadow-tested).
    Off,
    /// Candidates and the previous frame's reservoir.
    Temporal,
    /// Temporal, then `spatial` neighbours.
    #[default]
    Spatiotemporal,
}
crate::display_as_serde_name!(ResamplingMode);

/// How a frame resamples. The defaults are `EnvironmentResampling`'s.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Resampling {
    pub temporal: bool,
    /// Neighbours of the spatial pass (0: none), for pixels whose confidence after temporal
    /// reuse is under [`SPATIAL_UNTIL_HISTORY`](super::SPATIAL_UNTIL_HISTORY).
    pub spatial: u32,
    /// The history's confidence is capped at this many frames of candidates.
    pub max_history: u32,
    /// MIS weights with visibility (unbiased) or `1 / M` (biased, fewer rays).
    pub unbiased: bool,
    /// Shadow-test every candidate (one ray per light and BRDF sample), so that the target is
    /// the shadowed integrand from the start: no blocked sun can inflate a sky sample's weight
    /// (docs/temporal.md). Off by default: the budget is one ray per selected sample.
    pub candidate_visibility: bool,
    /// Sample and shade the map's bright part (a sun) apart from the rest, with its own table
    /// and shadow ray ([`Split`](super::Split); only the rest is resampled and reused).
    pub split_bright: bool,
    /// A deliberate fault, for the tests that must catch it (`None` in any real use).
    #[serde(skip)]
    pub mutation: Option<Mutation>,
}

impl Default for Resampling {
    fn default() -> Self {
        Resampling {
            temporal: true,
            spatial: 3,
            max_history: 20,
            unbiased: true,
            candidate_visibility: false,
            split_bright: true,
            mutation: None,
        }
    }
}

impl Resampling {
    /// The settings of a `--resampling` mode (`None` for `off`).
    pub fn for_mode(mode: ResamplingMode, unbiased: bool) -> Option<Self> {
        let base = Resampling {
            unbiased,
            ..Default::default()
        };
        match mode {
            ResamplingMode::Off => None,
            ResamplingMode::Temporal => Some(Resampling { spatial: 0, ..base }),
            ResamplingMode::Spatiotemporal => Some(base),
        }
    }
}

/// Faults the mutation tests inject, each one a way reuse can be broken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mutation {
    /// A reused sample keeps its old target instead of being re-evaluated here and now.
    StaleTarget,
    /// The other domains' terms are left out of the MIS weight's denominator.
    DroppedMisTerm,
    /// Reprojection looks the point up with this frame's camera instead of the previous one
    /// (applied by the sequence driver, which owns the cameras).
    WrongReprojection,
    /// The rest keeps the bright texels that the bright part's own estimate also counts (the
    /// split counts the sun twice; applied by the sequence driver, which makes the split).
    BrightCountedTwice,
}
