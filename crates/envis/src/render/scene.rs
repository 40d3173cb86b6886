//! G-buffers. `sphere`: orthographic view of the unit sphere, camera on +Z looking down -Z, image
//! x -> +X, top row -> +Y, pixel centres at ((i+0.5)/W, (j+0.5)/H) mapped onto [-1, 1]^2; pixels
//! off the sphere have no geometry (and render as 0).

use crate::sampling::Material;
use glam::Vec3;

/// One G-buffer texel: shading normal, direction towards the viewer, material.
#[derive(Clone, Copy, Debug)]
pub struct GPixel {
    pub n: Vec3,
    pub o: Vec3,
    pub material: Material,
}

/// The `sphere` scene's G-buffer, row-major, `width x height`.
pub fn sphere_gbuffer(width: usize, height: usize, material: Material) -> Vec<Option<GPixel>> {
    let mut g = Vec::with_capacity(width * height);
    for j in 0..height {
        for i in 0..width {
            let x = -1.0 + 2.0 * (i as f32 + 0.5) / width as f32;
            let y = 1.0 - 2.0 * (j as f32 + 0.5) / height as f32;
            let r2 = x * x + y * y;
            g.push((r2 < 1.0).then(|| GPixel {
                n: Vec3::new(x, y, (1.0 - r2).sqrt()),
                o: Vec3::Z,
                material,
            }));
        }
    }
    g
}
