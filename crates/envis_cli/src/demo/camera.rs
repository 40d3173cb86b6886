//! The demo's orbit camera and input: left-drag orbits, the wheel zooms, right-click probes a
//! pixel; keys `I` (integer / fractional counts), `O` (overlays), `D` (debug view).

use super::*;

#[derive(Component)]
pub(super) struct Orbit {
    pub(super) yaw: f32,
    pub(super) pitch: f32,
    pub(super) distance: f32,
    pub(super) target: Vec3,
}

fn egui_wants_pointer(contexts: &mut EguiContexts) -> bool {
    contexts
        .ctx_mut()
        .map(|c| c.egui_wants_pointer_input() || c.is_pointer_over_egui())
        .unwrap_or(false)
}

pub(super) fn orbit_camera(
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

pub(super) fn keys(
    keys: Res<ButtonInput<KeyCode>>,
    mut cams: Query<
        (Entity, &mut EnvironmentSampling, Has<EnvironmentResampling>),
        With<DemoCamera>,
    >,
    mut commands: Commands,
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
    let Ok((camera, mut settings, resampling)) = cams.single_mut() else {
        return;
    };
    if keys.just_pressed(KeyCode::KeyR) {
        set_resampling(&mut commands, camera, !resampling);
    }
    if keys.just_pressed(KeyCode::KeyI) {
        settings.counts = if settings.counts == Counts::Fractional {
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
pub(super) fn pick_pixel(
    mut contexts: EguiContexts,
    buttons: Res<ButtonInput<MouseButton>>,
    windows: Query<&Window, With<PrimaryWindow>>,
    mut cams: Query<&mut EnvironmentSampling, With<DemoCamera>>,
    mut state: ResMut<DemoState>,
) {
    if egui_wants_pointer(&mut contexts) || !buttons.just_pressed(MouseButton::Right) {
        return;
    }
    let Ok(w) = windows.single() else { return };
    if let (Some(p), Ok(mut settings)) = (w.physical_cursor_position(), cams.single_mut()) {
        settings.probe = Some(UVec2::new(p.x as u32, p.y as u32));
        state.debug = true;
    }
}
