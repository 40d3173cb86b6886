//! The Radiance RGBE (`.hdr`) reader: header (`FORMAT`, `EXPOSURE`, `PRIMARIES`), resolution
//! line, flat and run-length-encoded scanlines. Bounds-checked throughout: a file cannot make it
//! allocate more than it could hold, or read past its end.

use super::load::{MAX_PIXELS, MAX_SIDE};
use super::{Image, color};
use glam::Vec3;

type Parsed<T> = std::result::Result<T, String>;

/// Parse a Radiance RGBE (`.hdr`) file: `#?RADIANCE`/`#?RGBE` header, `FORMAT=32-bit_rle_rgbe`,
/// resolution line `-Y H +X W`, then flat or new-style run-length-encoded scanlines. The
/// radiance is divided by the header's `EXPOSURE` and converted from its `PRIMARIES` to Rec.709.
pub fn read_hdr_bytes(bytes: &[u8]) -> Parsed<Image> {
    let mut pos = 0usize;
    let header = read_header(bytes, &mut pos)?;
    let (w, h) = read_resolution(bytes, &mut pos)?;
    let mut img = Image::new(w, h);
    let mut scan = vec![[0u8; 4]; w];
    for y in 0..h {
        read_hdr_scanline(bytes, &mut pos, &mut scan).map_err(|e| format!("scanline {y}: {e}"))?;
        for (out, &px) in img.data[y * w..(y + 1) * w].iter_mut().zip(&scan) {
            *out = rgbe_to_rgb(px);
        }
    }
    header.apply(&mut img)?;
    Ok(img)
}

/// What the header says about the pixel values.
struct Header {
    /// The product of the `EXPOSURE=` lines: the pixels were scaled by it when written.
    exposure: f64,
    primaries: Option<color::Primaries>,
}

impl Header {
    /// Back to the scene's radiance, then to Rec.709 when the file declares other primaries.
    fn apply(&self, img: &mut Image) -> Parsed<()> {
        if self.exposure != 1.0 {
            let k = (1.0 / self.exposure) as f32;
            if !(k.is_finite() && k > 0.0) {
                let e = self.exposure;
                return Err(format!(
                    "the EXPOSURE lines multiply to {e:e}, out of range"
                ));
            }
            img.data.iter_mut().for_each(|c| *c *= k);
        }
        if let Some(p) = &self.primaries
            && let Some(m) = color::to_rec709(p)?
        {
            color::convert(&mut img.data, &m);
        }
        Ok(())
    }
}

/// One header line (without its newline), at most 4096 bytes.
fn line(bytes: &[u8], pos: &mut usize) -> Parsed<String> {
    let start = *pos;
    while *pos < bytes.len() && bytes[*pos] != b'\n' {
        *pos += 1;
        if *pos - start > 4096 {
            return Err("Radiance header line longer than 4096 bytes".into());
        }
    }
    if *pos >= bytes.len() {
        return Err("truncated Radiance header".into());
    }
    let s = String::from_utf8_lossy(&bytes[start..*pos]).into_owned();
    *pos += 1;
    Ok(s)
}

/// The signature and the header lines up to the blank line.
fn read_header(bytes: &[u8], pos: &mut usize) -> Parsed<Header> {
    if !line(bytes, pos)?.starts_with("#?") {
        return Err("not a Radiance HDR file (missing #? signature)".into());
    }
    let mut header = Header {
        exposure: 1.0,
        primaries: None,
    };
    loop {
        let l = line(bytes, pos)?;
        if l.is_empty() {
            return Ok(header);
        }
        if let Some(v) = l.strip_prefix("EXPOSURE=") {
            let e: f64 = v
                .trim()
                .parse()
                .map_err(|_| format!("bad header line '{l}'"))?;
            if !(e.is_finite() && e > 0.0) {
                let v = v.trim();
                return Err(format!("EXPOSURE must be a positive number, got '{v}'"));
            }
            header.exposure *= e;
        }
        if let Some(v) = l.strip_prefix("PRIMARIES=") {
            let nums: Vec<f64> = v
                .split_whitespace()
                .filter_map(|x| x.parse().ok())
                .collect();
            let arr: [f64; 8] = nums
                .try_into()
                .map_err(|_| format!("PRIMARIES needs 8 numbers: '{}'", v.trim()))?;
            header.primaries = Some(color::Primaries::from_array(arr));
        }
        if let Some(fmt) = l.strip_prefix("FORMAT=")
            && fmt.trim() != "32-bit_rle_rgbe"
        {
            let fmt = fmt.trim();
            return Err(format!(
                "unsupported Radiance pixel format '{fmt}' (needs 32-bit_rle_rgbe)"
            ));
        }
    }
}

/// The resolution line `-Y H +X W`, checked against the caps and the bytes left.
fn read_resolution(bytes: &[u8], pos: &mut usize) -> Parsed<(usize, usize)> {
    let res = line(bytes, pos)?;
    let parts: Vec<&str> = res.split_whitespace().collect();
    if parts.len() != 4 || parts[0] != "-Y" || parts[2] != "+X" {
        return Err(format!(
            "unsupported Radiance resolution line '{res}' (needs '-Y H +X W')"
        ));
    }
    let h: usize = parts[1]
        .parse()
        .map_err(|_| format!("bad height in '{res}'"))?;
    let w: usize = parts[3]
        .parse()
        .map_err(|_| format!("bad width in '{res}'"))?;
    if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE || w * h > MAX_PIXELS {
        return Err(format!(
            "absurd dimensions {w}x{h} (limit {MAX_SIDE} per side, {MAX_PIXELS} pixels)"
        ));
    }
    // A file cannot hold more pixels than 4 bytes each (flat), or than it has bytes (RLE, at
    // best ~ 2 bytes per 127 pixels per channel): refuse obvious lies before allocating.
    let left = bytes.len() - *pos;
    if left.saturating_mul(128) < w * h {
        return Err(format!(
            "truncated: {left} bytes of pixel data cannot hold {w}x{h} pixels"
        ));
    }
    Ok((w, h))
}

fn rgbe_to_rgb(p: [u8; 4]) -> Vec3 {
    if p[3] == 0 {
        return Vec3::ZERO;
    }
    let f = (2.0f32).powi(p[3] as i32 - 136); // 2^(e-128) / 256
    Vec3::new(p[0] as f32 + 0.5, p[1] as f32 + 0.5, p[2] as f32 + 0.5) * f
}

fn read_hdr_scanline(
    bytes: &[u8],
    pos: &mut usize,
    scan: &mut [[u8; 4]],
) -> std::result::Result<(), String> {
    let w = scan.len();
    let take = |pos: &mut usize| -> std::result::Result<u8, String> {
        let b = *bytes.get(*pos).ok_or("truncated pixel data")?;
        *pos += 1;
        Ok(b)
    };
    let is_rle = (8..0x8000).contains(&w) && bytes.get(*pos..*pos + 2) == Some(&[2, 2]);
    if !is_rle {
        for px in scan.iter_mut() {
            for c in px.iter_mut() {
                *c = take(pos)?;
            }
        }
        return Ok(());
    }
    let hdr = [take(pos)?, take(pos)?, take(pos)?, take(pos)?];
    if hdr[2] & 0x80 != 0 || ((hdr[2] as usize) << 8 | hdr[3] as usize) != w {
        return Err("run-length scanline width does not match the image width".into());
    }
    for ch in 0..4 {
        let mut x = 0;
        while x < w {
            let n = take(pos)? as usize;
            if n > 128 {
                let run = n - 128;
                if x + run > w {
                    return Err("run-length run overflows the scanline".into());
                }
                let v = take(pos)?;
                for px in &mut scan[x..x + run] {
                    px[ch] = v;
                }
                x += run;
            } else {
                if n == 0 || x + n > w {
                    return Err("bad run-length literal count".into());
                }
                for px in &mut scan[x..x + n] {
                    px[ch] = take(pos)?;
                }
                x += n;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hdr_flat_and_rle_round_trip() {
        // 8x2 image, first scanline flat, second run-length encoded.
        let mut f = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 8\n".to_vec();
        for x in 0..8u8 {
            f.extend_from_slice(&[x * 10, 128, 64, 129]);
        }
        f.extend_from_slice(&[2, 2, 0, 8]);
        for ch in 0..4 {
            f.extend_from_slice(&[128 + 8, [200, 100, 50, 130][ch]]);
        }
        let img = read_hdr_bytes(&f).unwrap();
        assert_eq!((img.width, img.height), (8, 2));
        assert!((img.get(1, 0).x - 10.5 / 128.0).abs() < 1e-6);
        assert!((img.get(5, 1).x - 200.5 / 64.0).abs() < 1e-6);
        assert!(
            read_hdr_bytes(&f[..f.len() - 3])
                .unwrap_err()
                .contains("truncated")
        );
    }
}
