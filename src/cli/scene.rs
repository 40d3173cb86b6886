//! What `render` and `reference` share: the material of the command line, and the environment,
//! G-buffer and material of `--scene` (the unit sphere, or a scene file).

use crate::{BrdfArg, SceneArgs};
use envis::envmap::load::{EnvSource, LoadedEnv, load_env};
use envis::error::{Error, Result};
use envis::render;
use envis::sampling::Material;

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

/// The environment, G-buffer and material of `--scene`: `sphere` (with the command-line
/// environment and material), or a TOML scene file, which supplies everything but the size.
/// What [`setup`] returns: the environment, the G-buffer, the material and the scene file.
pub type Setup = (
    LoadedEnv,
    Vec<Option<render::GPixel>>,
    Material,
    Option<envis::scene::Scene>,
);

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
        let sc = envis::scene::Scene::load(std::path::Path::new(&a.scene))?;
        let src: EnvSource = sc.environment.parse()?;
        let env = load_env(&src, sc.file.environment.face_size)?;
        if env.report.total() > 0 {
            eprintln!("envis: {}: {}", sc.environment, env.report);
        }
        let gbuf = sc.gbuffer(a.size, a.size);
        return Ok((env, gbuf, sc.objects[0].material, Some(sc)));
    }
    let mat = material(a)?;
    let src: EnvSource = a.env.parse()?;
    let env = load_env(&src, a.face_size)?;
    if env.report.total() > 0 {
        eprintln!("envis: {}: {}", a.env, env.report);
    }
    Ok((env, render::sphere_gbuffer(a.size, a.size, mat), mat, None))
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
