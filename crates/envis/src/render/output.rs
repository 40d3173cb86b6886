//! Image output: linear RGB float32 OpenEXR, and tone-mapped PNG previews for docs.

use crate::envmap::Image;
use crate::error::{Error, Result};
use std::path::Path;

/// Write `v` as pretty-printed JSON with a final newline: the one JSON writer of the command
/// line, the benchmarks and the demo's report. Errors name the file.
pub fn write_json(path: &Path, v: &impl serde::Serialize) -> Result<()> {
    let text = serde_json::to_string_pretty(v)
        .map_err(|e| Error::file(path, format!("cannot encode JSON: {e}")))?;
    std::fs::write(path, text + "\n").map_err(|e| Error::file(path, format!("cannot write: {e}")))
}

/// Write a linear RGB float32 EXR.
pub fn write_exr(path: &Path, img: &Image) -> Result<()> {
    exr::prelude::write_rgb_file(path, img.width, img.height, |x, y| {
        let c = img.get(x, y);
        (c.x, c.y, c.z)
    })
    .map_err(|e| Error::file(path, format!("cannot write OpenEXR: {e}")))
}

/// sRGB-encode a linear value in [0, 1].
fn srgb(x: f32) -> u8 {
    let x = x.clamp(0.0, 1.0);
    let y = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    (y * 255.0 + 0.5) as u8
}

/// Write an 8-bit sRGB PNG of `exposure * c`, Reinhard tone-mapped per channel.
pub fn write_png(path: &Path, img: &Image, exposure: f32) -> Result<()> {
    let mut bytes = Vec::with_capacity(img.width * img.height * 3);
    for c in &img.data {
        for v in c.to_array() {
            let v = v * exposure;
            bytes.push(srgb(v / (1.0 + v)));
        }
    }
    write_png_rgb8(path, img.width, img.height, &bytes)
}

/// Write raw 8-bit RGB rows as a PNG.
pub fn write_png_rgb8(path: &Path, width: usize, height: usize, rgb: &[u8]) -> Result<()> {
    let f = std::fs::File::create(path)
        .map_err(|e| Error::file(path, format!("cannot create: {e}")))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(f), width as u32, height as u32);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc
        .write_header()
        .map_err(|e| Error::file(path, format!("cannot write PNG: {e}")))?;
    w.write_image_data(rgb)
        .map_err(|e| Error::file(path, format!("cannot write PNG: {e}")))
}
