//! What [`super::EnvisPlugin`] sets up by itself, and the camera set-ups it warns about once
//! instead of doing nothing (or counting the environment twice) silently.
//!
//! - Deferred by default: envis lights what is in the G-buffer, and a `StandardMaterial` writes
//!   it only on Bevy's deferred path, so the plugin makes `DefaultOpaqueRendererMethod::deferred()`
//!   the default, as Bevy Solari's plugin does.
//! - A camera with envis and Bevy's own environment light (`EnvironmentMapLight`,
//!   `GeneratedEnvironmentMapLight`, `AtmosphereEnvironmentMapLight`) is lit by both: the
//!   environment counts twice.
//! - [`EnvironmentSampling`] without [`EnvisEnvironment`] (nothing to sample) or the reverse
//!   (no sampling asked for) lights nothing.

use super::components::{EnvironmentSampling, EnvisEnvironment};
use bevy::light::AtmosphereEnvironmentMapLight;
use bevy::pbr::DefaultOpaqueRendererMethod;
use bevy::prelude::*;
use std::collections::HashSet;

/// Make deferred the default opaque renderer method, unless the app already chose deferred.
///
/// Bevy's `PbrPlugin` inserts its default (forward) when it is built, so a forward default cannot
/// be told apart from an app's explicit choice: an app that wants forward by default inserts
/// `DefaultOpaqueRendererMethod::forward()` *after* adding `EnvisPlugin` (its forward meshes are
/// then lit by Bevy alone, and [`super::coverage::warn_forward_meshes`] says so once). A single
/// material still chooses for itself with `opaque_render_method`.
pub fn default_to_deferred(app: &mut App) {
    let deferred = app
        .world()
        .get_resource::<DefaultOpaqueRendererMethod>()
        .is_some_and(is_deferred);
    if !deferred {
        app.insert_resource(DefaultOpaqueRendererMethod::deferred());
    }
}

/// Whether the default renderer method is deferred. The resource has no getter nor `PartialEq`
/// in Bevy 0.19: read its `Debug` form.
pub fn is_deferred(m: &DefaultOpaqueRendererMethod) -> bool {
    format!("{m:?}").contains("Deferred")
}

/// A camera set-up that lights wrongly or not at all.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SetupProblem {
    /// envis and Bevy's environment light on one camera: the environment is counted twice.
    TwoEnvironmentLights,
    /// `EnvironmentSampling` without `EnvisEnvironment`.
    NoEnvironment,
    /// `EnvisEnvironment` without `EnvironmentSampling`.
    NoSampling,
}

impl SetupProblem {
    /// What is wrong and the fix, in one line.
    pub fn message(self) -> &'static str {
        match self {
            SetupProblem::TwoEnvironmentLights => {
                "has both envis and Bevy's environment light (EnvironmentMapLight / \
                 GeneratedEnvironmentMapLight / AtmosphereEnvironmentMapLight): the environment \
                 is counted twice; remove one of them"
            }
            SetupProblem::NoEnvironment => {
                "has EnvironmentSampling but no EnvisEnvironment: envis has nothing to sample \
                 and lights nothing; add EnvisEnvironment::new(image)"
            }
            SetupProblem::NoSampling => {
                "has EnvisEnvironment but no EnvironmentSampling: envis lights nothing; add \
                 EnvironmentSampling::default()"
            }
        }
    }
}

/// The problems of one camera's set-up.
pub fn setup_problems(
    sampling: bool,
    environment: bool,
    bevy_environment: bool,
) -> Vec<SetupProblem> {
    let mut p = Vec::new();
    if sampling && environment && bevy_environment {
        p.push(SetupProblem::TwoEnvironmentLights);
    }
    if sampling && !environment {
        p.push(SetupProblem::NoEnvironment);
    }
    if environment && !sampling {
        p.push(SetupProblem::NoSampling);
    }
    p
}

/// Warn once per camera and problem, looking only at cameras whose components came or changed
/// (change detection: nothing is done on a frame where no camera changed).
#[allow(
    clippy::type_complexity,
    reason = "a Bevy query's filter names the components it watches"
)]
pub fn warn_camera_setup(
    cameras: Query<
        (
            Entity,
            Option<&Name>,
            Has<EnvironmentSampling>,
            Has<EnvisEnvironment>,
            Has<EnvironmentMapLight>,
            Has<GeneratedEnvironmentMapLight>,
            Has<AtmosphereEnvironmentMapLight>,
        ),
        (
            With<Camera>,
            Or<(
                Added<EnvironmentSampling>,
                Added<EnvisEnvironment>,
                Added<EnvironmentMapLight>,
                Added<GeneratedEnvironmentMapLight>,
                Added<AtmosphereEnvironmentMapLight>,
            )>,
        ),
    >,
    mut warned: Local<HashSet<(Entity, SetupProblem)>>,
    counters: Res<super::EnvisCounters>,
) {
    for (e, name, sampling, env, map, generated, atmosphere) in &cameras {
        for p in setup_problems(sampling, env, map || generated || atmosphere) {
            if warned.insert((e, p)) {
                let who = name.map_or_else(|| format!("{e}"), |n| format!("{n} ({e})"));
                warn!("envis: camera {who} {}", p.message());
                counters.bump(|c| &c.setup_warnings);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_camera_set_up_has_its_problems() {
        use SetupProblem::*;
        let cases = [
            ((false, false, false), vec![]),
            ((false, false, true), vec![]),
            ((true, true, false), vec![]),
            ((true, true, true), vec![TwoEnvironmentLights]),
            ((true, false, false), vec![NoEnvironment]),
            ((true, false, true), vec![NoEnvironment]),
            ((false, true, false), vec![NoSampling]),
            ((false, true, true), vec![NoSampling]),
        ];
        for ((s, e, b), want) in cases {
            assert_eq!(setup_problems(s, e, b), want, "{s} {e} {b}");
        }
    }
}
