//! envis beside Bevy's temporal antialiasing: a jittered view's depth unprojects onto the
//! surface it sampled, and a TAA camera's frames draw new samples, so that TAA averages envis's
//! noise (and keeps its mean) instead of averaging the same noise again.

use super::bevy_app::on_sphere;
use super::gpu;
use bevy::anti_alias::taa::TemporalAntiAliasing;
use bevy::prelude::*;
use bevy::render::camera::TemporalJitter;
use bevy_envis::EnvisProbe;
use bevy_envis::prelude::*;
use envis::envmap::luminance;
use envis_cli::headless::{HeadlessApp, radiance_camera, sphere_view};

/// A sky brighter towards +Y, with a warm band, so that a few samples per pixel are noisy.
fn noisy_sky(h: &mut HeadlessApp) -> Handle<Image> {
    let (img, _) = super::bevy_plugin::latlong_image(32, |d| {
        let band = (-(d.y - 0.3).powi(2) / 0.01).exp();
        Vec3::new(4.0, 3.0, 1.5) * band + Vec3::splat(0.2 + 0.5 * d.y.max(0.0))
    });
    h.add::<Image>(img)
}

/// The probed pixel's world position, once the pass has read it back (asynchronously).
fn probed_point(h: &mut HeadlessApp) -> Option<Vec3> {
    for _ in 0..20 {
        h.update();
        let probe = h.app.world().resource::<EnvisProbe>().clone();
        let point = probe
            .lock()
            .ok()
            .and_then(|p| p.as_ref().and_then(|r| r.point));
        if point.is_some() {
            return point;
        }
    }
    None
}

/// Under TAA the depth buffer is rasterised with a sub-pixel jitter; the pass must unproject
/// with the same jittered matrix. A ground plane seen obliquely, a fixed jitter of about half a
/// pixel: the probed pixel's world position lies on the plane (`y = 0`) with the jitter as
/// without it. Unprojecting with the unjittered matrix puts it 0.02 off here.
#[test]
fn bevy_jittered_depth_unprojects_onto_the_surface() {
    let Some(_) = gpu() else { return };
    let size = 32u32;
    let heights: Vec<f32> = [None, Some(Vec2::new(0.45, -0.4))]
        .into_iter()
        .map(|jitter| {
            let mut h = HeadlessApp::new();
            let plane = h.add::<Mesh>(Plane3d::default().mesh().size(10.0, 10.0));
            let mat = h.add::<StandardMaterial>(StandardMaterial::default());
            h.app
                .world_mut()
                .spawn((Mesh3d(plane), MeshMaterial3d(mat)));
            let env = noisy_sky(&mut h);
            let target = h.float_target(size, size);
            let sampling = EnvironmentSampling {
                light_samples: 2,
                brdf_samples: 2,
                shadows: ShadowRays::On,
                probe: Some(UVec2::new(16, 23)),
                ..default()
            };
            let camera = h.app.world_mut().spawn(radiance_camera(
                target.clone(),
                Projection::Perspective(PerspectiveProjection::default()),
                Transform::from_xyz(0.0, 2.0, 4.0).looking_at(Vec3::ZERO, Vec3::Y),
                sampling,
                EnvisEnvironment::new(env),
            ));
            let camera = camera.id();
            if let Some(offset) = jitter {
                h.app
                    .world_mut()
                    .entity_mut(camera)
                    .insert(TemporalJitter { offset });
            }
            h.capture(&target).unwrap();
            let p = probed_point(&mut h).expect("the probed pixel came back");
            eprintln!("jitter {jitter:?}: probed point {p}");
            assert!(p.z > 0.5, "the probe missed the near ground: {p}");
            p.y
        })
        .collect();
    for y in heights {
        assert!(y.abs() < 2e-3, "the probed point is {y} off the plane");
    }
}

/// A TAA camera on a still scene with 2 + 2 samples per pixel: each frame draws new samples
/// (without TAA, or with it and without that, every frame repeats the same noise), so after 24
/// frames TAA's image is nearer the converged one (the same camera accumulating 96 frames) than
/// a single frame is, and its mean nearly the same. Measured inside the sphere, away from the edges
/// TAA smooths.
#[test]
fn bevy_taa_averages_envis_noise() {
    let Some(_) = gpu() else { return };
    let size = 32u32;
    let frame = |taa: bool, accumulate: bool, frames: usize| {
        let material = StandardMaterial {
            base_color: Color::srgb(0.8, 0.8, 0.8),
            perceptual_roughness: 0.5,
            ..default()
        };
        let sampling = EnvironmentSampling {
            light_samples: 2,
            brdf_samples: 2,
            accumulate,
            ..default()
        };
        let scene = SphereScene { size, frames };
        scene.render(material, noisy_sky, sampling, |h, camera| {
            if taa {
                let taa = TemporalAntiAliasing::default();
                h.app.world_mut().entity_mut(camera).insert(taa);
            }
        })
    };
    let inside = on_sphere(size);
    let px: Vec<usize> = (0..(size * size) as usize).filter(|&i| inside(i)).collect();
    let mean = |img: &[Vec3]| px.iter().map(|&i| luminance(img[i]) as f64).sum::<f64>();
    let converged = frame(false, true, 96);
    let error = |img: &[Vec3]| {
        let e: f64 = (px.iter())
            .map(|&i| (img[i] - converged[i]).length_squared() as f64)
            .sum();
        e / px
            .iter()
            .map(|&i| converged[i].length_squared() as f64)
            .sum::<f64>()
    };
    let single = frame(false, false, 4);
    let repeat = frame(false, false, 5);
    assert_eq!(
        single, repeat,
        "an unjittered still camera repeats its frame"
    );
    let taa = frame(true, false, 24);
    let (e1, et) = (error(&single), error(&taa));
    let (m, mt) = (mean(&converged), mean(&taa));
    eprintln!("relative squared error: one frame {e1:.2e}, TAA {et:.2e}; means {m:.4} {mt:.4}");
    assert!(
        et < 0.5 * e1,
        "TAA did not average envis's noise: {et:.2e} vs {e1:.2e}"
    );
    // Measured 3.0% low (2.8% at 8 + 8; Bevy's TAA over an already converged envis image is
    // 1.1% low itself): asserted within 5%. Without new samples per frame it was 64% low.
    assert!((mt - m).abs() < 0.05 * m, "TAA moved the mean: {mt} vs {m}");
}

/// A 4 x 4 cube image of one colour in every texel (`Rgba16Float`, filterable, as Bevy's
/// skybox samples it); `half` is the colour's f16 bits.
fn constant_cube(h: &mut HeadlessApp, half: [u16; 4]) -> Handle<Image> {
    use bevy::asset::RenderAssetUsages;
    use bevy::render::render_resource::{
        Extent3d, TextureDimension, TextureFormat, TextureViewDescriptor, TextureViewDimension,
    };
    let bytes: Vec<u8> = (0..6 * 16)
        .flat_map(|_| half)
        .flat_map(u16::to_ne_bytes)
        .collect();
    let mut img = Image::new(
        Extent3d {
            width: 4,
            height: 4,
            depth_or_array_layers: 6,
        },
        TextureDimension::D2,
        bytes,
        TextureFormat::Rgba16Float,
        RenderAssetUsages::RENDER_WORLD,
    );
    img.texture_view_descriptor = Some(TextureViewDescriptor {
        dimension: Some(TextureViewDimension::Cube),
        ..default()
    });
    h.add::<Image>(img)
}

/// The unit sphere under an environment, seen by the sphere view into a `size^2` target and
/// captured after `frames` frames.
struct SphereScene {
    size: u32,
    frames: usize,
}

impl SphereScene {
    /// The sphere in `material` under `env`; `extra` adds components to the camera (given the
    /// app and the camera).
    fn render(
        &self,
        material: StandardMaterial,
        env: impl FnOnce(&mut HeadlessApp) -> Handle<Image>,
        sampling: EnvironmentSampling,
        extra: impl FnOnce(&mut HeadlessApp, Entity),
    ) -> Vec<Vec3> {
        let mut h = HeadlessApp::new();
        let mesh = h.add::<Mesh>(Sphere::new(1.0).mesh().ico(5).expect("icosphere"));
        let mat = h.add::<StandardMaterial>(material);
        h.app
            .world_mut()
            .spawn((Mesh3d(mesh), MeshMaterial3d(mat), Transform::IDENTITY));
        let env = env(&mut h);
        let target = h.float_target(self.size, self.size);
        let (projection, transform) = sphere_view();
        let camera = radiance_camera(
            target.clone(),
            projection,
            transform,
            sampling,
            EnvisEnvironment::new(env),
        );
        let camera = h.app.world_mut().spawn(camera).id();
        extra(&mut h, camera);
        h.until_lit();
        for _ in 0..self.frames {
            h.update();
        }
        h.capture_next(&target).unwrap()
    }
}

/// With Bevy's `Skybox` on the camera the background is the skybox's (its colour times its
/// brightness), not envis's map, whatever `show_background` says; the lit sphere is the same
/// with and without it.
#[test]
fn bevy_skybox_owns_the_background() {
    let Some(_) = gpu() else { return };
    let size = 16u32;
    // (0.5, 0.25, 1.0, 1.0) in f16; the map is white.
    let colour = Vec3::new(0.5, 0.25, 1.0);
    let white = |h: &mut HeadlessApp| {
        let (img, _) = super::bevy_plugin::latlong_image(8, |_| Vec3::ONE);
        h.add::<Image>(img)
    };
    let sampling = || EnvironmentSampling {
        light_samples: 4,
        brdf_samples: 4,
        ..default()
    };
    let mat = StandardMaterial {
        perceptual_roughness: 1.0,
        reflectance: 0.0,
        ..default()
    };
    let scene = SphereScene { size, frames: 3 };
    let plain = scene.render(mat.clone(), white, sampling(), |_, _| {});
    let sky = scene.render(mat, white, sampling(), |h, camera| {
        let image = constant_cube(h, [0x3800, 0x3400, 0x3c00, 0x3c00]);
        let skybox = bevy::light::Skybox {
            image: Some(image),
            brightness: 1.0,
            ..default()
        };
        h.app.world_mut().entity_mut(camera).insert(skybox);
    });
    // A corner is background; the centre is the sphere.
    let (corner, centre) = (0, (size / 2 * size + size / 2) as usize);
    assert!(
        (plain[corner] - Vec3::ONE).abs().max_element() < 1e-3,
        "envis's background: {}",
        plain[corner]
    );
    assert!(
        (sky[corner] - colour).abs().max_element() < 2e-3,
        "the skybox's background: {} (want {colour})",
        sky[corner]
    );
    assert!(
        (sky[centre] - plain[centre]).abs().max_element() < 1e-4,
        "the skybox changed the lit sphere: {} vs {}",
        sky[centre],
        plain[centre]
    );
}

/// Bloom on a bright reflection: a near-mirror sphere reflects a small sun of radiance 2000 at
/// its centre (the sun behind the camera). With Bevy's `Bloom` the dim pixels around the
/// highlight brighten (its light spreads: +24% measured on lavapipe, asserted +15%) and the
/// highlight's peak drops (-15% measured, asserted -5%).
#[test]
fn bevy_bloom_spreads_a_sun_reflection() {
    let Some(_) = gpu() else { return };
    let size = 32u32;
    let sun = |h: &mut HeadlessApp| {
        let (img, _) = super::bevy_plugin::latlong_image(64, |d| {
            // Within about 6 degrees of +Z, towards the camera.
            Vec3::splat(if d.z > 0.995 { 2000.0 } else { 0.1 })
        });
        h.add::<Image>(img)
    };
    let mirror = || StandardMaterial {
        base_color: Color::WHITE,
        metallic: 1.0,
        perceptual_roughness: 0.089,
        ..default()
    };
    let sampling = || EnvironmentSampling {
        light_samples: 16,
        brdf_samples: 16,
        ..default()
    };
    let scene = SphereScene { size, frames: 3 };
    let plain = scene.render(mirror(), sun, sampling(), |_, _| {});
    let bloom = scene.render(mirror(), sun, sampling(), |h, camera| {
        let bloom = bevy::post_process::bloom::Bloom::NATURAL;
        h.app.world_mut().entity_mut(camera).insert(bloom);
    });
    // Pixels 4 to 8 from the centre: on the sphere, reflecting the dim sky 30-60 degrees away.
    let ring = |img: &[Vec3]| {
        let c = size as f32 / 2.0 - 0.5;
        let px: Vec<f32> = (0..img.len())
            .filter(|&i| {
                let (x, y) = ((i as u32 % size) as f32 - c, (i as u32 / size) as f32 - c);
                (4.0..8.0).contains(&x.hypot(y))
            })
            .map(|i| luminance(img[i]))
            .collect();
        px.iter().sum::<f32>() / px.len() as f32
    };
    let peak = |img: &[Vec3]| img.iter().map(|&c| luminance(c)).fold(0.0, f32::max);
    let (r0, r1) = (ring(&plain), ring(&bloom));
    eprintln!(
        "bloom: ring {r0:.4} -> {r1:.4}, peak {:.1} -> {:.1}",
        peak(&plain),
        peak(&bloom)
    );
    assert!(peak(&plain) > 100.0, "no sun reflection: {}", peak(&plain));
    assert!(r0 < 1.0, "the ring is not dim without bloom: {r0}");
    assert!(
        r1 > 1.15 * r0,
        "no bloom around the reflection: {r1} vs {r0}"
    );
    assert!(
        peak(&bloom) < 0.95 * peak(&plain),
        "the highlight kept all its light"
    );
}

/// SSAO and envis's environment term: envis shadows its own light (shadow rays), so Bevy's
/// `ScreenSpaceAmbientOcclusion` must not darken it again. A sphere resting on a plane, under
/// Bevy's ambient light (which SSAO does darken) and envis: envis's term (the image with envis
/// minus the image without it, each with and without SSAO) is the same with SSAO as without,
/// while the ambient-only image darkens near the contact.
#[test]
fn bevy_ssao_leaves_envis_term_alone() {
    let Some(_) = gpu() else { return };
    let size = 40u32;
    let render = |envis: bool, ssao: bool| {
        let mut h = HeadlessApp::new();
        h.app.insert_resource(GlobalAmbientLight {
            brightness: 1.0,
            ..default()
        });
        let mat = h.add::<StandardMaterial>(StandardMaterial {
            perceptual_roughness: 1.0,
            reflectance: 0.0,
            ..default()
        });
        let sphere = h.add::<Mesh>(Sphere::new(0.5).mesh().ico(5).expect("icosphere"));
        let plane = h.add::<Mesh>(Plane3d::default().mesh().size(6.0, 6.0));
        let world = h.app.world_mut();
        world.spawn((
            Mesh3d(sphere),
            MeshMaterial3d(mat.clone()),
            Transform::from_xyz(0.0, 0.5, 0.0),
        ));
        world.spawn((Mesh3d(plane), MeshMaterial3d(mat)));
        let env = noisy_sky(&mut h);
        let target = h.float_target(size, size);
        let projection = Projection::Perspective(PerspectiveProjection::default());
        let transform = Transform::from_xyz(0.0, 2.0, 3.0).looking_at(Vec3::ZERO, Vec3::Y);
        let sampling = EnvironmentSampling {
            light_samples: 8,
            brdf_samples: 8,
            shadows: ShadowRays::On,
            ..default()
        };
        let camera = if envis {
            let c = radiance_camera(
                target.clone(),
                projection,
                transform,
                sampling,
                EnvisEnvironment::new(env),
            );
            h.app.world_mut().spawn(c).id()
        } else {
            use bevy::core_pipeline::prepass::{DeferredPrepass, DepthPrepass};
            let c = envis_cli::headless::radiance_view(target.clone(), projection, transform);
            let prepasses = (DepthPrepass, DeferredPrepass, bevy::camera::Hdr, Msaa::Off);
            h.app.world_mut().spawn((c, prepasses)).id()
        };
        if ssao {
            let ssao = bevy::pbr::ScreenSpaceAmbientOcclusion::default();
            h.app.world_mut().entity_mut(camera).insert(ssao);
        }
        h.capture(&target).unwrap()
    };
    let total = |img: &[Vec3]| img.iter().map(|&c| luminance(c) as f64).sum::<f64>();
    let (ambient, ambient_ssao) = (render(false, false), render(false, true));
    let (both, both_ssao) = (render(true, false), render(true, true));
    let term: Vec<Vec3> = both.iter().zip(&ambient).map(|(a, b)| *a - *b).collect();
    let term_ssao: Vec<Vec3> = (both_ssao.iter().zip(&ambient_ssao))
        .map(|(a, b)| *a - *b)
        .collect();
    let moved: f64 = (term.iter().zip(&term_ssao))
        .map(|(a, b)| (luminance(*a) - luminance(*b)).abs() as f64)
        .sum();
    let (a0, a1, t0) = (total(&ambient), total(&ambient_ssao), total(&term));
    eprintln!("ssao: ambient {a0:.1} -> {a1:.1}; envis term {t0:.1}, moved by {moved:.3}");
    assert!(
        a1 < 0.98 * a0,
        "SSAO did not darken Bevy's ambient light: {a1} vs {a0}"
    );
    assert!(
        moved < 0.01 * t0,
        "SSAO changed envis's term by {moved} of {t0}"
    );
}
