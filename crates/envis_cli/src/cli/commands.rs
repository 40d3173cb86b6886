//! `envis render`, `envis reference` and `envis cross`: the bodies of the commands whose
//! arguments `main.rs` parses.

use super::scene::{check_exr_path, setup};
use crate::{BackendArg, CrossArgs, ReferenceArgs, RenderArgs};
use envis::envmap::load::load_env;
use envis::error::{Error, Result};
use envis::render::{self, PoolLayout, Settings, output, reference};
use envis::sampling::SubTexels;

/// `envis render`.
pub fn render(r: RenderArgs) -> Result<()> {
    check_exr_path(&r.out)?;
    let settings = render_settings(&r);
    settings.validate()?;
    let su = setup(&r.scene)?;
    let (env, gbuf) = (&su.env, &su.gbuf);
    // A scene file supplies the sampling settings too.
    let settings = su.scene.as_ref().map_or(settings, |sc| sc.settings);
    let size = r.scene.size;
    let (shadows, why) = su.shadows(r.scene.visibility);
    let (mut out, mut extra) = match r.backend {
        BackendArg::Cpu => (
            render_cpu(&su, shadows, size, &settings)?,
            serde_json::json!({ "backend": "cpu" }),
        ),
        BackendArg::Wgpu => {
            // The GPU traces triangles: the scene's meshes, and a tessellated sphere and a
            // square for each analytic one (`Scene::shadow_bvh`).
            let bvh = match shadows {
                true => Some(su.shadow_bvh().map_err(Error::invalid)?),
                false => None,
            };
            let shadows = bvh.as_ref().map(|b| (b, su.points.as_slice()));
            render_wgpu(&env.cube, env.fine.as_ref(), gbuf, size, &settings, shadows)?
        }
        BackendArg::Gpu => render_bevy(&r.scene, &settings, su.scene.as_ref(), shadows)?,
    };
    out.stats.visibility = why;
    extra["radiance"] = radiance_note(env, Some(r.backend)).into();
    // What the loader clamped, plus anything the GPU's own sanitise pass found.
    out.stats.clamped_texels.add(env.report);
    write_render(&r, &out, &extra)
}

/// `envis render`'s sampling settings from its flags (a scene file's replace them).
fn render_settings(r: &RenderArgs) -> Settings {
    Settings {
        light_samples: r.light_samples,
        brdf_samples: r.brdf_samples,
        pool_size: r.pool,
        strategy: r.strategy,
        counts: r.counts,
        heuristic: r.mis,
        seed: r.seed,
        pool_layout: if r.pixel_offset {
            PoolLayout::Offset
        } else {
            r.pool_layout
        },
        pool_blocks: r.pool_blocks,
        material_budget: r.material_budget,
        tiles: r.tiles,
        tile_counts: r.tile_counts,
        face_size: r.scene.face_size,
        shadows: r.scene.visibility.unwrap_or_default(),
        ..Default::default()
    }
}

/// `--backend cpu`: radiance (and sub-texel placement) from the map at its own resolution.
fn render_cpu(
    su: &super::scene::Setup,
    shadows: bool,
    size: usize,
    settings: &Settings,
) -> Result<render::Rendered> {
    let env = &su.env;
    let occluders = su.occluders();
    let lookup = |d: glam::Vec3| env.radiance_map().lookup(d);
    let extras = render::Extras {
        shadows: shadows.then_some((&occluders as _, su.points.as_slice())),
        fine: env.fine.is_some().then_some(&lookup as _),
        sub_texels: env.fine.as_ref(),
    };
    render::render_with(&env.cube, extras, &su.gbuf, size, size, settings)
}

/// The render's EXR, and the PNG and stats JSON (with the backend's `extra` fields) if asked.
fn write_render(r: &RenderArgs, out: &render::Rendered, extra: &serde_json::Value) -> Result<()> {
    output::write_exr(&r.out, &out.image)?;
    if let Some(p) = &r.png {
        output::write_png(p, &out.image, 1.0)?;
    }
    if let Some(p) = &r.stats {
        let mut v =
            serde_json::to_value(&out.stats).map_err(|e| Error::invalid(format!("stats: {e}")))?;
        if let (Some(o), Some(e)) = (v.as_object_mut(), extra.as_object()) {
            o.extend(e.clone());
        }
        output::write_json(p, &v)?;
    }
    Ok(())
}

/// `envis reference`.
pub fn reference(r: ReferenceArgs) -> Result<()> {
    check_exr_path(&r.out)?;
    if !(r.refine.is_finite() && r.refine > 0.0) {
        return Err(Error::invalid("--refine must be > 0"));
    }
    let su = setup(&r.scene)?;
    let (env, gbuf, mat) = (&su.env, &su.gbuf, su.material);
    let (shadows, why) = su.shadows(r.scene.visibility);
    let occluders = su.occluders();
    let shadows = shadows.then_some((&occluders as _, su.points.as_slice()));
    let t = std::time::Instant::now();
    let size = r.scene.size;
    // The map the renders read radiance from (`--radiance`): the reference integrates it.
    let map = env.radiance_map();
    let (img, _) = reference::reference_image_with(map, gbuf, shadows, size, size, r.refine);
    let ms = t.elapsed().as_secs_f64() * 1e3;
    output::write_exr(&r.out, &img)?;
    if let Some(p) = &r.png {
        output::write_png(p, &img, 1.0)?;
    }
    if let Some(p) = &r.stats {
        let k = reference::subdivision(map.size, &mat, r.refine);
        output::write_json(
            p,
            &serde_json::json!({ "reference_ms": ms, "subtexel_points_per_axis": k, "clamped_texels": env.report, "visibility": why, "radiance": radiance_note(env, None) }),
        )?;
    }
    Ok(())
}

/// `envis cross`.
pub fn cross(c: CrossArgs) -> Result<()> {
    let env = load_env(&c.env.parse()?, c.face_size)?;
    if env.report.total() > 0 {
        eprintln!("envis: {}: {}", c.env, env.report);
    }
    let img = envis::envmap::cube_to_cross(&env.cube);
    match c
        .out
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .as_deref()
    {
        Some("exr") => output::write_exr(&c.out, &img),
        Some("png") => output::write_png(&c.out, &img, c.exposure),
        _ => Err(Error::invalid(format!(
            "--out {}: expected .exr or .png",
            c.out.display()
        ))),
    }
}

/// `--backend wgpu`: the WGSL stages on a headless wgpu device (the same shaders the Bevy app runs).
fn render_wgpu(
    map: &envis::envmap::CubeMap,
    fine: Option<&envis::envmap::CubeMap>,
    gbuf: &[Option<render::GPixel>],
    size: usize,
    s: &Settings,
    shadows: Option<(&envis::visibility::FlatBvh, &[glam::Vec3])>,
) -> Result<(render::Rendered, serde_json::Value)> {
    let extras = envis_wgpu::GpuExtras { fine, shadows };
    let ctx = envis_wgpu::GpuContext::new()?;
    let (out, t) =
        envis_wgpu::GpuRenderer::new(&ctx).render_with(map, extras, gbuf, size, size, s)?;
    let extra = serde_json::json!({ "backend": "wgpu", "device": ctx.info.name, "device_backend": format!("{:?}", ctx.info.backend), "gpu_timings": t });
    Ok((out, extra))
}

/// `--backend gpu`: the Bevy app headless (no window), sphere mesh + deferred G-buffer. Pixels
/// off the sphere are 0, as in the CPU contract (the app's sky pass is off).
fn render_bevy(
    a: &crate::SceneArgs,
    s: &Settings,
    scene: Option<&envis::scene::Scene>,
    shadows: bool,
) -> Result<(render::Rendered, serde_json::Value)> {
    use bevy_envis::EnvisBrdf;
    use envis::envmap::load::EnvSource;
    use envis::visibility::ShadowRays;
    use envis_cli::headless::HeadlessSphere;
    envis_wgpu::context::check_adapter()?;
    use envis::stream::{EnvStream, StreamSource};
    let mut settings = *s;
    // Bevy traces the meshes it draws (a tessellated sphere included).
    settings.shadows = if shadows {
        ShadowRays::On
    } else {
        ShadowRays::Off
    };
    if let Some(sc) = scene {
        return render_bevy_scene(sc, settings, a.size, s);
    }
    let mat = super::scene::material(a)?;
    let em = EnvisBrdf::from_material(&mat);
    let source = match a.env.parse::<EnvSource>()? {
        EnvSource::Sky { hours } => StreamSource::Sky { hours, speed: 0.0 },
        EnvSource::File(p) => StreamSource::File(p),
    };
    EnvStream::open(source.clone(), a.face_size)?; // refuse a bad source here, with its error
    let t0 = std::time::Instant::now();
    let mut app = HeadlessSphere::new(source, a.face_size, em, settings, a.size as u32);
    let out = captured(&mut app, t0, a.size, s)?;
    let c = app.counters();
    let t = app
        .app
        .app
        .world()
        .resource::<bevy_envis::EnvisTimings>()
        .get();
    let extra = serde_json::json!({
        "backend": "gpu",
        "pipeline": "bevy (offscreen)",
        "pass_times_ms": t,
        "note": "shade_ms is the wall time of the whole headless app (start-up, pipelines, frames); per-pixel sample counts are not read back",
        "distribution_builds": c.get(|c| &c.builds),
        "lighting_passes": c.get(|c| &c.lighting_passes),
    });
    Ok((out, extra))
}

/// `--backend gpu` with `--scene`: the scene's objects and camera in the headless app.
fn render_bevy_scene(
    sc: &envis::scene::Scene,
    settings: Settings,
    size: usize,
    s: &Settings,
) -> Result<(render::Rendered, serde_json::Value)> {
    use envis_cli::headless::HeadlessSphere;
    let t0 = std::time::Instant::now();
    let mut app = HeadlessSphere::from_scene(sc, settings, size as u32)?;
    let out = captured(&mut app, t0, size, s)?;
    let extra =
        serde_json::json!({ "backend": "gpu", "pipeline": "bevy (offscreen)", "scene": sc.path });
    Ok((out, extra))
}

/// The headless app's `size`² image with the statistics of `s`, `shade_ms` the wall time since
/// `t0` (the app's start-up included).
fn captured(
    app: &mut envis_cli::headless::HeadlessSphere,
    t0: std::time::Instant,
    size: usize,
    s: &Settings,
) -> Result<render::Rendered> {
    let data = app.capture()?;
    let mut stats = render::RenderStats::for_settings(size, size, s, s.pool_per_face());
    stats.shade_ms = t0.elapsed().as_secs_f64() * 1e3;
    let image = envis::envmap::Image {
        width: size,
        height: size,
        data,
    };
    Ok(render::Rendered { image, stats })
}

/// Where the samples' radiance came from, for `--stats`.
fn radiance_note(env: &envis::envmap::load::LoadedEnv, backend: Option<BackendArg>) -> String {
    let n = env.radiance_map().size;
    match (backend, &env.fine) {
        (Some(BackendArg::Gpu), _) => "the image itself (the Bevy pass)".into(),
        (Some(_), Some(_)) => match SubTexels::ratio_of(n, env.cube.size) {
            Some(r) => format!(
                "the map at its own resolution ({n}^2 faces); light samples placed inside each \
                 distribution texel by the luminance of its {r}x{r} texels"
            ),
            None => format!("the map at its own resolution ({n}^2 faces)"),
        },
        (None, Some(_)) => format!("the map at its own resolution ({n}^2 faces)"),
        (_, None) => format!("the distribution's map ({n}^2 faces)"),
    }
}
