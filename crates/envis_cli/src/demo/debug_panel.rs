//! The panel's debug inset: the probed pixel's G-buffer, its face weights and counts, and its
//! samples drawn on the cube's unfolded faces (the red / green / yellow view's legend).

use super::debug_view::egui_kind_color;
use super::*;

pub(super) fn debug_ui(
    ui: &mut egui::Ui,
    settings: &mut EnvironmentSampling,
    state: &mut DemoState,
) {
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
    face_grid_ui(ui, d);
    let count = |k| d.samples.iter().filter(|s| s.kind == k).count();
    ui.label(format!(
        "red (discarded) {}, green (used, cos > 0) {}, yellow (used, cos <= 0) {}, blue (used, blocked) {}",
        count(SampleKind::Discarded),
        count(SampleKind::Used),
        count(SampleKind::Wasted),
        count(SampleKind::Blocked)
    ));
    if !state.debug {
        return;
    }
    draw_cross(ui, state.cross.as_ref().map(|(_, tex)| tex), d);
}

/// The pixel's per-face table: each face's weight `mu_f` and sample count `N_f`.
fn face_grid_ui(ui: &mut egui::Ui, d: &PixelDebug) {
    egui::Grid::new("faces").striped(true).show(ui, |ui| {
        ui.label("face");
        for f in 0..6 {
            ui.label(envis::envmap::Face::from_index(f).name());
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
}

/// The unfolded cube cross (the environment's `cross` image, when there is one) with each pool
/// sample at its face coordinates.
fn draw_cross(ui: &mut egui::Ui, cross: Option<&egui::TextureHandle>, d: &PixelDebug) {
    let w = 320.0;
    let block = w / 4.0;
    let (rect, _) =
        ui.allocate_exact_size(egui::vec2(4.0 * block, 3.0 * block), egui::Sense::hover());
    let painter = ui.painter_at(rect);
    if let Some(tex) = cross {
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
    draw_tiles(&painter, rect.min, block, d);
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

/// The tiles of each face on the cube cross (`--tiles K`): the tiles the pixel weights
/// (`N_t > 0`) outlined in white, the ones it skips (wholly below its horizon, or dark) in grey.
fn draw_tiles(painter: &egui::Painter, origin: egui::Pos2, block: f32, d: &PixelDebug) {
    if d.tiles <= 1 {
        return;
    }
    let grid = envis::sampling::TileGrid::new(d.face_size, d.tiles);
    let n = d.face_size as f32;
    for (r, &n_t) in d.n_t.iter().enumerate() {
        let (f, _, _) = grid.split(r);
        let (c0, c1, r0, r1) = grid.span(r);
        let (bx, by) = CROSS_BLOCKS[f];
        let at = |c: usize, r: usize| {
            origin
                + egui::vec2(
                    (bx as f32 + c as f32 / n) * block,
                    (by as f32 + r as f32 / n) * block,
                )
        };
        let stroke = if n_t > 0.0 {
            egui::Stroke::new(1.0, egui::Color32::WHITE)
        } else {
            egui::Stroke::new(0.5, egui::Color32::DARK_GRAY)
        };
        painter.rect_stroke(
            egui::Rect::from_two_pos(at(c0, r0), at(c1, r1)),
            0.0,
            stroke,
            egui::StrokeKind::Inside,
        );
    }
}
