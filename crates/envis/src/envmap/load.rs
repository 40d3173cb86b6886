//! Loaders: OpenEXR (via the `exr` crate) and Radiance RGBE `.hdr` (own reader), lat-long or
//! cube cross, and the `--env` source syntax (`PATH` or `builtin:sky[:T]`).
//!
//! Every failure names the file and the problem; dimensions are checked before any pixel buffer
//! is allocated; NaN/Inf/negative texels are clamped and counted (see [`SanitizeReport`]).

use super::color;
pub use super::hdr::read_hdr_bytes;
use super::{CubeMap, Image, SanitizeReport};
use crate::error::{Error, Result};
use glam::Vec3;
use std::io::Read;
use std::path::{Path, PathBuf};

/// Largest accepted image side, in pixels (refused before allocating).
pub const MAX_SIDE: usize = 32768;
/// Largest accepted pixel count (refused before allocating): 2^28 texels = 3 GiB of RGB f32.
pub const MAX_PIXELS: usize = 1 << 28;

/// The layout of an environment image, detected from its aspect ratio.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layout {
    /// 2:1 latitude-longitude (Mitsuba 3 convention).
    LatLong,
    /// 4:3 horizontal cross: `+Y` above, then `-X +Z +X -Z`, then `-Y` below (column 1).
    HorizontalCross,
    /// 3:4 vertical cross: `+Y`, `-X +Z +X`, `-Y`, `-Z` (the last one rotated by 180 degrees).
    VerticalCross,
}

/// Detect the layout from the image size, or say why it is none of them.
pub fn detect_layout(width: usize, height: usize) -> std::result::Result<Layout, String> {
    if width == 2 * height && height > 0 {
        Ok(Layout::LatLong)
    } else if width * 3 == height * 4 && width.is_multiple_of(4) && width > 0 {
        Ok(Layout::HorizontalCross)
    } else if width * 4 == height * 3 && width.is_multiple_of(3) && width > 0 {
        Ok(Layout::VerticalCross)
    } else {
        Err(format!(
            "{width}x{height} is neither a 2:1 lat-long map nor a 4:3 / 3:4 cube cross with square faces"
        ))
    }
}

fn check_dims(path: &Path, width: usize, height: usize) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::file(path, format!("empty image ({width}x{height})")));
    }
    if width > MAX_SIDE || height > MAX_SIDE || width.saturating_mul(height) > MAX_PIXELS {
        return Err(Error::file(
            path,
            format!(
                "absurd dimensions {width}x{height} (limit {MAX_SIDE} per side, {MAX_PIXELS} pixels)"
            ),
        ));
    }
    Ok(())
}

/// Read an image file (EXR or Radiance HDR, sniffed from its first bytes).
/// Returns the raw image: not yet sanitized.
pub fn read_image(path: &Path) -> Result<Image> {
    let mut head = [0u8; 4];
    let mut f =
        std::fs::File::open(path).map_err(|e| Error::file(path, format!("cannot open: {e}")))?;
    let n = f
        .read(&mut head)
        .map_err(|e| Error::file(path, format!("cannot read: {e}")))?;
    drop(f);
    if n == 4 && head == [0x76, 0x2f, 0x31, 0x01] {
        read_exr(path)
    } else if n >= 2 && &head[..2] == b"#?" {
        let bytes =
            std::fs::read(path).map_err(|e| Error::file(path, format!("cannot read: {e}")))?;
        read_hdr_bytes(&bytes).map_err(|p| Error::file(path, p))
    } else {
        Err(Error::file(
            path,
            "not an OpenEXR or Radiance HDR file (unknown magic bytes)",
        ))
    }
}

/// Read the first RGB(A) layer of an OpenEXR file as f32.
pub fn read_exr(path: &Path) -> Result<Image> {
    let meta = exr::meta::MetaData::read_from_file(path, false)
        .map_err(|e| Error::file(path, format!("invalid OpenEXR header: {e}")))?;
    let header = meta
        .headers
        .first()
        .ok_or_else(|| Error::file(path, "OpenEXR file has no layer"))?;
    let size = header.layer_size;
    check_dims(path, size.0, size.1)?;
    // Declared primaries other than Rec.709 (ACES AP0, wide-gamut captures): converted below.
    let to_709 = match &header.shared_attributes.chromaticities {
        Some(c) => {
            let xy = |p: exr::math::Vec2<f32>| glam::DVec2::new(p.x() as f64, p.y() as f64);
            let p = color::Primaries {
                red: xy(c.red),
                green: xy(c.green),
                blue: xy(c.blue),
                white: xy(c.white),
            };
            color::to_rec709(&p)
                .map_err(|e| Error::file(path, format!("OpenEXR chromaticities: {e}")))?
        }
        None => None,
    };
    let names: Vec<String> = header
        .channels
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    for want in ["R", "G", "B"] {
        if !names
            .iter()
            .any(|n| n == want || n.ends_with(&format!(".{want}")))
        {
            return Err(Error::file(
                path,
                format!(
                    "OpenEXR file has channels [{}], needs R, G and B",
                    names.join(", ")
                ),
            ));
        }
    }
    let img = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |res, _| Image::new(res.0, res.1),
        |img: &mut Image, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            let w = img.width;
            img.data[pos.1 * w + pos.0] = Vec3::new(r, g, b);
        },
    )
    .map_err(|e| Error::file(path, format!("cannot decode OpenEXR: {e}")))?;
    let mut pixels = img.layer_data.channel_data.pixels;
    if let Some(m) = to_709 {
        color::convert(&mut pixels.data, &m);
    }
    Ok(pixels)
}

/// Extract the six faces of a cube cross (see [`Layout`]).
pub fn cross_to_cube(img: &Image, layout: Layout) -> CubeMap {
    let n = match layout {
        Layout::HorizontalCross => img.width / 4,
        Layout::VerticalCross => img.width / 3,
        Layout::LatLong => panic!("not a cross"),
    };
    // (face, column block, row block, rotated by 180 degrees)
    let place: [(usize, usize, usize, bool); 6] = match layout {
        Layout::HorizontalCross => [
            (0, 2, 1, false),
            (1, 0, 1, false),
            (2, 1, 0, false),
            (3, 1, 2, false),
            (4, 1, 1, false),
            (5, 3, 1, false),
        ],
        _ => [
            (0, 2, 1, false),
            (1, 0, 1, false),
            (2, 1, 0, false),
            (3, 1, 2, false),
            (4, 1, 1, false),
            (5, 1, 3, true),
        ],
    };
    let mut cube = CubeMap::new(n);
    for (face, bx, by, rot) in place {
        for r in 0..n {
            for c in 0..n {
                let (sc, sr) = if rot { (n - 1 - c, n - 1 - r) } else { (c, r) };
                let i = cube.index(face, c, r);
                cube.data[i] = img.get(bx * n + sc, by * n + sr);
            }
        }
    }
    cube
}

/// Where an environment map comes from (the `--env` argument).
#[derive(Clone, Debug, PartialEq)]
pub enum EnvSource {
    /// The built-in procedural sky at time of day `hours` (0..24).
    Sky { hours: f32 },
    /// An `.exr` or `.hdr` file, lat-long or cube cross.
    File(PathBuf),
}

impl std::str::FromStr for EnvSource {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        if let Some(rest) = s.strip_prefix("builtin:") {
            let mut it = rest.splitn(2, ':');
            let name = it.next().unwrap_or("");
            if name != "sky" {
                return Err(Error::invalid(format!(
                    "unknown built-in environment 'builtin:{name}' (expected builtin:sky[:T])"
                )));
            }
            let hours = match it.next() {
                None => super::sky::DEFAULT_HOURS,
                Some(t) => t.parse::<f32>().ok().filter(|h| h.is_finite()).ok_or_else(|| {
                    Error::invalid(format!("bad time '{t}' in 'builtin:sky:{t}' (expected hours, e.g. builtin:sky:10.5)"))
                })?,
            };
            Ok(EnvSource::Sky { hours })
        } else if s.is_empty() {
            Err(Error::invalid(
                "empty --env (expected a file path or builtin:sky[:T])",
            ))
        } else {
            Ok(EnvSource::File(PathBuf::from(s)))
        }
    }
}

/// A loaded environment: the sanitized cube map, what was clamped, and where it came from.
#[derive(Clone, Debug)]
pub struct LoadedEnv {
    /// The map at the requested face size: the sampling distribution's texels.
    pub cube: CubeMap,
    pub report: SanitizeReport,
    pub layout: Option<Layout>,
    /// The map at its own resolution ([`native_face_size`]) where that is finer than `cube`
    /// and the caller asked for it ([`load_env_full`]): the radiance light and BRDF samples
    /// read, `cube` giving only their densities (`render::Extras::fine`), as the Bevy pass
    /// reads the image itself. `None`: radiance is `cube`'s.
    pub fine: Option<CubeMap>,
}

impl LoadedEnv {
    /// The map radiance is read from: [`Self::fine`] if there is one, else [`Self::cube`].
    pub fn radiance_map(&self) -> &CubeMap {
        self.fine.as_ref().unwrap_or(&self.cube)
    }
}

/// Face size of the built-in sky "at its own resolution": it is analytic, so this is a choice
/// (0.7 degrees a texel at the face centre, about four across the 1.5-degree sun), the same as
/// the 512 x 256 maps of `../shared/data` give.
pub const SKY_FACE: usize = 128;

/// Face size of a cube with as many texels across as the source has: a lat-long's width / 4, a
/// cross's face, [`SKY_FACE`] for the built-in sky.
pub fn native_face_size(layout: Option<Layout>, width: usize) -> usize {
    match layout {
        None => SKY_FACE,
        Some(Layout::LatLong) => (width / 4).max(1),
        Some(Layout::HorizontalCross) => width / 4,
        Some(Layout::VerticalCross) => width / 3,
    }
}

/// Load an environment source as a sanitized cube map with faces of `face_size` texels.
pub fn load_env(src: &EnvSource, face_size: usize) -> Result<LoadedEnv> {
    load(src, face_size, false)
}

/// [`load_env`], and the map at its own resolution as [`LoadedEnv::fine`] where that is finer
/// than `face_size`.
pub fn load_env_full(src: &EnvSource, face_size: usize) -> Result<LoadedEnv> {
    load(src, face_size, true)
}

fn load(src: &EnvSource, face_size: usize, full: bool) -> Result<LoadedEnv> {
    if face_size == 0 || face_size > 4096 {
        return Err(Error::invalid(format!(
            "face size {face_size} out of range 1..=4096"
        )));
    }
    let finer = |native: usize| full && native > face_size;
    match src {
        EnvSource::Sky { hours } => {
            let mut cube = super::sky::sky_cube(face_size, *hours);
            let report = cube.sanitize();
            let fine = finer(SKY_FACE).then(|| super::sky::sky_cube(SKY_FACE, *hours));
            Ok(LoadedEnv {
                cube,
                report,
                layout: None,
                fine,
            })
        }
        EnvSource::File(path) => {
            let mut img = read_image(path)?;
            let layout = detect_layout(img.width, img.height).map_err(|p| Error::file(path, p))?;
            // Clamp before any filtering so no bad value is spread into neighbours.
            let mut report = img.sanitize();
            let native = native_face_size(Some(layout), img.width);
            let (mut cube, mut fine) = match layout {
                // Both area-filtered (every source texel splatted into the texels it overlaps),
                // so a coarse texel is positive wherever a fine texel inside it is: the fine
                // radiance never falls where the coarse density is 0.
                Layout::LatLong => (
                    super::resample::latlong_to_cube(&img, face_size),
                    finer(native).then(|| super::resample::latlong_splat(&img, native, 4)),
                ),
                _ => {
                    let whole = cross_to_cube(&img, layout);
                    let cube = super::resample::resize_cube(&whole, face_size);
                    (cube, finer(native).then_some(whole))
                }
            };
            // Backstop: filtering of clamped data cannot create bad texels, but the distribution
            // must never see one, so check again (counted with the rest).
            report.add(cube.sanitize());
            if let Some(f) = fine.as_mut() {
                f.sanitize();
            }
            Ok(LoadedEnv {
                cube,
                report,
                layout: Some(layout),
                fine,
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn env_source_syntax() {
        assert_eq!(
            "builtin:sky".parse::<EnvSource>().unwrap(),
            EnvSource::Sky {
                hours: super::super::sky::DEFAULT_HOURS
            }
        );
        assert_eq!(
            "builtin:sky:7.5".parse::<EnvSource>().unwrap(),
            EnvSource::Sky { hours: 7.5 }
        );
        assert!("builtin:sky:x".parse::<EnvSource>().is_err());
        assert!("builtin:moon".parse::<EnvSource>().is_err());
    }
}
