//! The scripted run (`--script DIR`, what CI runs under Xvfb): a fixed list of steps, one every
//! few frames after a warm-up, each changing one thing, taking a screenshot or waiting for what
//! the next screenshot needs; then `report.json` and exit.

use super::*;

/// One step of the script.
#[derive(Clone, Copy, Debug)]
enum Step {
    /// Save a screenshot of the window under this name.
    Shot(&'static str),
    Counts(Counts),
    Overlay(Overlay),
    /// Overlays off, fractional counts, probe a pixel on the sphere and show the debug view.
    /// Whole faces: with tiles a probed pixel may have no yellow (wasted) sample left to show.
    Probe,
    /// Wait until the probed pixel has come back from the GPU and the CPU twin has classified
    /// its samples (the readback never blocks a frame, so on a slow machine it takes several).
    AwaitProbe,
    /// Show or hide the debug view.
    Debug(bool),
    /// Make the sphere a near-mirror GGX.
    GlossySphere,
    /// Add or remove `EnvironmentResampling` on the camera.
    Resampling(bool),
    /// Write `report.json` (timings, counters, the probed pixel's samples).
    Report,
    Exit,
}

/// The script, in order.
const SCRIPT: &[Step] = &[
    Step::Shot("start.png"),
    Step::Counts(Counts::Integer),
    Step::Shot("integer.png"),
    Step::Overlay(Overlay::EffectiveSamples),
    Step::Shot("overlay-samples.png"),
    Step::Overlay(Overlay::Wasted),
    Step::Shot("overlay-wasted.png"),
    Step::Overlay(Overlay::CountsDifference),
    Step::Shot("overlay-diff.png"),
    Step::Probe,
    Step::AwaitProbe,
    Step::Shot("debug-on.png"),
    Step::Debug(false),
    Step::Shot("debug-off.png"),
    Step::GlossySphere,
    Step::Shot("brdf.png"),
    Step::Resampling(true),
    Step::Shot("resampling.png"),
    Step::Overlay(Overlay::History),
    Step::Shot("overlay-history.png"),
    Step::Report,
    Step::Exit,
];

// A screenshot is taken by the frame after it is asked for; three frames a step leave room for it
// to be written before the next change.
const WARMUP: u32 = 6;
const STEP: u32 = 3;
/// How long a wait may last before the run fails, saying what it waited for.
const MAX_WAIT: u32 = 600;

/// The scripted CI sequence: one step every few frames, a screenshot after each.
#[allow(
    clippy::too_many_arguments,
    reason = "a Bevy system's parameters are the data it touches"
)]
pub(super) fn run_script(
    mut stream: ResMut<EnvMapStream>,
    mut state: ResMut<DemoState>,
    mut objects: Query<&mut SceneObject>,
    mut materials: ResMut<Assets<EnvisMaterial>>,
    windows: Query<&Window, With<PrimaryWindow>>,
    mut cams: Query<
        (Entity, &Camera, &GlobalTransform, &mut EnvironmentSampling),
        With<DemoCamera>,
    >,
    timings: Res<EnvisTimings>,
    counters: Res<EnvisCounters>,
    mut commands: Commands,
    mut exit: MessageWriter<AppExit>,
) {
    let Some(dir) = state.script.clone() else {
        return;
    };
    let Some((f, step)) = next_step(&mut state, &mut stream, &counters, &mut exit) else {
        return;
    };
    let Ok((entity, camera, cam_transform, mut settings)) = cams.single_mut() else {
        return;
    };
    let shot = |commands: &mut Commands, name: &str| {
        commands
            .spawn(Screenshot::primary_window())
            .observe(save_to_disk(dir.join(name)));
    };
    let (w, h) = windows
        .single()
        .map(|w| (w.physical_width(), w.physical_height()))
        .unwrap_or((0, 0));
    match SCRIPT.get(step) {
        Some(Step::Shot(name)) => shot(&mut commands, name),
        Some(Step::Counts(c)) => settings.counts = *c,
        Some(Step::Overlay(o)) => settings.overlay = *o,
        Some(Step::Probe) => {
            settings.overlay = Overlay::None;
            settings.counts = Counts::Fractional;
            let scale = windows.single().map(|w| w.scale_factor()).unwrap_or(1.0);
            settings.probe = Some(sphere_pixel(camera, cam_transform, (w, h), scale));
            state.debug = true;
        }
        Some(Step::AwaitProbe) => {}
        Some(Step::Debug(on)) => state.debug = *on,
        Some(Step::GlossySphere) => make_sphere_glossy(&mut objects, &mut materials),
        Some(Step::Resampling(on)) => set_resampling(&mut commands, entity, *on),
        Some(Step::Report) => {
            let report = script_report(&state, &timings, &counters, (w, h), f);
            write_report(&dir, &report, &mut exit);
        }
        Some(Step::Exit) => {
            exit.write(AppExit::Success);
        }
        None => {}
    }
}

/// Advance the script's clock by a frame; the frame number and the index of the step to run
/// when one is due (the warm-up is over, its time has come and nothing is awaited).
fn next_step(
    state: &mut DemoState,
    // A `ResMut`, written only on the first frame: the stream is not marked changed otherwise.
    stream: &mut ResMut<EnvMapStream>,
    counters: &EnvisCounters,
    exit: &mut MessageWriter<AppExit>,
) -> Option<(u32, usize)> {
    state.script_frame += 1;
    let f = state.script_frame;
    if f == 1 {
        // A still environment, so the screenshots differ only by what each step changed.
        stream.stream.playing = false;
        state.script_next = WARMUP;
    }
    if f < state.script_next {
        return None;
    }
    if script_waits(state, counters, exit) {
        return None;
    }
    let step = state.script_step;
    state.script_step += 1;
    state.script_next = f + STEP;
    Some((f, step))
}

/// Write `report.json` into `dir`; a report that cannot be written fails the scripted run,
/// saying why.
fn write_report(
    dir: &std::path::Path,
    report: &serde_json::Value,
    exit: &mut MessageWriter<AppExit>,
) {
    if let Err(e) = envis::render::output::write_json(&dir.join("report.json"), report) {
        error!("{e}");
        eprintln!("envis: error: {e}");
        exit.write(AppExit::error());
    }
}

/// Whether the script must wait this frame: for the lighting pipeline, which Bevy compiles in
/// the background (the steps start once envis has lit a frame), or, at an
/// [`Step::AwaitProbe`], for the probed pixel. A wait past its limit ends the run with an error.
fn script_waits(
    state: &mut DemoState,
    counters: &EnvisCounters,
    exit: &mut MessageWriter<AppExit>,
) -> bool {
    if counters.get(|c| &c.lighting_passes) == 0 {
        state.script_compile_wait += 1;
        if state.script_compile_wait > 20 * MAX_WAIT {
            eprintln!(
                "envis: error: the lighting pass did not run in {} frames",
                20 * MAX_WAIT
            );
            exit.write(AppExit::error());
        }
        return true;
    }
    if let Some(Step::AwaitProbe) = SCRIPT.get(state.script_step)
        && state.pixel.is_none()
    {
        state.script_waited += 1;
        if state.script_waited > MAX_WAIT {
            eprintln!("envis: error: the probed pixel did not come back in {MAX_WAIT} frames");
            exit.write(AppExit::error());
        }
        return true;
    }
    false
}

/// A pixel on the sphere to probe: its centre, projected (physical pixels of a window `w x h`
/// at `scale`), or a point left of the window's centre if it does not project.
fn sphere_pixel(camera: &Camera, at: &GlobalTransform, (w, h): (u32, u32), scale: f32) -> UVec2 {
    let p = camera
        .world_to_viewport(at, Vec3::new(-2.3, 1.0, 0.0))
        .ok()
        .unwrap_or(Vec2::new(w as f32 * 0.3, h as f32 * 0.5));
    (p * scale).as_uvec2()
}

/// The sphere made a near-mirror GGX.
fn make_sphere_glossy(
    objects: &mut Query<&mut SceneObject>,
    materials: &mut Assets<EnvisMaterial>,
) {
    for mut o in objects.iter_mut() {
        if o.name == "sphere" {
            o.material = EnvisBrdf::Ggx {
                albedo: Vec3::splat(0.8),
                alpha: 0.05,
            };
            if let Some(mut m) = materials.get_mut(&o.handle) {
                m.brdf = o.material;
            }
        }
    }
}

/// `report.json`: the window, frames and waits, timings, counters and the probed pixel's samples.
fn script_report(
    state: &DemoState,
    timings: &EnvisTimings,
    counters: &EnvisCounters,
    (w, h): (u32, u32),
    f: u32,
) -> serde_json::Value {
    serde_json::json!({
        "window": [w, h],
        "frames": f,
        "probe_wait_frames": state.script_waited,
        "lighting_wait_frames": state.script_compile_wait,
        "fps": state.fps,
        "timings_ms": timings.get(),
        "builds": counters.get(|c| &c.builds),
        "image_bytes_uploaded": counters.get(|c| &c.image_bytes_uploaded),
        "lighting_passes": counters.get(|c| &c.lighting_passes),
        "overlay_passes": counters.get(|c| &c.overlay_passes),
        "resampling_passes": counters.get(|c| &c.resampling_passes),
        "resampling_histories": counters.get(|c| &c.resampling_histories),
        "resampling_bright": counters.get(|c| &c.resampling_bright),
        "probe": state.pixel.as_ref().map(|(d, g, gpu)| serde_json::json!({
            "normal": g.n, "gpu_estimate": gpu, "cpu_estimate": d.estimate,
            "red": d.samples.iter().filter(|s| s.kind == SampleKind::Discarded).count(),
            "green": d.samples.iter().filter(|s| s.kind == SampleKind::Used).count(),
            "yellow": d.samples.iter().filter(|s| s.kind == SampleKind::Wasted).count(),
            "blue": d.samples.iter().filter(|s| s.kind == SampleKind::Blocked).count(),
        })),
    })
}
