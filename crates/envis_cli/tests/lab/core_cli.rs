//! The command line's contract: features, errors without a display or adapter, every subcommand's
//! flags and messages.

use super::*;

/// Each crate pulls only its layer (checked on the resolved dependency graph): a Bevy game
/// depending on `bevy_envis` compiles no window system, egui, plotting, progress bars, statistics
/// or command-line parsing; the core (`envis`) and the WGSL stages (`envis_wgpu`) compile no Bevy.
#[test]
fn each_crate_pulls_only_its_layer() {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let tree = |package: &str| {
        let out = std::process::Command::new(&cargo)
            .current_dir(support::repo())
            .args(["tree", "--locked", "-e", "normal", "--prefix", "none"])
            .args(["--format", "{p}", "-p", package])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let has = |tree: &str, krate: &str| tree.lines().any(|l| l.starts_with(&format!("{krate} v")));
    let lab = [
        "winit",
        "bevy_winit",
        "x11rb",
        "x11-dl",
        "egui",
        "bevy_egui",
        "plotters",
        "indicatif",
        "statrs",
        "clap",
        "envis_stats",
        "envis_cli",
    ];
    let plugins = tree("bevy_envis");
    assert!(has(&plugins, "bevy") && has(&plugins, "envis_wgpu"));
    for k in lab {
        assert!(!has(&plugins, k), "bevy_envis pulls {k}");
    }
    for core in ["envis", "envis_wgpu"] {
        let t = tree(core);
        for k in lab
            .iter()
            .chain(&["bevy", "bevy_ecs", "bevy_reflect", "bevy_envis"])
        {
            assert!(!has(&t, k), "{core} pulls {k}");
        }
    }
    // The lab does bring them: the checks above can see them.
    let lab_tree = tree("envis_cli");
    assert!(
        lab.iter()
            .all(|k| has(&lab_tree, k) || *k == "x11-dl" || *k == "x11rb")
    );
}

/// What a new user meets first: the demo on a machine without a display, and the GPU backend
/// with no such adapter, each give one line saying what to do, and no panic or backtrace.
#[test]
fn cli_without_display_or_adapter_says_what_to_do() {
    let one_line = |out: &std::process::Output, needles: &[&str]| {
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "succeeded: {err}");
        assert_eq!(err.trim().lines().count(), 1, "not one line: {err}");
        assert!(!err.contains("panicked"), "{err}");
        for n in needles {
            assert!(err.contains(n), "'{err}' does not say '{n}'");
        }
    };
    // Mesa's Vulkan loader prints its own complaint when XDG_RUNTIME_DIR is unset (as on a
    // desktop it never is): give the children one, so stderr holds only what envis says.
    let dir = tempdir();
    let demo = std::process::Command::new(env!("CARGO_BIN_EXE_envis"))
        .env("XDG_RUNTIME_DIR", &dir)
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    one_line(&demo, &["DISPLAY", "xvfb-run", "envis render"]);
    let gpu = std::process::Command::new(env!("CARGO_BIN_EXE_envis"))
        .args(["render", "--backend", "wgpu", "--size", "8", "--out"])
        .arg(dir.join("x.exr"))
        .env("XDG_RUNTIME_DIR", &dir)
        .env("WGPU_ADAPTER_NAME", "no-such-adapter-anywhere")
        .output()
        .unwrap();
    one_line(&gpu, &["no-such-adapter-anywhere", "mesa-vulkan-drivers"]);
}

#[test]
fn cli_contract() {
    let dir = tempdir();
    let out = dir.join("img.exr");
    let stats = dir.join("stats.json");
    let r = envis_cmd(&[
        "render",
        "--env",
        "builtin:sky:9",
        "--face-size",
        "16",
        "--scene",
        "sphere",
        "--size",
        "24",
        "--brdf",
        "ggx",
        "--alpha",
        "0.3",
        "--light-samples",
        "4",
        "--brdf-samples",
        "4",
        "--strategy",
        "paper",
        "--counts",
        "fractional",
        "--mis",
        "balance",
        "--seed",
        "3",
        "--backend",
        "cpu",
        "--out",
        out.to_str().unwrap(),
        "--stats",
        stats.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let img = envis::envmap::load::read_exr(&out).unwrap();
    assert_eq!((img.width, img.height), (24, 24));
    assert_eq!(img.get(0, 0), Vec3::ZERO, "corner pixel is off the sphere");
    assert!(img.get(12, 12).max_element() > 0.0);
    let js: serde_json::Value = support::read_json(&stats);
    for key in [
        "build_ms",
        "shade_ms",
        "samples_evaluated",
        "red",
        "green",
        "yellow",
        "wasted",
    ] {
        assert!(js[key].is_number(), "stats lack {key}: {js}");
    }
    let (red, green, yellow) = (
        js["red"].as_f64().unwrap(),
        js["green"].as_f64().unwrap(),
        js["yellow"].as_f64().unwrap(),
    );
    assert!((red + green + yellow - 1.0).abs() < 1e-9);

    let refp = dir.join("ref.exr");
    let r = envis_cmd(&[
        "reference",
        "--env",
        "builtin:sky:9",
        "--face-size",
        "8",
        "--size",
        "8",
        "--brdf",
        "phong",
        "--exponent",
        "20",
        "--out",
        refp.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(refp.exists());

    // Bad arguments and files: one line, non-zero exit, names the problem.
    let o = out.to_str().unwrap();
    let bad: &[(&[&str], &str)] = &[
        (
            &["render", "--env", "/nonexistent/x.exr", "--out", o],
            "x.exr",
        ),
        (&["render", "--strategy", "fancy", "--out", o], "fancy"),
        (
            &[
                "render",
                "--light-samples",
                "0",
                "--brdf-samples",
                "0",
                "--out",
                o,
            ],
            "both 0",
        ),
        (&["render", "--scene", "teapot", "--out", o], "teapot"),
        (
            &["render", "--brdf", "ggx", "--alpha", "0", "--out", o],
            "--alpha",
        ),
        (&["render", "--out", "image.png"], ".exr"),
        (&["render", "--env", "builtin:sky:noon", "--out", o], "noon"),
        (&["render", "--size", "abc", "--out", o], "abc"),
    ];
    for (args, needle) in bad {
        let r = envis_cmd(args);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success(), "{args:?} should fail");
        assert_eq!(
            err.trim_end().lines().count(),
            1,
            "{args:?}: not one line: {err}"
        );
        assert!(
            err.contains(needle),
            "{args:?}: '{err}' does not name '{needle}'"
        );
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}

/// `envis render` reads radiance from the map at its own resolution by default (`--radiance
/// full`; the built-in sky at 128^2 faces), `--face-size` giving the densities: the same image as
/// the library's `render_with` with that map as `Extras::fine`; `--radiance distribution` is
/// the library's `render` of the `--face-size` map. `envis reference` integrates the map the
/// renders read.
#[test]
fn render_reads_the_map_at_its_own_resolution() {
    let dir = tempdir();
    let run = |cmd: &str, radiance: &str, name: &str| {
        let out = dir.join(format!("{name}.exr"));
        let stats = dir.join(format!("{name}.json"));
        let mut args = vec![
            cmd,
            "--env",
            "builtin:sky:15",
            "--face-size",
            "8",
            "--size",
            "12",
        ];
        args.extend(["--brdf", "ggx", "--alpha", "0.05", "--radiance", radiance]);
        if cmd == "render" {
            args.extend(["--light-samples", "4", "--brdf-samples", "4", "--seed", "3"]);
        }
        args.extend([
            "--out",
            out.to_str().unwrap(),
            "--stats",
            stats.to_str().unwrap(),
        ]);
        let r = envis_cmd(&args);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let js = support::read_json(&stats);
        (
            envis::envmap::load::read_exr(&out).unwrap().data,
            js["radiance"].clone(),
        )
    };
    let src = EnvSource::Sky { hours: 15.0 };
    let env = envis::envmap::load::load_env_full(&src, 8).unwrap();
    let fine = env.fine.as_ref().unwrap();
    let gbuf = sphere_gbuffer(12, 12, Material::ggx(0.8, 0.05));
    let s = Settings {
        light_samples: 4,
        brdf_samples: 4,
        seed: 3,
        ..Default::default()
    };
    let lookup = |d: Vec3| fine.lookup(d);
    // The CLI samples inside the distribution's texels by the fine luminance (sub-texels).
    let extras = envis::render::Extras {
        fine: Some(&lookup),
        sub_texels: Some(fine),
        ..Default::default()
    };
    let want_full = envis::render::render_with(&env.cube, extras, &gbuf, 12, 12, &s).unwrap();
    let want_coarse = render(&env.cube, &gbuf, 12, 12, &s).unwrap();
    let (full, note) = run("render", "full", "full");
    assert_eq!(full, want_full.image.data);
    assert!(
        note.as_str().unwrap().contains("own resolution (128^2"),
        "{note}"
    );
    let (coarse, note) = run("render", "distribution", "coarse");
    assert_eq!(coarse, want_coarse.image.data);
    assert!(note.as_str().unwrap().contains("distribution"), "{note}");
    assert_ne!(full, coarse);

    let (rf, _) = run("reference", "full", "ref-full");
    let (want, _) = reference_image(fine, &gbuf, 12, 12, 1.0);
    assert_eq!(rf, want.data);
    let (rc, _) = run("reference", "distribution", "ref-coarse");
    assert_eq!(rc, reference_image(&env.cube, &gbuf, 12, 12, 1.0).0.data);
}
