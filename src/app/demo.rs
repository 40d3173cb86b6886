//! The interactive demo (`envis` with no subcommand): real objects lit only by the environment,
//! an orbit camera, the egui tweak panel, the seed's red / green / yellow sample-debug view and
//! full-screen overlays. `--script DIR` runs a scripted sequence (for CI under Xvfb): it takes
//! screenshots, writes `report.json` and exits.

use super::scene_objects::{SceneObject, spawn_scene_objects};
use super::{
    EnvFrame, EnvMapSamplingPlugin, EnvMapStream, EnvMapStreamPlugin, EnvisCamera, EnvisCounters,
    EnvisMaterial, EnvisProbe, EnvisSettings, EnvisTimings, MisLightingPlugin, Overlay,
};
use crate::envmap::{CROSS_BLOCKS, CubeMap, dir_to_face_ab};
use crate::render::{FrameData, PixelDebug, SampleKind, Settings, Strategy, debug_pixel};
use crate::sampling::{Counts, Heuristic};
use crate::stream::StreamSource;
use clap::ValueEnum;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::input::mouse::{AccumulatedMouseMotion, AccumulatedMouseScroll};
use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, save_to_disk};
use bevy::window::{PrimaryWindow, WindowResolution};
use bevy_egui::{EguiContexts, EguiPlugin, EguiPrimaryContextPass, egui};
use std::path::PathBuf;

/// How the demo starts.
#[derive(Clone, Debug)]
pub struct DemoOptions {
    pub source: StreamSource,
    pub face_size: usize,
    /// Scripted run: screenshots and `report.json` go here, then the app exits.
    pub script: Option<PathBuf>,
    pub window: (u32, u32),
    pub sampling: Settings,
    /// Objects and camera from a scene file (the built-in showcase otherwise).
    pub scene: Option<crate::scene::Scene>,
}

/// The scene file the demo was started with.
#[derive(Resource)]
struct SceneResource(crate::scene::Scene);

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
    .insert_resource(EnvisSettings {
        sampling: opts.sampling,
        ..default()
    })
    .add_plugins((
        EnvMapStreamPlugin {
            source: opts.source.clone(),
            face_size: opts.face_size,
        },
        EnvMapSamplingPlugin,
        MisLightingPlugin,
    ))
    .add_plugins(EguiPlugin::default())
    // Bevy's own per-pass GPU timings (its prepass writes the G-buffer) for the Timings panel.
    .add_plugins(bevy::render::diagnostic::RenderDiagnosticsPlugin)
    .insert_resource(DemoState {
        debug: false,
        script: opts.script.clone(),
        face_size: opts.face_size,
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
    concat!(env!("CARGO_MANIFEST_DIR"), "/assets").into()
}

#[derive(Component)]
struct Orbit {
    yaw: f32,
    pitch: f32,
    distance: f32,
    target: Vec3,
}

/// Demo-only state (panel selections, the debug view).
#[derive(Resource, Default)]
pub struct DemoState {
    /// The sample-debug view is on.
    pub debug: bool,
    /// The CPU twin's view of the probed pixel, with the key it was computed for.
    pub pixel: Option<(PixelDebug, crate::render::GPixel, Vec3)>,
    /// What `pixel` was computed from: frame generation, settings (with the frame's seed), pixel.
    key: Option<(u64, Settings, u32, Vec3)>,
    cross: Option<(u64, egui::TextureHandle)>,
    script: Option<PathBuf>,
    script_frame: u32,
    face_size: usize,
    env_text: String,
    fps: f32,
}

fn setup_scene(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    assets: Res<AssetServer>,
    scene: Option<Res<SceneResource>>,
) {
    let mut spawn =
        |name: &str, mesh: Handle<Mesh>, material: EnvisMaterial, transform: Transform| {
            let handle = materials.add(material.standard());
            commands.spawn((
                Mesh3d(mesh),
                MeshMaterial3d(handle.clone()),
                transform,
                SceneObject {
                    name: name.into(),
                    material,
                    handle,
                },
            ));
        };
    if let Some(sc) = scene {
        let cam = spawn_scene_objects(&mut commands, &mut meshes, &mut materials, &sc.0);
        let d = cam.eye - cam.target;
        let distance = d.length().max(0.1);
        commands.spawn((
            Camera3d::default(),
            Projection::Perspective(PerspectiveProjection {
                fov: cam.fov,
                ..default()
            }),
            bevy::camera::Hdr,
            Msaa::Off,
            Tonemapping::TonyMcMapface,
            EnvisCamera,
            Orbit {
                yaw: d.x.atan2(d.z),
                pitch: (d.y / distance).asin(),
                distance,
                target: cam.target,
            },
            Transform::default(),
        ));
        return;
    }
    spawn(
        "sphere",
        meshes.add(Sphere::new(1.0).mesh().ico(6).expect("icosphere")),
        EnvisMaterial::Phong {
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
        EnvisMaterial::Ggx {
            albedo: Vec3::new(0.9, 0.75, 0.5),
            alpha: 0.2,
        },
        Transform::from_xyz(0.0, 0.0, 0.3).with_scale(Vec3::splat(1.6)),
    );
    spawn(
        "torus",
        meshes.add(Torus::new(0.45, 0.9)),
        EnvisMaterial::Mix {
            albedo: Vec3::new(0.2, 0.5, 0.8),
            specular: 0.4,
            alpha: 0.3,
        },
        Transform::from_xyz(2.4, 0.45, 0.0),
    );
    spawn(
        "ground",
        meshes.add(Plane3d::default().mesh().size(12.0, 12.0)),
        EnvisMaterial::Lambert {
            albedo: Vec3::splat(0.5),
        },
        Transform::IDENTITY,
    );
    commands.spawn((
        Camera3d::default(),
        bevy::camera::Hdr,
        Msaa::Off,
        Tonemapping::TonyMcMapface,
        EnvisCamera,
        Orbit {
            yaw: 0.0,
            pitch: 0.35,
            distance: 9.0,
            target: Vec3::new(0.0, 0.8, 0.0),
        },
        Transform::default(),
    ));
}

fn egui_wants_pointer(contexts: &mut EguiContexts) -> bool {
    contexts
        .ctx_mut()
        .map(|c| c.egui_wants_pointer_input() || c.is_pointer_over_egui())
        .unwrap_or(false)
}

fn orbit_camera(
    mut contexts: EguiContexts,
    buttons: Res<ButtonInput<MouseButton>>,
    motion: Res<AccumulatedMouseMotion>,
    scroll: Res<AccumulatedMouseScroll>,
    mut cams: Query<(&mut Orbit, &mut Transform)>,
) {
    let over_ui = egui_wants_pointer(&mut contexts);
    for (mut o, mut t) in &mut cams {
        if !over_ui {
            if buttons.pressed(MouseButton::Left) {
                o.yaw -= motion.delta.x * 0.006;
                o.pitch = (o.pitch + motion.delta.y * 0.006).clamp(-0.2, 1.45);
            }
            o.distance = (o.distance * (1.0 - scroll.delta.y * 0.08)).clamp(2.0, 40.0);
        }
        let dir = Vec3::new(
            o.yaw.sin() * o.pitch.cos(),
            o.pitch.sin(),
            o.yaw.cos() * o.pitch.cos(),
        );
        *t = Transform::from_translation(o.target + dir * o.distance).looking_at(o.target, Vec3::Y);
    }
}

fn keys(
    keys: Res<ButtonInput<KeyCode>>,
    mut settings: ResMut<EnvisSettings>,
    mut state: ResMut<DemoState>,
    mut last: Local<Option<std::time::Instant>>,
) {
    // Frames per second of the app (an exponential moving average of wall-clock frame times).
    let now = std::time::Instant::now();
    if let Some(t) = *last {
        let dt = (now - t).as_secs_f32().max(1e-6);
        state.fps = if state.fps == 0.0 {
            1.0 / dt
        } else {
            0.9 * state.fps + 0.1 / dt
        };
    }
    *last = Some(now);
    if keys.just_pressed(KeyCode::KeyI) {
        settings.sampling.counts = if settings.sampling.counts == Counts::Fractional {
            Counts::Integer
        } else {
            Counts::Fractional
        };
    }
    if keys.just_pressed(KeyCode::KeyO) {
        let i = Overlay::ALL
            .iter()
            .position(|o| *o == settings.overlay)
            .unwrap_or(0);
        settings.overlay = Overlay::ALL[(i + 1) % Overlay::ALL.len()];
    }
    if keys.just_pressed(KeyCode::KeyD) {
        state.debug = !state.debug;
    }
}

/// Right click (or the script) picks the pixel whose samples the debug view shows.
fn pick_pixel(
    mut contexts: EguiContexts,
    buttons: Res<ButtonInput<MouseButton>>,
    windows: Query<&Window, With<PrimaryWindow>>,
    mut settings: ResMut<EnvisSettings>,
    mut state: ResMut<DemoState>,
) {
    if egui_wants_pointer(&mut contexts) || !buttons.just_pressed(MouseButton::Right) {
        return;
    }
    let Ok(w) = windows.single() else { return };
    if let Some(p) = w.physical_cursor_position() {
        settings.probe = Some(UVec2::new(p.x as u32, p.y as u32));
        state.debug = true;
    }
}

/// Recompute the CPU twin's view of the probed pixel when the probe, the frame or the settings change.
fn update_debug_view(
    frame: Res<EnvFrame>,
    settings: Res<EnvisSettings>,
    probe: Res<EnvisProbe>,
    mut state: ResMut<DemoState>,
) {
    let Some(p) = *probe.lock().expect("probe") else {
        return;
    };
    // The seed the GPU used for this frame (it changes per frame while accumulating).
    let s = Settings {
        seed: settings.frame_seed(),
        ..settings.sampling
    };
    let key = (frame.generation, s, p.pixel_index, p.gpixel.n);
    if state.key == Some(key) {
        return;
    }
    let fd = FrameData::prepare(&frame.map, &s);
    let d = debug_pixel(&fd, &s, &p.gpixel, p.pixel_index);
    state.pixel = Some((d, p.gpixel, p.estimate));
    state.key = Some(key);
}

/// The probed pixel's pool samples on the sky, far away in their directions.
fn draw_debug_samples(
    state: Res<DemoState>,
    cams: Query<&Transform, With<EnvisCamera>>,
    mut gizmos: Gizmos,
) {
    let (Some((d, _, _)), true) = (&state.pixel, state.debug) else {
        return;
    };
    let Ok(cam) = cams.single() else { return };
    for s in &d.samples {
        let p = cam.translation + s.dir * 30.0;
        gizmos.sphere(Isometry3d::from_translation(p), 0.25, kind_color(s.kind));
    }
}

fn kind_color(k: SampleKind) -> Color {
    match k {
        SampleKind::Discarded => Color::srgb(1.0, 0.0, 0.0),
        SampleKind::Used => Color::srgb(0.0, 1.0, 0.0),
        SampleKind::Wasted => Color::srgb(1.0, 1.0, 0.0),
    }
}

fn egui_kind_color(k: SampleKind) -> egui::Color32 {
    match k {
        SampleKind::Discarded => egui::Color32::from_rgb(255, 0, 0),
        SampleKind::Used => egui::Color32::from_rgb(0, 255, 0),
        SampleKind::Wasted => egui::Color32::from_rgb(255, 255, 0),
    }
}

/// The environment as a small 4:3 cross image (Reinhard-tonemapped) for the panel's inset.
fn cross_texture(ctx: &egui::Context, map: &CubeMap) -> egui::TextureHandle {
    let n = map.size.min(48);
    let small = if map.size == n {
        map.clone()
    } else {
        crate::envmap::resample::resize_cube(map, n)
    };
    let img = crate::envmap::cube_to_cross(&small);
    let px: Vec<egui::Color32> = img
        .data
        .iter()
        .map(|c| {
            let t = |x: f32| ((x / (1.0 + x)).powf(1.0 / 2.2) * 255.0) as u8;
            egui::Color32::from_rgb(t(c.x), t(c.y), t(c.z))
        })
        .collect();
    let ci = egui::ColorImage {
        size: [img.width, img.height],
        source_size: egui::vec2(img.width as f32, img.height as f32),
        pixels: px,
    };
    ctx.load_texture("envis-cross", ci, egui::TextureOptions::NEAREST)
}

#[allow(clippy::too_many_arguments)]
fn panel(
    mut contexts: EguiContexts,
    mut settings: ResMut<EnvisSettings>,
    mut stream: ResMut<EnvMapStream>,
    mut state: ResMut<DemoState>,
    frame: Res<EnvFrame>,
    timings: Res<EnvisTimings>,
    counters: Res<EnvisCounters>,
    mut objects: Query<&mut SceneObject>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    windows: Query<&Window, With<PrimaryWindow>>,
    diagnostics: Res<bevy::diagnostic::DiagnosticsStore>,
) -> Result {
    let ctx = contexts.ctx_mut()?.clone();
    if state
        .cross
        .as_ref()
        .is_none_or(|(g, _)| *g != frame.generation)
    {
        state.cross = Some((frame.generation, cross_texture(&ctx, &frame.map)));
    }
    egui::Window::new("envis").anchor(egui::Align2::RIGHT_TOP, [-8.0, 8.0]).default_width(320.0).show(&ctx, |ui| {
        egui::ScrollArea::vertical().show(ui, |ui| {
            ui.collapsing("Environment", |ui| environment_ui(ui, &mut stream, &mut settings, &mut state));
            egui::CollapsingHeader::new("Sampling").default_open(true).show(ui, |ui| sampling_ui(ui, &mut settings));
            ui.collapsing("Materials", |ui| {
                for mut o in &mut objects {
                    if material_ui(ui, &o.name.clone(), &mut o.material) {
                        if let Some(mut m) = materials.get_mut(&o.handle) {
                            *m = o.material.standard();
                        }
                        settings.scene_revision += 1;
                    }
                }
            });
            egui::CollapsingHeader::new("Timings").default_open(true).show(ui, |ui| {
                let t = timings.get();
                let f = |x: Option<f64>| x.map_or("n/a".to_string(), |v| format!("{v:.3} ms"));
                ui.label(format!("distribution build: GPU {}; light pool: GPU {}; upload + record: CPU {}", f(t.build_gpu_ms), f(t.pool_gpu_ms), f(t.build_cpu_ms)));
                ui.label(format!("lighting (G-buffer -> MIS): GPU {}, CPU {}", f(t.lighting_gpu_ms), f(t.lighting_cpu_ms)));
                let px = windows.single().map(|w| (w.physical_width() * w.physical_height()) as f64).unwrap_or(0.0);
                let budget = (settings.sampling.light_samples + settings.sampling.brdf_samples) as f64;
                ui.label(format!("{:.1} FPS, sample budget {:.1} M samples/s", state.fps, px * budget * state.fps as f64 / 1e6));
                ui.label(format!("builds {}, uploads {}, lighting passes {}", counters.get(|c| &c.builds), counters.get(|c| &c.uploads), counters.get(|c| &c.lighting_passes)));
                ui.label("overlays run inside the lighting pass (no pass of their own)");
                // Bevy's passes: the prepass writes the G-buffer.
                let mut bevy_passes: Vec<(String, f64)> = diagnostics
                    .iter()
                    .filter(|d| d.path().as_str().starts_with("render/") && d.path().as_str().ends_with("/elapsed_gpu"))
                    .filter_map(|d| d.smoothed().map(|v| (d.path().as_str().trim_start_matches("render/").trim_end_matches("/elapsed_gpu").to_string(), v)))
                    .collect();
                bevy_passes.sort_by(|a, b| b.1.total_cmp(&a.1));
                egui::CollapsingHeader::new(format!("Bevy passes ({})", bevy_passes.len())).show(ui, |ui| {
                    for (name, ms) in bevy_passes.iter().take(12) {
                        ui.label(format!("{name}: {ms:.3} ms GPU"));
                    }
                });
            });
            for m in stream.log.iter().rev().take(3) {
                ui.colored_label(egui::Color32::from_rgb(255, 170, 60), m);
            }
        });
    });
    egui::Window::new("sample debug (right-click a pixel, D)")
        .anchor(egui::Align2::LEFT_BOTTOM, [8.0, -8.0])
        .default_width(330.0)
        .show(&ctx, |ui| debug_ui(ui, &mut settings, &mut state));
    Ok(())
}

fn environment_ui(
    ui: &mut egui::Ui,
    stream: &mut EnvMapStream,
    settings: &mut EnvisSettings,
    state: &mut DemoState,
) {
    let s = &mut stream.stream;
    ui.horizontal(|ui| {
        if ui
            .button(if s.playing { "pause" } else { "play" })
            .clicked()
        {
            s.playing = !s.playing;
        }
        ui.add(egui::Slider::new(&mut s.speed, 0.0..=8.0).text("speed"));
    });
    if let Some(mut h) = s.sky_hours() {
        if ui
            .add(egui::Slider::new(&mut h, 0.0..=24.0).text("time of day (h)"))
            .changed()
        {
            s.set_sky_hours(h);
        }
    }
    ui.add(
        egui::Slider::new(&mut settings.exposure, 0.01..=8.0)
            .logarithmic(true)
            .text("exposure"),
    );
    ui.checkbox(
        &mut settings.show_sky,
        "show the environment behind objects",
    );
    let mut face = state.face_size;
    ui.add(
        egui::Slider::new(&mut face, 8..=1024)
            .logarithmic(true)
            .text("face size"),
    );
    ui.horizontal(|ui| {
        ui.label("source");
        ui.text_edit_singleline(&mut state.env_text);
    });
    ui.horizontal(|ui| {
        let apply = ui
            .button("open (file, frame directory, builtin:sky)")
            .clicked();
        if apply || face != state.face_size {
            let src = if state.env_text.trim().is_empty() {
                Ok(stream.stream.source().clone())
            } else {
                StreamSource::parse(state.env_text.trim())
            };
            match src {
                Ok(src) => {
                    if stream.switch(src, face) {
                        state.face_size = face;
                    }
                }
                Err(e) => stream.log.push(format!("{e}")),
            }
        }
    });
    ui.label(format!(
        "{:?}, generation {}",
        stream.stream.stats(),
        stream.stream.generation()
    ));
}

fn sampling_ui(ui: &mut egui::Ui, settings: &mut EnvisSettings) {
    let s = &mut settings.sampling;
    ui.add(egui::Slider::new(&mut s.light_samples, 0..=256).text("N_L light samples"));
    ui.add(egui::Slider::new(&mut s.brdf_samples, 0..=256).text("N_B BRDF samples"));
    if s.light_samples + s.brdf_samples == 0 {
        s.light_samples = 1;
    }
    ui.horizontal(|ui| {
        ui.label("strategy");
        for &st in Strategy::value_variants() {
            ui.selectable_value(&mut s.strategy, st, st.to_string());
        }
    });
    ui.horizontal(|ui| {
        ui.label("counts [I]");
        for &c in Counts::value_variants() {
            ui.selectable_value(&mut s.counts, c, c.to_string());
        }
    });
    ui.horizontal(|ui| {
        ui.label("MIS");
        for &h in Heuristic::value_variants() {
            ui.selectable_value(&mut s.mis, h, h.to_string());
        }
    });
    ui.horizontal(|ui| {
        ui.add(egui::DragValue::new(&mut s.seed).prefix("seed "));
        ui.checkbox(&mut s.pixel_offset, "per-pixel pool offset");
    });
    ui.checkbox(
        &mut s.material_budget,
        "material budget (diffuse: light only, mirror: BRDF only)",
    );
    let frame = settings.frame;
    ui.horizontal(|ui| {
        ui.checkbox(&mut settings.accumulate, "accumulate over frames");
        if settings.accumulate {
            ui.label(format!("{} frames", frame + 1));
        }
    });
    ui.horizontal(|ui| {
        ui.label("overlay [O]");
        egui::ComboBox::from_id_salt("overlay")
            .selected_text(settings.overlay.name())
            .show_ui(ui, |ui| {
                for o in Overlay::ALL {
                    ui.selectable_value(&mut settings.overlay, o, o.name());
                }
            });
    });
}

/// Returns true when the material changed.
fn material_ui(ui: &mut egui::Ui, name: &str, m: &mut EnvisMaterial) -> bool {
    let before = *m;
    ui.horizontal(|ui| {
        ui.label(name);
        let (albedo, alpha, exponent, specular) = match *m {
            EnvisMaterial::Lambert { albedo } => (albedo, 0.2, 150.0, 0.0),
            EnvisMaterial::Phong { albedo, exponent } => (albedo, 0.2, exponent, 1.0),
            EnvisMaterial::Ggx { albedo, alpha } => (albedo, alpha, 150.0, 1.0),
            EnvisMaterial::Mix {
                albedo,
                specular,
                alpha,
            } => (albedo, alpha, 150.0, specular),
        };
        egui::ComboBox::from_id_salt(name)
            .selected_text(match m {
                EnvisMaterial::Lambert { .. } => "diffuse",
                EnvisMaterial::Phong { .. } => "phong",
                EnvisMaterial::Ggx { .. } => "ggx",
                EnvisMaterial::Mix { .. } => "mix",
            })
            .show_ui(ui, |ui| {
                ui.selectable_value(m, EnvisMaterial::Lambert { albedo }, "diffuse");
                ui.selectable_value(m, EnvisMaterial::Phong { albedo, exponent }, "phong");
                ui.selectable_value(m, EnvisMaterial::Ggx { albedo, alpha }, "ggx");
                ui.selectable_value(
                    m,
                    EnvisMaterial::Mix {
                        albedo,
                        specular: specular.max(0.3),
                        alpha,
                    },
                    "mix",
                );
            });
    });
    match m {
        EnvisMaterial::Phong { exponent, .. } => {
            ui.add(
                egui::Slider::new(exponent, 0.0..=10000.0)
                    .logarithmic(true)
                    .text("exponent"),
            );
        }
        EnvisMaterial::Ggx { alpha, .. } => {
            ui.add(
                egui::Slider::new(alpha, 0.001..=1.0)
                    .logarithmic(true)
                    .text("alpha"),
            );
        }
        EnvisMaterial::Mix {
            alpha, specular, ..
        } => {
            ui.add(
                egui::Slider::new(alpha, 0.001..=1.0)
                    .logarithmic(true)
                    .text("alpha"),
            );
            ui.add(egui::Slider::new(specular, 0.0..=1.0).text("specular"));
        }
        EnvisMaterial::Lambert { .. } => {}
    }
    *m != before
}

fn debug_ui(ui: &mut egui::Ui, settings: &mut EnvisSettings, state: &mut DemoState) {
    ui.checkbox(&mut state.debug, "show the probed pixel's samples [D]");
    let Some((d, g, gpu)) = &state.pixel else {
        ui.label("right-click a pixel of an object");
        return;
    };
    if let Some(p) = settings.probe {
        ui.label(format!(
            "pixel ({}, {}), n = ({:.2}, {:.2}, {:.2})",
            p.x, p.y, g.n.x, g.n.y, g.n.z
        ));
    }
    ui.label(format!(
        "estimate: GPU ({:.3}, {:.3}, {:.3}), CPU twin ({:.3}, {:.3}, {:.3})",
        gpu.x, gpu.y, gpu.z, d.estimate.x, d.estimate.y, d.estimate.z
    ));
    egui::Grid::new("faces").striped(true).show(ui, |ui| {
        ui.label("face");
        for f in 0..6 {
            ui.label(crate::envmap::Face::from_index(f).name());
        }
        ui.end_row();
        ui.label("mu_f");
        for f in 0..6 {
            ui.label(format!("{:.3}", d.mu[f]));
        }
        ui.end_row();
        ui.label("N_f");
        for f in 0..6 {
            ui.label(format!("{:.2}", d.n_f[f]));
        }
        ui.end_row();
    });
    let count = |k| d.samples.iter().filter(|s| s.kind == k).count();
    ui.label(format!(
        "red (discarded) {}, green (used, cos > 0) {}, yellow (used, cos <= 0) {}",
        count(SampleKind::Discarded),
        count(SampleKind::Used),
        count(SampleKind::Wasted)
    ));
    if !state.debug {
        return;
    }
    // The unfolded cube cross with each pool sample at its face coordinates.
    let w = 320.0;
    let block = w / 4.0;
    let (rect, _) =
        ui.allocate_exact_size(egui::vec2(4.0 * block, 3.0 * block), egui::Sense::hover());
    let painter = ui.painter_at(rect);
    if let Some((_, tex)) = &state.cross {
        painter.image(
            tex.id(),
            rect,
            egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
            egui::Color32::WHITE,
        );
    }
    for &(bx, by) in &CROSS_BLOCKS {
        let r = egui::Rect::from_min_size(
            rect.min + egui::vec2(bx as f32 * block, by as f32 * block),
            egui::vec2(block, block),
        );
        painter.rect_stroke(
            r,
            0.0,
            egui::Stroke::new(1.0, egui::Color32::GRAY),
            egui::StrokeKind::Inside,
        );
    }
    for s in &d.samples {
        let (f, a, b) = dir_to_face_ab(s.dir);
        let (bx, by) = CROSS_BLOCKS[f];
        let p = rect.min
            + egui::vec2(
                (bx as f32 + 0.5 * (a + 1.0)) * block,
                (by as f32 + 0.5 * (b + 1.0)) * block,
            );
        painter.circle_filled(p, 2.5, egui_kind_color(s.kind));
    }
}

/// The scripted CI sequence: one step every few frames, a screenshot after each.
fn run_script(
    mut stream: ResMut<EnvMapStream>,
    mut state: ResMut<DemoState>,
    mut settings: ResMut<EnvisSettings>,
    mut objects: Query<&mut SceneObject>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    windows: Query<&Window, With<PrimaryWindow>>,
    cams: Query<(&Camera, &GlobalTransform), With<EnvisCamera>>,
    timings: Res<EnvisTimings>,
    counters: Res<EnvisCounters>,
    mut commands: Commands,
    mut exit: MessageWriter<AppExit>,
) {
    const WARMUP: u32 = 10;
    const STEP: u32 = 6;
    let Some(dir) = state.script.clone() else {
        return;
    };
    state.script_frame += 1;
    let f = state.script_frame;
    if f == 1 {
        // A still environment, so the screenshots differ only by what each step changed.
        stream.stream.playing = false;
    }
    if f < WARMUP || (f - WARMUP) % STEP != 0 {
        return;
    }
    let step = (f - WARMUP) / STEP;
    let shot = |commands: &mut Commands, name: &str| {
        commands
            .spawn(Screenshot::primary_window())
            .observe(save_to_disk(dir.join(name)));
    };
    let (w, h) = windows
        .single()
        .map(|w| (w.physical_width(), w.physical_height()))
        .unwrap_or((0, 0));
    match step {
        0 => shot(&mut commands, "start.png"),
        1 => {
            settings.sampling.counts = Counts::Integer;
        }
        2 => shot(&mut commands, "integer.png"),
        3 => settings.overlay = Overlay::EffectiveSamples,
        4 => shot(&mut commands, "overlay-samples.png"),
        5 => settings.overlay = Overlay::Wasted,
        6 => shot(&mut commands, "overlay-wasted.png"),
        7 => settings.overlay = Overlay::CountsDifference,
        8 => shot(&mut commands, "overlay-diff.png"),
        9 => {
            settings.overlay = Overlay::None;
            settings.sampling.counts = Counts::Fractional;
            // Probe a pixel on the sphere: its centre, projected (physical pixels).
            let scale = windows.single().map(|w| w.scale_factor()).unwrap_or(1.0);
            let p = cams
                .single()
                .ok()
                .and_then(|(c, t)| c.world_to_viewport(t, Vec3::new(-2.3, 1.0, 0.0)).ok())
                .unwrap_or(Vec2::new(w as f32 * 0.3, h as f32 * 0.5));
            settings.probe = Some((p * scale).as_uvec2());
            state.debug = true;
        }
        10 => shot(&mut commands, "debug-on.png"),
        11 => state.debug = false,
        12 => shot(&mut commands, "debug-off.png"),
        13 => {
            for mut o in &mut objects {
                if o.name == "sphere" {
                    o.material = EnvisMaterial::Ggx {
                        albedo: Vec3::splat(0.8),
                        alpha: 0.05,
                    };
                    if let Some(mut m) = materials.get_mut(&o.handle) {
                        *m = o.material.standard();
                    }
                }
            }
        }
        14 => shot(&mut commands, "brdf.png"),
        15 => {
            let report = serde_json::json!({
                "window": [w, h],
                "frames": f,
                "fps": state.fps,
                "timings_ms": timings.get(),
                "builds": counters.get(|c| &c.builds),
                "uploads": counters.get(|c| &c.uploads),
                "lighting_passes": counters.get(|c| &c.lighting_passes),
                "overlay_passes": counters.get(|c| &c.overlay_passes),
                "probe": state.pixel.as_ref().map(|(d, g, gpu)| serde_json::json!({
                    "normal": g.n, "gpu_estimate": gpu, "cpu_estimate": d.estimate,
                    "red": d.samples.iter().filter(|s| s.kind == SampleKind::Discarded).count(),
                    "green": d.samples.iter().filter(|s| s.kind == SampleKind::Used).count(),
                    "yellow": d.samples.iter().filter(|s| s.kind == SampleKind::Wasted).count(),
                })),
            });
            let _ = std::fs::write(
                dir.join("report.json"),
                serde_json::to_string_pretty(&report).expect("json") + "\n",
            );
        }
        16 => {
            exit.write(AppExit::Success);
        }
        _ => {}
    }
}
