//! `EnvMapStreamPlugin`: the environment-map stream as a main-world resource.

use super::{EnvisCounters, EnvisSettings};
use crate::envmap::CubeMap;
use crate::stream::{EnvStream, StreamSource};
use bevy::prelude::*;
use bevy::render::extract_resource::{ExtractResource, ExtractResourcePlugin};
use std::sync::Arc;

/// The current environment frame, extracted to the render world every frame (an `Arc` clone).
/// `generation` changes exactly when the map does.
#[derive(Resource, Clone, ExtractResource)]
pub struct EnvFrame {
    pub generation: u64,
    pub map: Arc<CubeMap>,
}

/// The stream (main world). Switch sources with [`EnvMapStream::switch`]; play / pause / speed
/// are fields of the inner [`EnvStream`].
#[derive(Resource)]
pub struct EnvMapStream {
    pub stream: EnvStream,
    /// Recent messages (bad frames, clamped texels, refused switches), newest last, at most 32.
    pub log: Vec<String>,
}

impl EnvMapStream {
    /// Open `source` at `face_size`; on error keep the current stream and log why.
    pub fn switch(&mut self, source: StreamSource, face_size: usize) -> bool {
        match EnvStream::open(source, face_size) {
            Ok(s) => {
                let (playing, speed) = (self.stream.playing, self.stream.speed);
                self.stream = s;
                self.stream.playing = playing;
                self.stream.speed = speed;
                true
            }
            Err(e) => {
                self.push_log(format!("{e} (kept the current environment)"));
                false
            }
        }
    }
    fn push_log(&mut self, m: String) {
        warn!("envis stream: {m}");
        self.log.push(m);
        if self.log.len() > 32 {
            self.log.remove(0);
        }
    }
}

/// Adds [`EnvMapStream`] and [`EnvFrame`] (the built-in animated sky by default).
pub struct EnvMapStreamPlugin {
    pub source: StreamSource,
    pub face_size: usize,
}

impl Default for EnvMapStreamPlugin {
    fn default() -> Self {
        EnvMapStreamPlugin {
            source: StreamSource::Sky {
                hours: 9.0,
                speed: 0.5,
            },
            face_size: 64,
        }
    }
}

impl Plugin for EnvMapStreamPlugin {
    fn build(&self, app: &mut App) {
        let stream = EnvStream::open(self.source.clone(), self.face_size).unwrap_or_else(|e| {
            error!("envis: {e}; falling back to the built-in sky");
            EnvStream::open(
                StreamSource::Sky {
                    hours: 9.0,
                    speed: 0.5,
                },
                self.face_size.clamp(1, 4096),
            )
            .expect("built-in sky")
        });
        let frame = EnvFrame {
            generation: stream.generation(),
            map: stream.frame().clone(),
        };
        let counters = app
            .world_mut()
            .get_resource_or_insert_with(EnvisCounters::default)
            .clone();
        let timings = app
            .world_mut()
            .get_resource_or_insert_with(super::EnvisTimings::default)
            .clone();
        let probe = app
            .world_mut()
            .get_resource_or_insert_with(super::EnvisProbe::default)
            .clone();
        app.insert_resource(EnvMapStream {
            stream,
            log: Vec::new(),
        })
        .insert_resource(frame)
        .init_resource::<EnvisSettings>()
        .add_plugins((
            ExtractResourcePlugin::<EnvFrame>::default(),
            ExtractResourcePlugin::<EnvisSettings>::default(),
        ))
        .add_systems(
            PostUpdate,
            (
                advance_stream,
                super::track_accumulation.after(bevy::transform::TransformSystems::Propagate),
            )
                .chain(),
        );
        // Share the counters with the render world.
        if let Some(render_app) = app.get_sub_app_mut(bevy::render::RenderApp) {
            render_app
                .insert_resource(counters)
                .insert_resource(timings)
                .insert_resource(probe);
        }
    }
}

/// Advance the stream by the frame time; publish a new [`EnvFrame`] only when the map changed
/// (a new frame, or a switched stream: every frame is a new `Arc`). Generations increase across
/// switches, so the render world never mistakes a new stream's frame for an old one.
pub fn advance_stream(
    time: Res<Time>,
    mut stream: ResMut<EnvMapStream>,
    mut frame: ResMut<EnvFrame>,
) {
    stream.stream.advance(time.delta_secs_f64());
    for m in stream.stream.take_messages() {
        stream.push_log(m);
    }
    if !Arc::ptr_eq(&frame.map, stream.stream.frame()) {
        let generation = frame.generation + 1;
        *frame = EnvFrame {
            generation,
            map: stream.stream.frame().clone(),
        };
    }
}
