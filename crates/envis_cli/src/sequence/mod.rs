//! An animated scene rendered frame by frame (`envis sequence`): each frame posed on the
//! sequence clock (`[animation]`), its map loaded for that time, shaded either by today's
//! estimator alone or with reservoir resampling across pixels and frames
//! ([`envis::render::resampling`]), which needs each pixel's place in the previous frame: the
//! point, moved back by its object's velocity, seen by the previous frame's camera. On the CPU
//! (the oracle), on a headless wgpu device (module `gpu`: the WGSL twins) or through Bevy
//! (module `bevy`).

mod bevy;
mod gpu;

use envis::envmap::load::{EnvSource, load_env};
use envis::envmap::{CubeMap, Image};
use envis::error::Result;
use envis::render::resampling::{
    self, History, Mutation, Resampling, Reservoirs, ReuseStats, Screen, Split,
};
use envis::render::{self, Extras, Settings};
use envis::scene::{Camera, Scene, SceneScreen};
use envis::visibility::{Occluder, ShadowRays};

/// What a sequence renders.
#[derive(Clone, Copy, Debug)]
pub struct SequenceOptions {
    /// Image width and height.
    pub size: usize,
    pub frames: u32,
    /// The candidates per pixel per frame with resampling; the whole budget without.
    pub settings: Settings,
    /// `None`: no resampling (today's estimator, every sample shadow-tested, the same seed in
    /// every frame).
    pub resampling: Option<Resampling>,
    /// Shadow rays (`None`: the scene file's choice).
    pub visibility: Option<ShadowRays>,
    pub backend: SequenceBackend,
}

/// Where a sequence is rendered.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SequenceBackend {
    /// The CPU oracle.
    #[default]
    Cpu,
    /// The WGSL passes on a headless wgpu device (`envis sequence --backend wgpu`).
    Wgpu,
    /// The Bevy pipeline in a headless app (`envis sequence --backend gpu`): the scene's meshes,
    /// Bevy's G-buffer and motion vectors, `EnvironmentResampling` on the camera.
    Bevy,
}

impl SequenceBackend {
    /// The `--backend` value that picks it.
    pub fn name(self) -> &'static str {
        match self {
            SequenceBackend::Cpu => "cpu",
            SequenceBackend::Wgpu => "wgpu",
            SequenceBackend::Bevy => "gpu",
        }
    }
}

/// One rendered frame.
pub struct SequenceFrame {
    pub image: Image,
    pub stats: FrameStats,
}

/// A frame's statistics (the `frames` list of `envis sequence --stats`).
#[derive(Clone, Debug, serde::Serialize)]
pub struct FrameStats {
    pub frame: u32,
    /// Seconds on the sequence clock.
    pub time: f32,
    /// Distribution and pool build, milliseconds.
    pub build_ms: f64,
    /// Candidates (or samples), reuse and shading, milliseconds.
    pub shade_ms: f64,
    /// Shadow rays cast this frame, over all pixels (`None`: not counted: the Bevy backend
    /// without resampling, whose plain lighting pass keeps no counts).
    pub shadow_rays: Option<u64>,
    /// Per shaded pixel.
    pub shadow_rays_per_pixel: Option<f64>,
    /// Light samples used and BRDF samples drawn, over all pixels.
    pub samples_evaluated: Option<u64>,
    pub shaded_pixels: Option<u64>,
    /// What reuse did (zeros without resampling).
    pub reuse: ReuseStats,
}

/// A frame posed and seen: what the next frame's reuse needs of it.
pub struct Posed {
    pub scene: Scene,
    pub map: CubeMap,
    pub screen: SceneScreen,
    pub camera: Camera,
    pub time: f32,
}

impl Posed {
    /// `scene` at time `t`, its map (faces of the scene file's size), its screen.
    pub fn new(scene: &Scene, t: f32, size: usize) -> Result<Posed> {
        let scene = scene.at_time(t)?;
        let src: EnvSource = scene.environment.parse()?;
        let map = load_env(&src, scene.file.environment.face_size)?.cube;
        Ok(Posed {
            screen: scene.screen(size, size),
            camera: scene.camera(size, size),
            map,
            scene,
            time: t,
        })
    }

    fn screen<'a>(&'a self, occluder: Option<&'a dyn Occluder>, split: &'a Split) -> Screen<'a> {
        Screen {
            split,
            gbuf: &self.screen.gbuf,
            points: &self.screen.points,
            surfaces: &self.screen.surfaces,
            width: self.camera.width,
            height: self.camera.height,
            occluder,
        }
    }

    /// Where pixel `i` was in `prev`: its point moved back by its object's velocity, projected
    /// by `prev`'s camera (by this frame's with [`Mutation::WrongReprojection`]).
    pub fn reproject(
        &self,
        prev: &Posed,
        i: usize,
        mutation: Option<Mutation>,
    ) -> Option<(usize, f32)> {
        self.screen.gbuf[i].as_ref()?;
        let s = self.screen.surfaces[i];
        let p = self
            .scene
            .earlier(s.id, self.screen.points[i], self.time - prev.time);
        match mutation {
            Some(Mutation::WrongReprojection) => self.camera.project(p),
            _ => prev.camera.project(p),
        }
    }
}

/// Render `o.frames` frames of `scene` on `o.backend`, handing each to `each` in order.
pub fn run(
    scene: &Scene,
    o: &SequenceOptions,
    each: impl FnMut(SequenceFrame) -> Result<()>,
) -> Result<()> {
    o.settings.validate()?;
    match o.backend {
        SequenceBackend::Cpu => run_cpu(scene, o, each),
        SequenceBackend::Wgpu => gpu::run(scene, o, each),
        SequenceBackend::Bevy => bevy::run(scene, o, each),
    }
}

/// [`run`] on the CPU.
fn run_cpu(
    scene: &Scene,
    o: &SequenceOptions,
    mut each: impl FnMut(SequenceFrame) -> Result<()>,
) -> Result<()> {
    let (shadows, _) = scene.shadows(o.visibility);
    let mut prev: Option<(Posed, Split, Vec<Reservoirs>)> = None;
    for k in 0..o.frames {
        let cur = Posed::new(scene, scene.frame_time(k), o.size)?;
        let occ = cur.scene.occluders();
        let occ: Option<&dyn Occluder> = shadows.then_some(&occ as _);
        let Some(r) = o.resampling else {
            each(plain_frame(&cur, occ, &o.settings, k)?)?;
            continue;
        };
        let prev_occ = prev.as_ref().map(|(p, _, _)| p.scene.occluders());
        let reproject = |i: usize| {
            let (p, _, _) = prev.as_ref()?;
            cur.reproject(p, i, r.mutation)
        };
        let history = prev.as_ref().map(|(p, split, res)| {
            let occ = prev_occ
                .as_ref()
                .filter(|_| shadows)
                .map(|o| o as &dyn Occluder);
            let h = History {
                screen: p.screen(occ, split),
                reservoirs: res,
                still_geometry: scene.geometry_is_still(),
            };
            (h, &reproject as resampling::Reproject)
        });
        let split = split_map(&cur.map, &r);
        let out =
            resampling::resample_frame(&cur.screen(occ, &split), history, &o.settings, &r, k)?;
        drop(prev_occ);
        each(SequenceFrame {
            stats: frame_stats(k, cur.time, &out.stats, out.reuse),
            image: out.image,
        })?;
        prev = Some((cur, split, out.reservoirs));
    }
    Ok(())
}

/// A frame's map split as `r` asks ([`Split`]); with [`Mutation::BrightCountedTwice`] the rest
/// keeps the bright texels.
fn split_map(map: &CubeMap, r: &Resampling) -> Split {
    match (r.split_bright, r.mutation) {
        (true, Some(Mutation::BrightCountedTwice)) => Split {
            rest: map.clone(),
            ..Split::new(map)
        },
        (true, _) => Split::new(map),
        (false, _) => Split::whole(map),
    }
}

/// A frame of today's estimator (every sample shadow-tested).
fn plain_frame(
    cur: &Posed,
    occ: Option<&dyn Occluder>,
    s: &Settings,
    k: u32,
) -> Result<SequenceFrame> {
    let extras = Extras {
        shadows: occ.map(|o| (o, cur.screen.points.as_slice())),
        ..Default::default()
    };
    let (w, h) = (cur.camera.width, cur.camera.height);
    let out = render::render_with(&cur.map, extras, &cur.screen.gbuf, w, h, s)?;
    Ok(SequenceFrame {
        stats: frame_stats(k, cur.time, &out.stats, ReuseStats::default()),
        image: out.image,
    })
}

fn frame_stats(k: u32, time: f32, st: &render::RenderStats, reuse: ReuseStats) -> FrameStats {
    FrameStats {
        frame: k,
        time,
        build_ms: st.build_ms,
        shade_ms: st.shade_ms,
        shadow_rays: Some(st.shadow_rays),
        shadow_rays_per_pixel: Some(st.shadow_rays as f64 / st.shaded_pixels.max(1) as f64),
        samples_evaluated: Some(st.samples_evaluated),
        shaded_pixels: Some(st.shaded_pixels),
        reuse,
    }
}
