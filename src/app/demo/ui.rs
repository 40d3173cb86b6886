//! The demo's egui panel: environment, sampling, materials, timings and the debug inset.

use super::debug_panel::debug_ui;
use super::*;

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
pub(super) fn panel(
    mut contexts: EguiContexts,
    mut cams: Query<
        (
            &mut EnvironmentSampling,
            &mut EnvisEnvironment,
            &mut bevy::camera::Exposure,
        ),
        With<DemoCamera>,
    >,
    mut stream: ResMut<EnvMapStream>,
    mut state: ResMut<DemoState>,
    frame: Res<EnvFrame>,
    timings: Res<EnvisTimings>,
    counters: Res<EnvisCounters>,
    mut objects: Query<&mut SceneObject>,
    mut materials: ResMut<Assets<EnvisMaterial>>,
    windows: Query<&Window, With<PrimaryWindow>>,
    diagnostics: Res<bevy::diagnostic::DiagnosticsStore>,
) -> Result {
    let ctx = contexts.ctx_mut()?.clone();
    if state.ui_scale > 0.0 && ctx.zoom_factor() != state.ui_scale {
        ctx.set_zoom_factor(state.ui_scale);
    }
    let Ok((mut settings, mut env, mut exposure)) = cams.single_mut() else {
        return Ok(());
    };
    if state
        .cross
        .as_ref()
        .is_none_or(|(g, _)| *g != frame.generation)
    {
        state.cross = Some((frame.generation, cross_texture(&ctx, &frame.map)));
    }
    egui::Window::new("envis").anchor(egui::Align2::RIGHT_TOP, [-8.0, 8.0]).default_width(320.0).show(&ctx, |ui| {
        egui::ScrollArea::vertical().show(ui, |ui| {
            ui.collapsing("Environment", |ui| environment_ui(ui, &mut stream, &mut env, &mut state));
            if settings.face_size != state.face_size {
                settings.face_size = state.face_size;
            }
            if ui.add(egui::Slider::new(&mut state.exposure, 0.01..=8.0).logarithmic(true).text("exposure")).changed() {
                *exposure = exposure_multiplier(state.exposure);
            }
            egui::CollapsingHeader::new("Sampling").default_open(true).show(ui, |ui| sampling_ui(ui, &mut settings));
            ui.collapsing("Materials", |ui| {
                for mut o in &mut objects {
                    if material_ui(ui, &o.name.clone(), &mut o.material)
                        && let Some(mut m) = materials.get_mut(&o.handle)
                    {
                        m.brdf = o.material;
                    }
                }
            });
            egui::CollapsingHeader::new("Timings").default_open(true).show(ui, |ui| {
                let t = timings.get();
                let f = |x: Option<f64>| x.map_or("n/a".to_string(), |v| format!("{v:.3} ms"));
                ui.label(format!("resample: GPU {}; distribution build: GPU {}; light pool: GPU {}; record: CPU {}", f(t.resample_gpu_ms), f(t.build_gpu_ms), f(t.pool_gpu_ms), f(t.build_cpu_ms)));
                ui.label(format!("lighting (G-buffer -> MIS): GPU {}, CPU {}", f(t.lighting_gpu_ms), f(t.lighting_cpu_ms)));
                let px = windows.single().map(|w| (w.physical_width() * w.physical_height()) as f64).unwrap_or(0.0);
                let budget = settings.samples_per_pixel() as f64;
                ui.label(format!("{:.1} FPS, sample budget {:.1} M samples/s", state.fps, px * budget * state.fps as f64 / 1e6));
                ui.label(format!("builds {}, image bytes uploaded {}, lighting passes {}", counters.get(|c| &c.builds), counters.get(|c| &c.image_bytes_uploaded), counters.get(|c| &c.lighting_passes)));
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
    let budget = settings.samples_per_pixel();
    if let Some(legend) = settings.overlay.legend(budget) {
        egui::Window::new(format!("overlay: {}", settings.overlay.name()))
            .anchor(egui::Align2::CENTER_BOTTOM, [0.0, -8.0])
            .resizable(false)
            .show(&ctx, |ui| legend_ui(ui, &legend));
    }
    egui::Window::new("sample debug (right-click a pixel, D)")
        .anchor(egui::Align2::LEFT_BOTTOM, [8.0, -8.0])
        .default_width(330.0)
        .show(&ctx, |ui| debug_ui(ui, &mut settings, &mut state));
    Ok(())
}

/// The overlay's colour bar with five labelled ticks and what it measures.
fn legend_ui(ui: &mut egui::Ui, legend: &crate::app::OverlayLegend) {
    const W: f32 = 320.0;
    const STEPS: usize = 64;
    let (rect, _) = ui.allocate_exact_size(egui::vec2(W, 16.0), egui::Sense::hover());
    let painter = ui.painter_at(rect);
    for k in 0..STEPS {
        let c = crate::app::heat((k as f32 + 0.5) / STEPS as f32);
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

fn environment_ui(
    ui: &mut egui::Ui,
    stream: &mut EnvMapStream,
    env: &mut EnvisEnvironment,
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
    if let Some(mut h) = s.sky_hours()
        && ui
            .add(egui::Slider::new(&mut h, 0.0..=24.0).text("time of day (h)"))
            .changed()
    {
        s.set_sky_hours(h);
    }
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
    });
    ui.label(format!(
        "{:?}, generation {}",
        stream.stream.stats(),
        stream.stream.generation()
    ));
}

fn sampling_ui(ui: &mut egui::Ui, settings: &mut EnvironmentSampling) {
    // Edited on a copy, so that Bevy's change detection sees a change only when there is one.
    let mut core = *settings;
    let s = &mut core;
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
            ui.selectable_value(&mut s.heuristic, h, h.to_string());
        }
    });
    ui.horizontal(|ui| {
        ui.add(egui::DragValue::new(&mut s.seed).prefix("seed "));
    });
    ui.horizontal(|ui| {
        ui.label("pool layout");
        for &l in PoolLayout::value_variants() {
            ui.selectable_value(&mut s.pool_layout, l, l.to_string());
        }
        if s.pool_layout == PoolLayout::Blocks {
            ui.add(
                egui::DragValue::new(&mut s.pool_blocks)
                    .range(1..=64)
                    .prefix("K "),
            );
        }
    });
    ui.horizontal(|ui| {
        ui.label("tiles per face side");
        ui.add(egui::DragValue::new(&mut s.tiles).range(1..=crate::sampling::MAX_TILES));
        if s.tiles > 1 {
            ui.label("counts per");
            for &c in crate::sampling::TileCounts::value_variants() {
                ui.selectable_value(&mut s.tile_counts, c, c.to_string());
            }
        }
    });
    ui.checkbox(
        &mut s.material_budget,
        "material budget (diffuse: light only, mirror: BRDF only)",
    );
    if core != *settings {
        *settings = core;
    }
    ui.checkbox(
        &mut settings.accumulate,
        "accumulate over frames (restarts when anything changes)",
    );
    ui.horizontal(|ui| {
        ui.label("environment shadows");
        for &v in crate::visibility::ShadowRays::value_variants() {
            ui.selectable_value(&mut settings.shadows, v, v.to_string());
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
fn material_ui(ui: &mut egui::Ui, name: &str, m: &mut EnvisBrdf) -> bool {
    let before = *m;
    ui.horizontal(|ui| {
        ui.label(name);
        let (albedo, alpha, exponent, specular) = match *m {
            EnvisBrdf::Lambert { albedo } => (albedo, 0.2, 150.0, 0.0),
            EnvisBrdf::Phong { albedo, exponent } => (albedo, 0.2, exponent, 1.0),
            EnvisBrdf::Ggx { albedo, alpha } => (albedo, alpha, 150.0, 1.0),
            EnvisBrdf::Mix {
                albedo,
                specular,
                alpha,
            } => (albedo, alpha, 150.0, specular),
        };
        egui::ComboBox::from_id_salt(name)
            .selected_text(match m {
                EnvisBrdf::Lambert { .. } => "diffuse",
                EnvisBrdf::Phong { .. } => "phong",
                EnvisBrdf::Ggx { .. } => "ggx",
                EnvisBrdf::Mix { .. } => "mix",
            })
            .show_ui(ui, |ui| {
                ui.selectable_value(m, EnvisBrdf::Lambert { albedo }, "diffuse");
                ui.selectable_value(m, EnvisBrdf::Phong { albedo, exponent }, "phong");
                ui.selectable_value(m, EnvisBrdf::Ggx { albedo, alpha }, "ggx");
                ui.selectable_value(
                    m,
                    EnvisBrdf::Mix {
                        albedo,
                        specular: specular.max(0.3),
                        alpha,
                    },
                    "mix",
                );
            });
    });
    match m {
        EnvisBrdf::Phong { exponent, .. } => {
            ui.add(
                egui::Slider::new(exponent, 0.0..=10000.0)
                    .logarithmic(true)
                    .text("exponent"),
            );
        }
        EnvisBrdf::Ggx { alpha, .. } => {
            ui.add(
                egui::Slider::new(alpha, 0.001..=1.0)
                    .logarithmic(true)
                    .text("alpha"),
            );
        }
        EnvisBrdf::Mix {
            alpha, specular, ..
        } => {
            ui.add(
                egui::Slider::new(alpha, 0.001..=1.0)
                    .logarithmic(true)
                    .text("alpha"),
            );
            ui.add(egui::Slider::new(specular, 0.0..=1.0).text("specular"));
        }
        EnvisBrdf::Lambert { .. } => {}
    }
    *m != before
}
