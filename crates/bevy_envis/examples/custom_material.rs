//! envis's own deferred material, `EnvisMaterial` (Lambert, normalised Phong, GGX, a Lambert +
//! GGX mix), next to a plain `StandardMaterial`, under envis's animated built-in sky: a stream
//! played into an `Image` by `EnvisStreamPlugin` (file sequences and the carousel work the same).
//!
//! `cargo run --release --example custom_material`

use bevy::prelude::*;
use bevy_envis::envis::stream::StreamSource;
use bevy_envis::prelude::*;
use bevy_envis::{EnvMapStream, EnvisStreamPlugin};

fn main() {
    App::new()
        .add_plugins((DefaultPlugins, EnvisPlugin))
        // Edit shaders/*.wgsl while it runs: the lighting pass recompiles.
        .add_plugins(EnvisShaderReloadPlugin::default())
        .add_plugins(example)
        .run();
}

/// The scene and the sky stream (everything but the window and `EnvisPlugin`).
pub fn example(app: &mut App) {
    app.add_plugins(EnvisStreamPlugin {
        // From 7 am, an hour of sky per second.
        source: StreamSource::Sky {
            hours: 7.0,
            speed: 1.0,
        },
        face_size: 64,
    })
    .add_systems(Startup, setup);
}

fn setup(
    mut commands: Commands,
    stream: Res<EnvMapStream>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut envis_materials: ResMut<Assets<EnvisMaterial>>,
    mut standard: ResMut<Assets<StandardMaterial>>,
) {
    let sphere = meshes.add(Sphere::new(0.45).mesh().ico(5).expect("icosphere"));
    let materials = [
        EnvisMaterial::lambert(Vec3::new(0.8, 0.3, 0.2)),
        EnvisMaterial::phong(Vec3::splat(0.9), 300.0),
        EnvisMaterial::ggx(Vec3::new(0.95, 0.8, 0.5), 0.15),
        EnvisMaterial::mix(Vec3::new(0.2, 0.4, 0.9), 0.3, 0.2),
    ];
    for (i, m) in materials.into_iter().enumerate() {
        commands.spawn((
            Mesh3d(sphere.clone()),
            MeshMaterial3d(envis_materials.add(m)),
            Transform::from_xyz(-1.65 + 1.1 * i as f32, 0.45, 0.0),
        ));
    }
    // A StandardMaterial ground: lit by envis through Bevy's G-buffer.
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(8.0, 8.0))),
        MeshMaterial3d(standard.add(StandardMaterial {
            base_color: Color::srgb(0.5, 0.5, 0.5),
            perceptual_roughness: 1.0,
            reflectance: 0.0,
            ..default()
        })),
    ));
    commands.spawn((
        Camera3d::default(),
        Transform::from_xyz(0.0, 1.5, 4.0).looking_at(Vec3::new(0.0, 0.4, 0.0), Vec3::Y),
        EnvironmentSampling::default(),
        EnvisEnvironment::new(stream.image.clone()),
        // The built-in sky is in relative units: show it as it is.
        exposure_multiplier(1.0),
    ));
}
