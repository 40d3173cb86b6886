//! The paper's sample-debug view: the CPU twin classifies the probed pixel's pool samples
//! (red: discarded by face weighting, green: used, yellow: used below the horizon) and draws
//! them on the sky.

use super::*;
use envis::envmap::resample::{SourceImage, bevy_cube_layers};

/// Recompute the CPU twin's view of the probed pixel when the probe, the frame or the settings change.
pub(super) fn update_debug_view(
    frame: Res<EnvFrame>,
    cams: Query<&EnvironmentSampling, With<DemoCamera>>,
    probe: Res<EnvisProbe>,
    geometry: Res<bevy_envis::shadows::ShadowGeometry>,
    mut state: ResMut<DemoState>,
) {
    let Some(p) = *probe.lock().expect("probe") else {
        return;
    };
    let Ok(sampling) = cams.single() else { return };
    // The seed the GPU used for the probed frame (it changes per frame while accumulating).
    let s = Settings {
        seed: p.seed,
        ..*sampling
    };
    let key = (
        frame.generation,
        s,
        p.pixel_index,
        p.gpixel.n,
        geometry.placement,
    );
    if state.key == Some(key) {
        return;
    }
    // As the GPU: densities from the image resampled to the distribution's face size, radiance
    // from the image itself.
    let source = SourceImage::new_cube(bevy_cube_layers(&frame.map));
    let coarse = source.to_cube(sampling.face_size);
    let fine = |d: Vec3| source.radiance_nearest(d);
    let mut fd = FrameData::prepare(&coarse, &s).with_fine(&fine);
    // The same shadow rays as the GPU, against the same meshes (the demo's map is unrotated, so
    // its frame is the world's).
    if p.point.is_some() {
        fd.occluder = Some(&geometry.bvh);
    }
    let d = envis::render::debug_pixel_at(&fd, &s, &p.gpixel, p.point, p.pixel_index);
    state.pixel = Some((d, p.gpixel, p.estimate));
    state.key = Some(key);
}

/// The probed pixel's pool samples on the sky, far away in their directions.
pub(super) fn draw_debug_samples(
    state: Res<DemoState>,
    cams: Query<&Transform, With<DemoCamera>>,
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

pub(super) fn kind_color(k: SampleKind) -> Color {
    match k {
        SampleKind::Discarded => Color::srgb(1.0, 0.0, 0.0),
        SampleKind::Used => Color::srgb(0.0, 1.0, 0.0),
        SampleKind::Wasted => Color::srgb(1.0, 1.0, 0.0),
        SampleKind::Blocked => Color::srgb(0.2, 0.4, 1.0),
    }
}

pub(super) fn egui_kind_color(k: SampleKind) -> egui::Color32 {
    match k {
        SampleKind::Discarded => egui::Color32::from_rgb(255, 0, 0),
        SampleKind::Used => egui::Color32::from_rgb(0, 255, 0),
        SampleKind::Wasted => egui::Color32::from_rgb(255, 255, 0),
        SampleKind::Blocked => egui::Color32::from_rgb(50, 100, 255),
    }
}
