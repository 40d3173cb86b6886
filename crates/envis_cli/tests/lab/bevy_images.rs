//! `Image` environments changed after they were lit by: modified on the CPU (rebuilt once) or
//! written on the GPU every frame (`EnvisEnvironment::dynamic`), through `bevy_envis::prelude`.

use super::bevy_plugin::{
    latlong_image, sphere_camera, sphere_mean, standard_sphere_app, white_furnace_material,
};
use super::{gpu, rel};
use bevy::asset::RenderAssetUsages;
use bevy::camera::{RenderTarget, visibility::RenderLayers};
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::prelude::*;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat, TextureUsages};
use bevy_envis::prelude::*;
use envis_cli::headless::{radiance_camera, sphere_view};

/// An `Image` asset modified on the CPU is rebuilt exactly once, and the lighting follows it.
#[test]
fn bevy_modified_image_rebuilds_once() {
    let Some(_) = gpu() else { return };
    let mut h = standard_sphere_app(white_furnace_material());
    let (env, _) = latlong_image(8, |_| Vec3::splat(0.5));
    let bytes = env.data.as_ref().map_or(0, |d| d.len()) as u64;
    let env = h.add::<Image>(env);
    let target = sphere_camera(&mut h, env.clone(), EnvironmentSampling::default(), 32);
    let before = sphere_mean(&h.capture(&target).unwrap(), 32);
    for _ in 0..5 {
        h.update();
    }
    let c = h.counters();
    assert_eq!(c.get(|c| &c.builds), 1, "a static image: {:?}", c.0);
    let (brighter, _) = latlong_image(8, |_| Vec3::splat(1.5));
    *h.app
        .world_mut()
        .resource_mut::<Assets<Image>>()
        .get_mut(&env)
        .unwrap() = brighter;
    for _ in 0..5 {
        h.update();
    }
    let after = sphere_mean(&h.capture(&target).unwrap(), 32);
    let c = h.counters();
    assert_eq!(
        c.get(|c| &c.builds),
        2,
        "one modification, one rebuild: {:?}",
        c.0
    );
    assert_eq!(c.get(|c| &c.image_bytes_uploaded), 2 * bytes);
    assert!(
        rel(before, 0.5) < 0.02 && rel(after, 1.5) < 0.02,
        "{before} -> {after}"
    );
}

/// The clear colour of the camera that renders the environment image (set per frame).
#[derive(Resource)]
struct SkyColor(f32);

fn paint_sky(color: Res<SkyColor>, mut cams: Query<&mut Camera, With<RenderLayers>>) {
    for mut c in &mut cams {
        c.clear_color = ClearColorConfig::Custom(Color::linear_rgb(color.0, color.0, color.0));
    }
}

/// An environment written on the GPU every frame (here: a camera rendering into it) with
/// `dynamic: true` is rebuilt every frame with no bytes uploaded from the CPU, and the lighting
/// follows it.
#[test]
fn bevy_gpu_written_image_rebuilds_every_frame() {
    let Some(_) = gpu() else { return };
    let mut h = standard_sphere_app(white_furnace_material());
    let mut sky = Image::new_uninit(
        Extent3d {
            width: 32,
            height: 16,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        TextureFormat::Rgba16Float,
        RenderAssetUsages::RENDER_WORLD,
    );
    sky.texture_descriptor.usage |=
        TextureUsages::RENDER_ATTACHMENT | TextureUsages::TEXTURE_BINDING;
    let sky = h.add::<Image>(sky);
    // A camera that sees nothing (an empty render layer) and clears the image to SkyColor.
    h.app
        .insert_resource(SkyColor(0.25))
        .add_systems(Update, paint_sky);
    h.app.world_mut().spawn((
        Camera3d::default(),
        Camera {
            order: -1,
            ..default()
        },
        RenderTarget::from(sky.clone()),
        RenderLayers::layer(1),
        bevy::camera::Hdr,
        Tonemapping::None,
        exposure_multiplier(1.0),
    ));
    let target = h.float_target(32, 32);
    let (projection, transform) = sphere_view();
    h.app.world_mut().spawn(radiance_camera(
        target.clone(),
        projection,
        transform,
        EnvironmentSampling::default(),
        EnvisEnvironment {
            dynamic: true,
            ..EnvisEnvironment::new(sky)
        },
    ));
    let first = sphere_mean(&h.capture(&target).unwrap(), 32);
    let c0 = h.counters().get(|c| &c.builds);
    for _ in 0..10 {
        h.update();
    }
    let c = h.counters();
    assert_eq!(
        c.get(|c| &c.builds),
        c0 + 10,
        "one build per frame: {:?}",
        c.0
    );
    assert_eq!(c.get(|c| &c.image_bytes_uploaded), 0, "{:?}", c.0);
    h.app.world_mut().resource_mut::<SkyColor>().0 = 1.0;
    for _ in 0..3 {
        h.update();
    }
    let later = sphere_mean(&h.capture(&target).unwrap(), 32);
    assert!(
        rel(first, 0.25) < 0.02 && rel(later, 1.0) < 0.02,
        "the lighting did not follow the GPU-written sky: {first} -> {later}"
    );
}
