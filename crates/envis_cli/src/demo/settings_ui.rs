//! The panel's editors of the camera's sampling settings ("Sampling") and of an object's BRDF
//! ("Materials").

use super::*;

/// The "Sampling" section: sample counts and strategy, pool and tiles, then how the view shows
/// the result.
pub(super) fn sampling_ui(ui: &mut egui::Ui, settings: &mut EnvironmentSampling) {
    // Edited on a copy, so that Bevy's change detection sees a change only when there is one.
    let mut core = *settings;
    sample_strategy_ui(ui, &mut core);
    pool_and_tiles_ui(ui, &mut core);
    ui.checkbox(
        &mut core.material_budget,
        "material budget (diffuse: light only, mirror: BRDF only)",
    );
    if core != *settings {
        *settings = core;
    }
    view_options_ui(ui, settings);
}

/// The "Resampling" section: reservoir resampling across pixels and frames on or off (the
/// component added to or removed from the camera), and its settings.
pub(super) fn resampling_ui(
    ui: &mut egui::Ui,
    commands: &mut Commands,
    (camera, current): (Entity, Option<Mut<EnvironmentResampling>>),
) {
    let mut on = current.is_some();
    if ui
        .checkbox(
            &mut on,
            "resampling (ReSTIR: candidates reused across pixels and frames) [R]",
        )
        .changed()
    {
        set_resampling(commands, camera, on);
    }
    let Some(mut r) = current else { return };
    let mut edit = *r;
    ui.checkbox(&mut edit.temporal, "temporal reuse");
    ui.add(
        egui::Slider::new(&mut edit.spatial, 0..=envis_wgpu::resampling::MAX_SPATIAL)
            .text("spatial neighbours"),
    );
    ui.add(egui::Slider::new(&mut edit.max_history, 1..=64).text("max history"));
    ui.checkbox(
        &mut edit.unbiased,
        "unbiased (pairwise MIS, visibility in the reuse)",
    );
    if ui.button("reset history").clicked() {
        edit.reset = true;
    }
    if edit != *r {
        *r = edit;
    }
}

/// Light and BRDF sample counts, the strategy, how counts are rounded, the MIS heuristic and
/// the seed.
fn sample_strategy_ui(ui: &mut egui::Ui, s: &mut EnvironmentSampling) {
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
}

/// The light pool's layout (and its block count) and the tiles per face side (and what their
/// counts are per).
fn pool_and_tiles_ui(ui: &mut egui::Ui, s: &mut EnvironmentSampling) {
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
        ui.add(egui::DragValue::new(&mut s.tiles).range(1..=envis::sampling::MAX_TILES));
        if s.tiles > 1 {
            ui.label("counts per");
            for &c in envis::sampling::TileCounts::value_variants() {
                ui.selectable_value(&mut s.tile_counts, c, c.to_string());
            }
        }
    });
}

/// Accumulation, environment shadows and the overlay, edited on the settings directly.
fn view_options_ui(ui: &mut egui::Ui, settings: &mut EnvironmentSampling) {
    ui.checkbox(
        &mut settings.accumulate,
        "accumulate over frames (restarts when anything changes)",
    );
    ui.horizontal(|ui| {
        ui.label("environment shadows");
        for &v in envis::visibility::ShadowRays::value_variants() {
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
pub(super) fn material_ui(ui: &mut egui::Ui, name: &str, m: &mut EnvisBrdf) -> bool {
    let before = *m;
    ui.horizontal(|ui| {
        ui.label(name);
        brdf_kind_ui(ui, name, m);
    });
    brdf_parameters_ui(ui, m);
    *m != before
}

/// The BRDF kind's combo box; a new kind keeps the albedo and what parameters it shares.
fn brdf_kind_ui(ui: &mut egui::Ui, name: &str, m: &mut EnvisBrdf) {
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
}

/// The sliders of the BRDF kind's own parameters (none for diffuse).
fn brdf_parameters_ui(ui: &mut egui::Ui, m: &mut EnvisBrdf) {
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
}
