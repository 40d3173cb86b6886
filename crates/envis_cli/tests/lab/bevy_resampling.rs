//! `EnvironmentResampling` in a Bevy app (the resampling pass: gather + the WGSL passes the
//! headless twin runs, `envis_cli/tests/lab/gpu_resampling.rs`): its image is the plain estimator's in
//! expectation, its frames draw new samples, its history is found through the motion vectors
//! on a still and on a moving camera (read through the history overlay), and removing it gives
//! the plain estimator back.

use super::bevy_app::on_sphere;
use super::{gpu, rel};
use bevy::prelude::*;
use bevy_envis::prelude::*;
use envis::envmap::luminance;
use envis_cli::headless::{HeadlessApp, radiance_camera, sphere_view};

const SIZE: u32 = 40;

/// A glossy StandardMaterial sphere under a sky with a bright patch, seen by the headless
/// sphere view with `sampling` (and resampling where given).
fn sphere_app(
    sampling: EnvironmentSampling,
    resampling: Option<EnvironmentResampling>,
) -> (HeadlessApp, Handle<Image>, Entity) {
    let (env, _) = super::bevy_plugin::latlong_image(16, |d| {
        let patch = d
            .dot(Vec3::new(0.5, 0.7, 0.5).normalize())
            .max(0.0)
            .powi(16);
        Vec3::new(0.3, 0.4, 0.6) * (0.5 + 0.5 * d.y.max(0.0)) + Vec3::splat(20.0 * patch)
    });
    sphere_app_lit(sampling, resampling, env)
}

/// [`sphere_app`] lit by the image `env`.
fn sphere_app_lit(
    sampling: EnvironmentSampling,
    resampling: Option<EnvironmentResampling>,
    env: Image,
) -> (HeadlessApp, Handle<Image>, Entity) {
    let mut h = HeadlessApp::new();
    let mesh = h.add::<Mesh>(Sphere::new(1.0).mesh().ico(6).expect("icosphere"));
    let mat = h.add::<StandardMaterial>(StandardMaterial {
        base_color: Color::linear_rgb(0.8, 0.7, 0.6),
        perceptual_roughness: 0.5,
        ..default()
    });
    h.app
        .world_mut()
        .spawn((Mesh3d(mesh), MeshMaterial3d(mat), Transform::IDENTITY));
    let env = h.add::<Image>(env);
    let target = h.float_target(SIZE, SIZE);
    let (projection, transform) = sphere_view();
    let mut cam = h.app.world_mut().spawn(radiance_camera(
        target.clone(),
        projection,
        transform,
        sampling,
        EnvisEnvironment::new(env),
    ));
    if let Some(r) = resampling {
        cam.insert(r);
    }
    let cam = cam.id();
    (h, target, cam)
}

fn candidates() -> EnvironmentSampling {
    EnvironmentSampling {
        light_samples: 4,
        brdf_samples: 4,
        ..default()
    }
}

/// Mean luminance over the sphere's inside pixels in its upper and its lower half.
fn half_means(img: &[Vec3]) -> [f64; 2] {
    let inside = on_sphere(SIZE);
    let half = |upper: bool| {
        let idx: Vec<usize> = (0..img.len())
            .filter(|&i| inside(i) && ((i as u32 / SIZE) < SIZE / 2) == upper)
            .collect();
        idx.iter().map(|&i| luminance(img[i]) as f64).sum::<f64>() / idx.len() as f64
    };
    [half(true), half(false)]
}

/// Mean luminance over the sphere's inside pixels.
fn sphere_mean(img: &[Vec3]) -> f64 {
    let inside = on_sphere(SIZE);
    let idx: Vec<usize> = (0..img.len()).filter(|&i| inside(i)).collect();
    idx.iter().map(|&i| luminance(img[i]) as f64).sum::<f64>() / idx.len() as f64
}

/// `t` of the overlays' `heat(t)` ramp (bevy_envis::heat), read back from a colour.
fn unheat(c: Vec3) -> f32 {
    let x = if c.z >= 1.0 {
        c.y
    } else if c.x <= 0.0 {
        2.0 - c.z
    } else if c.y >= 1.0 {
        2.0 + c.x
    } else {
        4.0 - c.y
    };
    x / 4.0
}

/// The mean confidence M near the sphere's centre (inside whichever way the camera sways),
/// read through the history overlay.
fn mean_history(h: &mut HeadlessApp, target: &Handle<Image>, cam: Entity) -> f64 {
    let world = h.app.world_mut();
    world.get_mut::<EnvironmentSampling>(cam).unwrap().overlay = Overlay::History;
    let img = h.capture_next(target).unwrap();
    let m: Vec<f64> = (0..img.len())
        .filter(|&i| {
            let (x, y) = ((i as u32 % SIZE) as f32, (i as u32 / SIZE) as f32);
            let (u, v) = (2.0 * x / SIZE as f32 - 1.0, 2.0 * y / SIZE as f32 - 1.0);
            u * u + v * v < 0.25
        })
        .map(|i| unheat(img[i]) as f64 * envis_wgpu::resampling::HISTORY_FULL_SCALE as f64)
        .collect();
    m.iter().sum::<f64>() / m.len() as f64
}

/// Every frame, the resampling camera moves half the view's half-width sideways, back and
/// forth (10 pixels a frame at 40²): each frame's history is elsewhere on screen, far enough
/// that the same pixel of the previous frame fails the normal test.
fn sway(mut cams: Query<&mut Transform, With<EnvironmentResampling>>, mut frame: Local<u32>) {
    *frame += 1;
    let dx = if frame.is_multiple_of(2) { 0.5 } else { -0.5 };
    for mut t in &mut cams {
        t.translation.x += dx;
    }
}

/// Resampled 4 + 4 candidates give the 32 + 32 estimator's mean (unbiased, and biased within
/// its measured bias), successive frames differ (new samples each frame), and the history is
/// reused: M grows past what one frame's spatial reuse gives.
#[test]
fn bevy_resampling_matches_the_plain_estimator() {
    let Some(_) = gpu() else { return };
    let reference = {
        let s = EnvironmentSampling {
            light_samples: 32,
            brdf_samples: 32,
            ..default()
        };
        let (mut h, target, _) = sphere_app(s, None);
        sphere_mean(&h.capture(&target).unwrap())
    };
    for unbiased in [true, false] {
        let r = EnvironmentResampling {
            unbiased,
            ..default()
        };
        let (mut h, target, cam) = sphere_app(candidates(), Some(r));
        // A few frames of history past the first lit one, as a game's first seconds are: the
        // biased mode's first frames are darker (its 1/M weights over a short history).
        h.until_lit();
        for _ in 0..3 {
            h.update();
        }
        let a = h.capture(&target).unwrap();
        let b = h.capture_next(&target).unwrap();
        let (ma, mb) = (sphere_mean(&a), sphere_mean(&b));
        eprintln!("unbiased {unbiased}: means {ma:.4}, {mb:.4}, reference {reference:.4}");
        let tol = if unbiased { 0.03 } else { 0.08 };
        for m in [ma, mb] {
            assert!(rel(m, reference) < tol, "mean {m} vs {reference}");
        }
        let differ = a.iter().zip(&b).filter(|(x, y)| x != y).count();
        assert!(differ > a.len() / 4, "frames alike: {differ} pixels differ");
        let c = h.counters();
        let (passes, histories) = (
            c.get(|c| &c.resampling_passes),
            c.get(|c| &c.resampling_histories),
        );
        assert!(
            histories + 1 >= passes && passes > 3,
            "{passes} passes, {histories} with history"
        );
        let m = mean_history(&mut h, &target, cam);
        eprintln!("unbiased {unbiased}: mean M {m:.2}");
        // One frame with 3 neighbours: M <= 1 + 3 * 0.25 = 1.75.
        assert!(m > 4.0, "mean history M {m}: the history is not reused");
    }
}

/// A camera moving every frame (`sway`) still finds its history through the motion vectors
/// (with the motion vectors' sign flipped in the gather, M stayed near one frame's); a reset
/// clears it.
#[test]
fn bevy_resampling_follows_a_moving_camera() {
    let Some(_) = gpu() else { return };
    let (mut h, target, cam) = sphere_app(candidates(), Some(EnvironmentResampling::default()));
    h.app.add_systems(Update, sway);
    h.capture(&target).unwrap();
    for _ in 0..6 {
        h.update();
    }
    let moving = mean_history(&mut h, &target, cam);
    let world = h.app.world_mut();
    world.get_mut::<EnvironmentResampling>(cam).unwrap().reset = true;
    let reset = mean_history(&mut h, &target, cam);
    eprintln!("moving camera: mean M {moving:.2}, after a reset {reset:.2}");
    assert!(moving > 4.0, "moving camera: mean M {moving}");
    // After a reset, M is at most one frame's: its own candidates and `spatial` neighbours',
    // each capped at SPATIAL_CONFIDENCE of its own (1.75 here), plus the overlay's rounding.
    let spatial = EnvironmentResampling::default().spatial as f64;
    let one_frame = 1.0 + spatial * envis::render::resampling::SPATIAL_CONFIDENCE as f64;
    assert!(
        reset < one_frame + 0.1,
        "a reset kept the history: M {reset} vs {moving}"
    );
    assert!(
        !h.app
            .world()
            .get::<EnvironmentResampling>(cam)
            .unwrap()
            .reset,
        "reset is cleared after its frame"
    );
}

/// Removing `EnvironmentResampling` gives the plain estimator's image back, pixel for pixel.
#[test]
fn bevy_resampling_removed_gives_the_plain_image() {
    let Some(_) = gpu() else { return };
    let (mut plain, plain_target, _) = sphere_app(candidates(), None);
    let want = plain.capture(&plain_target).unwrap();
    let (mut h, target, cam) = sphere_app(candidates(), Some(EnvironmentResampling::default()));
    h.capture(&target).unwrap();
    assert_eq!(h.counters().get(|c| &c.resampling_views), 1);
    h.app
        .world_mut()
        .entity_mut(cam)
        .remove::<EnvironmentResampling>();
    // The frame already extracted (pipelined rendering) still resamples.
    h.update();
    let before = h.counters().get(|c| &c.resampling_passes);
    let got = h.capture(&target).unwrap();
    assert_eq!(h.counters().get(|c| &c.resampling_passes), before);
    let kept = h.counters().get(|c| &c.resampling_views);
    assert_eq!(kept, 0, "the removed camera's resampling buffers were kept");
    let worst = got
        .iter()
        .zip(&want)
        .map(|(a, b)| (*a - *b).abs().max_element())
        .fold(0.0f32, f32::max);
    assert!(
        worst <= 1e-5,
        "without resampling the image differs by {worst}"
    );
}

/// A camera lit by a user's image (not the envis stream) resamples the map's bright part apart
/// where the image keeps its texels in the main world (`RenderAssetUsages::default()`, what
/// Bevy's loaders give; read on the async compute pool, so most frames, not all):
/// `resampling_bright` counts its frames, and the means of the sphere's
/// upper and lower halves are the plain estimator's (the split's tables are the radiance the
/// passes read: a map read upside down lights the other half). Without main-world texels the
/// map is resampled whole, and the means are right too.
#[test]
fn bevy_resampling_splits_a_user_image() {
    let Some(_) = gpu() else { return };
    let sun = Vec3::new(0.4, 0.8, 0.45).normalize();
    let sky = |usage| {
        let (mut img, _) = super::bevy_plugin::latlong_image(32, |d| {
            let disc = if d.dot(sun) > 0.995 { 2000.0 } else { 0.0 };
            Vec3::new(0.3, 0.4, 0.6) * (0.5 + 0.5 * d.y.max(0.0)) + Vec3::splat(disc)
        });
        img.asset_usage = usage;
        img
    };
    let all = bevy::asset::RenderAssetUsages::default();
    let reference = {
        let s = EnvironmentSampling {
            light_samples: 32,
            brdf_samples: 32,
            ..default()
        };
        let (mut h, target, _) = sphere_app_lit(s, None, sky(all));
        half_means(&h.capture(&target).unwrap())
    };
    let gpu_only = bevy::asset::RenderAssetUsages::RENDER_WORLD;
    for (usage, split) in [(all, true), (gpu_only, false)] {
        let r = Some(EnvironmentResampling::default());
        let (mut h, target, cam) = sphere_app_lit(candidates(), r, sky(usage));
        let a = half_means(&h.capture(&target).unwrap());
        let b = half_means(&h.capture_next(&target).unwrap());
        let c = h.counters();
        let (passes, bright) = (
            c.get(|c| &c.resampling_passes),
            c.get(|c| &c.resampling_bright),
        );
        eprintln!(
            "split {split}: halves {a:.4?}, {b:.4?}, reference {reference:.4?}; {bright} of {passes} frames split"
        );
        for (m, r) in a.into_iter().chain(b).zip(reference.into_iter().cycle()) {
            assert!(rel(m, r) < 0.05, "split {split}: half mean {m} vs {r}");
        }
        match split {
            // The map is read on the async compute pool: the first frames may be whole.
            true => assert!(2 * bright > passes && passes > 3, "{bright} of {passes}"),
            false => assert_eq!(bright, 0),
        }
        if split {
            // A face size the map was not read for is made from its texels on the async pool
            // (never on the render thread): the frames split again once it is.
            let world = h.app.world_mut();
            let mut sampling = world.get_mut::<EnvironmentSampling>(cam).unwrap();
            sampling.face_size /= 2;
            let split_frames = |h: &HeadlessApp| h.counters().get(|c| &c.resampling_bright);
            // Bounded, and left as soon as it splits: under a loaded machine (the suite's other
            // tests on 2 cores) the pool's read can take more than the 10 frames once waited.
            let resumed = (0..120).any(|_| {
                h.update();
                split_frames(&h) > bright + 1
            });
            assert!(resumed, "no split at the new face size");
        }
    }
}

/// A new version of a user's image (a carousel step made by editing the asset): its texels are
/// read on the async pool, the frames meanwhile are lit by the whole map, the first of them
/// dropping the history (a change the CPU cannot measure yet: kept, a hand mutation, M 19
/// where it is 1.0), and when the split returns the history made under the whole map is
/// dropped too (another rest). That second drop shows here only when the read takes frames
/// (before the first drop existed: 2.1 against 20 kept, a hand mutation).
#[test]
fn bevy_resampling_drops_the_history_of_a_replaced_image() {
    let Some(_) = gpu() else { return };
    let first = Vec3::new(0.4, 0.8, 0.45).normalize();
    let r = Some(EnvironmentResampling::default());
    let (mut h, target, cam) = sphere_app_lit(candidates(), r, sun_sky(first));
    h.capture(&target).unwrap();
    for _ in 0..8 {
        h.update();
    }
    let before = mean_history(&mut h, &target, cam);
    let image = (h.app.world().get::<EnvisEnvironment>(cam).unwrap().image).clone();
    let start = whole_and_split(&h);
    let second = Vec3::new(-0.6, 0.5, -0.3).normalize();
    let mut images = h.app.world_mut().resource_mut::<Assets<Image>>();
    *images.get_mut(&image).unwrap() = sun_sky(second);
    // The frame after the edit: whole (its texels are being read), or already split again.
    let changed = mean_history(&mut h, &target, cam);
    let mut split = false;
    for _ in 0..20 {
        let now = whole_and_split(&h);
        split = now.0 > start.0 && now.1 > start.1;
        if split {
            break;
        }
        h.update();
    }
    assert!(
        split,
        "no whole frame, then a split one: {start:?} {:?}",
        whole_and_split(&h)
    );
    let after = mean_history(&mut h, &target, cam);
    eprintln!(
        "mean M before the new image {before:.2}, after it {changed:.2}, after its split {after:.2}"
    );
    // Dropped: the frame's own and the spatial neighbours' quarter shares, and a frame or two
    // of history. Half of `before` leaves room for the counters to be read a frame late (a
    // frame adds about one).
    assert!(before > 8.0, "mean history M {before}");
    for m in [changed, after] {
        assert!(m < before / 2.0, "mean history M {m}: the history was kept");
    }
}

/// A sky with a sun disc in direction `sun`, its texels kept in the main world (as Bevy's
/// loaders keep them: the resampling pass splits its bright part).
fn sun_sky(sun: Vec3) -> Image {
    let (mut img, _) = super::bevy_plugin::latlong_image(32, |d| {
        let disc = if d.dot(sun) > 0.995 { 2000.0 } else { 0.0 };
        Vec3::new(0.3, 0.4, 0.6) * (0.5 + 0.5 * d.y.max(0.0)) + Vec3::splat(disc)
    });
    img.asset_usage = bevy::asset::RenderAssetUsages::default();
    img
}

/// The frames resampled whole and those split so far (bumped by the same pass, read together).
fn whole_and_split(h: &HeadlessApp) -> (u64, u64) {
    let c = h.counters();
    let (all, split) = (
        c.get(|c| &c.resampling_passes),
        c.get(|c| &c.resampling_bright),
    );
    (all - split, split)
}
