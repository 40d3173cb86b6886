//! Integration tests of the core (no Bevy, no GPU): conventions, samplers (chi-square goodness of
//! fit and normalisation, Mitsuba-style), estimator unbiasedness against the f64 reference,
//! loaders, streams, scene files and shadow rays (the command line's tests are envis_cli's).

use envis::envmap::load::{EnvSource, load_env, read_hdr_bytes};
use envis::envmap::resample::{latlong_integral, latlong_to_cube};
use envis::envmap::*;
use envis::render::reference::{reference_image, reference_pixel};
use envis::render::{GPixel, Settings, Strategy, render, sphere_gbuffer};
use envis::sampling::rng::Rng;
use envis::sampling::warp::Frame;
use envis::sampling::*;
use envis_stats::{Chi2Test, Discrete, FacePlane, MeanCheck, Sphere, UnbiasedTest, mean_se};
use glam::{DVec3, Vec2, Vec3};
use std::path::Path;

mod support;
use support::{rng_vec2, tempdir};

// The unbiasedness harness, shared with the estimator and visibility tests.
use unbiased::{few_sample_configs, unbiased_checks, unbiased_checks_with};

// Helpers

fn random_dir(r: &mut Rng) -> Vec3 {
    let z = 1.0 - 2.0 * r.next_f32();
    let p = 2.0 * std::f32::consts::PI * r.next_f32();
    let s = (1.0 - z * z).max(0.0).sqrt();
    Vec3::new(s * p.cos(), s * p.sin(), z)
}

/// A generated lat-long map with a gradient, a small very bright spot and some bad texels.
fn generated_latlong(w: usize, seed: u32) -> Image {
    let h = w / 2;
    let mut img = Image::new(w, h);
    let mut r = Rng::new(seed, 99);
    let spot = latlong_to_dir(r.next_f32(), 0.2 + 0.4 * r.next_f32());
    for y in 0..h {
        for x in 0..w {
            let d = latlong_to_dir((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
            let mut c = Vec3::new(0.3, 0.4, 0.6) * (1.0 + d.y) + Vec3::splat(0.05 * r.next_f32());
            if d.dot(spot) > 0.995 {
                c += Vec3::new(800.0, 700.0, 500.0);
            }
            img.data[y * w + x] = c;
        }
    }
    img.data[3] = Vec3::new(-5.0, 1.0, 1.0);
    img.data[7] = Vec3::new(f32::NAN, 1.0, 1.0);
    img
}

/// Test environments: built-in sky at two times, plus real maps (or generated stand-ins).
fn test_envs(face: usize, n_real: usize) -> Vec<(String, CubeMap)> {
    let mut v = vec![
        (
            "builtin:sky:10".to_string(),
            load_env(&EnvSource::Sky { hours: 10.0 }, face)
                .unwrap()
                .cube,
        ),
        (
            "builtin:sky:17".to_string(),
            load_env(&EnvSource::Sky { hours: 17.0 }, face)
                .unwrap()
                .cube,
        ),
    ];
    match support::real_maps() {
        Some(maps) => {
            // Spread the picks over the sorted list (deterministic).
            for i in 0..n_real.min(maps.len()) {
                let p = &maps[i * maps.len() / n_real];
                v.push((
                    p.display().to_string(),
                    load_env(&EnvSource::File(p.clone()), face).unwrap().cube,
                ));
            }
        }
        None => {
            for i in 0..n_real {
                let mut img = generated_latlong(128, i as u32);
                img.sanitize();
                v.push((format!("generated:{i}"), latlong_to_cube(&img, face)));
            }
        }
    }
    v
}

/// A chi-square check of a direction sampler on the sphere around `axis`, drawing `n` samples
/// from `sample` with the stream `seed`; one of `checks` in its test.
fn chi2_sphere(
    name: String,
    checks: usize,
    axis: Vec3,
    n: usize,
    mut sample: impl FnMut(&mut Rng) -> Option<Vec3>,
    pdf: impl Fn(Vec3) -> f32 + Sync,
    seed: u32,
) {
    let mut rng = Rng::new(seed, 7);
    Chi2Test::new(name, Sphere::new(axis), n, checks)
        .run(|| sample(&mut rng), |d| pdf(d) as f64)
        .assert();
}

/// A smooth map (small texel-to-texel jumps) for tests whose expectations come from quadrature.
fn smooth_cube(n: usize) -> CubeMap {
    CubeMap::from_fn(n, |d| {
        Vec3::splat(0.3 + (1.0 + d.y).powi(2) + 0.5 * d.x.abs() + 0.3 * (3.0 * d.z).sin().abs())
    })
}

/// A structured face map with zero rows, a zero column and a hot texel.
fn structured_cube(n: usize) -> CubeMap {
    let mut m = CubeMap::from_fn(n, |d| Vec3::splat(0.2 + d.y.max(0.0) + 0.5 * d.x.abs()));
    for f in 0..6 {
        for c in 0..n {
            let i = m.index(f, c, 1);
            m.data[i] = Vec3::ZERO; // zero row
        }
        for r in 0..n {
            let i = m.index(f, 2, r);
            m.data[i] = Vec3::ZERO; // zero column
        }
    }
    let i = m.index(2, 5, 6);
    m.data[i] = Vec3::splat(300.0);
    let i = m.index(3, 0, 0);
    m.data[i] = Vec3::new(0.0, 40.0, 0.0);
    m
}

#[path = "core/conventions.rs"]
mod conventions;

#[path = "core/distributions.rs"]
mod distributions;

#[path = "core/samplers.rs"]
mod samplers;

#[path = "core/unbiased.rs"]
mod unbiased;

#[path = "core/subtexel.rs"]
mod subtexel;

#[path = "core/loaders.rs"]
mod loaders;

#[path = "core/estimator.rs"]
mod estimator;

#[path = "core/scenes.rs"]
mod scenes;

#[path = "core/stability.rs"]
mod stability;

#[path = "core/stream.rs"]
mod stream;

#[path = "core/visibility.rs"]
mod visibility;
