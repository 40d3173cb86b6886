//! What `render` and `reference` share: the material of the command line, and the environment,
//! G-buffer and material of `--scene` (the unit sphere, or a scene file).

use crate::{BrdfArg, RadianceArg, SceneArgs};
use envis::envmap::load::{EnvSource, LoadedEnv, load_env, load_env_full};
use envis::error::{Error, Result};
use envis::render;
use envis::sampling::Material;
use envis::visibility::ShadowRays;

pub fn material(a: &SceneArgs) -> Result<Material> {
    if !(a.albedo.is_finite() && a.albedo >= 0.0) {
        return Err(Error::invalid(format!(
            "--albedo {} must be finite and >= 0",
            a.albedo
        )));
    }
    Ok(match a.brdf {
        BrdfArg::Diffuse => Material::diffuse(a.albedo),
        BrdfArg::Phong => {
            if !(a.exponent.is_finite() && a.exponent >= 0.0) {
                return Err(Error::invalid(format!(
                    "--exponent {} must be finite and >= 0",
                    a.exponent
                )));
            }
            Material::phong(a.albedo, a.exponent)
        }
        BrdfArg::Ggx => {
            if !(a.alpha.is_finite() && a.alpha > 0.0 && a.alpha <= 1.0) {
                return Err(Error::invalid(format!(
                    "--alpha {} must be in (0, 1]",
                    a.alpha
                )));
            }
            Material::ggx(a.albedo, a.alpha)
        }
    })
}

/// What [`setup`] returns.
pub struct Setup {
    pub env: LoadedEnv,
    pub gbuf: Vec<Option<render::GPixel>>,
    /// Each pixel's surface point (where its shadow rays leave from).
    pub points: Vec<glam::Vec3>,
    /// The material of the sphere (or of the scene's first object).
    pub material: Material,
    pub scene: Option<envis::scene::Scene>,
}

/// The unit sphere of the `sphere` scene, for its shadow rays (it cannot shadow itself).
const UNIT_SPHERE: envis::scene::Shape = envis::scene::Shape::Sphere {
    center: glam::Vec3::ZERO,
    radius: 1.0,
};

impl Setup {
    /// Whether to cast shadow rays (`--visibility`, else the scene file's, else `auto`) and why.
    pub fn shadows(&self, mode: Option<ShadowRays>) -> (bool, String) {
        match &self.scene {
            Some(sc) => sc.shadows(mode),
            None => match mode.unwrap_or_default() {
                ShadowRays::Auto => envis::scene::shadows::auto_rule(&[&UNIT_SPHERE]),
                ShadowRays::On => (true, "on (asked for)".into()),
                ShadowRays::Off => (false, "off (asked for)".into()),
            },
        }
    }

    /// The shadow-casting geometry as the GPU traces it.
    pub fn shadow_bvh(&self) -> std::result::Result<envis::visibility::FlatBvh, String> {
        self.occluders().flat()
    }

    /// The shapes that block shadow rays.
    pub fn occluders(&self) -> envis::scene::shadows::Occluders<'_> {
        match &self.scene {
            Some(sc) => sc.occluders(),
            None => envis::scene::shadows::Occluders::new(vec![&UNIT_SPHERE]),
        }
    }
}

/// The environment, G-buffer and material of `--scene`: `sphere` (with the command-line
/// environment and material), or a TOML scene file, which supplies everything but the size.
pub fn setup(a: &SceneArgs) -> Result<Setup> {
    if a.size == 0 || a.size > 16384 {
        return Err(Error::invalid(format!(
            "--size {} out of range 1..=16384",
            a.size
        )));
    }
    if a.scene != "sphere" {
        if !a.scene.ends_with(".toml") {
            return Err(Error::invalid(format!(
                "unknown scene '{}' (expected: sphere, or a .toml scene file)",
                a.scene
            )));
        }
        let sc = envis::scene::Scene::load(std::path::Path::new(&a.scene))?.at_time(a.time)?;
        let src: EnvSource = sc.environment.parse()?;
        let env = load(a, &src, sc.file.environment.face_size)?;
        if env.report.total() > 0 {
            eprintln!("envis: {}: {}", sc.environment, env.report);
        }
        let (gbuf, points) = sc.gbuffer_points(a.size, a.size);
        return Ok(Setup {
            env,
            gbuf,
            points,
            material: sc.objects[0].material,
            scene: Some(sc),
        });
    }
    if a.time != 0.0 {
        return Err(Error::invalid(
            "--time needs a scene file (--scene FILE.toml with an [animation] table)",
        ));
    }
    let mat = material(a)?;
    let src: EnvSource = a.env.parse()?;
    let env = load(a, &src, a.face_size)?;
    if env.report.total() > 0 {
        eprintln!("envis: {}: {}", a.env, env.report);
    }
    let gbuf = render::sphere_gbuffer(a.size, a.size, mat);
    // On the unit sphere at the origin a point is its normal.
    let points = gbuf
        .iter()
        .map(|p| p.as_ref().map_or(glam::Vec3::ZERO, |p| p.n))
        .collect();
    Ok(Setup {
        env,
        gbuf,
        points,
        material: mat,
        scene: None,
    })
}

pub fn check_exr_path(p: &std::path::Path) -> Result<()> {
    match p.extension().and_then(|e| e.to_str()) {
        Some(e) if e.eq_ignore_ascii_case("exr") => Ok(()),
        _ => Err(Error::invalid(format!(
            "--out {}: output must be an .exr file",
            p.display()
        ))),
    }
}

/// The environment at `face_size`, with the map at its own resolution for `--radiance full`.
fn load(a: &SceneArgs, src: &EnvSource, face_size: usize) -> Result<LoadedEnv> {
    match a.radiance {
        RadianceArg::Full => load_env_full(src, face_size),
        RadianceArg::Distribution => load_env(src, face_size),
    }
}
