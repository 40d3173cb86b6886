//! The interactive demo under Xvfb on lavapipe: a scripted sequence (start, integer counts, each
//! overlay, a probed pixel with the sample-debug view on and off, a BRDF change), with assertions
//! on the screenshots and on the run's report.

use super::*;

struct Png {
    w: usize,
    h: usize,
    rgba: Vec<u8>,
}

fn read_png(path: &Path) -> Png {
    let dec = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())),
    ));
    let mut r = dec.read_info().unwrap();
    let mut buf = vec![0; r.output_buffer_size().unwrap()];
    let info = r.next_frame(&mut buf).unwrap();
    let ch = match info.color_type {
        png::ColorType::Rgba => 4,
        png::ColorType::Rgb => 3,
        c => panic!("{}: unexpected colour type {c:?}", path.display()),
    };
    let rgba = buf[..info.buffer_size()]
        .chunks_exact(ch)
        .flat_map(|p| [p[0], p[1], p[2], 255])
        .collect();
    Png {
        w: info.width as usize,
        h: info.height as usize,
        rgba,
    }
}

fn count_exact(p: &Png, rgb: [u8; 3]) -> usize {
    p.rgba.chunks_exact(4).filter(|q| q[..3] == rgb).count()
}

/// Mean absolute difference (0..255) over the central region, where no panel is drawn.
fn centre_diff(a: &Png, b: &Png) -> f64 {
    assert_eq!((a.w, a.h), (b.w, b.h));
    let (x0, x1, y0, y1) = (
        a.w * 30 / 100,
        a.w * 62 / 100,
        a.h * 25 / 100,
        a.h * 95 / 100,
    );
    let mut sum = 0.0;
    let mut n = 0.0;
    for y in y0..y1 {
        for x in x0..x1 {
            let i = 4 * (y * a.w + x);
            for c in 0..3 {
                sum += (a.rgba[i + c] as f64 - b.rgba[i + c] as f64).abs();
                n += 1.0;
            }
        }
    }
    sum / n
}

#[test]
fn demo_scripted_under_xvfb() {
    let Some(_) = gpu() else { return };
    if std::process::Command::new("xvfb-run")
        .arg("--help")
        .output()
        .is_err()
    {
        crate::support::skip_gpu_or_fail(
            "the demo test",
            "xvfb-run not found",
            "Install Xvfb (apt-get install xvfb xauth).",
        );
        return;
    }
    let dir = support::TempDir::new("demo");
    let t0 = std::time::Instant::now();
    // Every step of the script, at a small cost: a 512 x 320 window with the panels at half
    // size (so the scene stays visible), 4 + 4 samples with shadow rays, 57 frames. About a
    // minute on 2 cores (docs/testing.md); the limit only stops a hung demo.
    let out = std::process::Command::new("timeout")
        .args(["900", "xvfb-run", "-a", "-s", "-screen 0 1280x800x24"])
        .arg(env!("CARGO_BIN_EXE_envis"))
        .args([
            "--window",
            "512x320",
            "--ui-scale",
            "0.5",
            "--light-samples",
            "4",
            "--brdf-samples",
            "4",
            "--face-size",
            "32",
            "--script",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "demo failed ({:?}):\n{log}",
        out.status
    );
    assert!(!log.contains("panicked"), "{log}");
    eprintln!("demo script ran in {:.1} s", t0.elapsed().as_secs_f64());
    let shot = |n: &str| read_png(&dir.join(n));
    let start = shot("start.png");
    let integer = shot("integer.png");
    let (on, off) = (shot("debug-on.png"), shot("debug-off.png"));
    let (red, green, yellow) = ([255, 0, 0], [0, 255, 0], [255, 255, 0]);
    // The three debug colours are present with the sample-debug view on, absent with it off.
    for (name, c) in [("red", red), ("green", green), ("yellow", yellow)] {
        assert!(
            count_exact(&on, c) > 0,
            "debug view on: no {name} samples drawn"
        );
        assert_eq!(
            count_exact(&off, c),
            0,
            "debug view off: {name} samples still drawn"
        );
    }
    // Toggling the counts changes the image (the scene, not just the panel).
    let d = centre_diff(&start, &integer);
    assert!(
        d > 0.2,
        "integer counts did not change the image (mean diff {d})"
    );
    // Each overlay replaces the shading.
    for o in [
        "overlay-samples.png",
        "overlay-wasted.png",
        "overlay-diff.png",
        "overlay-history.png",
    ] {
        let d = centre_diff(&start, &shot(o));
        assert!(d > 10.0, "{o}: overlay not visible (mean diff {d})");
    }
    // Changing the sphere's BRDF changes the image.
    assert!(
        centre_diff(&off, &shot("brdf.png")) > 0.05,
        "BRDF change not visible"
    );
    // The report: per-pass timings, counters, and the probed pixel (GPU estimate = CPU twin).
    let r: serde_json::Value = crate::support::read_json(&dir.join("report.json"));
    // The probe's readback is asynchronous: the script waits for it (a slow machine needs more
    // frames); say how long, so a slow run is visible in the log.
    eprintln!(
        "the probed pixel came back after {} extra frames",
        r["probe_wait_frames"]
    );
    let t = &r["timings_ms"];
    assert!(
        t["lighting_cpu_ms"].as_f64().is_some_and(|x| x >= 0.0)
            && t["build_cpu_ms"].as_f64().is_some(),
        "{r}"
    );
    assert!(r["lighting_passes"].as_u64().unwrap() >= 40, "{r}");
    // Overlays were on for three steps (and only then).
    let ov = r["overlay_passes"].as_u64().unwrap();
    assert!(
        ov >= 3 && ov < r["lighting_passes"].as_u64().unwrap(),
        "{r}"
    );
    // Resampling (its last steps) reused history in every frame after its first, and drew a
    // new pool each frame: those are the only builds besides the first ones.
    let resampled = r["resampling_passes"].as_u64().unwrap();
    assert!(
        resampled >= 3 && r["resampling_histories"].as_u64().unwrap() + 1 >= resampled,
        "{r}"
    );
    assert!(
        centre_diff(&shot("brdf.png"), &shot("resampling.png")) > 0.05,
        "resampling did not change the image"
    );
    assert!(
        r["builds"].as_u64().unwrap() <= 3 + resampled,
        "a paused sky must not be rebuilt every frame: {r}"
    );
    let p = &r["probe"];
    let total: u64 = ["red", "green", "yellow"]
        .iter()
        .map(|k| p[k].as_u64().unwrap())
        .sum();
    assert_eq!(total, 6 * 4, "every pool sample is classified: {p}");
    for c in 0..3 {
        let (g, cpu) = (
            p["gpu_estimate"][c].as_f64().unwrap(),
            p["cpu_estimate"][c].as_f64().unwrap(),
        );
        assert!(
            (g - cpu).abs() <= 1e-3 * cpu.abs().max(1e-3),
            "probe: GPU {g} vs CPU twin {cpu}"
        );
    }
    // Keep a copy for the docs when asked.
    if let Ok(d) = std::env::var("ENVIS_TEST_DUMP") {
        for n in [
            "start.png",
            "debug-on.png",
            "overlay-samples.png",
            "overlay-wasted.png",
            "overlay-diff.png",
            "resampling.png",
            "overlay-history.png",
        ] {
            let _ = std::fs::copy(dir.join(n), Path::new(&d).join(format!("demo-{n}")));
        }
    }
}
