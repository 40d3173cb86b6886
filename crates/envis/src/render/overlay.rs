//! The debug views a live view can draw instead of its image (the Bevy lighting pass draws them;
//! [`super::EnvironmentSampling::overlay`] picks one).

/// Full-screen debug overlays of the lighting pass.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "bevy", derive(bevy_reflect::Reflect))]
pub enum Overlay {
    #[default]
    None,
    /// Samples each pixel evaluated (used light + BRDF) over its budget, as a heat map.
    EffectiveSamples,
    /// Fraction of the used light samples with a negative cosine (the paper's yellow).
    Wasted,
    /// |fractional - integer| / fractional: where integer counts pop.
    CountsDifference,
    /// Per pixel, the confidence `M` of its resampled reservoir (frames of candidates reused,
    /// plus the spatial neighbours' share): where reuse holds and where it restarts. Cameras
    /// with `EnvironmentResampling` only; blue elsewhere.
    History,
}

impl Overlay {
    pub const ALL: [Overlay; 5] = [
        Overlay::None,
        Overlay::EffectiveSamples,
        Overlay::Wasted,
        Overlay::CountsDifference,
        Overlay::History,
    ];
    pub fn name(self) -> &'static str {
        match self {
            Overlay::None => "none",
            Overlay::EffectiveSamples => "effective samples",
            Overlay::Wasted => "wasted (yellow) fraction",
            Overlay::CountsDifference => "fractional - integer",
            Overlay::History => "resampling history",
        }
    }
}
