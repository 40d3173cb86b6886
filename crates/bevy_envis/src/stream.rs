//! `EnvisStreamPlugin`: envis's own environment streams (the built-in sky, file sequences, the
//! carousel) played into a Bevy `Image`, so they light cameras through the same
//! [`super::EnvisEnvironment`] as any other image.

use bevy::asset::RenderAssetUsages;
use bevy::prelude::*;
use bevy::render::render_resource::{
    Extent3d, TextureDimension, TextureFormat, TextureViewDescriptor, TextureViewDimension,
};
use envis::envmap::CubeMap;
use envis::stream::{EnvStream, StreamSource};
use std::sync::Arc;

/// The stream's current frame (main world; the demo's CPU twin reads it). `generation` changes
/// exactly when the map does, and the stream's `Image` is rewritten then.
#[derive(Resource, Clone)]
pub struct EnvFrame {
    pub generation: u64,
    pub map: Arc<CubeMap>,
}

/// The stream (main world). Switch sources with [`EnvMapStream::switch`]; play / pause / speed
/// are fields of the inner [`EnvStream`].
#[derive(Resource)]
pub struct EnvMapStream {
    pub stream: EnvStream,
    /// The cube image the frames are written into (give it to an `EnvisEnvironment`).
    pub image: Handle<Image>,
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

/// Adds [`EnvMapStream`] and [`EnvFrame`] (the built-in animated sky by default); frames are
/// `face_size` texels per cube face.
pub struct EnvisStreamPlugin {
    pub source: StreamSource,
    pub face_size: usize,
}

impl Default for EnvisStreamPlugin {
    fn default() -> Self {
        EnvisStreamPlugin {
            source: StreamSource::Sky {
                hours: 9.0,
                speed: 0.5,
            },
            face_size: 64,
        }
    }
}

impl Plugin for EnvisStreamPlugin {
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
        let image = app
            .world_mut()
            .resource_mut::<Assets<Image>>()
            .add(cube_image(&frame.map));
        app.insert_resource(EnvMapStream {
            stream,
            image,
            log: Vec::new(),
        })
        .insert_resource(frame)
        .add_systems(PostUpdate, advance_stream);
    }
}

/// A Bevy cube image (6 layers, `Rgba32Float`, Bevy's convention) of a cube map.
pub fn cube_image(map: &CubeMap) -> Image {
    let layers = envis::envmap::resample::bevy_cube_layers(map);
    let data: Vec<u8> = layers
        .data
        .iter()
        .flat_map(|c| [c.x, c.y, c.z, 1.0])
        .flat_map(f32::to_ne_bytes)
        .collect();
    let n = map.size as u32;
    let mut img = Image::new(
        Extent3d {
            width: n,
            height: n,
            depth_or_array_layers: 6,
        },
        TextureDimension::D2,
        data,
        TextureFormat::Rgba32Float,
        RenderAssetUsages::RENDER_WORLD,
    );
    img.texture_view_descriptor = Some(TextureViewDescriptor {
        dimension: Some(TextureViewDimension::Cube),
        ..default()
    });
    img
}

/// Advance the stream by the frame time; publish a new [`EnvFrame`] only when the map changed
/// (a new frame, or a switched stream: every frame is a new `Arc`). Generations increase across
/// switches, so the render world never mistakes a new stream's frame for an old one.
pub fn advance_stream(
    time: Res<Time>,
    mut stream: ResMut<EnvMapStream>,
    mut frame: ResMut<EnvFrame>,
    mut images: ResMut<Assets<Image>>,
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
        // A new image rather than new bytes in the old one: the face size may have changed.
        if let Err(e) = images.insert(&stream.image, cube_image(&frame.map)) {
            let msg = format!("the stream's image could not be updated ({e}); kept the last frame");
            stream.push_log(msg);
        }
    }
}
