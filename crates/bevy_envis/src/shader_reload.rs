//! `EnvisShaderReloadPlugin`: the lighting pass recompiled when its WGSL files change on disk,
//! for working on the shaders with an example or the demo running. The shaders are plain WGSL
//! modules concatenated (they are shared with the headless wgpu backend, which has no naga_oil
//! imports), so they cannot be Bevy file assets one by one: this polls the files' modification
//! times twice a second and, on a change, replaces the [`LightingSource`]; envis's compile thread
//! then compiles the new version beside the one in use (`programs::EnvisPrograms`), which it
//! replaces once compiled (an error is logged and the last good pipeline kept).

use super::programs::LightingSource;
use bevy::prelude::*;
use envis_wgpu::shaders;
use std::path::PathBuf;
use std::time::SystemTime;

/// Recompile the lighting pass when a file of `dir` changes.
pub struct EnvisShaderReloadPlugin {
    /// The shaders' folder (default: `envis_wgpu`'s `shaders/`,
    /// [`envis_wgpu::shaders::SHADER_DIR`]).
    pub dir: PathBuf,
}

impl Default for EnvisShaderReloadPlugin {
    fn default() -> Self {
        EnvisShaderReloadPlugin {
            dir: PathBuf::from(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../envis_wgpu/shaders"
            )),
        }
    }
}

#[derive(Resource)]
struct ShaderDir {
    dir: PathBuf,
    /// The newest modification time seen, and when the files were last checked.
    seen: Option<SystemTime>,
    timer: Timer,
}

impl Plugin for EnvisShaderReloadPlugin {
    fn build(&self, app: &mut App) {
        let seen = newest_change(&self.dir);
        app.insert_resource(ShaderDir {
            dir: self.dir.clone(),
            seen,
            timer: Timer::from_seconds(0.5, TimerMode::Repeating),
        })
        .add_systems(Update, reload_changed_shaders);
    }
}

/// The latest modification time of the lighting pass's files (`None` if one cannot be read).
fn newest_change(dir: &std::path::Path) -> Option<SystemTime> {
    shaders::LIGHTING_MODULES
        .iter()
        .map(|(name, _)| {
            std::fs::metadata(dir.join(name))
                .and_then(|m| m.modified())
                .ok()
        })
        .try_fold(SystemTime::UNIX_EPOCH, |a, t| Some(a.max(t?)))
}

fn reload_changed_shaders(
    time: Res<Time>,
    mut state: ResMut<ShaderDir>,
    source: Option<ResMut<LightingSource>>,
) {
    if !state.timer.tick(time.delta()).just_finished() {
        return;
    }
    let Some(mut source) = source else { return };
    let now = newest_change(&state.dir);
    if now.is_none() || now == state.seen {
        return;
    }
    state.seen = now;
    match shaders::lighting_source_from(&state.dir) {
        Ok(src) => {
            info!(
                "envis: {} changed: recompiling the lighting pass",
                state.dir.display()
            );
            source.wgsl = src.into();
            source.version += 1;
        }
        Err(e) => warn!("envis: cannot read {}: {e}", state.dir.display()),
    }
}
