//! A headless Bevy app (no window) built on the public API only (`bevy_envis::prelude`):
//! [`HeadlessApp`] is Bevy's `DefaultPlugins` without a window, [`bevy_envis::EnvisPlugin`], and
//! float render targets read back as linear RGB. [`HeadlessSphere`] is the `sphere` scene of the
//! CPU renderer — the unit sphere seen by an orthographic camera on +Z looking down -Z, framing
//! `[-1, 1]^2` — lit by an envis stream. Used by `envis render --backend bevy`, the examples'
//! tests and the Bevy tests.

use bevy::asset::{AssetPlugin, RenderAssetUsages};
use bevy::camera::{RenderTarget, ScalingMode};
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::image::Image;
use bevy::prelude::*;
use bevy::render::RenderPlugin;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat, TextureUsages};
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};
use bevy::window::ExitCondition;
use bevy_envis::components::{EnvironmentSampling, EnvisEnvironment, exposure_multiplier};
use bevy_envis::{
    EnvMapStream, EnvisBrdf, EnvisCounters, EnvisMaterial, EnvisPlugin, EnvisStreamPlugin,
};
use envis::stream::StreamSource;

/// Frames to wait for a screenshot of the render target before giving up.
pub const CAPTURE_FRAMES: usize = 20;

/// Frames [`HeadlessApp::until_lit`] waits for envis to light every camera (with pipelines
/// compiled synchronously: a few frames while Bevy loads its shaders).
pub const READY_FRAMES: usize = 60;

/// A windowless Bevy app with envis, driven by [`HeadlessApp::update`].
pub struct HeadlessApp {
    pub app: App,
    finished: bool,
}

impl Default for HeadlessApp {
    fn default() -> Self {
        Self::new()
    }
}

impl HeadlessApp {
    /// `DefaultPlugins` (no window, no log, pipelines compiled synchronously) + `EnvisPlugin`.
    /// Add entities and resources through [`Self::app`] before the first update.
    pub fn new() -> Self {
        let sync = RenderPlugin {
            synchronous_pipeline_compilation: true,
            ..default()
        };
        Self::with(sync, AssetPlugin::default(), true)
    }

    /// As a game starts: pipelines compiled asynchronously (frames go on meanwhile, Bevy's
    /// default), assets loaded by the `AssetServer` from the folder `assets`.
    pub fn as_a_game(assets: &std::path::Path) -> Self {
        Self::with(RenderPlugin::default(), Self::assets(assets), true)
    }

    /// [`Self::as_a_game`] without envis: Bevy alone (a baseline).
    pub fn bevy_alone_as_a_game(assets: &std::path::Path) -> Self {
        Self::with(RenderPlugin::default(), Self::assets(assets), false)
    }

    fn assets(folder: &std::path::Path) -> AssetPlugin {
        AssetPlugin {
            file_path: folder.to_string_lossy().into_owned(),
            ..default()
        }
    }

    fn with(render: RenderPlugin, assets: AssetPlugin, envis: bool) -> Self {
        let mut app = App::new();
        let plugins = DefaultPlugins
            .set(render)
            .set(assets)
            .set(WindowPlugin {
                primary_window: None,
                exit_condition: ExitCondition::DontExit,
                ..default()
            })
            .disable::<bevy::log::LogPlugin>();
        // The lab's Bevy has a window system (the demo's); a headless app drives itself.
        let plugins = plugins.disable::<bevy::winit::WinitPlugin>();
        // No ambient light: the environment is the only indirect light.
        app.add_plugins(plugins);
        if envis {
            app.add_plugins(EnvisPlugin);
        }
        app.insert_resource(GlobalAmbientLight {
            brightness: 0.0,
            ..default()
        });
        HeadlessApp {
            app,
            finished: false,
        }
    }

    /// A `width x height` Rgba32Float image a camera can render into and [`Self::capture`] read.
    pub fn float_target(&mut self, width: u32, height: u32) -> Handle<Image> {
        let mut img = Image::new_uninit(
            Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            TextureDimension::D2,
            TextureFormat::Rgba32Float,
            RenderAssetUsages::RENDER_WORLD,
        );
        img.texture_descriptor.usage |= TextureUsages::RENDER_ATTACHMENT | TextureUsages::COPY_SRC;
        self.app
            .world_mut()
            .resource_mut::<Assets<Image>>()
            .add(img)
    }

    /// Add an asset.
    pub fn add<A: Asset>(&mut self, asset: impl Into<A>) -> Handle<A> {
        self.app.world_mut().resource_mut::<Assets<A>>().add(asset)
    }

    pub fn update(&mut self) {
        if !self.finished {
            self.app.finish();
            self.app.cleanup();
            self.finished = true;
        }
        self.app.update();
    }

    /// Draw frames until a capture of `target` arrives (after a few frames of set-up: meshes,
    /// materials and pipelines are prepared over the first frames, and until every envis camera
    /// is lit: [`Self::until_lit`]). Linear RGB, row-major. An error (never a panic) when no
    /// capture comes or it has the wrong size.
    pub fn capture(&mut self, target: &Handle<Image>) -> envis::error::Result<Vec<Vec3>> {
        for _ in 0..3 {
            self.update();
        }
        self.until_lit();
        self.capture_next(target)
    }

    /// Draw frames until every camera with `EnvironmentSampling` has `EnvisLightReady` (at most
    /// [`READY_FRAMES`]: a camera envis cannot light is left as it is).
    pub fn until_lit(&mut self) {
        for _ in 0..READY_FRAMES {
            let world = self.app.world_mut();
            let mut waiting = world.query_filtered::<(), (
                With<EnvironmentSampling>,
                Without<bevy_envis::EnvisLightReady>,
            )>();
            if waiting.iter(world).next().is_none() {
                return;
            }
            self.update();
        }
    }

    /// [`Self::capture`] without the set-up frames: the first frame rendered from now.
    pub fn capture_next(&mut self, target: &Handle<Image>) -> envis::error::Result<Vec<Vec3>> {
        let got = Captures::default();
        self.request_capture(target, 0, &got);
        for _ in 0..CAPTURE_FRAMES {
            self.update();
            if let Some(img) = got.take(0) {
                return img;
            }
        }
        Err(no_capture())
    }

    /// Ask for `target` as the next update renders it: its pixels arrive in `sink` under
    /// `tag` (a frame or two later: the readback is asynchronous), so a caller can ask every
    /// frame and take them in order ([`bevy_envis::tagged::Tagged::take`]).
    pub fn request_capture(&mut self, target: &Handle<Image>, tag: u32, sink: &Captures) {
        let sink = sink.clone();
        self.app
            .world_mut()
            .spawn(Screenshot::image(target.clone()))
            .observe(move |ev: On<ScreenshotCaptured>| {
                sink.push(tag, decode_capture(ev.image.clone()));
            });
    }

    pub fn counters(&self) -> EnvisCounters {
        self.app.world().resource::<EnvisCounters>().clone()
    }
}

/// Captures asked for with [`HeadlessApp::request_capture`], each tagged, as they arrive: the
/// pixels, or why there are none.
pub type Captures = bevy_envis::tagged::Tagged<envis::error::Result<Vec<Vec3>>>;

/// The error when a capture never arrives.
pub fn no_capture() -> envis::error::Error {
    envis::error::Error::invalid(format!(
        "the GPU render produced no image after {CAPTURE_FRAMES} frames (the render target \
         was never captured)"
    ))
}

/// A captured Rgba32Float image as linear RGB, row-major; an error where its size is wrong.
fn decode_capture(img: Image) -> envis::error::Result<Vec<Vec3>> {
    let (w, h) = (img.width(), img.height());
    let data = img.data.unwrap_or_default();
    let want = (w * h * 4) as usize;
    // Decoded byte by byte: the capture's bytes need not be aligned for f32.
    let px: Vec<f32> = data
        .chunks_exact(4)
        .map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    if px.len() != want {
        return Err(envis::error::Error::invalid(format!(
            "the GPU capture has {} floats, expected {want} ({w}x{h} RGBA32F)",
            px.len()
        )));
    }
    Ok(px
        .chunks_exact(4)
        .map(|c| Vec3::new(c[0], c[1], c[2]))
        .collect())
}

/// A camera rendering HDR radiance as it is (no tonemapping, exposure multiplier 1, black where
/// nothing is drawn) into `target`, with envis sampling `env`.
pub fn radiance_camera(
    target: Handle<Image>,
    projection: Projection,
    transform: Transform,
    sampling: EnvironmentSampling,
    env: EnvisEnvironment,
) -> impl Bundle {
    (radiance_view(target, projection, transform), sampling, env)
}

/// [`radiance_camera`] without envis.
pub fn radiance_view(
    target: Handle<Image>,
    projection: Projection,
    transform: Transform,
) -> impl Bundle {
    (
        Camera3d::default(),
        Camera {
            clear_color: ClearColorConfig::Custom(Color::BLACK),
            ..default()
        },
        projection,
        transform,
        RenderTarget::from(target),
        Tonemapping::None,
        exposure_multiplier(1.0),
    )
}

/// The orthographic camera of the CPU renderer's `sphere` scene.
pub fn sphere_view() -> (Projection, Transform) {
    (
        Projection::Orthographic(OrthographicProjection {
            scaling_mode: ScalingMode::Fixed {
                width: 2.0,
                height: 2.0,
            },
            ..OrthographicProjection::default_3d()
        }),
        Transform::from_xyz(0.0, 0.0, 5.0).looking_at(Vec3::ZERO, Vec3::Y),
    )
}

/// The sphere scene lit by an envis stream, and its float render target.
pub struct HeadlessSphere {
    pub app: HeadlessApp,
    target: Handle<Image>,
}

impl HeadlessSphere {
    /// Build the app: stream `source` at `face` texels per face (and sample it at that face
    /// size), the sphere with `brdf`, HDR output without tonemapping into a `size x size`
    /// Rgba32Float image.
    pub fn new(
        source: StreamSource,
        face: usize,
        brdf: EnvisBrdf,
        sampling: EnvironmentSampling,
        size: u32,
    ) -> Self {
        let mut h = HeadlessApp::new();
        h.app.add_plugins(EnvisStreamPlugin {
            source,
            face_size: face,
        });
        let mesh = h.add::<Mesh>(Sphere::new(1.0).mesh().ico(7).expect("icosphere"));
        let material = h.add::<EnvisMaterial>(brdf);
        h.app
            .world_mut()
            .spawn((Mesh3d(mesh), MeshMaterial3d(material), Transform::IDENTITY));
        let (projection, transform) = sphere_view();
        Self::finish(h, projection, transform, sampling, face, size)
    }

    /// A scene file's objects and camera (perspective), with the scene's environment.
    pub fn from_scene(
        sc: &envis::scene::Scene,
        sampling: EnvironmentSampling,
        size: u32,
    ) -> envis::error::Result<Self> {
        let source = sc.stream_source(0.0)?;
        let face = sc.file.environment.face_size;
        let mut h = HeadlessApp::new();
        h.app.add_plugins(EnvisStreamPlugin {
            source,
            face_size: face,
        });
        let cam = h
            .app
            .world_mut()
            .resource_scope(|world, mut meshes: Mut<Assets<Mesh>>| {
                world.resource_scope(|world, mut materials: Mut<Assets<EnvisMaterial>>| {
                    let mut commands = world.commands();
                    bevy_envis::scene_objects::spawn_scene_objects(
                        &mut commands,
                        &mut meshes,
                        &mut materials,
                        sc,
                    )
                })
            });
        h.app.world_mut().flush();
        let projection = Projection::Perspective(PerspectiveProjection {
            fov: cam.fov,
            ..default()
        });
        Ok(Self::finish(
            h,
            projection,
            cam.transform(),
            sampling,
            face,
            size,
        ))
    }

    /// Add the camera (HDR radiance into the float target), lit by the stream's image.
    fn finish(
        mut h: HeadlessApp,
        projection: Projection,
        transform: Transform,
        mut sampling: EnvironmentSampling,
        face: usize,
        size: u32,
    ) -> Self {
        let target = h.float_target(size, size);
        let image = h.app.world().resource::<EnvMapStream>().image.clone();
        sampling.face_size = face;
        let env = EnvisEnvironment {
            show_background: false,
            ..EnvisEnvironment::new(image)
        };
        h.app.world_mut().spawn(radiance_camera(
            target.clone(),
            projection,
            transform,
            sampling,
            env,
        ));
        HeadlessSphere { app: h, target }
    }

    pub fn update(&mut self) {
        self.app.update();
    }

    /// See [`HeadlessApp::capture`].
    pub fn capture(&mut self) -> envis::error::Result<Vec<Vec3>> {
        self.app.capture(&self.target)
    }

    /// See [`HeadlessApp::request_capture`].
    pub fn request_capture(&mut self, tag: u32, sink: &Captures) {
        self.app.request_capture(&self.target.clone(), tag, sink);
    }

    pub fn counters(&self) -> EnvisCounters {
        self.app.counters()
    }

    pub fn stream_mut(&mut self) -> Mut<'_, EnvMapStream> {
        self.app.app.world_mut().resource_mut::<EnvMapStream>()
    }

    /// The camera's environment (change it between frames).
    pub fn env_mut(&mut self) -> Mut<'_, EnvisEnvironment> {
        let e = self.camera();
        let world = self.app.app.world_mut();
        world.get_mut::<EnvisEnvironment>(e).expect("camera")
    }

    /// The scene's one envis camera.
    pub fn camera(&mut self) -> Entity {
        let world = self.app.app.world_mut();
        world
            .query_filtered::<Entity, With<EnvironmentSampling>>()
            .single(world)
            .expect("one envis camera")
    }

    /// Frames the camera has accumulated before its last frame.
    pub fn accumulated_frames(&mut self) -> u32 {
        let e = self.camera();
        self.app
            .app
            .world()
            .resource::<bevy_envis::AccumulatedFrames>()
            .get(e)
            .unwrap_or(0)
    }

    /// The camera's sampling settings (change them between frames).
    pub fn sampling_mut(&mut self) -> Mut<'_, EnvironmentSampling> {
        let e = self.camera();
        let world = self.app.app.world_mut();
        world.get_mut::<EnvironmentSampling>(e).expect("camera")
    }
}
