//! envis's GPU programs (the resample, the distribution build, the lighting pass per target
//! format, the resampling passes), compiled on envis's own thread from start-up, never on the
//! frame path and never on Bevy's async compute pool.
//!
//! Why a thread of its own: creating a pipeline is where a GPU's driver compiles it (lavapipe
//! takes 0.5-1 s to create the lighting pass, and compiles the machine code later, at its first
//! draw: `docs/bevy.md`, "Ready to light"). Bevy's `PipelineCache` compiles on the async compute
//! pool, which has one thread on a 2-core machine:
//! queued there, envis's programs held back Bevy's own (tonemapping, the deferred lighting, the
//! lighting-pass ids), and frames came out black or without the ids envis reads
//! (`docs/bevy.md`, "Ready to light"). Compiled on the render thread they stall frames.
//!
//! With `RenderPlugin::synchronous_pipeline_compilation` (headless tools and tests) a program is
//! compiled when first needed and the frame waits for it, as Bevy's own pipelines then do; nothing
//! is compiled ahead.

use super::lighting::{LightingEntry, lighting_layout};
use super::ready::{ProgramLog, ReadyReport};
use bevy::prelude::*;
use bevy::render::extract_resource::ExtractResource;
use bevy::render::render_resource::TextureFormat;
use bevy::render::renderer::RenderDevice;
use bevy::render::{Render, RenderApp, RenderStartup, RenderSystems};
use envis_wgpu::resampling::ResamplingPasses;
use envis_wgpu::sampler::BuildPipelines;
use envis_wgpu::{ImageResampler, shaders};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Instant;

pub use super::resampling::ResamplingPrograms;
pub use worker::Compiled;
use worker::{Worker, checked, validate_wgsl};

mod worker;

/// What a job compiles (a job is found by it to be moved up the queue).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Program {
    /// The resample of an environment image into the texel table (`resample.wgsl`).
    Resample,
    /// The distribution and the light pool (`distribution.wgsl`).
    Build,
    /// The lighting pass for a target format, an entry point and a source version.
    Lighting(TextureFormat, LightingEntry, u64),
    /// The resampling passes and their gather (`resampling.wgsl`, `gather.wgsl`).
    Resampling,
}

/// The lighting pass's source, held in the main world and extracted: [`EnvisShaderReloadPlugin`]
/// replaces it, and the render world compiles the new version beside the last good one.
///
/// [`EnvisShaderReloadPlugin`]: super::EnvisShaderReloadPlugin
#[derive(Resource, Clone, ExtractResource)]
pub struct LightingSource {
    pub wgsl: Arc<str>,
    /// Bumped on each replacement.
    pub version: u64,
}

impl Default for LightingSource {
    fn default() -> Self {
        LightingSource {
            wgsl: shaders::lighting_source().into(),
            version: 0,
        }
    }
}

/// One lighting pipeline: the version in use, and a newer one while it compiles.
#[derive(Default)]
struct LightingSlot {
    current: Option<(u64, Compiled<wgpu::RenderPipeline>)>,
    next: Option<(u64, Compiled<wgpu::RenderPipeline>)>,
    /// The version whose failure was logged.
    reported: Option<u64>,
}

/// The lighting pass's programs, their shared layout and the source they compile.
struct LightingPrograms {
    layout: Arc<wgpu::PipelineLayout>,
    source: LightingSource,
    slots: HashMap<(TextureFormat, LightingEntry), LightingSlot>,
}

/// The view target formats whose lighting pipelines start compiling at start-up: Bevy's HDR
/// format (`ViewTarget::TEXTURE_FORMAT_HDR`) and its default LDR one. Another format compiles
/// when a camera first has it.
pub const START_FORMATS: [TextureFormat; 2] =
    [TextureFormat::Rgba16Float, TextureFormat::Rgba8UnormSrgb];

/// envis's GPU programs in the render world (see the module's doc).
#[derive(Resource)]
pub struct EnvisPrograms {
    device: wgpu::Device,
    worker: Worker,
    /// Wait for a program where it is needed (`synchronous_pipeline_compilation`).
    synchronous: bool,
    started: Instant,
    resample: Compiled<ImageResampler>,
    build: Compiled<Arc<BuildPipelines>>,
    resampling: Compiled<ResamplingPrograms>,
    /// The lighting pipelines' bind group layout (`lighting_layout`): the frames bind with it.
    lighting_group: wgpu::BindGroupLayout,
    lighting: Mutex<LightingPrograms>,
    /// Each program queued, and when it was compiled, from start-up.
    log: ProgramLog,
}

impl EnvisPrograms {
    /// Start envis's compile thread; unless `synchronous`, queue every program at once, in the
    /// order a first lit frame needs them.
    pub fn new(device: &wgpu::Device, synchronous: bool, log: ProgramLog) -> Self {
        let group = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("envis lighting layout"),
            entries: &lighting_layout().entries,
        });
        let layout = envis_wgpu::one_group_layout(device, "envis lighting", &group);
        let programs = EnvisPrograms {
            device: device.clone(),
            worker: Worker::start(),
            synchronous,
            started: Instant::now(),
            resample: Compiled::default(),
            build: Compiled::default(),
            resampling: Compiled::default(),
            lighting_group: group,
            lighting: Mutex::new(LightingPrograms {
                layout: Arc::new(layout),
                source: LightingSource::default(),
                slots: HashMap::new(),
            }),
            log,
        };
        if !synchronous {
            programs.queue_all();
        }
        programs
    }

    /// Queue every program: what the first lit frame of a plain camera needs first, then the
    /// resampling passes.
    fn queue_all(&self) {
        self.queue(Program::Resample);
        self.queue(Program::Build);
        for format in START_FORMATS {
            self.lighting_slot(format, LightingEntry::Shade);
        }
        self.queue(Program::Resampling);
        for format in START_FORMATS {
            self.lighting_slot(format, LightingEntry::ShowResampled);
        }
    }

    /// Queue the compute program `program` once (`Lighting` is queued by [`Self::lighting`]).
    fn queue(&self, program: Program) {
        let device = self.device.clone();
        match program {
            Program::Resample if self.resample.first_queued() => {
                let (slot, timed) = (self.resample.clone(), self.timed(program));
                self.worker.push(program, move || {
                    slot.set(checked(&device, ImageResampler::new));
                    timed();
                });
            }
            Program::Build if self.build.first_queued() => {
                let (slot, timed) = (self.build.clone(), self.timed(program));
                self.worker.push(program, move || {
                    slot.set(checked(&device, |d| Arc::new(BuildPipelines::new(d))));
                    timed();
                });
            }
            Program::Resampling if self.resampling.first_queued() => {
                let (slot, timed) = (self.resampling.clone(), self.timed(program));
                self.worker.push(program, move || {
                    let made = ResamplingPasses::supported(&device.limits())
                        .map_err(|e| e.to_string())
                        .and_then(|()| checked(&device, ResamplingPrograms::new));
                    slot.set(made);
                    timed();
                });
            }
            _ => {}
        }
    }

    /// Log `program` as queued; the closure returned logs it compiled.
    fn timed(&self, program: Program) -> impl FnOnce() + Send + 'static {
        self.log.queued();
        let (log, started) = (self.log.clone(), self.started);
        move || log.done(program, started.elapsed())
    }

    /// `slot`'s program for this frame: at once where compiled; where not, its job queued or
    /// moved to the front (and waited for when compiling is synchronous).
    fn ready<'a, T>(&self, slot: &'a Compiled<T>, program: Program) -> Option<&'a T> {
        if slot.done() {
            return slot.get();
        }
        self.queue(program);
        self.worker.hurry(program);
        if self.synchronous {
            return slot.wait();
        }
        None
    }

    /// The resample, once compiled.
    pub fn resample(&self) -> Option<&ImageResampler> {
        self.ready(&self.resample, Program::Resample)
    }

    /// The distribution build, once compiled.
    pub fn build(&self) -> Option<&Arc<BuildPipelines>> {
        self.ready(&self.build, Program::Build)
    }

    /// The resampling passes, once compiled; `None` for good, with a warning once, where the
    /// device cannot run them.
    pub fn resampling(&self) -> Option<&ResamplingPrograms> {
        let made = self.ready(&self.resampling, Program::Resampling);
        if let Some(e) = self.resampling.error() {
            bevy::log::warn_once!("envis resampling is off: {e}");
        }
        made
    }

    /// Use `source` for the lighting pass: a new version compiles beside the one in use,
    /// which stays until the new one is ready (and for good if it fails to compile).
    pub fn set_lighting_source(&self, source: &LightingSource) {
        if let Ok(mut l) = self.lighting.lock()
            && l.source.version != source.version
        {
            l.source = source.clone();
        }
    }

    /// The lighting pipeline for target `format` and `entry`, once compiled (queued at its first
    /// request, a newer source version compiled beside it).
    pub fn lighting(
        &self,
        format: TextureFormat,
        entry: LightingEntry,
    ) -> Option<wgpu::RenderPipeline> {
        let (v, current) = self.lighting_slot(format, entry)?;
        let program = Program::Lighting(format, entry, v);
        self.ready(&current, program).cloned()
    }

    /// The lighting pipeline in use for `format` and `entry` (compiled or not) and its source
    /// version: queued if there is none, its newer version queued if the source changed, and
    /// swapped in once compiled.
    fn lighting_slot(
        &self,
        format: TextureFormat,
        entry: LightingEntry,
    ) -> Option<(u64, Compiled<wgpu::RenderPipeline>)> {
        let mut l = self.lighting.lock().ok()?;
        let version = l.source.version;
        let (layout, wgsl) = (l.layout.clone(), l.source.wgsl.clone());
        let slot = l.slots.entry((format, entry)).or_default();
        promote(slot);
        let newest = slot.next.as_ref().or(slot.current.as_ref()).map(|n| n.0);
        if newest.is_none_or(|v| v < version) {
            let compiled = Compiled::default();
            let program = Program::Lighting(format, entry, version);
            let (device, timed, c) = (self.device.clone(), self.timed(program), compiled.clone());
            self.worker.push(program, move || {
                let made = validate_wgsl(&wgsl).and_then(|()| {
                    checked(&device, |d| {
                        lighting_pipeline(d, &layout, &wgsl, (format, entry))
                    })
                });
                c.set(made);
                timed();
            });
            let kept = Some((version, compiled));
            match slot.current {
                None => slot.current = kept,
                Some(_) => slot.next = kept,
            }
        }
        let (v, current) = slot.current.clone()?;
        if let Some(e) = current.error()
            && slot.reported != Some(v)
        {
            error!("envis: the lighting pass does not compile: {e}");
            slot.reported = Some(v);
        }
        Some((v, current))
    }

    /// The bind group layout of the lighting pipelines (`lighting_layout`).
    pub fn lighting_group_layout(&self) -> &wgpu::BindGroupLayout {
        &self.lighting_group
    }
}

/// The newer version of a lighting pipeline replaces the one in use once it compiled (or when
/// the one in use failed); a newer version that failed is logged and dropped.
fn promote(slot: &mut LightingSlot) {
    let Some((v, next)) = slot.next.as_ref() else {
        return;
    };
    if !next.done() {
        return;
    }
    let current_ok = slot.current.as_ref().is_some_and(|c| c.1.get().is_some());
    match next.error() {
        Some(e) if current_ok => {
            error!(
                "envis: the edited lighting pass does not compile (the last good one stays): {e}"
            );
            slot.reported = Some(*v);
            slot.next = None;
        }
        _ => slot.current = slot.next.take(),
    }
}

/// The lighting pass's render pipeline: `fullscreen` + `entry`'s fragment, into `format`,
/// premultiplied (alpha 0 adds to Bevy's lighting, alpha 1 replaces).
fn lighting_pipeline(
    device: &wgpu::Device,
    layout: &wgpu::PipelineLayout,
    wgsl: &str,
    (format, entry): (TextureFormat, LightingEntry),
) -> wgpu::RenderPipeline {
    let module = shaders::module(device, "envis lighting.wgsl", wgsl);
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("envis lighting"),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("fullscreen"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: Default::default(),
        depth_stencil: None,
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some(entry.entry_point()),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format,
                blend: Some(wgpu::BlendState::PREMULTIPLIED_ALPHA_BLENDING),
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// Whether the app compiles pipelines synchronously (`RenderPlugin`'s setting), read when the
/// plugins are built.
#[derive(Resource, Clone, Copy)]
struct CompileMode {
    synchronous: bool,
}

/// Set up [`EnvisPrograms`] once (each envis plugin that uses them calls this): the lighting
/// source extracted to the render world, the programs made at the render world's start-up.
pub(crate) fn add_programs(app: &mut App) {
    if app.world().contains_resource::<LightingSource>() {
        return;
    }
    let synchronous = app
        .get_added_plugins::<bevy::render::RenderPlugin>()
        .first()
        .is_some_and(|p| p.synchronous_pipeline_compilation);
    app.init_resource::<LightingSource>().add_plugins(
        bevy::render::extract_resource::ExtractResourcePlugin::<LightingSource>::default(),
    );
    if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
        render_app
            .insert_resource(CompileMode { synchronous })
            .add_systems(RenderStartup, init_programs)
            .add_systems(
                Render,
                follow_lighting_source.in_set(RenderSystems::PrepareResources),
            );
    }
}

fn init_programs(
    mut commands: Commands,
    device: Res<RenderDevice>,
    mode: Res<CompileMode>,
    report: Option<Res<ReadyReport>>,
) {
    let log = report.map(|r| r.programs().clone()).unwrap_or_default();
    let programs = EnvisPrograms::new(device.wgpu_device(), mode.synchronous, log);
    commands.insert_resource(programs);
}

/// A replaced lighting source (`EnvisShaderReloadPlugin`) starts compiling.
fn follow_lighting_source(
    programs: Option<Res<EnvisPrograms>>,
    source: Option<Res<LightingSource>>,
) {
    if let (Some(programs), Some(source)) = (programs, source) {
        programs.set_lighting_source(&source);
    }
}
