//! Every example of `bevy_envis` (`crates/bevy_envis/examples/`) runs headless here: its own scene-building function on a
//! windowless app (`HeadlessApp`: `DefaultPlugins` without a window + `EnvisPlugin`), its cameras
//! pointed at a float image, and checks that envis lit what the example promises.

use super::gpu;
use bevy::camera::RenderTarget;
use bevy::prelude::*;
use bevy_envis::EnvisCounters;
use envis::envmap::luminance;
use envis_cli::headless::HeadlessApp;

#[path = "../../../bevy_envis/examples/custom_material.rs"]
#[allow(dead_code)]
mod custom_material;
#[path = "../../../bevy_envis/examples/dynamic_sky.rs"]
#[allow(dead_code)]
mod dynamic_sky;
#[path = "../../../bevy_envis/examples/gltf_scene.rs"]
#[allow(dead_code)]
mod gltf_scene;
#[path = "../../../bevy_envis/examples/split_screen.rs"]
#[allow(dead_code)]
mod split_screen;

const W: u32 = 192;
const H: u32 = 128;

/// Run `example` headless until every envis camera has been lit (assets load asynchronously),
/// then capture its frame. Returns the image, the counters and the app.
fn run(name: &str, example: fn(&mut App), cameras: u64) -> (Vec<Vec3>, EnvisCounters, HeadlessApp) {
    let mut h = HeadlessApp::new();
    example(&mut h.app);
    let target = h.float_target(W, H);
    h.update(); // Startup: the example spawns its cameras
    let world = h.app.world_mut();
    let cams: Vec<Entity> = world
        .query_filtered::<Entity, With<Camera3d>>()
        .iter(world)
        .collect();
    for e in cams {
        world
            .entity_mut(e)
            .insert(RenderTarget::from(target.clone()));
    }
    for _ in 0..300 {
        h.update();
        let c = h.counters();
        if c.get(|c| &c.builds) >= 1 && c.get(|c| &c.lighting_passes) >= 4 * cameras {
            break;
        }
    }
    let img = h.capture(&target).unwrap();
    if let Ok(dir) = std::env::var("ENVIS_TEST_DUMP") {
        let im = envis::envmap::Image {
            width: W as usize,
            height: H as usize,
            data: img.clone(),
        };
        let path = std::path::Path::new(&dir).join(format!("example-{name}.png"));
        envis::render::output::write_png(&path, &im, 1.0).unwrap();
    }
    let c = h.counters();
    assert!(
        c.get(|c| &c.lighting_passes) >= 4 * cameras,
        "the example's cameras were never lit by envis: {:?}",
        c.0
    );
    // The examples tonemap (TonyMcMapface): its LUT may round a channel a hair below 0.
    let bad: Vec<(usize, Vec3)> = img
        .iter()
        .copied()
        .enumerate()
        .filter(|(_, p)| !(p.is_finite() && p.min_element() >= -1e-5))
        .collect();
    assert!(
        bad.is_empty(),
        "{} non-finite or negative pixels, first {:?}",
        bad.len(),
        &bad[..bad.len().min(4)]
    );
    (img, c, h)
}

/// Share of pixels brighter than `t` in columns `cols`.
fn lit_share(img: &[Vec3], cols: std::ops::Range<u32>, t: f32) -> f64 {
    let px: Vec<f32> = (0..H)
        .flat_map(|y| cols.clone().map(move |x| (y * W + x) as usize))
        .map(|i| luminance(img[i]))
        .collect();
    px.iter().filter(|&&l| l > t).count() as f64 / px.len() as f64
}

#[test]
fn example_gltf_scene() {
    let Some(_) = gpu() else { return };
    let (img, c, _) = run("gltf_scene", gltf_scene::example, 1);
    assert_eq!(
        c.get(|c| &c.builds),
        1,
        "a static map is built once: {:?}",
        c.0
    );
    assert!(lit_share(&img, 0..W, 0.02) > 0.9, "the scene is dark");
}

#[test]
fn example_custom_material() {
    let Some(_) = gpu() else { return };
    let (img, c, _) = run("custom_material", custom_material::example, 1);
    assert!(c.get(|c| &c.builds) >= 1, "{:?}", c.0);
    assert!(lit_share(&img, 0..W, 0.02) > 0.9, "the scene is dark");
}

/// The compute-shader sky: one build per frame, nothing uploaded from the CPU, and the sky the
/// shader painted is what the background shows.
#[test]
fn example_dynamic_sky() {
    let Some(_) = gpu() else { return };
    let (img, c, mut h) = run("dynamic_sky", dynamic_sky::example, 1);
    assert_eq!(c.get(|c| &c.image_bytes_uploaded), 0, "{:?}", c.0);
    // One build per frame: builds keep pace with lighting passes (both counted in the render
    // world, which runs a frame behind the main world: read together, they may differ by one).
    let (b0, l0) = (c.get(|c| &c.builds), c.get(|c| &c.lighting_passes));
    for _ in 0..10 {
        h.update();
    }
    let c = h.counters();
    let (db, dl) = (
        c.get(|c| &c.builds) - b0,
        c.get(|c| &c.lighting_passes) - l0,
    );
    assert!(
        db >= 9 && db.abs_diff(dl) <= 1,
        "{db} builds for {dl} lighting passes"
    );
    // The top row is sky (blue over red), the objects are lit.
    let top = img[(W / 2) as usize];
    assert!(top.z > top.x && top.z > 0.2, "sky pixel {top}");
    assert!(lit_share(&img, 0..W, 0.05) > 0.9, "the scene is dark");
}

/// Two cameras, two strategies, one target: both halves are lit.
#[test]
fn example_split_screen() {
    let Some(_) = gpu() else { return };
    let (img, c, _) = run("split_screen", split_screen::example, 2);
    assert!(c.get(|c| &c.live_distributions) >= 1, "{:?}", c.0);
    for half in [0..W / 2, W / 2..W] {
        assert!(
            lit_share(&img, half.clone(), 0.02) > 0.9,
            "half {half:?} is dark"
        );
    }
}
