//! Morph-target blending as Bevy's shader does it (`mesh.wgsl`, `morph_vertex`): each vertex
//! moved by the weighted sum of its targets' position displacements, before any skinning. The
//! Bevy layer reads a mesh's morph targets and weights and calls [`morph_points`]; a skinned
//! mesh's morphed vertices then go through [`super::skin::skin_points`].

use glam::Vec3;

/// `p` moved by `weights`: `p[v] + sum_t weights[t] * targets[t * p.len() + v]`, the displacements
/// laid out target after target (Bevy's `Mesh::morph_targets` order, which its shader reads).
/// As Bevy's shader, only the targets that have a weight are summed, and weights past the last
/// target are ignored. `None` when `targets` is not a whole number of targets of `p.len()`
/// vertices.
pub fn morph_points(p: &[Vec3], targets: &[Vec3], weights: &[f32]) -> Option<Vec<Vec3>> {
    if p.is_empty() || !targets.len().is_multiple_of(p.len()) {
        return (p.is_empty() && targets.is_empty()).then(Vec::new);
    }
    let mut out = p.to_vec();
    for (target, &w) in targets.chunks_exact(p.len()).zip(weights) {
        if w == 0.0 {
            continue; // Bevy skips it too: a NaN displacement of an unused target stays out
        }
        for (o, &d) in out.iter_mut().zip(target) {
            *o += w * d;
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two vertices, two targets: each target's displacement is scaled by its own weight and
    /// added to its own vertex; a zero weight leaves a target out; a ragged target list is
    /// refused.
    #[test]
    fn morphing_adds_weighted_displacements_target_by_target() {
        let p = [Vec3::ZERO, Vec3::X];
        // Target 0 lifts vertex 0, target 1 pushes vertex 1 along +Z.
        let targets = [Vec3::Y, Vec3::ZERO, Vec3::ZERO, Vec3::Z];
        let m = morph_points(&p, &targets, &[0.5, 2.0]).unwrap();
        assert_eq!(m, vec![Vec3::new(0.0, 0.5, 0.0), Vec3::new(1.0, 0.0, 2.0)]);
        let only_first = morph_points(&p, &targets, &[1.0]).unwrap();
        assert_eq!(only_first, vec![Vec3::Y, Vec3::X]);
        let nan = [Vec3::NAN, Vec3::NAN];
        let unused = morph_points(&p, &[targets.as_slice(), &nan].concat(), &[1.0, 0.0, 0.0]);
        assert_eq!(unused.unwrap(), vec![Vec3::Y, Vec3::X]);
        assert!(morph_points(&p, &targets[..3], &[1.0]).is_none());
    }
}
