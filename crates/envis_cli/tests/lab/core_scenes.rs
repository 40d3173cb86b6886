//! The command-line side of scene files and visibility (`envis render --scene`, the visibility
//! stats, `bench --suite visibility`): the core's tests of them need the binary.

use super::*;
use support::{CAMERA, PLANE, SPHERE, scene_in};

/// Scene files: the shipped examples load and render; errors name the file, the line and the
/// field; a broken glTF names the file.
#[test]
fn scene_files_load_render_and_report_errors() {
    use envis::scene::Scene;
    let dir = support::repo().join("assets/scenes");
    for name in [
        "showcase.toml",
        "diffuse-static.toml",
        "glossy-dynamic.toml",
    ] {
        let sc = Scene::load(&dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        let g = sc.gbuffer(24, 24);
        let hits = g.iter().filter(|p| p.is_some()).count();
        assert!(
            hits > 24 * 24 / 4,
            "{name}: only {hits} pixels hit geometry"
        );
        for p in g.iter().flatten() {
            assert!(
                (p.n.length() - 1.0).abs() < 1e-3 && p.n.dot(p.o) > -1e-3,
                "{name}: bad G-buffer texel {p:?}"
            );
        }
    }
    // The CLI renders a scene file (the file supplies everything but the size).
    let t = tempdir();
    let out = t.join("scene.exr");
    let o = envis_cmd(&[
        "render",
        "--scene",
        dir.join("diffuse-static.toml").to_str().unwrap(),
        "--size",
        "24",
        "--out",
        out.to_str().unwrap(),
        "--stats",
        t.join("s.json").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = support::read_json(&t.join("s.json"));
    assert_eq!(
        j["brdf_samples_drawn"], 0,
        "diffuse scene with material_budget drew BRDF samples: {j}"
    );
    // Errors: file + line + field.
    let cases = [
        (
            "typo.toml",
            "[environment]\nsource = \"builtin:sky\"\n\n[[object]]\nshape = \"sphere\"\nradus = 1.0\nmaterial = { type = \"diffuse\" }\n",
            &["typo.toml", "line 6", "radus"][..],
        ),
        (
            "nomat.toml",
            "[environment]\nsource = \"builtin:sky\"\n[[object]]\nshape = \"sphere\"\n",
            &["nomat.toml", "material"][..],
        ),
        (
            "shape.toml",
            "[environment]\nsource = \"builtin:sky\"\n[[object]]\nshape = \"cone\"\nmaterial = { type = \"diffuse\" }\n",
            &["shape.toml", "object 1", "`shape`", "cone"][..],
        ),
        (
            "mat.toml",
            "[environment]\nsource = \"builtin:sky\"\n[[object]]\nshape = \"sphere\"\nmaterial = { type = \"velvet\" }\n",
            &["mat.toml", "`material`", "velvet"][..],
        ),
        (
            "samp.toml",
            "[environment]\nsource = \"builtin:sky\"\n[sampling]\ncounts = \"often\"\n[[object]]\nshape = \"sphere\"\nmaterial = { type = \"diffuse\" }\n",
            &["samp.toml", "counts", "often"][..],
        ),
        (
            "switch.toml",
            "[environment]\nsource = \"builtin:sky\"\n[[animation.switch]]\nat = 0.0\nsource = \"builtin:sky:9\"\n",
            &["switch.toml", "animation.switch", "at 0"][..],
        ),
        (
            "glb.toml",
            "[environment]\nsource = \"builtin:sky\"\n[[object]]\nshape = \"gltf\"\npath = \"broken.glb\"\nmaterial = { type = \"diffuse\" }\n",
            &["broken.glb", "glTF"][..],
        ),
    ];
    std::fs::write(t.join("broken.glb"), b"glTF\x02\x00\x00\x00garbage").unwrap();
    for (file, text, needles) in cases {
        let p = t.join(file);
        std::fs::write(&p, text).unwrap();
        let e = Scene::load(&p)
            .err()
            .unwrap_or_else(|| panic!("{file}: accepted"))
            .to_string();
        for n in needles {
            assert!(e.contains(n), "{file}: '{e}' does not name '{n}'");
        }
        assert_eq!(e.lines().count(), 1, "{file}: not one line: {e}");
    }
}

/// `--visibility` and `--stats`: the reason and the shadow rays are reported; `off` casts none;
/// the `sphere` scene is off under `auto` and renders the same image as with `off`.
#[test]
fn cli_visibility_stats() {
    let dir = support::TempDir::new("vis-cli");
    let sc = scene_in(&dir, CAMERA, &format!("{SPHERE}\n{PLANE}"));
    let run = |scene: &str, vis: &str| {
        let out = dir.join(format!("{}-{vis}.exr", scene.len()));
        let stats = dir.join(format!("{}-{vis}.json", scene.len()));
        let o = envis_cmd(&[
            "render",
            "--scene",
            scene,
            "--size",
            "16",
            "--visibility",
            vis,
            "--out",
            out.to_str().unwrap(),
            "--stats",
            stats.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        (support::read_json(&stats), std::fs::read(&out).unwrap())
    };
    let path = sc.path.to_str().unwrap().to_string();
    let (auto, _) = run(&path, "auto");
    assert!(auto["visibility"].as_str().unwrap().starts_with("on (auto"));
    assert!(auto["shadow_rays"].as_u64().unwrap() > 0);
    let (off, _) = run(&path, "off");
    assert_eq!(off["shadow_rays"].as_u64(), Some(0));
    let (sphere_auto, a) = run("sphere", "auto");
    let (_, b) = run("sphere", "off");
    assert!(
        sphere_auto["visibility"]
            .as_str()
            .unwrap()
            .starts_with("off (auto")
    );
    assert_eq!(sphere_auto["shadow_rays"].as_u64(), Some(0));
    assert!(a == b, "the sphere scene changed with visibility off");
}

/// `envis bench --suite visibility --quick`: the three scenes (the last the bunny placed 100
/// times) timed with and without shadow rays (rays counted only with), the three BVH builds,
/// and each level of the instanced bunnies timed.
#[test]
fn bench_visibility_smoke() {
    let dir = support::TempDir::new("bench-vis");
    let js = bench_json(&dir, &["visibility", "--quick"], "bench-visibility.json");
    let scenes = js["scenes"].as_array().unwrap();
    assert_eq!(scenes.len(), 3);
    for s in scenes {
        assert!(s["shadow_rays_per_frame"].as_u64().unwrap() > 0, "{s}");
        assert!(s["on_ms"].as_f64().unwrap() > 0.0 && s["off_ms"].as_f64().unwrap() > 0.0);
        assert!(
            s["visibility_auto"].as_str().unwrap().starts_with("on"),
            "{s}"
        );
    }
    let builds = js["bvh_builds"].as_array().unwrap();
    assert_eq!(builds.len(), 3);
    assert_eq!(builds[2]["triangles"].as_u64(), Some(100 * 5648));
    let inst = &js["instanced"];
    assert_eq!(inst["instances"].as_u64(), Some(100), "{inst}");
    assert_eq!(inst["triangles_placed"].as_u64(), Some(100 * 5648));
    for k in [
        "mesh_bvh_ms",
        "tlas_build_ms",
        "tlas_refit_ms",
        "flat_build_ms",
        "flat_place_ms",
    ] {
        assert!(inst[k].as_f64().unwrap() >= 0.0, "{k}: {inst}");
    }
}
