//! `envis sequence`: an animated scene file, frame by frame, with or without resampling.

use crate::{BackendArg, SequenceArgs};
use envis::error::{Error, Result};
use envis::render::output;
use envis::render::resampling::Resampling;
use envis::scene::Scene;
use envis_cli::sequence::{self, SequenceBackend, SequenceOptions};

pub fn sequence(a: SequenceArgs) -> Result<()> {
    check_args(&a)?;
    let scene = Scene::load(&a.scene)?;
    let mut settings = scene.settings;
    settings.light_samples = a.light_samples.unwrap_or(settings.light_samples);
    settings.brdf_samples = a.brdf_samples.unwrap_or(settings.brdf_samples);
    settings.seed = a.seed.unwrap_or(settings.seed);
    settings.validate()?;
    let vis = a.visibility.or(scene.file.sampling.shadows);
    let o = SequenceOptions {
        size: a.size,
        frames: a.frames,
        settings,
        resampling: Resampling::for_mode(a.resampling, !a.biased),
        visibility: vis,
        backend: match a.backend {
            BackendArg::Wgpu => SequenceBackend::Wgpu,
            BackendArg::Gpu => SequenceBackend::Bevy,
            BackendArg::Cpu => SequenceBackend::Cpu,
        },
    };
    std::fs::create_dir_all(&a.out)
        .map_err(|e| Error::file(&a.out, format!("cannot create: {e}")))?;
    let mut frames = Vec::new();
    sequence::run(&scene, &o, |f| {
        let name = format!("frame_{:04}", f.stats.frame);
        output::write_exr(&a.out.join(format!("{name}.exr")), &f.image)?;
        if a.png {
            output::write_png(&a.out.join(format!("{name}.png")), &f.image, 1.0)?;
        }
        frames.push(f.stats);
        Ok(())
    })?;
    if let Some(p) = &a.stats {
        write_stats(p, &a, &scene, &o, frames)?;
    }
    Ok(())
}

/// The flags `sequence` checks before loading anything.
fn check_args(a: &SequenceArgs) -> Result<()> {
    if a.frames == 0 || a.frames > 100_000 {
        return Err(Error::invalid(format!(
            "--frames {} out of range 1..=100000",
            a.frames
        )));
    }
    if a.size == 0 || a.size > 16384 {
        return Err(Error::invalid(format!(
            "--size {} out of range 1..=16384",
            a.size
        )));
    }
    Ok(())
}

/// The stats JSON: the settings, then one object per frame.
fn write_stats(
    p: &std::path::Path,
    a: &SequenceArgs,
    scene: &Scene,
    o: &SequenceOptions,
    frames: Vec<envis_cli::sequence::FrameStats>,
) -> Result<()> {
    let (shadows, why) = scene.shadows(o.visibility);
    output::write_json(
        p,
        &serde_json::json!({
            "scene": a.scene.display().to_string(),
            "size": a.size,
            "backend": o.backend.name(),
            "counts": match o.backend {
                SequenceBackend::Bevy => "read back from the resampling pass (null without resampling: the plain lighting pass keeps none); build_ms and shade_ms are the latest GPU timestamps when the frame arrived",
                _ => "counted",
            },
            "resampling": a.resampling.to_string(),
            "unbiased": !a.biased,
            "reuse": o.resampling,
            "settings": o.settings,
            "shadows": shadows,
            "visibility": why,
            "fps": scene.file.animation.fps,
            "frames": frames,
        }),
    )
}
