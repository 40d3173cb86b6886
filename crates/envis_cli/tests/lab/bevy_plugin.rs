//! The public plugin API on a user's kind of scene, through `bevy_envis::prelude` only (plus the
//! headless harness): `StandardMaterial` meshes, Bevy's sun and its shadows, split screen, the
//! plugin's own set-up; and the helpers the other Bevy test files build their apps with.
//! `Image` environments changed after they were lit are in `bevy_images.rs`, environment
//! shadows in `bevy_shadows.rs`.

use super::bevy_app::{assert_per_pixel_matches_cpu, cpu_render_fine, on_sphere};
use super::{gpu, rel};
use bevy::asset::RenderAssetUsages;
use bevy::camera::Viewport;
use bevy::pbr::DefaultOpaqueRendererMethod;
use bevy::prelude::*;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
use bevy_envis::prelude::*;
use bevy_envis::standard_material_decoded;
use envis::envmap::luminance;
use envis_cli::headless::{HeadlessApp, radiance_camera, radiance_view, sphere_view};

/// A `2w x w` lat-long `Rgba32Float` image with `f(direction)` in every texel.
pub(crate) fn latlong_image(w: u32, f: impl Fn(Vec3) -> Vec3) -> (Image, envis::envmap::Image) {
    let (width, height) = (2 * w, w);
    let mut cpu = envis::envmap::Image::new(width as usize, height as usize);
    for y in 0..height {
        for x in 0..width {
            let (u, v) = (
                (x as f32 + 0.5) / width as f32,
                (y as f32 + 0.5) / height as f32,
            );
            cpu.data[(y * width + x) as usize] = f(envis::envmap::latlong_to_dir(u, v));
        }
    }
    let bytes: Vec<u8> = cpu
        .data
        .iter()
        .flat_map(|c| [c.x, c.y, c.z, 1.0])
        .flat_map(f32::to_ne_bytes)
        .collect();
    let img = Image::new(
        Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        bytes,
        TextureFormat::Rgba32Float,
        RenderAssetUsages::RENDER_WORLD,
    );
    (img, cpu)
}

/// The one entity `F` matches in `world` (a test's set-up makes it one).
pub(super) fn the_one<F: bevy::ecs::query::QueryFilter>(world: &mut World) -> Entity {
    world.query_filtered::<Entity, F>().single(world).unwrap()
}

/// An app with the unit sphere in `material`, set up by `EnvisPlugin` alone: its
/// StandardMaterials render deferred without a line of the app's own (a forward sphere would
/// come out unlit, so every test on this app checks that set-up).
pub(super) fn standard_sphere_app(material: StandardMaterial) -> HeadlessApp {
    let mut h = HeadlessApp::new();
    let mesh = h.add::<Mesh>(Sphere::new(1.0).mesh().ico(7).expect("icosphere"));
    let mat = h.add::<StandardMaterial>(material);
    h.app
        .world_mut()
        .spawn((Mesh3d(mesh), MeshMaterial3d(mat), Transform::IDENTITY));
    h
}

/// White, fully rough, non-metallic, reflectance 0: no specular lobe at all (Bevy's f90 is 0), so
/// under a constant map L it reflects exactly L.
pub(super) fn white_furnace_material() -> StandardMaterial {
    StandardMaterial {
        base_color: Color::WHITE,
        perceptual_roughness: 1.0,
        metallic: 0.0,
        reflectance: 0.0,
        ..default()
    }
}

/// Spawn the sphere view's camera lit by `image` into a new `size^2` target.
pub(super) fn sphere_camera(
    h: &mut HeadlessApp,
    image: Handle<Image>,
    sampling: EnvironmentSampling,
    size: u32,
) -> Handle<Image> {
    let target = h.float_target(size, size);
    let (projection, transform) = sphere_view();
    h.app.world_mut().spawn(radiance_camera(
        target.clone(),
        projection,
        transform,
        sampling,
        EnvisEnvironment::new(image),
    ));
    target
}

pub(super) fn sphere_mean(img: &[Vec3], size: u32) -> f64 {
    let inside = on_sphere(size);
    let idx: Vec<usize> = (0..img.len()).filter(|&i| inside(i)).collect();
    idx.iter().map(|&i| luminance(img[i]) as f64).sum::<f64>() / idx.len() as f64
}

/// White furnace on a plain StandardMaterial: white, fully rough, non-metallic, reflectance 0
/// (no specular lobe at all: Bevy's f90 is 0) under a constant map L comes out as L.
#[test]
fn bevy_standard_material_furnace() {
    let Some(_) = gpu() else { return };
    let l = 0.7;
    let mut h = standard_sphere_app(white_furnace_material());
    let (env, _) = latlong_image(16, |_| Vec3::splat(l));
    let env = h.add::<Image>(env);
    let target = sphere_camera(&mut h, env, EnvironmentSampling::default(), 48);
    let img = h.capture(&target).unwrap();
    let mean = sphere_mean(&img, 48);
    assert!(rel(mean, l as f64) < 0.02, "furnace: mean {mean}, want {l}");
}

/// A StandardMaterial sphere under a sky image (from an `Image` asset, resampled on the GPU)
/// matches the CPU renderer on the resample's CPU twin with the decoded material: the mean
/// within 2%, 90% of the pixels within 10%.
#[test]
fn bevy_standard_material_matches_cpu() {
    let Some(_) = gpu() else { return };
    let (size, face) = (48u32, 16u32);
    let material = StandardMaterial {
        base_color: Color::linear_rgb(0.7, 0.5, 0.3),
        perceptual_roughness: 0.5,
        metallic: 0.3,
        reflectance: 0.5,
        ..default()
    };
    let mut h = standard_sphere_app(material.clone());
    let (env, cpu_env) = latlong_image(64, |d| envis::envmap::sky::sky_radiance(d, 15.0));
    let env = h.add::<Image>(env);
    let sampling = EnvironmentSampling {
        face_size: face as usize,
        seed: 3,
        pool_blocks: 16,
        ..default()
    };
    let target = sphere_camera(&mut h, env, sampling, size);
    let img = h.capture(&target).unwrap();
    // The pass reads densities from the resampled table and radiance from the image itself.
    let source = envis::envmap::resample::SourceImage::new_latlong(cpu_env);
    let cube = source.to_cube(face as usize);
    let fine = |d: Vec3| source.radiance_nearest(d);
    let gbuf = envis::render::sphere_gbuffer(
        size as usize,
        size as usize,
        standard_material_decoded(&material),
    );
    let cpu = cpu_render_fine(&cube, &fine, &gbuf, size, &sampling);
    // The sky's sun covers part of one texel: a pool sample whose direction (or the image texel
    // it reads) differs by rounding between the GPU and the CPU can see the sun in one and not
    // in the other, which moves every pixel of that sample's block (seen: one block off by 2x,
    // one by 5%, the other 14 within 0.5%). So the frame mean is compared per block (the pixels
    // that read one of the 16 pools): a decoding error moves them all; at most 2 may differ.
    let k = sampling.pool_blocks;
    let mut per = vec![(0.0f64, 0.0f64); k as usize];
    for (i, px) in gbuf.iter().enumerate() {
        if px.is_some() && on_sphere(size)(i) {
            let b = envis::sampling::rng::Rng::new(sampling.seed, i as u32).next_u32() % k as u32;
            per[b as usize].0 += luminance(img[i]) as f64;
            per[b as usize].1 += luminance(cpu[i]) as f64;
        }
    }
    let off: Vec<usize> = (0..per.len())
        .filter(|&b| rel(per[b].0, per[b].1) >= 0.02)
        .collect();
    assert!(off.len() <= 2, "blocks {off:?} differ: {per:?}");
    assert_per_pixel_matches_cpu("standard material", &img, &cpu, size);
}

/// Bevy's own lights stay: a sun (with shadows, and an occluder casting one on the sphere) adds
/// the same light with envis as without it. Sun + environment - environment alone = sun alone,
/// to the G-buffer's quantisation. Removing envis from the camera gives it back to Bevy's
/// lighting alone and frees the camera's distribution.
#[test]
fn bevy_keeps_the_sun_and_its_shadow() {
    let Some(_) = gpu() else { return };
    let size = 48;
    let render = |sun: bool, envis: bool| {
        let mut h = standard_sphere_app(StandardMaterial {
            base_color: Color::linear_rgb(0.8, 0.8, 0.8),
            perceptual_roughness: 0.6,
            ..default()
        });
        if sun {
            h.app.world_mut().spawn((
                DirectionalLight {
                    illuminance: 2.0,
                    shadow_maps_enabled: true,
                    ..default()
                },
                Transform::from_xyz(1.0, 2.0, 3.0).looking_at(Vec3::ZERO, Vec3::Y),
            ));
        }
        // A small occluder between the sun and the sphere (in every render: it shadows the
        // environment too, the same with and without the sun).
        let cube = h.add::<Mesh>(Cuboid::new(0.4, 0.4, 0.4));
        let black = h.add::<StandardMaterial>(StandardMaterial::from(Color::BLACK));
        h.app.world_mut().spawn((
            Mesh3d(cube),
            MeshMaterial3d(black),
            Transform::from_xyz(0.6, 1.2, 1.8),
        ));
        let (env, _) = latlong_image(16, |d| Vec3::splat(0.3 + 0.2 * d.y));
        let env = h.add::<Image>(env);
        let target = if envis {
            sphere_camera(&mut h, env, EnvironmentSampling::default(), size)
        } else {
            // The same camera without envis: Bevy's deferred lighting alone.
            let target = h.float_target(size, size);
            let (projection, transform) = sphere_view();
            h.app.world_mut().spawn((
                radiance_view(target.clone(), projection, transform),
                bevy::core_pipeline::prepass::DepthPrepass,
                bevy::core_pipeline::prepass::DeferredPrepass,
                bevy::camera::Hdr,
                Msaa::Off,
            ));
            target
        };
        let img = h.capture(&target).unwrap();
        (img, h, target)
    };
    let (sun, _, _) = render(true, false);
    let (both, mut h, target) = render(true, true);
    let (env, _, _) = render(false, true);
    let inside = on_sphere(size);
    let (mut worst, mut lit, mut shadowed) = (0.0f32, 0, 0);
    for i in (0..sun.len()).filter(|&i| inside(i)) {
        let d = (both[i] - env[i] - sun[i]).abs().max_element();
        worst = worst.max(d / sun[i].max_element().max(0.05));
        lit += (sun[i].x > 0.05) as usize;
        shadowed += (sun[i].x < 1e-4 && env[i].x > 0.01) as usize;
    }
    assert!(
        lit > 100 && shadowed > 10,
        "the scene has no sunlit ({lit}) or shadowed ({shadowed}) pixels"
    );
    assert!(
        worst < 1e-2,
        "sun + env - env differs from the sun alone by {worst}"
    );
    let world = h.app.world_mut();
    let cam = the_one::<With<EnvironmentSampling>>(world);
    world
        .entity_mut(cam)
        .remove::<(EnvironmentSampling, EnvisEnvironment)>();
    let removed = h.capture(&target).unwrap();
    let diff = removed
        .iter()
        .zip(&sun)
        .map(|(a, b)| (*a - *b).abs().max_element())
        .fold(0.0, f32::max);
    assert!(
        diff <= 1e-5,
        "without envis the camera differs from Bevy's own lighting by {diff}"
    );
    let c = h.counters();
    assert_eq!(
        c.get(|c| &c.live_distributions),
        0,
        "the removed camera's distribution was kept: {:?}",
        c.0
    );
}

/// Split screen: two cameras with different settings share one target; each paints only its
/// own viewport, and each half equals that camera rendered alone.
#[test]
fn bevy_split_screen() {
    let Some(_) = gpu() else { return };
    let size = 32u32;
    let settings = [
        EnvironmentSampling {
            seed: 1,
            ..default()
        },
        EnvironmentSampling {
            strategy: Strategy::Brdf,
            light_samples: 8,
            brdf_samples: 8,
            seed: 2,
            ..default()
        },
    ];
    let render = |which: &[usize]| {
        let mut h = standard_sphere_app(StandardMaterial {
            base_color: Color::linear_rgb(0.6, 0.6, 0.6),
            perceptual_roughness: 0.4,
            ..default()
        });
        let (env, _) = latlong_image(32, |d| envis::envmap::sky::sky_radiance(d, 10.0));
        let env = h.add::<Image>(env);
        let target = h.float_target(2 * size, size);
        // Bevy clears the parts of a target outside every viewport with the global colour.
        h.app.insert_resource(ClearColor(Color::BLACK));
        for &k in which {
            let (projection, transform) = sphere_view();
            h.app
                .world_mut()
                .spawn(radiance_camera(
                    target.clone(),
                    projection,
                    transform,
                    settings[k],
                    EnvisEnvironment::new(env.clone()),
                ))
                .insert(Camera {
                    order: k as isize,
                    viewport: Some(Viewport {
                        physical_position: UVec2::new(k as u32 * size, 0),
                        physical_size: UVec2::new(size, size),
                        ..default()
                    }),
                    clear_color: ClearColorConfig::Custom(Color::BLACK),
                    ..default()
                });
        }
        h.capture(&target).unwrap()
    };
    let both = render(&[0, 1]);
    let halves = [render(&[0]), render(&[1])];
    for (k, alone) in halves.iter().enumerate() {
        let mut worst = 0.0f32;
        for y in 0..size {
            for x in 0..size {
                let i = (y * 2 * size + k as u32 * size + x) as usize;
                worst = worst.max((both[i] - alone[i]).abs().max_element());
            }
        }
        assert!(
            worst <= 1e-5,
            "half {k}: split screen differs from the camera alone by {worst}"
        );
        let other = 1 - k;
        let painted = (0..size * size).any(|j| {
            let i = ((j / size) * 2 * size + other as u32 * size + j % size) as usize;
            alone[i] != Vec3::ZERO
        });
        assert!(!painted, "camera {k} alone painted outside its viewport");
    }
}

/// Meshes envis cannot light are reported: an opaque StandardMaterial left forward (the app
/// chose forward as its default after `EnvisPlugin`), and a transparent one; the deferred one is
/// lit.
#[test]
fn bevy_reports_meshes_it_cannot_light() {
    let Some(_) = gpu() else { return };
    let mut h = HeadlessApp::new();
    h.app
        .insert_resource(DefaultOpaqueRendererMethod::forward());
    let mesh = h.add::<Mesh>(Sphere::new(0.5).mesh().ico(3).expect("icosphere"));
    for (x, m) in [
        (-1.0, StandardMaterial::default()),
        (
            0.0,
            StandardMaterial {
                alpha_mode: AlphaMode::Blend,
                ..default()
            },
        ),
        (
            1.0,
            StandardMaterial {
                opaque_render_method: bevy::material::OpaqueRendererMethod::Deferred,
                ..default()
            },
        ),
    ] {
        let m = h.add::<StandardMaterial>(m);
        h.app.world_mut().spawn((
            Mesh3d(mesh.clone()),
            MeshMaterial3d(m),
            Transform::from_xyz(x, 0.0, 0.0),
        ));
    }
    let (env, _) = latlong_image(8, |_| Vec3::ONE);
    let env = h.add::<Image>(env);
    let target = sphere_camera(&mut h, env, EnvironmentSampling::default(), 16);
    let _ = h.capture(&target).unwrap();
    let c = h.counters();
    assert_eq!(c.get(|c| &c.forward_meshes), 1, "{:?}", c.0);
    assert_eq!(c.get(|c| &c.transparent_meshes), 1, "{:?}", c.0);
}

/// `EnvisPlugin` sets itself up: deferred is the default renderer method, and each camera set
/// up so that envis lights nothing, or with Bevy's environment light as well, gets one warning
/// per problem (not one per frame); a well set-up camera gets none. Its types meet Bevy's
/// conventions: `EnvisMaterial` is reflected, `ShadowRays` does not clash with `Visibility`.
#[test]
fn bevy_plugin_sets_itself_up_and_warns_once() {
    let Some(_) = gpu() else { return };
    let mut h = HeadlessApp::new();
    assert!(bevy_envis::setup::is_deferred(
        h.app.world().resource::<DefaultOpaqueRendererMethod>()
    ));
    let (env, _) = latlong_image(8, |_| Vec3::ONE);
    let env = h.add::<Image>(env);
    // Inactive cameras: only their components matter here, nothing is drawn.
    let camera = || {
        (
            Camera3d::default(),
            Camera {
                is_active: false,
                ..default()
            },
        )
    };
    let w = h.app.world_mut();
    w.spawn((camera(), EnvironmentSampling::default()));
    w.spawn((camera(), EnvisEnvironment::new(env.clone())));
    w.spawn((
        camera(),
        EnvironmentSampling::default(),
        EnvisEnvironment::new(env.clone()),
        EnvironmentMapLight::default(),
    ));
    w.spawn((
        camera(),
        EnvironmentSampling::default(),
        EnvisEnvironment::new(env.clone()),
    ));
    for _ in 0..3 {
        h.update();
    }
    let warnings = |h: &HeadlessApp| h.counters().get(|c| &c.setup_warnings);
    assert_eq!(warnings(&h), 3, "one warning per badly set-up camera");
    // Another of Bevy's environment lights added to the camera already warned adds nothing.
    let w = h.app.world_mut();
    let e = the_one::<With<EnvironmentMapLight>>(w);
    w.entity_mut(e)
        .insert(GeneratedEnvironmentMapLight::default());
    h.update();
    assert_eq!(warnings(&h), 3, "a problem is warned about once per camera");
    // Both preludes together name Bevy's `Visibility` and envis's `ShadowRays` without a clash.
    let (_, _) = (Visibility::Hidden, ShadowRays::On);
    // `EnvisMaterial` is reflected and registered, as Bevy's own materials are.
    let registry = h.app.world().resource::<AppTypeRegistry>().read();
    assert!(registry.contains(std::any::TypeId::of::<EnvisMaterial>()));
    let m = EnvisMaterial::lambert(Vec3::ONE);
    let brdf = m.reflect_ref().as_struct().unwrap().field("brdf").unwrap();
    assert_eq!(
        brdf.try_downcast_ref::<EnvisBrdf>(),
        Some(&EnvisBrdf::Lambert { albedo: Vec3::ONE })
    );
}

/// `EnvisShaderReloadPlugin`: editing the lighting pass's WGSL on disk recompiles it (the
/// `Shader` asset replaced, Bevy's pipeline cache recompiling): doubling the radiance the
/// fragment returns doubles the envis term of an `EnvisMaterial` sphere (same seed every frame).
#[test]
fn bevy_shader_edit_recompiles_the_lighting_pass() {
    use envis::stream::StreamSource;
    use envis_cli::headless::HeadlessSphere;
    use std::time::{Duration, Instant};
    let Some(_) = gpu() else { return };
    let dir = super::support::TempDir::new("shader-reload");
    let shaders = crate::support::repo().join("crates/envis_wgpu/shaders");
    for (name, _) in envis_wgpu::shaders::LIGHTING_MODULES {
        std::fs::copy(shaders.join(name), dir.join(name)).unwrap();
    }
    let sampling = EnvironmentSampling {
        light_samples: 4,
        brdf_samples: 4,
        ..default()
    };
    let brdf = EnvisBrdf::Lambert {
        albedo: Vec3::splat(0.8),
    };
    let sky = StreamSource::Sky {
        hours: 10.0,
        speed: 0.0,
    };
    let mut h = HeadlessSphere::new(sky, 16, brdf, sampling, 24);
    h.app.app.add_plugins(EnvisShaderReloadPlugin {
        dir: dir.to_path_buf(),
    });
    let sum = |img: &[Vec3]| img.iter().map(|c| luminance(*c) as f64).sum::<f64>();
    let before = sum(&h.capture().unwrap());
    assert!(before > 0.0);
    let path = dir.join("lighting.wgsl");
    let src = std::fs::read_to_string(&path).unwrap();
    let edited = src.replace(
        "return vec4(color * scale, 0.0);",
        "return vec4(color * scale * 2.0, 0.0);",
    );
    assert_ne!(edited, src, "the fragment's return was not found");
    // A modification time later than the copy's, on file systems with coarse clocks.
    std::thread::sleep(Duration::from_millis(1100));
    std::fs::write(&path, edited).unwrap();
    let start = Instant::now();
    let mut ratio = 1.0;
    while start.elapsed() < Duration::from_secs(60) && (ratio - 2.0f64).abs() > 1e-3 {
        ratio = sum(&h.capture().unwrap()) / before;
    }
    assert!(
        (ratio - 2.0).abs() < 1e-3,
        "after the edit: {ratio} x the image"
    );
}
