//! [`EnvisMaterial`]: a Bevy `Material` whose deferred fragment shader writes envis's BRDFs
//! (Lambert, normalised Phong, GGX, a Lambert + GGX mix) into Bevy's G-buffer, under its own
//! deferred lighting pass id ([`ENVIS_LIGHTING_PASS_ID`]), so Bevy's deferred lighting leaves
//! these pixels to envis. The design card's custom deferred material.
//!
//! G-buffer layout (`envis_material.wgsl`, decoded in `shaders/lighting.wgsl`):
//! `x` = kd in Bevy's 8-bit `pow(c, 1/2.2)` encoding + the lobe kind, `y` = ks likewise,
//! `z` = the lobe parameter (Phong exponent or GGX alpha) as f32 bits, `w` = Bevy's 24-bit
//! octahedral normal.

use bevy::asset::{AssetPath, embedded_asset, embedded_path};
use bevy::material::OpaqueRendererMethod;
use bevy::pbr::{Material, MaterialPlugin};
use bevy::prelude::*;
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::{AsBindGroup, AsBindGroupShaderType, ShaderType};
use bevy::render::texture::GpuImage;
use bevy::shader::ShaderRef;
use envis::sampling::{Lobe, Material as CoreMaterial};
use envis_wgpu::GpuCode;

/// The deferred lighting pass id of [`EnvisMaterial`] pixels. Bevy's `StandardMaterial` uses 1
/// (lit by Bevy's lights, then envis adds the environment); pixels with this id are lit by envis
/// alone. Pick another id for your own deferred materials.
pub const ENVIS_LIGHTING_PASS_ID: u8 = 231;

/// The BRDF of an [`EnvisMaterial`].
#[derive(Clone, Copy, Debug, PartialEq, Reflect)]
#[reflect(Clone, Debug, PartialEq)]
pub enum EnvisBrdf {
    Lambert {
        albedo: Vec3,
    },
    /// Normalised Phong around the mirror direction (exponent up to 1e6).
    Phong {
        albedo: Vec3,
        exponent: f32,
    },
    /// GGX microfacet with F = 1.
    Ggx {
        albedo: Vec3,
        alpha: f32,
    },
    /// Lambert `(1 - specular) albedo` plus GGX `specular albedo`.
    Mix {
        albedo: Vec3,
        specular: f32,
        alpha: f32,
    },
}

/// sRGB-ish 8-bit round trip of the G-buffer's colours (`pow(c, 1/2.2)` in unorm8, as Bevy's).
pub(crate) fn gbuffer_color(c: Vec3) -> Vec3 {
    c.map(|x| ((x.clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0).round() / 255.0).powf(2.2))
}

impl EnvisBrdf {
    /// The core material (what the CPU renderer shades), exactly.
    pub fn material(&self) -> CoreMaterial {
        let clamp_alpha = |a: f32| a.clamp(envis::sampling::brdf::MIN_ALPHA, 1.0);
        match *self {
            EnvisBrdf::Lambert { albedo } => CoreMaterial {
                kd: albedo,
                ks: Vec3::ZERO,
                lobe: Lobe::None,
            },
            EnvisBrdf::Phong { albedo, exponent } => CoreMaterial {
                kd: Vec3::ZERO,
                ks: albedo,
                lobe: Lobe::Phong {
                    exponent: exponent.clamp(0.0, envis::sampling::brdf::MAX_EXPONENT),
                },
            },
            EnvisBrdf::Ggx { albedo, alpha } => CoreMaterial {
                kd: Vec3::ZERO,
                ks: albedo,
                lobe: Lobe::Ggx {
                    alpha: clamp_alpha(alpha),
                },
            },
            EnvisBrdf::Mix {
                albedo,
                specular,
                alpha,
            } => {
                let s = specular.clamp(0.0, 1.0);
                CoreMaterial {
                    kd: albedo * (1.0 - s),
                    ks: albedo * s,
                    lobe: Lobe::Ggx {
                        alpha: clamp_alpha(alpha),
                    },
                }
            }
        }
    }

    /// The BRDF of a core material (a scene file's).
    pub fn from_material(m: &CoreMaterial) -> Self {
        match m.lobe {
            Lobe::None => EnvisBrdf::Lambert { albedo: m.kd },
            Lobe::Phong { exponent } => EnvisBrdf::Phong {
                albedo: m.ks + m.kd,
                exponent,
            },
            Lobe::Ggx { alpha } | Lobe::GgxSchlick { alpha } if m.kd.max_element() <= 0.0 => {
                EnvisBrdf::Ggx {
                    albedo: m.ks,
                    alpha,
                }
            }
            Lobe::Ggx { alpha } | Lobe::GgxSchlick { alpha } => {
                let all = m.kd + m.ks;
                let lum = envis::envmap::luminance;
                EnvisBrdf::Mix {
                    albedo: all,
                    specular: lum(m.ks) / lum(all).max(1e-6),
                    alpha,
                }
            }
        }
    }

    /// What the lighting pass decodes from the G-buffer (colours through 8 bits, the lobe
    /// parameter exact): what the CPU twin must shade to compare with a Bevy frame.
    pub fn decoded(&self) -> CoreMaterial {
        let m = self.material();
        CoreMaterial {
            kd: gbuffer_color(m.kd),
            ks: gbuffer_color(m.ks),
            lobe: m.lobe,
        }
    }
}

fn unorm8(x: f32) -> f32 {
    (x.clamp(0.0, 1.0) * 255.0).round() / 255.0
}

/// The material the lighting pass shades for a `StandardMaterial` pixel (twin of
/// `decode_standard` in `shaders/lighting.wgsl`, through the G-buffer's 8-bit quantisation):
/// Lambert `kd = base (1 - metallic)` plus Bevy's GGX with Schlick's Fresnel,
/// `F0 = 0.16 reflectance^2 (1 - metallic) + base metallic`, `alpha = clamp(roughness, 0.089,
/// 1)^2`. Textures, a specular tint and occlusion are not modelled here (white, none).
pub fn standard_material_decoded(m: &StandardMaterial) -> CoreMaterial {
    let c = m.base_color.to_linear();
    let base = gbuffer_color(Vec3::new(c.red, c.green, c.blue));
    let (metallic, reflectance) = (unorm8(m.metallic), unorm8(m.reflectance));
    let pr = unorm8(m.perceptual_roughness).clamp(0.089, 1.0);
    CoreMaterial {
        kd: base * (1.0 - metallic),
        ks: Vec3::splat(0.16 * reflectance * reflectance * (1.0 - metallic)) + base * metallic,
        lobe: Lobe::GgxSchlick { alpha: pr * pr },
    }
}

/// An envis material: meshes with it are lit by the environment alone (Bevy's lights do not
/// reach them; see `docs/bevy.md`). Deferred only: it is drawn by cameras with
/// [`super::EnvironmentSampling`] (any camera with a deferred prepass writes its G-buffer).
///
/// Reflected like Bevy's own materials, so inspectors and scene files can edit it.
#[derive(Asset, AsBindGroup, Reflect, Clone, Debug)]
#[reflect(Clone, Debug)]
#[uniform(0, EnvisMaterialUniform)]
pub struct EnvisMaterial {
    pub brdf: EnvisBrdf,
}

impl From<EnvisBrdf> for EnvisMaterial {
    fn from(brdf: EnvisBrdf) -> Self {
        EnvisMaterial { brdf }
    }
}

impl EnvisMaterial {
    pub fn lambert(albedo: Vec3) -> Self {
        EnvisBrdf::Lambert { albedo }.into()
    }
    pub fn phong(albedo: Vec3, exponent: f32) -> Self {
        EnvisBrdf::Phong { albedo, exponent }.into()
    }
    pub fn ggx(albedo: Vec3, alpha: f32) -> Self {
        EnvisBrdf::Ggx { albedo, alpha }.into()
    }
    pub fn mix(albedo: Vec3, specular: f32, alpha: f32) -> Self {
        EnvisBrdf::Mix {
            albedo,
            specular,
            alpha,
        }
        .into()
    }
}

/// The GPU form of [`EnvisMaterial`]: kd (w = the lobe's code, [`envis_wgpu::GpuCode`]), ks (w = its
/// parameter, [`envis_wgpu::codes::lobe_param`]).
#[derive(Clone, Default, ShaderType)]
pub struct EnvisMaterialUniform {
    pub kd: Vec4,
    pub ks: Vec4,
}

impl AsBindGroupShaderType<EnvisMaterialUniform> for EnvisMaterial {
    fn as_bind_group_shader_type(&self, _: &RenderAssets<GpuImage>) -> EnvisMaterialUniform {
        let m = self.brdf.material();
        EnvisMaterialUniform {
            kd: m.kd.extend(m.lobe.gpu_code() as f32),
            ks: m.ks.extend(envis_wgpu::codes::lobe_param(m.lobe)),
        }
    }
}

impl Material for EnvisMaterial {
    fn opaque_render_method(&self) -> OpaqueRendererMethod {
        OpaqueRendererMethod::Deferred
    }
    fn deferred_fragment_shader() -> ShaderRef {
        ShaderRef::Path(
            AssetPath::from_path_buf(embedded_path!("envis_material.wgsl")).with_source("embedded"),
        )
    }
}

/// Registers [`EnvisMaterial`] and embeds its shader.
pub struct EnvisMaterialPlugin;

impl Plugin for EnvisMaterialPlugin {
    fn build(&self, app: &mut App) {
        embedded_asset!(app, "envis_material.wgsl");
        app.register_type::<EnvisMaterial>()
            .add_plugins(MaterialPlugin::<EnvisMaterial>::default());
    }
}
