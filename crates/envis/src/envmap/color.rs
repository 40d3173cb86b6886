//! Colour spaces of input maps. envis computes in linear Rec.709 / sRGB primaries with a D65
//! white (what Bevy renders in). A file that declares other primaries (OpenEXR `chromaticities`,
//! Radiance `PRIMARIES=`) is converted on load: RGB -> XYZ by its primaries, Bradford chromatic
//! adaptation from its white to D65, XYZ -> Rec.709. Colours outside Rec.709 come out with a
//! negative component, which the loader then clamps and counts like any negative texel.

use glam::{DMat3, DVec2, DVec3, Vec3};

/// Chromaticities (CIE xy) of the three primaries and the white point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Primaries {
    pub red: DVec2,
    pub green: DVec2,
    pub blue: DVec2,
    pub white: DVec2,
}

impl Primaries {
    /// ITU-R BT.709 / sRGB, D65: envis's working space.
    pub const REC709: Primaries = Primaries {
        red: DVec2::new(0.64, 0.33),
        green: DVec2::new(0.30, 0.60),
        blue: DVec2::new(0.15, 0.06),
        white: DVec2::new(0.3127, 0.3290),
    };

    /// ACES2065-1 (AP0), ACES white: the interchange space of VFX pipelines.
    pub const ACES_AP0: Primaries = Primaries {
        red: DVec2::new(0.7347, 0.2653),
        green: DVec2::new(0.0, 1.0),
        blue: DVec2::new(0.0001, -0.0770),
        white: DVec2::new(0.32168, 0.33767),
    };

    /// From 8 numbers `rx ry gx gy bx by wx wy` (the order of both file formats).
    pub fn from_array(v: [f64; 8]) -> Self {
        Primaries {
            red: DVec2::new(v[0], v[1]),
            green: DVec2::new(v[2], v[3]),
            blue: DVec2::new(v[4], v[5]),
            white: DVec2::new(v[6], v[7]),
        }
    }

    /// RGB -> XYZ for these primaries (white maps to Y = 1); `None` when degenerate (a primary
    /// with y = 0, collinear primaries, non-finite numbers).
    pub fn rgb_to_xyz(&self) -> Option<DMat3> {
        let xyz = |c: DVec2| (c.y != 0.0).then(|| xy_to_xyz(c));
        let m = DMat3::from_cols(xyz(self.red)?, xyz(self.green)?, xyz(self.blue)?);
        let det = m.determinant();
        if !det.is_finite() || det.abs() < 1e-9 {
            return None;
        }
        let s = m.inverse() * xyz(self.white)?;
        s.is_finite().then(|| m * DMat3::from_diagonal(s))
    }
}

/// The XYZ of chromaticity `c` at luminance Y = 1 (non-finite when `c.y` is 0).
fn xy_to_xyz(c: DVec2) -> DVec3 {
    DVec3::new(c.x / c.y, 1.0, (1.0 - c.x - c.y) / c.y)
}

/// Bradford chromatic adaptation (XYZ -> XYZ) from white `from` to white `to` (CIE xy).
pub fn bradford(from: DVec2, to: DVec2) -> DMat3 {
    // Rows of the Bradford cone-response matrix, as columns of the transpose.
    let mb = DMat3::from_cols_array(&[
        0.8951, -0.7502, 0.0389, //
        0.2664, 1.7135, -0.0685, //
        -0.1614, 0.0367, 1.0296,
    ]);
    let (s, d) = (mb * xy_to_xyz(from), mb * xy_to_xyz(to));
    mb.inverse() * DMat3::from_diagonal(d / s) * mb
}

/// The matrix taking linear RGB in `p` to linear Rec.709 / D65, or `None` when `p` is Rec.709
/// already (within 1e-4 in xy: nothing to do) or degenerate (the error says which).
pub fn to_rec709(p: &Primaries) -> std::result::Result<Option<DMat3>, String> {
    let r = Primaries::REC709;
    let same = [
        (p.red, r.red),
        (p.green, r.green),
        (p.blue, r.blue),
        (p.white, r.white),
    ]
    .iter()
    .all(|(a, b)| (*a - *b).abs().max_element() < 1e-4);
    if same {
        return Ok(None);
    }
    let src = p
        .rgb_to_xyz()
        .ok_or_else(|| format!("unusable primaries {p:?}"))?;
    let dst = r.rgb_to_xyz().expect("Rec.709 is well-formed").inverse();
    Ok(Some(dst * bradford(p.white, r.white) * src))
}

/// Apply a colour matrix to every pixel (f64 inside, so the conversion adds no rounding bias).
pub fn convert(data: &mut [Vec3], m: &DMat3) {
    for c in data {
        *c = (*m * c.as_dvec3()).as_vec3();
    }
}
