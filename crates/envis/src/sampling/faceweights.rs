//! Per-pixel face weighting (the paper's "dynamic sample distribution"), per whole face: the
//! paper's formula as written, kept as the labelled test oracle of the estimator's weighting.
//! The estimator weights regions with [`super::tiles::TileWeights`] (the same formula per
//! sub-face tile; one tile per face gives exactly this, checked by
//! `one_tile_per_face_gives_the_paper_face_weights`).
//!
//! `C_f = sum over the 4 corners of max(0, <n, corner>)`, `F_f = C_f / sum C_f`,
//! `mu_f = F_f I_f / sum(F_f I_f)`, `N_f = mu_f N_L`. A face whose four corners all have
//! `cos <= 0` gets `C_f = 0` and is skipped: that is exact, since `<n, p>` is linear over the planar
//! face and so is `<= 0` on all of it. Conversely any face with a point of positive cosine has a
//! corner of positive cosine, so `mu_f > 0` wherever the integrand can be non-zero: light
//! sampling alone is unbiased.

use glam::Vec3;

/// The 8 unit cube-corner directions `(+-1, +-1, +-1) / sqrt(3)`, index bits (x, y, z): bit set = negative.
pub fn corner(i: usize) -> Vec3 {
    let s = |bit: usize| if i & bit != 0 { -1.0 } else { 1.0 };
    Vec3::new(s(1), s(2), s(4)) / 3f32.sqrt()
}

/// The four corner indices of each face (+X, -X, +Y, -Y, +Z, -Z).
pub const FACE_CORNERS: [[usize; 4]; 6] = [
    [0, 2, 4, 6], // x > 0: bit 1 clear
    [1, 3, 5, 7], // x < 0
    [0, 1, 4, 5], // y > 0: bit 2 clear
    [2, 3, 6, 7], // y < 0
    [0, 1, 2, 3], // z > 0: bit 4 clear
    [4, 5, 6, 7], // z < 0
];

/// Face weights of one pixel.
#[derive(Clone, Copy, Debug, Default)]
pub struct FaceWeights {
    /// Pseudo form factors `F_f`.
    pub form: [f32; 6],
    /// `mu_f`.
    pub mu: [f32; 6],
}

/// `C_f` for normal `n` (need not be unit: only signs and ratios matter).
#[inline]
pub fn corner_cosines(n: Vec3) -> [f32; 6] {
    let cos: [f32; 8] = std::array::from_fn(|i| n.dot(corner(i)).max(0.0));
    std::array::from_fn(|f| FACE_CORNERS[f].iter().map(|&c| cos[c]).sum())
}

/// `F_f` and `mu_f` for normal `n` and face energies `I_f`. With `use_cosine == false` this is
/// the `light` baseline (`mu_f = I_f / sum I_f`). All-zero when nothing can contribute.
pub fn face_weights(n: Vec3, energy: &[f64; 6], use_cosine: bool) -> FaceWeights {
    let c = if use_cosine {
        corner_cosines(n)
    } else {
        [1.0; 6]
    };
    let csum: f32 = c.iter().sum();
    let mut w = FaceWeights::default();
    if csum <= 0.0 {
        return w;
    }
    let form: [f32; 6] = std::array::from_fn(|f| c[f] / csum);
    let fi: [f64; 6] = std::array::from_fn(|f| form[f] as f64 * energy[f]);
    let total: f64 = fi.iter().sum();
    w.form = form;
    if total > 0.0 {
        w.mu = std::array::from_fn(|f| (fi[f] / total) as f32);
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corners_belong_to_their_faces() {
        let axes = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
        for f in 0..6 {
            for &c in &FACE_CORNERS[f] {
                assert!((corner(c).dot(axes[f]) - 1.0 / 3f32.sqrt()).abs() < 1e-6);
            }
        }
    }
}
