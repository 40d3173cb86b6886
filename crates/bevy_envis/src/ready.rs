//! [`EnvisLightReady`]: the marker a camera carries from the first frame envis lit it, so a game
//! can keep its loading screen up until then (`docs/bevy.md`, "Ready to light").
//!
//! The render world's lighting pass reports each camera it lit in a frame ([`ReadyReport`],
//! shared by both worlds, with what the frame waited on); after each rendered frame the main
//! world adds the marker to the cameras lit in it and removes it from those that were not.
//!
//! A camera is first lit only once Bevy has drawn what envis's pass reads and adds to: its
//! pipeline cache has nothing left to compile (the prepass, the lighting-pass ids, the deferred
//! lighting, tonemapping), so the first lit frame is never envis's background over geometry Bevy
//! has not lit or identified yet. Where a pipeline never compiles (a shader that never loads),
//! envis waits [`BEVY_PIPELINES_WAIT`] for it and then lights the camera anyway, with a warning.

use super::components::EnvironmentSampling;
use bevy::pbr::deferred::DeferredLightingPipeline;
use bevy::prelude::*;
use bevy::render::render_resource::PipelineCache;
use bevy::render::{Render, RenderApp, RenderSystems};
use std::collections::{HashMap, HashSet};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// On a camera from the first frame envis lit it (its environment sampled and shaded, Bevy's own
/// passes ready under it); removed when a frame is not lit (the camera stopped sampling, its
/// environment cannot be used). Added by envis: query it, never insert it.
///
/// ```ignore
/// fn leave_loading_screen(ready: Query<(), (With<Camera3d>, Added<EnvisLightReady>)>) {
///     if !ready.is_empty() { /* hide the loading screen */ }
/// }
/// ```
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq, Reflect)]
#[reflect(Component, Default)]
pub struct EnvisLightReady;

/// How long envis waits, once it could light a camera, for Bevy's pipeline cache to finish
/// compiling before it lights the camera anyway (a pipeline whose shader never loads stays queued
/// for ever; Bevy's own take well under a second on a GPU and a few on lavapipe).
pub const BEVY_PIPELINES_WAIT: Duration = Duration::from_secs(10);

/// What the render world says about readiness, shared by both worlds (the render world runs on
/// its own thread, a frame behind): of its last frame, the cameras envis lit in it and whether
/// Bevy's pipelines were compiled; and, as they happen, envis's programs compiled.
#[derive(Resource, Clone, Default)]
pub struct ReadyReport {
    frames: Arc<Mutex<ReportFrames>>,
    programs: ProgramLog,
    /// When the render world first found Bevy's start-up pipelines compiled ([`BevyStarted`]).
    bevy_started: Arc<Mutex<Option<Instant>>>,
}

/// envis's programs queued and compiled, written by its compile thread as it goes.
#[derive(Clone, Default)]
pub struct ProgramLog(Arc<Mutex<ProgramEntries>>);

#[derive(Default)]
struct ProgramEntries {
    queued: usize,
    done: Vec<(super::programs::Program, Duration)>,
}

impl ProgramLog {
    pub(crate) fn queued(&self) {
        if let Ok(mut l) = self.0.lock() {
            l.queued += 1;
        }
    }

    pub(crate) fn done(&self, program: super::programs::Program, at: Duration) {
        if let Ok(mut l) = self.0.lock() {
            l.done.push((program, at));
        }
    }

    /// Every program queued so far has been compiled (well or not), and there was one.
    pub fn all_done(&self) -> bool {
        self.0
            .lock()
            .is_ok_and(|l| l.queued > 0 && l.done.len() >= l.queued)
    }

    /// The programs compiled so far, each with when it was, from the render world's start-up.
    pub fn done_so_far(&self) -> Vec<(super::programs::Program, Duration)> {
        self.0.lock().map(|l| l.done.clone()).unwrap_or_default()
    }
}

#[derive(Default)]
struct ReportFrames {
    /// Lit so far in the frame being rendered.
    current: HashSet<Entity>,
    last: LastFrame,
}

/// The last frame rendered to the end, as [`ReadyReport::last_frame`] gives it.
#[derive(Clone, Debug, Default)]
pub struct LastFrame {
    /// Frames rendered to the end so far (this one included).
    pub number: u64,
    /// The cameras (main-world entities) envis lit in it.
    pub lit: HashSet<Entity>,
}

impl ReadyReport {
    /// The lighting pass lit `camera` in this frame.
    pub(crate) fn lit(&self, camera: Entity) {
        if let Ok(mut f) = self.frames.lock() {
            f.current.insert(camera);
        }
    }

    /// The frame has been rendered: its cameras become the last frame's.
    fn end_frame(&self) {
        if let Ok(mut f) = self.frames.lock() {
            let lit = std::mem::take(&mut f.current);
            f.last = LastFrame {
                number: f.last.number + 1,
                lit,
            };
        }
    }

    /// The last frame rendered to the end.
    pub fn last_frame(&self) -> LastFrame {
        self.frames
            .lock()
            .map(|f| f.last.clone())
            .unwrap_or_default()
    }

    /// When the render world first found Bevy's start-up pipelines compiled (`None` before).
    pub fn bevy_started(&self) -> Option<Instant> {
        self.bevy_started.lock().ok().and_then(|t| *t)
    }

    /// envis's programs, as its compile thread reports them.
    pub fn programs(&self) -> &ProgramLog {
        &self.programs
    }
}

/// Whether Bevy's pipeline cache has been idle once since start-up (or [`BEVY_PIPELINES_WAIT`]
/// has passed): envis records its first build only then. A driver that compiles a shader at its
/// first dispatch, on the one thread that runs the GPU's work (lavapipe), stalls every frame
/// meanwhile: the first build, earlier, held back Bevy's first frames by seconds (black), where
/// now Bevy's image shows while envis's shaders compile.
#[derive(Resource)]
pub struct BevyStarted {
    since: Instant,
    started: bool,
    report: ReadyReport,
}

impl BevyStarted {
    /// Whether Bevy had compiled what it queued at start-up when last looked at.
    pub fn started(&self) -> bool {
        self.started
    }

    /// Look at `cache` now (each frame, before envis's passes): the moment Bevy first has its
    /// start-up pipelines compiled goes to the [`ReadyReport`].
    fn check(&mut self, cache: &PipelineCache) {
        if self.started {
            return;
        }
        self.started = bevy_idle(cache) || self.since.elapsed() >= BEVY_PIPELINES_WAIT;
        if self.started
            && let Ok(mut at) = self.report.bevy_started.lock()
        {
            *at = Some(Instant::now());
        }
    }
}

/// Whether Bevy's pipeline cache has compiled all it was given: it holds pipelines (those queued
/// at start-up reach its list at its first frame) and none is still compiling or waiting for its
/// shader.
fn bevy_idle(cache: &PipelineCache) -> bool {
    cache.pipelines().next().is_some() && cache.waiting_pipelines().next().is_none()
}

/// Per view (render world), whether envis may light it now as far as Bevy is concerned (see the
/// module's doc): once it was, it stays so.
#[derive(Resource, Default)]
pub(crate) struct BevyReadiness {
    allowed: HashSet<Entity>,
    /// Views envis could light, waiting for Bevy's pipelines since.
    waiting: HashMap<Entity, Instant>,
}

impl BevyReadiness {
    /// Whether envis may light `view` this frame: Bevy's pipeline cache has nothing left to
    /// compile and the view's deferred lighting pipeline is ready, or it has waited
    /// [`BEVY_PIPELINES_WAIT`] for that; always, once it was allowed.
    pub(crate) fn allows(
        &mut self,
        view: Entity,
        cache: &PipelineCache,
        deferred: Option<&DeferredLightingPipeline>,
    ) -> bool {
        if self.allowed.contains(&view) {
            return true;
        }
        let deferred_ready =
            deferred.is_none_or(|d| cache.get_render_pipeline(d.pipeline_id).is_some());
        let settled = deferred_ready && bevy_idle(cache);
        let since = *self.waiting.entry(view).or_insert_with(Instant::now);
        let waited = since.elapsed() >= BEVY_PIPELINES_WAIT;
        if !settled && waited {
            warn!(
                "envis: Bevy's pipeline cache still compiles {} pipelines after {}s: lighting the \
                 camera anyway",
                cache.waiting_pipelines().count(),
                BEVY_PIPELINES_WAIT.as_secs()
            );
        }
        if settled || waited {
            self.allowed.insert(view);
            self.waiting.remove(&view);
        }
        self.allowed.contains(&view)
    }

    /// Whether `view` has been allowed (read-only: the resampling pass, which runs before the
    /// lighting pass, starts from the frame after the first lit one, so that no history is made
    /// from a G-buffer Bevy has not finished).
    pub(crate) fn allowed(&self, view: Entity) -> bool {
        self.allowed.contains(&view)
    }

    /// Forget views that are gone.
    fn retain(&mut self, keep: impl Fn(Entity) -> bool) {
        self.allowed.retain(|e| keep(*e));
        self.waiting.retain(|e, _| keep(*e));
    }
}

/// The marker and its two systems: the render world ends each frame's list of lit cameras, the
/// main world marks them (part of `EnvisLightingPlugin`).
pub fn add_ready(app: &mut App) {
    let report = app
        .world_mut()
        .get_resource_or_insert_with(ReadyReport::default)
        .clone();
    app.register_type::<EnvisLightReady>()
        .add_systems(First, mark_ready_cameras);
    if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
        render_app
            .insert_resource(report.clone())
            .init_resource::<BevyReadiness>()
            .insert_resource(BevyStarted {
                since: Instant::now(),
                started: false,
                report: report.clone(),
            })
            .add_systems(
                Render,
                (
                    end_lit_frame.in_set(RenderSystems::Cleanup),
                    (forget_gone_views, note_bevy_started).in_set(RenderSystems::Prepare),
                ),
            );
    }
}

fn note_bevy_started(mut started: ResMut<BevyStarted>, cache: Res<PipelineCache>) {
    started.check(&cache);
}

fn end_lit_frame(report: Res<ReadyReport>) {
    report.end_frame();
}

fn forget_gone_views(
    mut readiness: ResMut<BevyReadiness>,
    views: Query<Entity, With<bevy::render::view::ExtractedView>>,
) {
    readiness.retain(|e| views.contains(e));
}

/// After each rendered frame: [`EnvisLightReady`] on the cameras lit in it, off the others.
fn mark_ready_cameras(
    mut commands: Commands,
    report: Res<ReadyReport>,
    mut seen: Local<u64>,
    cameras: Query<(Entity, Has<EnvisLightReady>), With<EnvironmentSampling>>,
    stale: Query<Entity, (With<EnvisLightReady>, Without<EnvironmentSampling>)>,
) {
    for e in &stale {
        commands.entity(e).remove::<EnvisLightReady>();
    }
    let last = report.last_frame();
    if last.number == *seen {
        return; // no frame rendered since the last look
    }
    *seen = last.number;
    for (e, ready) in &cameras {
        match (last.lit.contains(&e), ready) {
            (true, false) => {
                commands.entity(e).insert(EnvisLightReady);
            }
            (false, true) => {
                commands.entity(e).remove::<EnvisLightReady>();
            }
            _ => {}
        }
    }
}
