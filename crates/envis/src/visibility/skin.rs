//! Linear blend skinning as Bevy's shader does it (`skinning.wgsl`, `skin_model`): each vertex
//! placed by the weighted sum of its (up to four) joints' matrices, the weights as given. The
//! Bevy layer reads a `SkinnedMesh`'s attributes and joints and calls [`skin_points`]; the
//! shadow BVH over the result is then refitted ([`super::FlatBlas::refit`]).

use glam::{Mat4, Vec3};

/// `p` skinned by `matrices` (`index[v]` the joints of vertex `v`, `weight[v]` their weights):
/// `sum_k weight[v][k] * matrices[index[v][k]]` applied to `p[v]`. `None` when the arrays differ
/// in length or an index is past `matrices`.
pub fn skin_points(
    p: &[Vec3],
    index: &[[u16; 4]],
    weight: &[[f32; 4]],
    matrices: &[Mat4],
) -> Option<Vec<Vec3>> {
    if index.len() != p.len() || weight.len() != p.len() {
        return None;
    }
    (p.iter().zip(index).zip(weight))
        .map(|((&v, i), w)| {
            let mut m = Mat4::ZERO;
            for k in 0..4 {
                m += *matrices.get(i[k] as usize)? * w[k];
            }
            Some(m.transform_point3(v))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A vertex weighted half to each of two joints lands halfway between their placements;
    /// one weighted wholly to a joint follows it; an index past the joints is refused.
    #[test]
    fn skinning_sums_weighted_joint_matrices() {
        let p = [Vec3::X; 2];
        let index = [[0, 1, 0, 0], [1, 0, 0, 0]];
        let weight = [[0.5, 0.5, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]];
        let joints = [
            Mat4::from_translation(Vec3::Y),
            Mat4::from_rotation_z(std::f32::consts::FRAC_PI_2),
        ];
        let s = skin_points(&p, &index, &weight, &joints).unwrap();
        assert!(
            (s[0] - Vec3::new(0.5, 1.0, 0.0)).length() < 1e-6,
            "{}",
            s[0]
        );
        assert!((s[1] - Vec3::Y).length() < 1e-6, "{}", s[1]);
        assert!(skin_points(&p, &index, &weight, &joints[..1]).is_none());
        assert!(skin_points(&p[..1], &index, &weight, &joints).is_none());
    }
}
