//! The interactive demo (`envis` with no subcommand): real objects lit only by the environment,
//! an orbit camera, the egui tweak panel, the paper's red / green / yellow sample-debug view and
//! full-screen overlays. `--script DIR` runs a scripted sequence (for CI under Xvfb): it takes
//! screenshots, writes `report.json` and exits.

mod camera;
mod debug_panel;
mod debug_view;
mod script;
mod settings_ui;
mod ui;

use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::input::mouse::{AccumulatedMouseMotion, AccumulatedMouseScroll};
use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, save_to_disk};
use bevy::window::{PrimaryWindow, WindowResolution};
use bevy_egui::{EguiContexts, EguiPlugin, EguiPrimaryContextPass, egui};
use bevy_envis::prelude::{
    EnvironmentResampling, EnvironmentSampling, EnvisEnvironment, exposure_multiplier,
};
use bevy_envis::scene_objects::{SceneCamera, SceneObject, spawn_object, spawn_scene_objects};
use bevy_envis::{
    EnvFrame, EnvMapStream, EnvisBrdf, EnvisCounters, EnvisMaterial, EnvisPlugin, EnvisProbe,
    EnvisStreamPlugin, EnvisTimings, Overlay,
};
use camera::{Orbit, keys, orbit_camera, pick_pixel};
use clap::ValueEnum;
use debug_view::{draw_debug_samples, update_debug_view};
use envis::envmap::{CROSS_BLOCKS, CubeMap, dir_to_face_ab};
use envis::render::{FrameData, PixelDebug, PoolLayout, SampleKind, Settings, Strategy};
use envis::sampling::{Counts, Heuristic};
use envis::stream::StreamSource;
use script::run_script;
use std::path::PathBuf;
use ui::panel;

/// How the demo starts.
#[derive(Clone, Debug)]
pub struct DemoOptions {
    pub source: StreamSource,
    pub face_size: usize,
    /// Scripted run: screenshots and `report.json` go here, then the app exits.
    pub script: Option<PathBuf>,
    pub window: (u32, u32),
    /// The panels' zoom factor (1: egui's normal size).
    pub ui_scale: f32,
    pub sampling: Settings,
    /// Objects and camera from a scene file (the built-in showcase otherwise).
    pub scene: Option<envis::scene::Scene>,
}

/// Reservoir resampling on (`EnvironmentResampling`'s defaults) or off for the demo camera.
fn set_resampling(commands: &mut Commands, camera: Entity, on: bool) {
    if on {
        commands
            .entity(camera)
            .insert(EnvironmentResampling::default());
    } else {
        commands.entity(camera).remove::<EnvironmentResampling>();
    }
}

/// The scene file the demo was started with.
#[derive(Resource)]
struct SceneResource(envis::scene::Scene);

/// Run the demo until the window closes (or the script ends).
pub fn run(opts: DemoOptions) -> AppExit {
    let mut app = App::new();
    let scripted = opts.script.is_some();
    app.add_plugins(
        DefaultPlugins
            .set(WindowPlugin {
                primary_window: Some(Window {
                    title: "envis — real-time importance sampling of dynamic environment maps"
                        .into(),
                    resolution: WindowResolution::new(opts.window.0, opts.window.1),
                    ..default()
                }),
                ..default()
            })
            .set(AssetPlugin {
                file_path: asset_root(),
                ..default()
            }),
    )
    .add_plugins((
        EnvisPlugin,
        EnvisStreamPlugin {
            source: opts.source.clone(),
            face_size: stream_face_size(opts.face_size),
        },
    ))
    .add_plugins(EguiPlugin::default())
    .insert_resource(DemoState {
        debug: false,
        script: opts.script.clone(),
        face_size: opts.face_size,
        ui_scale: opts.ui_scale,
        exposure: 1.0,
        sampling: opts.sampling,
        ..default()
    })
    .add_systems(Startup, setup_scene)
    .add_systems(
        Update,
        (
            orbit_camera,
            keys,
            pick_pixel,
            update_debug_view,
            draw_debug_samples,
        )
            .chain(),
    )
    .add_systems(EguiPrimaryContextPass, panel);
    if scripted {
        app.add_systems(Update, run_script.after(update_debug_view));
    }
    if let Some(sc) = opts.scene {
        app.insert_resource(SceneResource(sc));
    }
    app.run()
}

/// Where the demo's assets are: `$ENVIS_ASSETS`, else `./assets` when it has the demo's files,
/// else the source tree's `assets/` (a binary run from its build directory).
pub fn asset_root() -> String {
    if let Ok(p) = std::env::var("ENVIS_ASSETS") {
        return p;
    }
    if std::path::Path::new("assets/models/bunny_plain.glb").exists() {
        return std::fs::canonicalize("assets")
            .map(|p| p.display().to_string())
            .unwrap_or_else(|_| "assets".into());
    }
    crate::repo_path("assets").to_string_lossy().into_owned()
}

/// Demo-only state (panel selections, the debug view).
#[derive(Resource, Default)]
pub struct DemoState {
    /// The sample-debug view is on.
    pub debug: bool,
    /// The CPU twin's view of the probed pixel, with the key it was computed for.
    pub pixel: Option<(PixelDebug, envis::render::GPixel, Vec3)>,
    /// What `pixel` was computed from: frame generation, settings (with the frame's seed), pixel,
    /// normal and the shadow geometry's generation.
    key: Option<(u64, Settings, u32, Vec3, u64)>,
    cross: Option<(u64, egui::TextureHandle)>,
    script: Option<PathBuf>,
    /// The scripted run's clock: frames so far, the next step, the frame it runs at and how
    /// many frames the current wait has lasted.
    script_frame: u32,
    script_step: usize,
    script_next: u32,
    script_waited: u32,
    /// Frames the script waited for the lighting pipeline to compile.
    script_compile_wait: u32,
    face_size: usize,
    env_text: String,
    fps: f32,
    /// The exposure multiplier the panel sets (written to the camera's `Exposure`).
    exposure: f32,
    /// The sampling settings the camera starts with.
    sampling: Settings,
    /// The panels' zoom factor.
    ui_scale: f32,
}

/// The stream's face size for a distribution of `face` texels per face: the picture (the sky,
/// mirror reflections) comes from the stream's image at this resolution, the densities from the
/// distribution; 4x, up to 512.
pub fn stream_face_size(face: usize) -> usize {
    (4 * face).clamp(face, 512)
}

/// The demo's camera (the one the panel, the keys and the script edit).
#[derive(Component)]
pub struct DemoCamera;

/// The demo camera's envis components, lit by the stream's image, starting with `s`.
fn envis_camera(stream: &EnvMapStream, s: &Settings, face_size: usize) -> impl Bundle {
    let sampling = EnvironmentSampling { face_size, ..*s };
    (
        sampling,
        EnvisEnvironment::new(stream.image.clone()),
        exposure_multiplier(1.0),
        DemoCamera,
    )
}

/// The scene (from the scene file, else the built-in showcase) and the demo camera.
fn setup_scene(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<EnvisMaterial>>,
    assets: Res<AssetServer>,
    scene: Option<Res<SceneResource>>,
    stream: Res<EnvMapStream>,
    state: Res<DemoState>,
) {
    let camera = envis_camera(&stream, &state.sampling, state.face_size);
    if let Some(sc) = scene {
        let cam = spawn_scene_objects(&mut commands, &mut meshes, &mut materials, &sc.0);
        spawn_scene_camera(&mut commands, camera, &cam);
        return;
    }
    spawn_showcase(&mut commands, &mut meshes, &mut materials, &assets);
    commands.spawn((
        Camera3d::default(),
        Tonemapping::TonyMcMapface,
        camera,
        Orbit {
            yaw: 0.0,
            pitch: 0.35,
            distance: 9.0,
            target: Vec3::new(0.0, 0.8, 0.0),
        },
        Transform::default(),
    ));
}

/// The demo camera where the scene file puts it: orbiting its target from its eye, with its
/// field of view.
fn spawn_scene_camera(commands: &mut Commands, camera: impl Bundle, cam: &SceneCamera) {
    let d = cam.eye - cam.target;
    let distance = d.length().max(0.1);
    commands.spawn((
        Camera3d::default(),
        Projection::Perspective(PerspectiveProjection {
            fov: cam.fov,
            ..default()
        }),
        Tonemapping::TonyMcMapface,
        camera,
        Orbit {
            yaw: d.x.atan2(d.z),
            pitch: (d.y / distance).asin(),
            distance,
            target: cam.target,
        },
        Transform::default(),
    ));
}

/// The built-in showcase: a Phong sphere, a GGX bunny, a mixed torus and a diffuse ground.
fn spawn_showcase(
    commands: &mut Commands,
    meshes: &mut Assets<Mesh>,
    materials: &mut Assets<EnvisMaterial>,
    assets: &AssetServer,
) {
    let mut spawn = |name: &str, mesh, material, transform| {
        spawn_object(commands, materials, name, mesh, material, transform);
    };
    spawn(
        "sphere",
        meshes.add(Sphere::new(1.0).mesh().ico(6).expect("icosphere")),
        EnvisBrdf::Phong {
            albedo: Vec3::splat(0.8),
            exponent: 150.0,
        },
        Transform::from_xyz(-2.3, 1.0, 0.0),
    );
    let bunny = assets.load(
        GltfAssetLabel::Primitive {
            mesh: 0,
            primitive: 0,
        }
        .from_asset("models/bunny_plain.glb"),
    );
    spawn(
        "bunny",
        bunny,
        EnvisBrdf::Ggx {
            albedo: Vec3::new(0.9, 0.75, 0.5),
            alpha: 0.2,
        },
        Transform::from_xyz(0.0, 0.0, 0.3).with_scale(Vec3::splat(1.6)),
    );
    spawn(
        "torus",
        meshes.add(Torus::new(0.45, 0.9)),
        EnvisBrdf::Mix {
            albedo: Vec3::new(0.2, 0.5, 0.8),
            specular: 0.4,
            alpha: 0.3,
        },
        Transform::from_xyz(2.4, 0.45, 0.0),
    );
    spawn(
        "ground",
        meshes.add(Plane3d::default().mesh().size(12.0, 12.0)),
        EnvisBrdf::Lambert {
            albedo: Vec3::splat(0.5),
        },
        Transform::IDENTITY,
    );
}
