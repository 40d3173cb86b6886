//! Ready to light ([`EnvisLightReady`]): an app that starts as a game does (pipelines compiled
//! asynchronously, frames going on meanwhile, its map loaded by the `AssetServer`) with one
//! camera sampling and one resampling, while other tasks hold every thread of Bevy's async
//! compute pool until envis's programs are compiled (Bevy's render thread itself waits for that
//! pool at a new view: so envis's compiling owes nothing to the pool nor to frames). Checked on
//! every frame's capture: never an all-black frame once Bevy draws, never envis's background
//! over a sphere it has not lit, the marker on both cameras, lit on every frame after it, and
//! through a switch to another map.

use super::gpu;
use super::support::TempDir;
use bevy::camera::RenderTarget;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::prelude::*;
use bevy::tasks::AsyncComputeTaskPool;
use bevy_envis::ReadyReport;
use bevy_envis::prelude::*;
use envis::envmap::luminance;
use envis_cli::headless::{Captures, HeadlessApp};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

const SIZE: u32 = 24;
/// The cameras' clear colour: what Bevy shows where envis draws no background yet.
const CLEAR: Vec3 = Vec3::new(0.05, 0.1, 0.2);
/// The radiance of the map switched to (a uniform white map).
const WHITE: f32 = 1.0;
/// Wall-clock limit of each phase (compiling on 2 cores takes tens of seconds).
const PHASE_LIMIT: Duration = Duration::from_secs(240);

/// What one captured frame shows.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Shown {
    /// Nothing at all (Bevy has not drawn yet).
    Black,
    /// Bevy's own image: the clear colour around the sphere.
    Bevy,
    /// envis's: the map around a sphere it lit (mean radiance of the sphere's centre, and the
    /// background's).
    Lit(f32, f32),
    /// envis's background over a sphere it did not light: the defect.
    Unlit,
}

fn classify(img: &[Vec3]) -> Shown {
    let n = SIZE as usize;
    if img.iter().all(|c| c.max_element() < 1e-4) {
        return Shown::Black;
    }
    let corner = img[0];
    // The sphere covers the middle of the frame: the mean of its 4 x 4 centre.
    let centre = (n / 2 - 2..n / 2 + 2)
        .flat_map(|y| (n / 2 - 2..n / 2 + 2).map(move |x| img[y * n + x]))
        .map(luminance)
        .sum::<f32>()
        / 16.0;
    if (corner - CLEAR).abs().max_element() < 0.01 {
        Shown::Bevy
    } else if centre > 0.02 {
        Shown::Lit(centre, luminance(corner))
    } else {
        Shown::Unlit
    }
}

/// A white uniform lat-long EXR at `path`.
fn write_white_exr(path: &std::path::Path) {
    let img = envis::envmap::Image {
        width: 16,
        height: 8,
        data: vec![Vec3::splat(WHITE); 128],
    };
    envis::render::output::write_exr(path, &img).unwrap();
}

/// Spawn the sphere and the two cameras (the second resampling), each into its own target.
fn spawn_scene(h: &mut HeadlessApp, map: Handle<Image>) -> [(Entity, Handle<Image>); 2] {
    let mesh = h.add::<Mesh>(Sphere::new(1.0).mesh().ico(4).unwrap());
    let material = h.add::<StandardMaterial>(StandardMaterial {
        base_color: Color::WHITE,
        perceptual_roughness: 1.0,
        ..default()
    });
    h.app
        .world_mut()
        .spawn((Mesh3d(mesh), MeshMaterial3d(material)));
    [false, true].map(|resampling| {
        let target = h.float_target(SIZE, SIZE);
        let mut camera = h.app.world_mut().spawn((
            Camera3d::default(),
            Camera {
                clear_color: ClearColorConfig::Custom(Color::linear_rgb(CLEAR.x, CLEAR.y, CLEAR.z)),
                ..default()
            },
            RenderTarget::from(target.clone()),
            Transform::from_xyz(0.0, 0.0, 3.0).looking_at(Vec3::ZERO, Vec3::Y),
            Tonemapping::None,
            exposure_multiplier(1.0),
            EnvironmentSampling {
                light_samples: 8,
                brdf_samples: 8,
                ..default()
            },
            EnvisEnvironment::new(map.clone()),
        ));
        if resampling {
            camera.insert(EnvironmentResampling::default());
        }
        (camera.id(), target)
    })
}

/// Hold every thread of Bevy's async compute pool until envis's compile thread reports all its
/// programs compiled, or [`PHASE_LIMIT`]; `released_by_envis` says which it was.
fn hold_async_pool(report: &ReadyReport, released_by_envis: &Arc<AtomicBool>) {
    let pool = AsyncComputeTaskPool::get();
    for _ in 0..pool.thread_num().max(1) {
        let (log, flag) = (report.programs().clone(), released_by_envis.clone());
        pool.spawn(async move {
            let start = Instant::now();
            while !log.all_done() && start.elapsed() < PHASE_LIMIT {
                std::thread::sleep(Duration::from_millis(5));
            }
            flag.store(log.all_done(), Ordering::Release);
        })
        .detach();
    }
}

/// The frames one camera showed, by frame, and the first frame drawn after its marker was seen.
struct Seen {
    shown: Vec<(u32, Shown)>,
    ready_from: Option<u32>,
}

#[test]
fn bevy_first_light_as_a_game() {
    let Some(_) = gpu() else { return };
    let dir = TempDir::new("ready");
    let park = crate::support::repo().join("assets/hdri/park.exr");
    std::fs::copy(park, dir.join("park.exr")).unwrap();
    write_white_exr(&dir.join("white.exr"));
    let mut h = HeadlessApp::as_a_game(&dir);
    let released_by_envis = Arc::new(AtomicBool::new(false));
    hold_async_pool(h.app.world().resource::<ReadyReport>(), &released_by_envis);
    let server = h.app.world().resource::<AssetServer>().clone();
    let cams = spawn_scene(&mut h, server.load("park.exr"));
    let shots = [Captures::default(), Captures::default()];
    let mut seen = [0, 1].map(|_| Seen {
        shown: vec![],
        ready_from: None,
    });
    let (start, mut frame) = (Instant::now(), 0u32);
    let mut switched_at = None;
    let run = |h: &mut HeadlessApp, frame: &mut u32, seen: &mut [Seen; 2]| {
        for (i, (_, target)) in cams.iter().enumerate() {
            h.request_capture(target, *frame, &shots[i]);
        }
        h.update();
        *frame += 1;
        for (i, (cam, _)) in cams.iter().enumerate() {
            if seen[i].ready_from.is_none() && h.app.world().get::<EnvisLightReady>(*cam).is_some()
            {
                seen[i].ready_from = Some(*frame);
            }
            for (tag, img) in shots[i].take_all() {
                seen[i].shown.push((tag, classify(&img.unwrap())));
            }
        }
    };
    // Until both cameras are ready (the pool released itself once envis's programs compiled).
    while seen.iter().any(|s| s.ready_from.is_none()) && start.elapsed() < 2 * PHASE_LIMIT {
        run(&mut h, &mut frame, &mut seen);
    }
    assert!(
        released_by_envis.load(Ordering::Acquire),
        "envis's programs were not compiled while the async compute pool was held"
    );
    // Lit a few frames, then switched to the white map: lit on every frame until it shows.
    for _ in 0..4 {
        run(&mut h, &mut frame, &mut seen);
    }
    let white = server.load("white.exr");
    for (cam, _) in &cams {
        h.app
            .world_mut()
            .get_mut::<EnvisEnvironment>(*cam)
            .unwrap()
            .image = white.clone();
    }
    switched_at.get_or_insert(frame);
    let switched = Instant::now();
    let showing_white = |s: &Seen| matches!(s.shown.last(), Some((_, Shown::Lit(_, bg))) if (bg - WHITE).abs() < 0.05 * WHITE);
    while !seen.iter().all(showing_white) && switched.elapsed() < PHASE_LIMIT {
        run(&mut h, &mut frame, &mut seen);
    }
    for _ in 0..3 {
        run(&mut h, &mut frame, &mut seen);
    }
    for (i, s) in seen.iter().enumerate() {
        check_camera(i, s, showing_white(s));
    }
    // The marker goes when the camera stops sampling.
    h.app
        .world_mut()
        .entity_mut(cams[0].0)
        .remove::<EnvironmentSampling>();
    for _ in 0..3 {
        run(&mut h, &mut frame, &mut seen);
    }
    assert!(h.app.world().get::<EnvisLightReady>(cams[0].0).is_none());
    assert!(h.app.world().get::<EnvisLightReady>(cams[1].0).is_some());
    eprintln!(
        "first light as a game: ready at frames {:?} after {:.1}s, map switched at frame {:?}",
        seen.each_ref().map(|s| s.ready_from),
        start.elapsed().as_secs_f64(),
        switched_at
    );
}

/// Camera `i`'s frames: never black once Bevy drew, never the defect, lit from its marker on.
fn check_camera(i: usize, s: &Seen, shows_new_map: bool) {
    let ready = s
        .ready_from
        .unwrap_or_else(|| panic!("camera {i}: never ready"));
    let mut sorted = s.shown.clone();
    sorted.sort_by_key(|f| f.0);
    let first_drawn = sorted.iter().position(|(_, f)| *f != Shown::Black);
    let first_drawn = first_drawn.unwrap_or_else(|| panic!("camera {i}: nothing drawn"));
    for (tag, shown) in &sorted[first_drawn..] {
        assert_ne!(*shown, Shown::Black, "camera {i}: frame {tag} is all black");
        assert_ne!(
            *shown,
            Shown::Unlit,
            "camera {i}: frame {tag}: background, unlit sphere"
        );
        if *tag >= ready {
            assert!(
                matches!(shown, Shown::Lit(..)),
                "camera {i}: frame {tag}, after the marker (frame {ready}), shows {shown:?}"
            );
        }
    }
    assert!(
        sorted.iter().any(|(t, _)| *t >= ready + 4),
        "camera {i}: too few frames captured after the marker"
    );
    assert!(
        shows_new_map,
        "camera {i}: the white map never showed: {:?}",
        sorted.last()
    );
}
