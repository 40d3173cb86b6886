//! The demo's egui panel: environment, sampling, materials, timings and the debug inset.

use super::debug_panel::debug_ui;
use super::settings_ui::{material_ui, resampling_ui, sampling_ui};
use super::*;
use bevy::ecs::system::SystemParam;

/// The environment as a small 4:3 cross image (Reinhard-tonemapped) for the panel's inset.
fn cross_texture(ctx: &egui::Context, map: &CubeMap) -> egui::TextureHandle {
    let n = map.size.min(48);
    let small = if map.size == n {
        map.clone()
    } else {
        envis::envmap::resample::resize_cube(map, n)
    };
    let img = envis::envmap::cube_to_cross(&small);
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

/// The panel's read-only sources for the "Timings" section: timings, counters, the window's
/// size and Bevy's diagnostics.
#[derive(SystemParam)]
pub(super) struct PanelStats<'w, 's> {
    timings: Res<'w, EnvisTimings>,
    counters: Res<'w, EnvisCounters>,
    windows: Query<'w, 's, &'static Window, With<PrimaryWindow>>,
    diagnostics: Res<'w, bevy::diagnostic::DiagnosticsStore>,
    /// The demo camera once envis lit it (`EnvisLightReady`).
    ready: Query<'w, 's, (), (With<DemoCamera>, With<bevy_envis::EnvisLightReady>)>,
}

/// The scene's objects and their material assets, edited by the "Materials" section.
#[derive(SystemParam)]
pub(super) struct PanelObjects<'w, 's> {
    objects: Query<'w, 's, &'static mut SceneObject>,
    materials: ResMut<'w, Assets<EnvisMaterial>>,
}

/// The demo camera's components the panel edits, kept as `Mut` (Bevy's change detection sees a
/// write wherever a section takes `&mut` of one, as the single system did before).
struct CameraEdits<'a> {
    entity: Entity,
    settings: Mut<'a, EnvironmentSampling>,
    resampling: Option<Mut<'a, EnvironmentResampling>>,
    env: Mut<'a, EnvisEnvironment>,
    exposure: Mut<'a, bevy::camera::Exposure>,
}

/// The demo camera's components as the panel queries them.
type CameraData = (
    Entity,
    &'static mut EnvironmentSampling,
    Option<&'static mut EnvironmentResampling>,
    &'static mut EnvisEnvironment,
    &'static mut bevy::camera::Exposure,
);

/// The demo's egui windows: the "envis" panel, the overlay's legend and the sample-debug inset.
#[allow(
    clippy::too_many_arguments,
    reason = "a Bevy system's parameters are the data it touches"
)]
pub(super) fn panel(
    mut contexts: EguiContexts,
    mut cams: Query<CameraData, With<DemoCamera>>,
    mut commands: Commands,
    mut stream: ResMut<EnvMapStream>,
    mut state: ResMut<DemoState>,
    frame: Res<EnvFrame>,
    mut objects: PanelObjects,
    stats: PanelStats,
) -> Result {
    let ctx = contexts.ctx_mut()?.clone();
    if state.ui_scale > 0.0 && ctx.zoom_factor() != state.ui_scale {
        ctx.set_zoom_factor(state.ui_scale);
    }
    let Ok((entity, settings, resampling, env, exposure)) = cams.single_mut() else {
        return Ok(());
    };
    let mut cam = CameraEdits {
        entity,
        settings,
        resampling,
        env,
        exposure,
    };
    if cross_is_stale(&state, &frame) {
        state.cross = Some((frame.generation, cross_texture(&ctx, &frame.map)));
    }
    egui::Window::new("envis")
        .anchor(egui::Align2::RIGHT_TOP, [-8.0, 8.0])
        .default_width(320.0)
        .show(&ctx, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| {
                envis_window_ui(ui, &mut cam, &mut stream, &mut state, &mut objects, &stats);
                egui::CollapsingHeader::new("Resampling")
                    .default_open(true)
                    .show(ui, |ui| {
                        resampling_ui(ui, &mut commands, (cam.entity, cam.resampling.take()))
                    });
            });
        });
    overlay_legend_window(&ctx, &cam.settings);
    egui::Window::new("sample debug (right-click a pixel, D)")
        .anchor(egui::Align2::LEFT_BOTTOM, [8.0, -8.0])
        .default_width(330.0)
        .show(&ctx, |ui| debug_ui(ui, &mut cam.settings, &mut state));
    Ok(())
}

/// Whether the inset's cross image is missing or of an older environment frame.
fn cross_is_stale(state: &DemoState, frame: &EnvFrame) -> bool {
    state
        .cross
        .as_ref()
        .is_none_or(|(g, _)| *g != frame.generation)
}

/// The "envis" window's sections, top to bottom, and the stream's latest messages.
fn envis_window_ui(
    ui: &mut egui::Ui,
    cam: &mut CameraEdits,
    // A `ResMut`: the stream is marked changed only while the Environment section is open.
    stream: &mut ResMut<EnvMapStream>,
    state: &mut DemoState,
    objects: &mut PanelObjects,
    stats: &PanelStats,
) {
    if stats.ready.is_empty() {
        // Until envis's programs are compiled (seconds on a CPU driver), Bevy's own image shows.
        let waiting = "envis is compiling its shaders: Bevy's own lighting until it is ready";
        ui.colored_label(egui::Color32::from_rgb(255, 170, 60), waiting);
    }
    ui.collapsing("Environment", |ui| {
        environment_ui(ui, stream, &mut cam.env, state)
    });
    if cam.settings.face_size != state.face_size {
        cam.settings.face_size = state.face_size;
    }
    if ui
        .add(
            egui::Slider::new(&mut state.exposure, 0.01..=8.0)
                .logarithmic(true)
                .text("exposure"),
        )
        .changed()
    {
        *cam.exposure = exposure_multiplier(state.exposure);
    }
    egui::CollapsingHeader::new("Sampling")
        .default_open(true)
        .show(ui, |ui| sampling_ui(ui, &mut cam.settings));
    ui.collapsing("Materials", |ui| materials_ui(ui, objects));
    egui::CollapsingHeader::new("Timings")
        .default_open(true)
        .show(ui, |ui| timings_ui(ui, stats, &cam.settings, state.fps));
    for m in stream.log.iter().rev().take(3) {
        ui.colored_label(egui::Color32::from_rgb(255, 170, 60), m);
    }
}

/// One row per object; an edited material is written to its asset too.
fn materials_ui(ui: &mut egui::Ui, objects: &mut PanelObjects) {
    for mut o in &mut objects.objects {
        if material_ui(ui, &o.name.clone(), &mut o.material)
            && let Some(mut m) = objects.materials.get_mut(&o.handle)
        {
            m.brdf = o.material;
        }
    }
}

/// GPU and CPU times of envis's passes, the frame rate and sample budget, the counters and
/// Bevy's own passes.
fn timings_ui(ui: &mut egui::Ui, stats: &PanelStats, settings: &EnvironmentSampling, fps: f32) {
    let t = stats.timings.get();
    let f = |x: Option<f64>| x.map_or("n/a".to_string(), |v| format!("{v:.3} ms"));
    ui.label(format!(
        "resample: GPU {}; distribution build: GPU {}; light pool: GPU {}; record: CPU {}",
        f(t.resample_gpu_ms),
        f(t.build_gpu_ms),
        f(t.pool_gpu_ms),
        f(t.build_cpu_ms)
    ));
    ui.label(format!(
        "lighting (G-buffer -> MIS): GPU {}, CPU {}",
        f(t.lighting_gpu_ms),
        f(t.lighting_cpu_ms)
    ));
    if t.resampling_cpu_ms.is_some() {
        ui.label(format!(
            "resampling (gather, candidates, reuse, shading): GPU {}, CPU {}",
            f(t.resampling_gpu_ms),
            f(t.resampling_cpu_ms)
        ));
    }
    let px = stats
        .windows
        .single()
        .map(|w| (w.physical_width() * w.physical_height()) as f64)
        .unwrap_or(0.0);
    let budget = settings.samples_per_pixel() as f64;
    ui.label(format!(
        "{:.1} FPS, sample budget {:.1} M samples/s",
        fps,
        px * budget * fps as f64 / 1e6
    ));
    let counters = &stats.counters;
    ui.label(format!(
        "builds {}, image bytes uploaded {}, lighting passes {}",
        counters.get(|c| &c.builds),
        counters.get(|c| &c.image_bytes_uploaded),
        counters.get(|c| &c.lighting_passes)
    ));
    ui.label("overlays run inside the lighting pass (no pass of their own)");
    bevy_passes_ui(ui, &stats.diagnostics);
}

/// Bevy's passes' GPU times from its render diagnostics, slowest first (the prepass writes the
/// G-buffer).
fn bevy_passes_ui(ui: &mut egui::Ui, diagnostics: &bevy::diagnostic::DiagnosticsStore) {
    let mut bevy_passes: Vec<(String, f64)> = diagnostics
        .iter()
        .filter(|d| {
            d.path().as_str().starts_with("render/") && d.path().as_str().ends_with("/elapsed_gpu")
        })
        .filter_map(|d| {
            d.smoothed().map(|v| {
                let path = d.path().as_str();
                let name = path.trim_start_matches("render/");
                (name.trim_end_matches("/elapsed_gpu").to_string(), v)
            })
        })
        .collect();
    bevy_passes.sort_by(|a, b| b.1.total_cmp(&a.1));
    egui::CollapsingHeader::new(format!("Bevy passes ({})", bevy_passes.len())).show(ui, |ui| {
        for (name, ms) in bevy_passes.iter().take(12) {
            ui.label(format!("{name}: {ms:.3} ms GPU"));
        }
    });
}

/// The active overlay's legend in its own window at the bottom (none for no overlay).
fn overlay_legend_window(ctx: &egui::Context, settings: &EnvironmentSampling) {
    let budget = settings.samples_per_pixel();
    if let Some(legend) = bevy_envis::overlay_legend(settings.overlay, budget) {
        egui::Window::new(format!("overlay: {}", settings.overlay.name()))
            .anchor(egui::Align2::CENTER_BOTTOM, [0.0, -8.0])
            .resizable(false)
            .show(ctx, |ui| legend_ui(ui, &legend));
    }
}

/// The overlay's colour bar with five labelled ticks and what it measures.
fn legend_ui(ui: &mut egui::Ui, legend: &bevy_envis::OverlayLegend) {
    const W: f32 = 320.0;
    const STEPS: usize = 64;
    let (rect, _) = ui.allocate_exact_size(egui::vec2(W, 16.0), egui::Sense::hover());
    let painter = ui.painter_at(rect);
    for k in 0..STEPS {
        let c = bevy_envis::heat((k as f32 + 0.5) / STEPS as f32);
        let x0 = rect.left() + W * k as f32 / STEPS as f32;
        let cell = egui::Rect::from_min_max(
            egui::pos2(x0, rect.top()),
            egui::pos2(x0 + W / STEPS as f32 + 0.5, rect.bottom()),
        );
        let rgb = c.to_array().map(|v| (v * 255.0).round() as u8);
        painter.rect_filled(cell, 0.0, egui::Color32::from_rgb(rgb[0], rgb[1], rgb[2]));
    }
    // Tick labels under the bar, each at its value's position.
    let (ticks, _) = ui.allocate_exact_size(egui::vec2(W, 14.0), egui::Sense::hover());
    let font = egui::FontId::proportional(12.0);
    for k in 0..5 {
        let v = legend.full_scale * k as f32 / 4.0;
        // Whole numbers as such, others to one decimal (6.3%, not 6%).
        let digits = if v.fract() == 0.0 { 0 } else { 1 };
        let unit = if legend.unit == "%" { "%" } else { "" };
        let text = format!("{v:.digits$}{unit}");
        let align = match k {
            0 => egui::Align2::LEFT_TOP,
            4 => egui::Align2::RIGHT_TOP,
            _ => egui::Align2::CENTER_TOP,
        };
        let pos = egui::pos2(ticks.left() + W * k as f32 / 4.0, ticks.top());
        let color = ui.visuals().text_color();
        ui.painter().text(pos, align, text, font.clone(), color);
    }
    ui.label(format!("{} ({})", legend.measures, legend.unit));
}

/// The "Environment" section: playback, background, distribution face size and the source.
fn environment_ui(
    ui: &mut egui::Ui,
    stream: &mut EnvMapStream,
    env: &mut EnvisEnvironment,
    state: &mut DemoState,
) {
    playback_ui(ui, &mut stream.stream);
    ui.checkbox(
        &mut env.show_background,
        "show the environment behind objects",
    );
    let mut face = state.face_size;
    ui.add(
        egui::Slider::new(&mut face, 8..=1024)
            .logarithmic(true)
            .text("distribution face size"),
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
            open_source(stream, state, face);
        }
    });
    ui.label(format!(
        "{:?}, generation {}",
        stream.stream.stats(),
        stream.stream.generation()
    ));
}

/// Play / pause, the playback speed and, for the built-in sky, the time of day.
fn playback_ui(ui: &mut egui::Ui, s: &mut envis::stream::EnvStream) {
    ui.horizontal(|ui| {
        if ui
            .button(if s.playing { "pause" } else { "play" })
            .clicked()
        {
            s.playing = !s.playing;
        }
        ui.add(egui::Slider::new(&mut s.speed, 0.0..=8.0).text("speed"));
    });
    if let Some(mut h) = s.sky_hours()
        && ui
            .add(egui::Slider::new(&mut h, 0.0..=24.0).text("time of day (h)"))
            .changed()
    {
        s.set_sky_hours(h);
    }
}

/// Switch the stream to the typed source (the current one when empty) at distribution face
/// size `face`; a source that does not parse goes to the log.
fn open_source(stream: &mut EnvMapStream, state: &mut DemoState, face: usize) {
    let src = if state.env_text.trim().is_empty() {
        Ok(stream.stream.source().clone())
    } else {
        StreamSource::parse(state.env_text.trim())
    };
    match src {
        Ok(src) => {
            if stream.switch(src, stream_face_size(face)) {
                state.face_size = face;
            }
        }
        Err(e) => stream.log.push(format!("{e}")),
    }
}
