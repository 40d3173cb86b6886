//! A headless Bevy app (no window): the `sphere` scene of the CPU renderer — the unit sphere seen
//! by an orthographic camera on +Z looking down -Z, framing `[-1, 1]^2` — drawn through Bevy's
//! deferred G-buffer and the envis lighting pass into a float image. Used by
//! `envis render --backend bevy` and by the tests.

use super::{
    EnvMapSamplingPlugin, EnvMapStream, EnvMapStreamPlugin, EnvisCamera, EnvisCounters,
    EnvisMaterial, EnvisSettings, MisLightingPlugin,
};
use crate::stream::StreamSource;
use bevy::asset::RenderAssetUsages;
use bevy::camera::{Hdr, RenderTarget, ScalingMode};
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::image::Image;
use bevy::prelude::*;
use bevy::render::RenderPlugin;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat, TextureUsages};
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};
use bevy::window::ExitCondition;
use std::sync::{Arc, Mutex};

/// Frames to wait for a screenshot of the render target before giving up.
const CAPTURE_FRAMES: usize = 20;

/// The app, its float render target and the target's size.
pub struct HeadlessSphere {
    pub app: App,
    target: Handle<Image>,
    size: u32,
}

impl HeadlessSphere {
    /// Build the app: stream `source` at `face` texels per face, the sphere with `mat`, HDR output
    /// without tonemapping into a `size x size` Rgba32Float image.
    pub fn new(
        source: StreamSource,
        face: usize,
        mat: EnvisMaterial,
        settings: EnvisSettings,
        size: u32,
    ) -> Self {
        let (mut app, target) = Self::base(source, face, settings, size);
        let mesh = app
            .world_mut()
            .resource_mut::<Assets<Mesh>>()
            .add(Sphere::new(1.0).mesh().ico(7).expect("icosphere"));
        let material = app
            .world_mut()
            .resource_mut::<Assets<StandardMaterial>>()
            .add(mat.standard());
        app.world_mut()
            .spawn((Mesh3d(mesh), MeshMaterial3d(material), Transform::IDENTITY));
        let projection = Projection::Orthographic(OrthographicProjection {
            scaling_mode: ScalingMode::Fixed {
                width: 2.0,
                height: 2.0,
            },
            ..OrthographicProjection::default_3d()
        });
        Self::finish(
            app,
            target,
            projection,
            Transform::from_xyz(0.0, 0.0, 5.0).looking_at(Vec3::ZERO, Vec3::Y),
            size,
        )
    }

    /// A scene file's objects and camera (perspective), with the scene's environment and settings.
    pub fn from_scene(
        sc: &crate::scene::Scene,
        settings: EnvisSettings,
        size: u32,
    ) -> crate::error::Result<Self> {
        let source = match StreamSource::parse(&sc.environment)? {
            StreamSource::Sky { hours, .. } => StreamSource::Sky { hours, speed: 0.0 },
            other => other,
        };
        let (mut app, target) = Self::base(source, sc.file.environment.face_size, settings, size);
        let cam = app
            .world_mut()
            .resource_scope(|world, mut meshes: Mut<Assets<Mesh>>| {
                world.resource_scope(|world, mut materials: Mut<Assets<StandardMaterial>>| {
                    let mut commands = world.commands();
                    super::scene_objects::spawn_scene_objects(
                        &mut commands,
                        &mut meshes,
                        &mut materials,
                        sc,
                    )
                })
            });
        app.world_mut().flush();
        let projection = Projection::Perspective(PerspectiveProjection {
            fov: cam.fov,
            ..default()
        });
        Ok(Self::finish(app, target, projection, cam.transform(), size))
    }

    /// The app with the envis plugins and a float render target.
    fn base(
        source: StreamSource,
        face: usize,
        settings: EnvisSettings,
        size: u32,
    ) -> (App, Handle<Image>) {
        let mut app = App::new();
        let plugins = DefaultPlugins
            .set(RenderPlugin {
                synchronous_pipeline_compilation: true,
                ..default()
            })
            .set(WindowPlugin {
                primary_window: None,
                exit_condition: ExitCondition::DontExit,
                ..default()
            })
            .disable::<bevy::log::LogPlugin>();
        // With the `demo` feature Bevy has a window system; a headless app drives itself.
        #[cfg(feature = "demo")]
        let plugins = plugins.disable::<bevy::winit::WinitPlugin>();
        app.add_plugins(plugins)
            .insert_resource(settings)
            .add_plugins((
                EnvMapStreamPlugin {
                    source,
                    face_size: face,
                },
                EnvMapSamplingPlugin,
                MisLightingPlugin,
            ));
        let mut img = Image::new_uninit(
            Extent3d {
                width: size,
                height: size,
                depth_or_array_layers: 1,
            },
            TextureDimension::D2,
            TextureFormat::Rgba32Float,
            RenderAssetUsages::RENDER_WORLD,
        );
        img.texture_descriptor.usage |= TextureUsages::RENDER_ATTACHMENT | TextureUsages::COPY_SRC;
        let target = app.world_mut().resource_mut::<Assets<Image>>().add(img);
        (app, target)
    }

    /// Add the camera (HDR, no tonemapping, into the float target) and finish the app.
    fn finish(
        mut app: App,
        target: Handle<Image>,
        projection: Projection,
        transform: Transform,
        size: u32,
    ) -> Self {
        app.world_mut().spawn((
            Camera3d::default(),
            projection,
            transform,
            RenderTarget::from(target.clone()),
            Hdr,
            Msaa::Off,
            Tonemapping::None,
            EnvisCamera,
        ));
        app.finish();
        app.cleanup();
        HeadlessSphere { app, target, size }
    }

    pub fn update(&mut self) {
        self.app.update();
    }

    /// Draw frames until a capture of the target arrives (after a few frames of set-up: meshes,
    /// materials and pipelines are prepared over the first frames). Linear RGB, row-major. An
    /// error (never a panic) when no capture comes or it has the wrong size.
    pub fn capture(&mut self) -> crate::error::Result<Vec<Vec3>> {
        use crate::error::Error;
        for _ in 0..3 {
            self.update();
        }
        let got: Arc<Mutex<Option<Image>>> = Arc::default();
        let sink = got.clone();
        self.app
            .world_mut()
            .spawn(Screenshot::image(self.target.clone()))
            .observe(move |ev: On<ScreenshotCaptured>| {
                if let Ok(mut slot) = sink.lock() {
                    *slot = Some(ev.image.clone());
                }
            });
        for _ in 0..CAPTURE_FRAMES {
            self.update();
            let img = got.lock().ok().and_then(|mut slot| slot.take());
            let Some(img) = img else { continue };
            let data = img.data.unwrap_or_default();
            let want = (self.size * self.size * 4) as usize;
            // Decoded byte by byte: the capture's bytes need not be aligned for f32.
            let px: Vec<f32> = data
                .chunks_exact(4)
                .map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]]))
                .collect();
            if px.len() != want {
                return Err(Error::invalid(format!(
                    "the GPU capture has {} floats, expected {want} ({}x{} RGBA32F)",
                    px.len(),
                    self.size,
                    self.size
                )));
            }
            return Ok(px
                .chunks_exact(4)
                .map(|c| Vec3::new(c[0], c[1], c[2]))
                .collect());
        }
        Err(Error::invalid(format!(
            "the GPU render produced no image after {CAPTURE_FRAMES} frames (the render \
             target was never captured)"
        )))
    }

    pub fn counters(&self) -> EnvisCounters {
        self.app.world().resource::<EnvisCounters>().clone()
    }

    pub fn stream_mut(&mut self) -> Mut<'_, EnvMapStream> {
        self.app.world_mut().resource_mut::<EnvMapStream>()
    }
}
