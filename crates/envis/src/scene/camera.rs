//! A scene's pinhole camera: the ray through each pixel (the CPU G-buffer's), and the way back,
//! from a world point to the pixel that sees it (reprojection into a previous frame).

use super::CameraSpec;
use glam::Vec3;

/// The camera of a `width x height` image: eye, orthonormal basis, and the image plane's half
/// extents at distance 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    pub fwd: Vec3,
    pub right: Vec3,
    pub up: Vec3,
    /// `tan(fov / 2)`.
    pub tan_half: f32,
    pub width: usize,
    pub height: usize,
}

impl Camera {
    pub fn new(c: &CameraSpec, width: usize, height: usize) -> Self {
        let eye = Vec3::from(c.position);
        let fwd = (Vec3::from(c.target) - eye).normalize_or(Vec3::NEG_Z);
        let right = fwd.cross(Vec3::Y).normalize_or(Vec3::X);
        let up = right.cross(fwd);
        Camera {
            eye,
            fwd,
            right,
            up,
            tan_half: (0.5 * c.fov.clamp(1.0, 170.0).to_radians()).tan(),
            width,
            height,
        }
    }

    fn aspect(&self) -> f32 {
        self.width as f32 / self.height as f32
    }

    /// The unit direction through the centre of pixel `i` (row-major).
    pub fn ray(&self, i: usize) -> Vec3 {
        let (w, h) = (self.width, self.height);
        let (x, y) = ((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
        let ndc_x = (2.0 * x / w as f32 - 1.0) * self.tan_half * self.aspect();
        let ndc_y = (1.0 - 2.0 * y / h as f32) * self.tan_half;
        (self.fwd + self.right * ndc_x + self.up * ndc_y).normalize()
    }

    /// The pixel whose footprint holds world point `p`, and `p`'s distance from the eye;
    /// `None` behind the camera or off the image.
    pub fn project(&self, p: Vec3) -> Option<(usize, f32)> {
        let v = p - self.eye;
        let z = v.dot(self.fwd);
        if z <= 0.0 {
            return None;
        }
        let ndc_x = v.dot(self.right) / (z * self.tan_half * self.aspect());
        let ndc_y = v.dot(self.up) / (z * self.tan_half);
        let x = (ndc_x + 1.0) * 0.5 * self.width as f32;
        let y = (1.0 - ndc_y) * 0.5 * self.height as f32;
        let inside = x >= 0.0 && y >= 0.0 && x < self.width as f32 && y < self.height as f32;
        inside.then(|| (y as usize * self.width + x as usize, v.length()))
    }
}
