//! Suite `popping`: integer against fractional counts while the sun moves (the paper's popping).

use super::*;
use std::path::Path;

/// Suite `popping`: temporal stability of integer vs fractional counts (the paper's "smooth
/// transitions"). The built-in sun moves from 9h to 11h over `frames` frames; every frame uses the
/// same seed, so frame-to-frame change comes only from the environment and the counts. For each
/// mode: mean |change| per pixel relative to the reference's own mean |change| (1 = as smooth as
/// the truth), and the fraction of (pixel, frame) pairs that jump by more than 10% of the pixel
/// while the reference moves by less than 1% (discontinuities). Writes `popping.json`, a plot of
/// the change per frame (`popping.svg` / `.png`) and PNG strips of 6 frames per mode.
pub(super) fn popping(a: BenchArgs, dir: PathBuf) -> Result<()> {
    let frames = if a.quick { 8 } else { 48 };
    let (size, face) = (a.size.min(64), a.face_size.min(32));
    let anim = Animation::new(frames, size, face);
    let mut series = vec![accuracy::Series {
        name: "reference".into(),
        color: "#000000",
        points: anim.per_frame(&|t| anim.reference_change(t)),
        dashed: true,
    }];
    let mut rows = Vec::new();
    for (name, counts, color) in [
        ("fractional", envis::sampling::Counts::Fractional, "#d62728"),
        ("integer", envis::sampling::Counts::Integer, "#ff7f0e"),
    ] {
        let (s, row) = anim.mode(&a, &dir, name, counts, color)?;
        series.push(s);
        rows.push(row);
    }
    let report = serde_json::json!({ "suite": "popping", "frames": frames, "hours": [9.0, 11.0], "size": size, "face_size": face, "light_samples": a.light_samples, "brdf_samples": a.brdf_samples, "seed": "1 for every frame", "rows": rows });
    let path = dir.join("popping.json");
    envis::render::output::write_json(&path, &report)?;
    let chart = accuracy::Chart {
        title: "Frame-to-frame change, sun moving 9h -> 11h (same seed every frame)".into(),
        xlabel: "frame",
        ylabel: "mean |luminance change| per pixel",
        xlog: false,
        ylog: false,
        series,
    };
    let (svg, png) = chart.write(&dir, "popping")?;
    eprintln!(
        "wrote {}, {svg}, {png} and popping-strip-*.png",
        path.display()
    );
    Ok(())
}

/// What every counts mode is compared against: the sky of each frame, the sphere's G-buffer and
/// covered pixels, and the reference's luminances and total change.
struct Animation {
    size: usize,
    maps: Vec<envis::envmap::CubeMap>,
    gbuf: Vec<Option<render::GPixel>>,
    idx: Vec<usize>,
    refs: Vec<Vec<f64>>,
    /// The reference's summed |luminance change| over all frames and covered pixels.
    ref_change: f64,
}

impl Animation {
    /// The sun from 9h to 11h over `frames` skies (faces of `face`) on a diffuse `size x size`
    /// sphere.
    fn new(frames: usize, size: usize, face: usize) -> Self {
        let mat = Material::diffuse(0.8);
        let gbuf = render::sphere_gbuffer(size, size, mat);
        let idx: Vec<usize> = (0..gbuf.len()).filter(|&i| gbuf[i].is_some()).collect();
        let hours = |t: usize| 9.0 + 2.0 * t as f32 / (frames - 1) as f32;
        let maps: Vec<envis::envmap::CubeMap> = (0..frames)
            .map(|t| envis::envmap::sky::sky_cube(face, hours(t)))
            .collect();
        let refs = reference_luminances(&maps, &gbuf, size);
        let mut anim = Self {
            size,
            maps,
            gbuf,
            idx,
            refs,
            ref_change: 0.0,
        };
        anim.ref_change = (1..frames).map(|t| anim.reference_change(t)).sum::<f64>();
        anim
    }

    /// The reference's summed |luminance change| over the covered pixels from frame `t - 1` to `t`.
    fn reference_change(&self, t: usize) -> f64 {
        self.idx
            .iter()
            .map(|&i| (self.refs[t][i] - self.refs[t - 1][i]).abs())
            .sum::<f64>()
    }

    /// `(t, f(t) per covered pixel)` for every frame `t` after the first: a chart series' points.
    fn per_frame(&self, f: &dyn Fn(usize) -> f64) -> Vec<(f64, f64)> {
        let np = self.idx.len().max(1) as f64;
        (1..self.maps.len())
            .map(|t| (t as f64, f(t) / np))
            .collect()
    }

    /// Every frame rendered with `counts` (same seed throughout): its chart series and JSON row,
    /// printing its summary and writing its strip.
    fn mode(
        &self,
        a: &BenchArgs,
        dir: &Path,
        name: &str,
        counts: envis::sampling::Counts,
        color: &'static str,
    ) -> Result<(accuracy::Series, serde_json::Value)> {
        let (size, idx) = (self.size, &self.idx);
        let lum = |c: glam::Vec3| envis::envmap::luminance(c) as f64;
        let s = Settings {
            light_samples: a.light_samples,
            brdf_samples: a.brdf_samples,
            counts,
            seed: 1,
            ..Default::default()
        };
        let imgs: Vec<envis::envmap::Image> = self
            .maps
            .iter()
            .map(|m| render::render(m, &self.gbuf, size, size, &s).map(|o| o.image))
            .collect::<Result<_>>()?;
        let (change, jumps, pairs) = frame_changes(&imgs, &self.refs, idx);
        let series = accuracy::Series {
            name: format!("{name} counts"),
            color,
            points: self.per_frame(&|t| {
                idx.iter()
                    .map(|&i| (lum(imgs[t].data[i]) - lum(imgs[t - 1].data[i])).abs())
                    .sum()
            }),
            dashed: false,
        };
        let ratio = change / self.ref_change.max(1e-12);
        let jump_frac = jumps as f64 / pairs.max(1) as f64;
        eprintln!(
            "  {name:10}: mean |frame change| = {ratio:.2} x the reference's; discontinuities {:.3}% of pixel-frames",
            100.0 * jump_frac
        );
        let picks = write_strip(dir, name, &imgs, size)?;
        let row = serde_json::json!({ "counts": name, "change_over_reference": ratio, "discontinuity_fraction": jump_frac, "strip_frames": picks });
        Ok((series, row))
    }
}

/// Per frame, the reference's luminance of every pixel of `gbuf` (`size x size`).
fn reference_luminances(
    maps: &[envis::envmap::CubeMap],
    gbuf: &[Option<render::GPixel>],
    size: usize,
) -> Vec<Vec<f64>> {
    maps.iter()
        .map(|m| {
            envis::render::reference::reference_image(m, gbuf, size, size, 1.0)
                .1
                .iter()
                .map(|&c| envis::envmap::luminance_f64(c))
                .collect()
        })
        .collect()
}

/// Over the frames and the pixels `idx`: the summed |luminance change| of `imgs`, how many
/// (pixel, frame) pairs jump by over 10% while the reference `refs` moves by under 1%, and the
/// pairs counted.
fn frame_changes(
    imgs: &[envis::envmap::Image],
    refs: &[Vec<f64>],
    idx: &[usize],
) -> (f64, usize, usize) {
    let lum = |c: glam::Vec3| envis::envmap::luminance(c) as f64;
    let (mut change, mut jumps, mut pairs) = (0.0, 0usize, 0usize);
    for t in 1..imgs.len() {
        for &i in idx {
            let (x0, x1) = (lum(imgs[t - 1].data[i]), lum(imgs[t].data[i]));
            let d = (x1 - x0).abs();
            change += d;
            pairs += 1;
            let r = (refs[t][i] - refs[t - 1][i]).abs();
            if d > 0.1 * x0.max(x1).max(1e-6) && r < 0.01 * refs[t][i].max(1e-6) {
                jumps += 1;
            }
        }
    }
    (change, jumps, pairs)
}

/// `popping-strip-{name}.png`: 6 of the `size x size` frames `imgs`, spread over the animation;
/// returns which.
fn write_strip(
    dir: &Path,
    name: &str,
    imgs: &[envis::envmap::Image],
    size: usize,
) -> Result<Vec<usize>> {
    let picks: Vec<usize> = (0..6).map(|k| k * (imgs.len() - 1) / 5).collect();
    let mut strip = envis::envmap::Image::new(6 * size, size);
    for (k, &t) in picks.iter().enumerate() {
        for y in 0..size {
            for x in 0..size {
                strip.data[y * 6 * size + k * size + x] = imgs[t].get(x, y);
            }
        }
    }
    envis::render::output::write_png(&dir.join(format!("popping-strip-{name}.png")), &strip, 1.0)?;
    Ok(picks)
}
