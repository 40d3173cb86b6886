//! `envis bench --suite ready`: how long a game waits for envis's first lit
//! frame, and on what. A headless Bevy app started as a game starts (pipelines compiled
//! asynchronously, the map loaded by the `AssetServer`: `assets/hdri/park.exr`, or `--env`'s
//! `.exr` / `.hdr` file), a sphere and a camera at `--size`; per configuration:
//! - from start-up: when the map was loaded (its `AssetEvent`), when Bevy's own pipelines were
//!   compiled (its pipeline cache empty: the first frame Bevy draws everything), when each of
//!   envis's programs was compiled on its thread, and when the camera got `EnvisLightReady`;
//! - from a map's load event to `EnvisLightReady` for a camera added once all is compiled (a
//!   new level's first map);
//! - the same app without envis, in the same sitting: when Bevy alone had compiled everything.
//!
//! Results in `DIR/bench-ready.json`. Wall-clock times of one run each (compiling is done once
//! per run; a second run in the same process would find the driver's caches warm).

use super::BenchArgs;
use crate::headless::HeadlessApp;
use bevy::camera::RenderTarget;
use bevy::prelude::*;
use bevy_envis::{
    EnvironmentResampling, EnvironmentSampling, EnvisEnvironment, EnvisLightReady, ReadyReport,
};
use envis::error::{Error, Result};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// How long a configuration may take before it is reported as never ready.
const LIMIT: Duration = Duration::from_secs(300);

/// What one configuration's camera does.
#[derive(Clone, Copy, Debug, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
enum Config {
    /// `EnvironmentSampling` with `--light-samples` + `--brdf-samples`.
    Sampling,
    /// The same with `EnvironmentResampling::default()`.
    Resampling,
    /// No envis at all: Bevy alone, rendering deferred with the prepasses envis needs (the
    /// baseline: the same pipelines of Bevy's to compile).
    BevyAlone,
}

/// Seconds from start-up (or from the map's load event, where said) until each event.
#[derive(Debug, Default, serde::Serialize)]
struct Row {
    config: Option<Config>,
    map_loaded_s: Option<f64>,
    bevy_compiled_s: Option<f64>,
    /// envis's programs, each with the second it was compiled on envis's thread.
    programs_s: Vec<(String, f64)>,
    ready_s: Option<f64>,
    /// A camera added after everything compiled, its map loaded then: load event to ready.
    new_map_to_ready_s: Option<f64>,
    frames: u32,
}

pub fn run(a: BenchArgs, dir: PathBuf) -> Result<()> {
    let (assets, ext) = map_folder(&a)?;
    let mut rows = Vec::new();
    for config in [Config::BevyAlone, Config::Sampling, Config::Resampling] {
        let row = measure(config, &a, (&assets, &ext))?;
        println!("{}", describe(&row));
        rows.push(row);
    }
    let path = dir.join("bench-ready.json");
    let json = serde_json::to_string_pretty(&rows).map_err(|e| Error::invalid(e.to_string()))?;
    std::fs::write(&path, json).map_err(|e| Error::file(&path, e.to_string()))?;
    println!("wrote {}", path.display());
    Ok(())
}

/// A folder for the `AssetServer` holding the map twice (`first.EXT`, `second.EXT`: the second
/// is loaded anew for the new camera), and the extension: the map is `--env` where it names a
/// file, else the repository's `assets/hdri/park.exr`.
fn map_folder(a: &BenchArgs) -> Result<(PathBuf, String)> {
    let path = Path::new(&a.env);
    let path = if path.is_file() {
        path.to_path_buf()
    } else {
        crate::repo_path("assets/hdri/park.exr")
    };
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("exr");
    let dir = std::env::temp_dir().join(format!("envis-bench-ready-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| Error::file(&dir, e.to_string()))?;
    for name in ["first", "second"] {
        let to = dir.join(format!("{name}.{ext}"));
        std::fs::copy(&path, &to).map_err(|e| Error::file(&path, e.to_string()))?;
    }
    Ok((dir, ext.to_string()))
}

fn describe(r: &Row) -> String {
    let s = |t: Option<f64>| t.map_or("never".into(), |t| format!("{t:.2}s"));
    let programs: Vec<String> = r
        .programs_s
        .iter()
        .map(|(p, t)| format!("{p} {t:.2}s"))
        .collect();
    format!(
        "{:?}: map loaded {}, Bevy compiled {}, ready {}, new map to ready {} ({} frames); envis \
         programs: {}",
        r.config.unwrap_or(Config::BevyAlone),
        s(r.map_loaded_s),
        s(r.bevy_compiled_s),
        s(r.ready_s),
        s(r.new_map_to_ready_s),
        r.frames,
        programs.join(", ")
    )
}

/// One run of `config` in a fresh app.
fn measure(config: Config, a: &BenchArgs, (assets, ext): (&Path, &str)) -> Result<Row> {
    let started = Instant::now();
    let mut h = match config {
        Config::BevyAlone => {
            let mut h = HeadlessApp::bevy_alone_as_a_game(assets);
            // Only the report of what each frame waited on (envis's part of it stays empty).
            bevy_envis::ready::add_ready(&mut h.app);
            // Deferred, as envis makes it: the same pipelines of Bevy's to compile.
            h.app
                .insert_resource(bevy::pbr::DefaultOpaqueRendererMethod::deferred());
            h
        }
        _ => HeadlessApp::as_a_game(assets),
    };
    let since = |t: Instant| t.duration_since(started).as_secs_f64();
    let server = h.app.world().resource::<AssetServer>().clone();
    let map: Handle<Image> = server.load(format!("first.{ext}"));
    let size = a.size as u32;
    let camera = spawn_view(&mut h, (config, a), map.clone(), size);
    let mut row = Row {
        config: Some(config),
        ..Row::default()
    };
    while started.elapsed() < LIMIT {
        h.update();
        row.frames += 1;
        let now = Instant::now();
        if row.map_loaded_s.is_none() && server.is_loaded_with_dependencies(&map) {
            row.map_loaded_s = Some(since(now));
        }
        if row.bevy_compiled_s.is_none() {
            row.bevy_compiled_s = bevy_compiled(&h).map(since);
        }
        if row.ready_s.is_none() && h.app.world().get::<EnvisLightReady>(camera).is_some() {
            row.ready_s = Some(since(now));
        }
        let envis_done = matches!(config, Config::BevyAlone) || row.ready_s.is_some();
        if envis_done && row.bevy_compiled_s.is_some() && programs_done(&h, config) {
            break;
        }
    }
    row.programs_s = program_times(&h);
    if !matches!(config, Config::BevyAlone) && row.ready_s.is_some() {
        row.new_map_to_ready_s = new_map_to_ready(&mut h, (config, a), ext);
    }
    Ok(row)
}

/// A sphere and a camera rendering into a `size` x `size` image, lit by `map` unless `config`
/// is Bevy alone.
fn spawn_view(
    h: &mut HeadlessApp,
    (config, a): (Config, &BenchArgs),
    map: Handle<Image>,
    size: u32,
) -> Entity {
    let mesh = h.add::<Mesh>(Sphere::new(1.0).mesh().ico(5).expect("icosphere"));
    let material = h.add::<StandardMaterial>(StandardMaterial::default());
    h.app
        .world_mut()
        .spawn((Mesh3d(mesh), MeshMaterial3d(material)));
    let target = h.float_target(size, size);
    let mut camera = h.app.world_mut().spawn((
        Camera3d::default(),
        RenderTarget::from(target),
        Transform::from_xyz(0.0, 0.0, 3.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    if matches!(config, Config::BevyAlone) {
        // What `EnvironmentSampling` requires of a camera.
        use bevy::core_pipeline::prepass::{DeferredPrepass, DepthPrepass};
        camera.insert((DepthPrepass, DeferredPrepass, Msaa::Off, bevy::camera::Hdr));
    } else {
        camera.insert((
            EnvironmentSampling {
                light_samples: a.light_samples,
                brdf_samples: a.brdf_samples,
                ..default()
            },
            EnvisEnvironment::new(map),
        ));
    }
    if matches!(config, Config::Resampling) {
        camera.insert(EnvironmentResampling::default());
    }
    camera.id()
}

/// When the render world first found Bevy's start-up pipelines compiled.
fn bevy_compiled(h: &HeadlessApp) -> Option<Instant> {
    report(h).and_then(|r| r.bevy_started())
}

fn report(h: &HeadlessApp) -> Option<&ReadyReport> {
    h.app.world().get_resource::<ReadyReport>()
}

/// Whether envis's compile thread had compiled all it queued (Bevy alone: nothing to compile).
fn programs_done(h: &HeadlessApp, config: Config) -> bool {
    matches!(config, Config::BevyAlone) || report(h).is_some_and(|r| r.programs().all_done())
}

fn program_times(h: &HeadlessApp) -> Vec<(String, f64)> {
    let times = report(h)
        .map(|r| r.programs().done_so_far())
        .unwrap_or_default();
    times
        .into_iter()
        .map(|(p, t)| (format!("{p:?}"), t.as_secs_f64()))
        .collect()
}

/// In an app where everything is compiled: a new camera whose map is loaded now (the second
/// copy of the file, new to the server); seconds from its load event to ready.
fn new_map_to_ready(
    h: &mut HeadlessApp,
    (config, a): (Config, &BenchArgs),
    ext: &str,
) -> Option<f64> {
    let server = h.app.world().resource::<AssetServer>().clone();
    let map: Handle<Image> = server.load(format!("second.{ext}"));
    let camera = spawn_view(h, (config, a), map.clone(), 16);
    let (start, mut loaded) = (Instant::now(), None);
    while start.elapsed() < LIMIT {
        h.update();
        if loaded.is_none() && server.is_loaded_with_dependencies(&map) {
            loaded = Some(Instant::now());
        }
        if let Some(t) = loaded
            && h.app.world().get::<EnvisLightReady>(camera).is_some()
        {
            return Some(t.elapsed().as_secs_f64());
        }
    }
    None
}
