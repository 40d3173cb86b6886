//! A user's glTF scene (plain `StandardMaterial`s) with a sun and its shadows, lit by an HDR
//! environment map loaded through the `AssetServer` and importance-sampled by envis every frame.
//!
//! `cargo run --release --example gltf_scene`

use bevy::prelude::*;
use bevy_envis::prelude::*;

fn main() {
    App::new()
        .add_plugins((DefaultPlugins, EnvisPlugin))
        // Edit shaders/*.wgsl while it runs: the lighting pass recompiles.
        .add_plugins(EnvisShaderReloadPlugin::default())
        .add_plugins(example)
        .run();
}

/// The scene (everything but the window and the plugins): the tests run it headless.
pub fn example(app: &mut App) {
    // No set-up of its own: EnvisPlugin makes StandardMaterials render deferred, so they write
    // the G-buffer the envis pass reads.
    app.add_systems(Startup, (setup, loading_screen))
        .add_systems(Update, leave_loading_screen);
}

/// A loading screen without any UI crate: a camera drawn after the scene's (order 1) that sees
/// nothing (an empty render layer) and clears the window to grey.
#[derive(Component)]
pub struct LoadingScreen;

fn loading_screen(mut commands: Commands) {
    commands.spawn((
        LoadingScreen,
        Camera3d::default(),
        Camera {
            order: 1,
            clear_color: ClearColorConfig::Custom(Color::srgb(0.2, 0.2, 0.2)),
            ..default()
        },
        bevy::camera::visibility::RenderLayers::layer(31),
    ));
}

/// Envis marks a camera `EnvisLightReady` from the first frame it lit it (its shaders compiled,
/// its map loaded): the loading screen goes then, and every frame shown is lit.
fn leave_loading_screen(
    mut commands: Commands,
    lit: Query<(), Added<EnvisLightReady>>,
    screens: Query<Entity, With<LoadingScreen>>,
) {
    if !lit.is_empty() {
        screens.iter().for_each(|e| commands.entity(e).despawn());
    }
}

fn setup(
    mut commands: Commands,
    assets: Res<AssetServer>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    // A glTF scene as a user would load it: its material becomes a StandardMaterial.
    commands.spawn((
        WorldAssetRoot(assets.load(GltfAssetLabel::Scene(0).from_asset("models/suzi_plain.glb"))),
        Transform::from_xyz(-0.6, 0.75, 0.0).with_scale(Vec3::splat(0.7)),
    ));
    commands.spawn((
        Mesh3d(meshes.add(Sphere::new(0.6).mesh().ico(5).expect("icosphere"))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(1.0, 0.78, 0.34),
            metallic: 1.0,
            perceptual_roughness: 0.25,
            ..default()
        })),
        Transform::from_xyz(1.4, 0.6, 0.2),
    ));
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(10.0, 10.0))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.55, 0.55, 0.5),
            perceptual_roughness: 0.9,
            ..default()
        })),
    ));
    // Bevy's own sun and its shadow map stay: envis adds the environment on top.
    commands.spawn((
        DirectionalLight {
            illuminance: 2_000.0,
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::from_xyz(3.0, 5.0, 2.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    commands.spawn((
        Camera3d::default(),
        Transform::from_xyz(0.0, 1.6, 4.6).looking_at(Vec3::new(0.2, 0.5, 0.0), Vec3::Y),
        EnvironmentSampling {
            light_samples: 16,
            brdf_samples: 16,
            ..default()
        },
        // The map's values are scaled to cd/m^2 like EnvironmentMapLight::intensity; the camera's
        // default Exposure then applies to it as to the sun.
        EnvisEnvironment {
            intensity: 1500.0,
            ..EnvisEnvironment::new(assets.load("hdri/park.exr"))
        },
    ));
}
