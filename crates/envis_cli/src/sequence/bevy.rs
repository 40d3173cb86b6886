//! A sequence through the Bevy pipeline (`envis sequence --backend gpu`): the scene file's
//! objects and camera in a headless Bevy app ([`HeadlessSphere::from_scene`]), posed on the
//! sequence clock before each update, so Bevy's motion vectors, G-buffer and the
//! `EnvironmentResampling` pass see the motion as a game's frames would. One update is one
//! frame; each frame's capture is asked for before its update and arrives a frame or two later
//! (the readback is asynchronous), and frames are handed on in order.
//!
//! With resampling, each frame's counts (shadow rays, samples, reuse) are read back too
//! ([`ResamplingReadback`], tagged with the frame). What this backend does not report: counts
//! without resampling (the plain lighting pass keeps none), and exact per-frame times:
//! `build_ms` and `shade_ms` are the GPU timestamps of the latest frame measured when the
//! capture arrived (`PassTimes`, which arrive late too).

use super::{FrameStats, SequenceFrame, SequenceOptions};
use crate::headless::{CAPTURE_FRAMES, Captures, HeadlessSphere, no_capture};
use bevy::prelude::*;
use bevy_envis::resampling::{FrameCounts, ResamplingReadback};
use bevy_envis::scene_objects::{SceneIndex, object_transform, scene_camera};
use bevy_envis::{EnvMapStream, EnvironmentResampling, EnvisTimings};
use envis::envmap::Image;
use envis::error::Result;
use envis::render::resampling::{Resampling, ReuseStats};
use envis::scene::Scene;
use envis::stream::EnvStream;
use envis::visibility::ShadowRays;

/// [`super::run`] in a headless Bevy app.
pub(super) fn run(
    scene: &Scene,
    o: &SequenceOptions,
    mut each: impl FnMut(SequenceFrame) -> Result<()>,
) -> Result<()> {
    envis_wgpu::context::check_adapter()?;
    let mut settings = o.settings;
    settings.shadows = match scene.shadows(o.visibility).0 {
        true => ShadowRays::On,
        false => ShadowRays::Off,
    };
    let mut app = HeadlessSphere::from_scene(scene, settings, o.size as u32)?;
    // Set-up frames (meshes, materials, pipelines, the prepasses resampling requires) at
    // time 0; a resampling camera then starts its history afresh at frame 0 (`reset`).
    let cam = app.camera();
    if let Some(r) = o.resampling {
        app.app
            .app
            .world_mut()
            .entity_mut(cam)
            .insert(component(&r));
    }
    app.capture()?;
    // The counts from frame 0 on (none of the set-up frames').
    let readback = o.resampling.map(|_| ResamplingReadback::default());
    if let Some(rb) = &readback {
        let mut cam = app.app.app.world_mut().entity_mut(cam);
        cam.insert(rb.clone());
        if let Some(mut r) = cam.get_mut::<EnvironmentResampling>() {
            r.reset = true;
        }
    }
    let captures = Captures::default();
    let mut env = scene.environment.clone();
    let mut next = 0;
    for k in 0..o.frames {
        pose(&mut app, scene, scene.frame_time(k), &mut env)?;
        if let Some(mut rb) = app.app.app.world_mut().get_mut::<ResamplingReadback>(cam) {
            rb.tag = k;
        }
        app.request_capture(k, &captures);
        app.update();
        // Only what arrived: an update here would draw a frame the sequence did not pose.
        while let Some(f) = arrived(&app, (&captures, readback.as_ref()), next, scene, o) {
            each(f?)?;
            next += 1;
        }
    }
    // The last frames' captures: the updates now only flush the readback.
    for waited in 0..=CAPTURE_FRAMES {
        while let Some(f) = arrived(&app, (&captures, readback.as_ref()), next, scene, o) {
            each(f?)?;
            next += 1;
        }
        if next == o.frames {
            return Ok(());
        }
        if waited < CAPTURE_FRAMES {
            app.update();
        }
    }
    Err(no_capture())
}

/// `r` as the camera component.
fn component(r: &Resampling) -> EnvironmentResampling {
    EnvironmentResampling {
        temporal: r.temporal,
        spatial: r.spatial,
        max_history: r.max_history,
        unbiased: r.unbiased,
        reset: false,
    }
}

/// Pose the app at time `t`: the camera, every object, and the map where the scene's
/// environment at `t` differs from `env` (the last one loaded).
fn pose(app: &mut HeadlessSphere, scene: &Scene, t: f32, env: &mut String) -> Result<()> {
    let posed = scene.at_time(t)?;
    let cam = app.camera();
    let world = app.app.app.world_mut();
    // Written only where they change: a transform written unchanged still marks the shadow
    // geometry moved (a new placement), and the resampling pass then casts the rays a still
    // scene's history does without.
    let camera = scene_camera(&posed).transform();
    (world.get_mut::<Transform>(cam).expect("camera")).set_if_neq(camera);
    let mut objects = world.query::<(&SceneIndex, &mut Transform)>();
    for (i, mut tr) in objects.iter_mut(world) {
        if let Some(o) = posed.objects.get(i.0) {
            tr.set_if_neq(object_transform(&o.shape));
        }
    }
    if posed.environment != *env {
        let face = posed.file.environment.face_size;
        let mut stream = EnvStream::open(posed.stream_source(0.0)?, face)?;
        stream.playing = false;
        world.resource_mut::<EnvMapStream>().stream = stream;
        *env = posed.environment.clone();
    }
    Ok(())
}

/// Frame `k`, where its capture (and with resampling its counts) arrived.
fn arrived(
    app: &HeadlessSphere,
    (captures, readback): (&Captures, Option<&ResamplingReadback>),
    k: u32,
    scene: &Scene,
    o: &SequenceOptions,
) -> Option<Result<SequenceFrame>> {
    if !captures.has(k) {
        return None;
    }
    let counts = match readback {
        Some(r) => Some(r.sink.take(k)?),
        None => None,
    };
    let px = captures.take(k)?;
    Some(px.map(|data| SequenceFrame {
        image: Image {
            width: o.size,
            height: o.size,
            data,
        },
        stats: stats(app, k, scene.frame_time(k), counts),
    }))
}

/// Frame `k`'s statistics: the latest GPU pass times, and its counts where they were read back.
fn stats(app: &HeadlessSphere, k: u32, time: f32, counts: Option<FrameCounts>) -> FrameStats {
    let t = app.app.app.world().resource::<EnvisTimings>().get();
    // NaN (null in the JSON) where the device has no timestamp queries: not measured.
    let sum = |v: &[Option<f64>]| match v.iter().flatten().sum::<f64>() {
        _ if v.iter().all(Option::is_none) => f64::NAN,
        ms => ms,
    };
    FrameStats {
        frame: k,
        time,
        build_ms: sum(&[t.resample_gpu_ms, t.build_gpu_ms, t.pool_gpu_ms]),
        shade_ms: sum(&[t.lighting_gpu_ms, t.resampling_gpu_ms]),
        shadow_rays: counts.map(|c| c.shadow_rays),
        shadow_rays_per_pixel: counts.map(|c| c.shadow_rays as f64 / c.shaded_pixels.max(1) as f64),
        samples_evaluated: counts.map(|c| c.samples_evaluated),
        shaded_pixels: counts.map(|c| c.shaded_pixels),
        reuse: counts.map_or_else(ReuseStats::default, |c| ReuseStats {
            temporal_accepted: c.temporal_accepted,
            spatial_accepted: c.spatial_accepted,
            bright_temporal_accepted: c.bright_temporal_accepted,
            mean_history: c.mean_history,
        }),
    }
}
