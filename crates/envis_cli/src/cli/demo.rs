//! `envis` with no subcommand: the interactive demo, after checking what it needs (a display,
//! a GPU adapter, a readable environment) so that a missing piece is a one-line error.

use crate::DemoArgs;
use envis::error::{Error, Result};
use envis::render::Settings;

pub fn run_demo(mut a: DemoArgs) -> Result<()> {
    let scene = a
        .scene
        .as_deref()
        .map(envis::scene::Scene::load)
        .transpose()?;
    let source = demo_source(&mut a, scene.as_ref())?;
    check_display()?;
    envis_wgpu::context::check_adapter()?;
    let face_size = scene
        .as_ref()
        .map_or(a.face_size, |s| s.file.environment.face_size);
    // Refuse a bad source before opening a window, with its error.
    envis::stream::EnvStream::open(source.clone(), face_size)?;
    let window = parse_window(&a.window)?;
    let sampling = scene.as_ref().map_or(
        Settings {
            light_samples: a.light_samples,
            brdf_samples: a.brdf_samples,
            ..Default::default()
        },
        |s| s.settings,
    );
    sampling.validate()?;
    if !(a.ui_scale.is_finite() && (0.25..=4.0).contains(&a.ui_scale)) {
        return Err(Error::invalid(format!(
            "--ui-scale {} out of range 0.25..=4",
            a.ui_scale
        )));
    }
    if let Some(d) = &a.script {
        std::fs::create_dir_all(d).map_err(|e| Error::file(d, format!("cannot create: {e}")))?;
    }
    let exit = envis_cli::demo::run(envis_cli::demo::DemoOptions {
        source,
        face_size,
        script: a.script,
        window,
        ui_scale: a.ui_scale,
        sampling,
        scene,
    });
    match exit {
        bevy::app::AppExit::Success => Ok(()),
        bevy::app::AppExit::Error(c) => {
            Err(Error::invalid(format!("the demo exited with code {c}")))
        }
    }
}

/// The environment the demo streams: the scene's (its sky moving at the scene's speed), else
/// `--sequence`, `--carousel`, then `--env`, in that order.
fn demo_source(
    a: &mut DemoArgs,
    scene: Option<&envis::scene::Scene>,
) -> Result<envis::stream::StreamSource> {
    use envis::stream::StreamSource;
    Ok(if let Some(sc) = scene {
        sc.stream_source(sc.file.environment.speed)?
    } else if let Some(dir) = a.sequence.take() {
        StreamSource::Sequence { dir, fps: a.fps }
    } else if !a.carousel.is_empty() {
        StreamSource::Carousel {
            paths: std::mem::take(&mut a.carousel),
            period: 8.0,
            fade: 2.0,
            spin: 0.05,
        }
    } else {
        StreamSource::parse(&a.env)?
    })
}

/// `--window WIDTHxHEIGHT`, each side in 64..=8192.
fn parse_window(window: &str) -> Result<(u32, u32)> {
    window
        .split_once('x')
        .and_then(|(w, h)| Some((w.parse::<u32>().ok()?, h.parse::<u32>().ok()?)))
        .filter(|(w, h)| (64..=8192).contains(w) && (64..=8192).contains(h))
        .ok_or_else(|| {
            Error::invalid(format!(
                "--window {window}: expected WIDTHxHEIGHT, e.g. 1280x720"
            ))
        })
}

/// The demo opens an X11 window (this build's only windowing backend): without a display, say
/// what to do instead of letting the event loop panic.
fn check_display() -> Result<()> {
    if cfg!(target_os = "linux") && std::env::var_os("DISPLAY").is_none_or(|d| d.is_empty()) {
        return Err(Error::invalid(
            "the demo needs a display and DISPLAY is not set: run it under Xvfb \
             (`xvfb-run -a envis`), or render without a window \
             (`envis render --env builtin:sky --out sphere.exr`)",
        ));
    }
    Ok(())
}
