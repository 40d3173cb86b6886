//! A scene file's `[animation]`: the sequence clock, the camera's orbit, objects' velocities,
//! the sky's clock and switches of the environment, and the scene posed at a time `t` (what
//! `envis sequence` renders frame by frame and `--time` renders once).

use super::{Scene, SceneFile};
use crate::envmap::load::EnvSource;
use crate::error::Result;
use glam::{Quat, Vec3};
use serde::Deserialize;

/// `[animation]` (every field optional).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnimationSpec {
    /// Frames per second of the sequence clock (frame `k` is at `k / fps` seconds).
    #[serde(default = "default_fps")]
    pub fps: f32,
    /// The camera's orbit about `camera.target`, around +Y, in degrees per second.
    #[serde(default)]
    pub orbit: f32,
    /// Switches of the environment (`[[animation.switch]]`): from `at` seconds on, the
    /// environment is `source`, a built-in sky's clock then running from `at`. A sun that jumps
    /// or a carousel's step: what `bench --suite motion` measures reuse following.
    #[serde(default)]
    pub switch: Vec<SwitchSpec>,
}

/// One `[[animation.switch]]`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SwitchSpec {
    /// Seconds, > 0.
    pub at: f32,
    /// As `environment.source`.
    pub source: String,
}

impl Default for AnimationSpec {
    fn default() -> Self {
        AnimationSpec {
            fps: default_fps(),
            orbit: 0.0,
            switch: Vec::new(),
        }
    }
}

impl AnimationSpec {
    /// The time of the latest switch at or before `t`, and its source (`None` before any).
    pub fn switch_at(&self, t: f32) -> Option<&SwitchSpec> {
        (self.switch.iter())
            .filter(|s| s.at <= t)
            .max_by(|a, b| a.at.total_cmp(&b.at))
    }
}

fn default_fps() -> f32 {
    30.0
}

impl SceneFile {
    /// The file's scene at time `t` seconds: the camera orbited, each object moved by its
    /// velocity, the environment the latest switch's, a built-in sky's clock advanced by
    /// `environment.speed` (hours per second, from the switch; a map from a file does not
    /// move). `t = 0` is the file as written.
    pub fn posed(&self, t: f32) -> SceneFile {
        let mut f = self.clone();
        if t == 0.0 {
            return f;
        }
        let angle = (self.animation.orbit * t).to_radians();
        if angle != 0.0 {
            let target = Vec3::from(f.camera.target);
            let p = Quat::from_rotation_y(angle) * (Vec3::from(f.camera.position) - target);
            f.camera.position = (target + p).to_array();
        }
        for o in &mut f.objects {
            o.position = (Vec3::from(o.position) + Vec3::from(o.velocity) * t).to_array();
        }
        let mut since = 0.0;
        if let Some(s) = self.animation.switch_at(t) {
            f.environment.source = s.source.clone();
            since = s.at;
        }
        let speed = self.environment.speed;
        if let (true, Ok(EnvSource::Sky { hours })) = (speed != 0.0, f.environment.source.parse()) {
            let h: f32 = hours + speed * (t - since);
            f.environment.source = format!("builtin:sky:{}", h.rem_euclid(24.0));
        }
        f
    }
}

impl Scene {
    /// This scene at time `t` seconds ([`SceneFile::posed`]).
    pub fn at_time(&self, t: f32) -> Result<Scene> {
        if !t.is_finite() {
            return Err(crate::error::Error::invalid(format!(
                "time {t} must be finite"
            )));
        }
        if t == 0.0 {
            return Ok(self.clone());
        }
        Scene::from_file(&self.path, self.file.posed(t))
    }

    /// Whether no shadow-casting object moves (every caster's velocity zero): the shadow
    /// geometry is then the same at every time.
    pub fn geometry_is_still(&self) -> bool {
        (self.objects.iter())
            .filter(|o| o.spec.cast_shadows)
            .all(|o| o.spec.velocity == [0.0; 3])
    }

    /// The time of frame `k` on the sequence clock.
    pub fn frame_time(&self, k: u32) -> f32 {
        k as f32 / self.file.animation.fps
    }

    /// Where object `id`'s points were `dt` seconds earlier than now (objects translate).
    pub fn earlier(&self, id: u32, p: Vec3, dt: f32) -> Vec3 {
        let v = self
            .objects
            .get(id as usize)
            .map_or(Vec3::ZERO, |o| Vec3::from(o.spec.velocity));
        p - v * dt
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A switch takes the environment over from its time on, a built-in sky's clock running from
    /// the switch; the latest switch wins; before any, the file's own.
    #[test]
    fn switches_take_over_the_environment_from_their_time() {
        let f: SceneFile = toml::from_str(
            r#"
[environment]
source = "builtin:sky:15"
speed = 1.0
[[animation.switch]]
at = 2.0
source = "sky.exr"
[[animation.switch]]
at = 0.5
source = "builtin:sky:10"
"#,
        )
        .unwrap();
        let at = |t: f32| f.posed(t).environment.source;
        assert_eq!(at(0.25), "builtin:sky:15.25");
        assert_eq!(at(0.5), "builtin:sky:10");
        assert_eq!(at(1.0), "builtin:sky:10.5");
        assert_eq!(at(3.0), "sky.exr");
    }
}
