//! Two cameras in one window, each with its own envis settings: the method (face-weighted light
//! samples + BRDF samples by MIS) on the left, the `global` lat-long baseline on the right, at the
//! same sample budget. Each camera shades only its own viewport.
//!
//! `cargo run --release --example split_screen`

use bevy::camera::Viewport;
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

/// Which half of the target a camera draws.
#[derive(Component)]
pub struct Half(pub u32);

/// The scene and the two cameras (everything but the window and `EnvisPlugin`).
pub fn example(app: &mut App) {
    app.add_systems(Startup, setup)
        .add_systems(Update, fit_viewports);
}

fn setup(
    mut commands: Commands,
    assets: Res<AssetServer>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    let sphere = meshes.add(Sphere::new(0.5).mesh().ico(5).expect("icosphere"));
    for (i, roughness) in [0.15, 0.4, 0.8].into_iter().enumerate() {
        commands.spawn((
            Mesh3d(sphere.clone()),
            MeshMaterial3d(materials.add(StandardMaterial {
                base_color: Color::srgb(0.9, 0.9, 0.9),
                metallic: 1.0,
                perceptual_roughness: roughness,
                ..default()
            })),
            Transform::from_xyz(-1.2 + 1.2 * i as f32, 0.5, 0.0),
        ));
    }
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(8.0, 8.0))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.4, 0.4, 0.4),
            perceptual_roughness: 1.0,
            ..default()
        })),
    ));
    let env = assets.load("hdri/park.exr");
    let strategies = [Strategy::Paper, Strategy::Global];
    for (k, strategy) in strategies.into_iter().enumerate() {
        commands.spawn((
            Camera3d::default(),
            Camera {
                order: k as isize,
                ..default()
            },
            Transform::from_xyz(0.0, 1.4, 3.6).looking_at(Vec3::new(0.0, 0.4, 0.0), Vec3::Y),
            EnvironmentSampling {
                strategy,
                light_samples: 8,
                brdf_samples: 8,
                ..default()
            },
            EnvisEnvironment {
                intensity: 1500.0,
                ..EnvisEnvironment::new(env.clone())
            },
            Half(k as u32),
        ));
    }
}

/// Each camera takes its half of whatever it renders to (a window, or an image in the tests).
fn fit_viewports(mut cameras: Query<(&mut Camera, &Half)>) {
    for (mut camera, half) in &mut cameras {
        let Some(size) = camera.physical_target_size() else {
            continue;
        };
        let width = size.x / 2;
        let viewport = Viewport {
            physical_position: UVec2::new(half.0 * width, 0),
            physical_size: UVec2::new(width.max(1), size.y.max(1)),
            ..default()
        };
        let same = camera.viewport.as_ref().is_some_and(|v| {
            v.physical_position == viewport.physical_position
                && v.physical_size == viewport.physical_size
        });
        if !same {
            camera.viewport = Some(viewport);
        }
    }
}
