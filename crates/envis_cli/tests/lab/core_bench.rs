//! `envis bench` suites run end to end (no timing asserted), and the FLIP metric matches NVIDIA's
//! evaluator.

use super::*;

#[test]
fn bench_accuracy_quick_smoke() {
    // The quick sweep runs and writes well-formed CSV / JSON / Markdown (no timing asserted).
    let dir = tempdir();
    let r = envis_cmd(&[
        "bench",
        "--suite",
        "accuracy",
        "--quick",
        "--out",
        dir.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    // stderr is not a terminal here: the progress comes as plain lines, the last at 100%, with
    // the time left and the rate.
    let last = err.lines().rfind(|l| l.contains(" left, ")).unwrap_or("");
    assert!(last.contains("100%") && last.contains("points/s"), "{err}");
    let cfg = envis_cli::bench::accuracy::Config::new(true, None).unwrap();
    let n = envis_cli::bench::accuracy::point_count(&cfg);
    let csv = std::fs::read_to_string(dir.join("accuracy.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), n + 1, "one header + one row per point");
    // CI (which has lavapipe) must time every point on the GPU backend too.
    let gpu_required = support::ci();
    for l in &lines[1..] {
        let cols: Vec<&str> = l.split(',').collect();
        assert_eq!(cols.len(), 14, "{l}");
        let relmse: f64 = cols[6].parse().unwrap();
        assert!(relmse.is_finite() && relmse >= 0.0, "{l}");
        let flip: f64 = cols[11].parse().unwrap();
        assert!(
            (0.0..=1.0).contains(&flip) && flip > 0.0,
            "FLIP of a noisy render: {l}"
        );
        if gpu_required {
            for c in &cols[12..14] {
                let ms: f64 = c
                    .parse()
                    .unwrap_or_else(|_| panic!("GPU timing missing: {l}"));
                assert!(ms.is_finite() && ms >= 0.0, "{l}");
            }
        }
    }
    let js: serde_json::Value = support::read_json(&dir.join("accuracy.json"));
    assert_eq!(js["points"].as_array().unwrap().len(), n);
    let md = std::fs::read_to_string(dir.join("accuracy-vs-time.md")).unwrap();
    assert!(
        md.contains("## diffuse")
            && md.contains("Pareto front")
            && md.contains("Mean HDR-FLIP")
            && md.contains("envis bench --suite accuracy --quick"),
        "{md}"
    );
    for (m, _) in &cfg.materials {
        let stem = envis_cli::bench::accuracy::plot_stem(m);
        check_plot(&dir, &stem, &["paper-fractional", "global", "Pareto front"]);
        check_plot(
            &dir,
            &format!("{stem}-samples"),
            &["paper-fractional", "brdf"],
        );
        assert!(md.contains(&format!("{stem}.png")), "{m}");
    }
    check_plot(&dir, "accuracy-wasted", &["paper-fractional", "light"]);
    assert!(md.contains("accuracy-wasted.png"));
}

/// A chart written by `envis bench`: an SVG naming every series and with no non-finite
/// coordinates, and a PNG of the chart's size that is not blank.
fn check_plot(dir: &std::path::Path, stem: &str, series: &[&str]) {
    let svg = std::fs::read_to_string(dir.join(format!("{stem}.svg")))
        .unwrap_or_else(|e| panic!("{stem}.svg: {e}"));
    assert!(
        svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"),
        "{stem}.svg"
    );
    assert!(
        !svg.contains("NaN") && !svg.contains("inf"),
        "{stem}.svg: non-finite coordinates"
    );
    assert!(
        svg.matches("<polyline").count() >= series.len(),
        "{stem}.svg: too few lines"
    );
    for name in series {
        assert!(svg.contains(name), "{stem}.svg: no series '{name}'");
    }
    let file = std::fs::File::open(dir.join(format!("{stem}.png")))
        .unwrap_or_else(|e| panic!("{stem}.png: {e}"));
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .unwrap();
    let mut buf = vec![0u8; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), (800, 520), "{stem}.png");
    let pixels = &buf[..info.buffer_size()];
    let coloured = pixels
        .chunks(3)
        .filter(|p| p[0] != p[1] || p[1] != p[2])
        .count();
    assert!(
        coloured > 500,
        "{stem}.png: only {coloured} coloured pixels"
    );
}

/// An interrupted sweep resumes: the points in `accuracy.partial.jsonl` (same configuration) are
/// taken as they are, a line cut short is measured again, and the journal is removed at the end.
#[test]
fn bench_accuracy_resumes() {
    let dir = tempdir();
    let out = dir.to_str().unwrap();
    let args = [
        "bench",
        "--suite",
        "accuracy",
        "--quick",
        "--cpu-only",
        "--out",
        out,
    ];
    let r = envis_cmd(&args);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(
        !dir.join("accuracy.partial.jsonl").exists(),
        "journal left behind"
    );
    let js: serde_json::Value = support::read_json(&dir.join("accuracy.json"));
    let mut pts: Vec<serde_json::Value> = js["points"].as_array().unwrap().clone();
    let n = pts.len();
    // Journal of an interrupted run: 10 finished points (the first marked) and a torn line.
    pts[0]["relmse"] = serde_json::json!(123.0);
    let cfg = envis_cli::bench::accuracy::Config::new(true, None).unwrap();
    let mut journal =
        serde_json::to_string(&envis_cli::bench::accuracy::fingerprint(&cfg, None)).unwrap() + "\n";
    for p in &pts[..10] {
        journal += &(p.to_string() + "\n");
    }
    journal += "{\"env\":\"builtin:sk";
    std::fs::write(dir.join("accuracy.partial.jsonl"), &journal).unwrap();
    let r = envis_cmd(&args);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        r.status.success() && err.contains(&format!("resuming 10 of {n} points")),
        "{err}"
    );
    let csv = std::fs::read_to_string(dir.join("accuracy.csv")).unwrap();
    assert_eq!(csv.lines().count(), n + 1);
    let first: Vec<&str> = csv.lines().nth(1).unwrap().split(',').collect();
    assert_eq!(
        first[6].parse::<f64>().unwrap(),
        123.0,
        "the resumed point was measured again"
    );
    let md = std::fs::read_to_string(dir.join("accuracy-vs-time.md")).unwrap();
    assert!(md.contains(&format!("10 of {n} points resumed")), "{md}");
    assert!(!dir.join("accuracy.partial.jsonl").exists());
    // A journal from another configuration is not used.
    std::fs::write(
        dir.join("accuracy.partial.jsonl"),
        journal.replace("size=16", "size=17"),
    )
    .unwrap();
    let r = envis_cmd(&args);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        r.status.success() && err.contains("different configuration"),
        "{err}"
    );
    let csv = std::fs::read_to_string(dir.join("accuracy.csv")).unwrap();
    assert_ne!(
        csv.lines()
            .nth(1)
            .unwrap()
            .split(',')
            .nth(6)
            .unwrap()
            .parse::<f64>()
            .unwrap(),
        123.0
    );
}

#[test]
fn bench_popping_quick_smoke() {
    let dir = tempdir();
    let js = bench_json(
        &dir,
        &[
            "popping",
            "--quick",
            "--size",
            "16",
            "--face-size",
            "8",
            "--light-samples",
            "4",
            "--brdf-samples",
            "0",
        ],
        "popping.json",
    );
    let rows = js["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2);
    for row in rows {
        let c = row["change_over_reference"].as_f64().unwrap();
        assert!(c.is_finite() && c > 0.0, "{row}");
    }
    // What the suite is for: integer counts change more from frame to frame than fractional
    // counts (they pop where round(N_f) changes), and jump where the reference does not.
    let get = |m: &str, k: &str| {
        rows.iter()
            .find(|r| r["counts"] == m)
            .and_then(|r| r[k].as_f64())
            .unwrap_or_else(|| panic!("no {k} for {m}"))
    };
    let (frac, int) = (
        get("fractional", "change_over_reference"),
        get("integer", "change_over_reference"),
    );
    assert!(
        int > frac,
        "integer change {int} not above fractional {frac}"
    );
    let (frac_j, int_j) = (
        get("fractional", "discontinuity_fraction"),
        get("integer", "discontinuity_fraction"),
    );
    assert!(
        int_j > frac_j,
        "integer jumps {int_j} not above fractional {frac_j}"
    );
    for m in ["fractional", "integer"] {
        assert!(dir.join(format!("popping-strip-{m}.png")).exists());
    }
    check_plot(
        &dir,
        "popping",
        &["reference", "fractional counts", "integer counts"],
    );
}

/// The flicker suite runs every layout and reports what it is for: on the furnace, the shared
/// pool's image mean moves from seed to seed far more than with a per-pixel offset.
#[test]
fn bench_flicker_smoke() {
    let dir = tempdir();
    let js = bench_json(
        &dir,
        &[
            "flicker",
            "--size",
            "24",
            "--face-size",
            "8",
            "--light-samples",
            "8",
            "--brdf-samples",
            "8",
            "--repeat",
            "24",
        ],
        "bench-flicker.json",
    );
    let rows = js["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 8);
    let sd = |i: usize| rows[i]["image_mean_rel_sd"].as_f64().unwrap();
    let layout = |i: usize| rows[i]["pool_layout"].as_str().unwrap().to_string();
    assert!((0..8).all(|i| sd(i).is_finite() && sd(i) >= 0.0));
    assert_eq!(
        (layout(0), layout(1), layout(5)),
        ("shared".into(), "offset".into(), "blocks".into())
    );
    assert!(sd(0) > 3.0 * sd(1), "shared {} vs offset {}", sd(0), sd(1));
    assert!(
        sd(0) > 2.0 * sd(5),
        "shared {} vs 16 blocks {}",
        sd(0),
        sd(5)
    );
}

/// envis's FLIP / HDR-FLIP against NVIDIA's `flip-evaluator` 1.7 on the images that
/// `docs/bench/flip_reference.py` builds (rebuilt here from the same formulas): exposure range,
/// mean and every pixel of the error map.
#[test]
fn flip_matches_flip_evaluator() {
    use envis_cli::bench::flip::{exposure_range, hdr_flip, ldr_flip};
    let js: serde_json::Value =
        serde_json::from_str(include_str!("../data/flip_reference.json")).unwrap();
    let (w, h) = (
        js["width"].as_u64().unwrap() as usize,
        js["height"].as_u64().unwrap() as usize,
    );
    let mut reference = vec![Vec3::ZERO; w * h];
    for y in 0..h {
        for x in 0..w {
            if (x as i64 - 12).pow(2) + (y as i64 - 10).pow(2) > 100 {
                continue;
            }
            reference[y * w + x] = Vec3::from_array(std::array::from_fn(|c| {
                (4.0 * (0.5 + 0.5 * (0.7 * x as f64 + 1.3 * y as f64 + 2.0 * c as f64).sin())
                    .powi(3)) as f32
            }));
        }
    }
    reference[7 * w + 5] += Vec3::splat(1000.0);
    let mut checked = 0;
    for case in js["cases"].as_array().unwrap() {
        let amp = case["amp"].as_f64().unwrap();
        let want: Vec<f32> = case["map"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap() as f32)
            .collect();
        let (got, mean) = if case["kind"] == "hdr" {
            let mut test = reference.clone();
            for y in 0..h {
                for x in 0..w {
                    for c in 0..3 {
                        let r = reference[y * w + x][c] as f64;
                        test[y * w + x][c] = (r
                            * (1.0
                                + amp * (2.1 * (x * x) as f64 + 3.7 * y as f64 + c as f64).sin()))
                        .max(0.0) as f32;
                    }
                }
            }
            let (start, stop, count) = exposure_range(&reference);
            assert!(
                (start as f64 - case["start"].as_f64().unwrap()).abs() < 1e-4,
                "start {start} vs {}",
                case["start"]
            );
            assert!(
                (stop as f64 - case["stop"].as_f64().unwrap()).abs() < 1e-4,
                "stop {stop} vs {}",
                case["stop"]
            );
            assert_eq!(count as u64, case["count"].as_u64().unwrap());
            hdr_flip(&reference, &test, w, h)
        } else {
            let (mut r, mut t) = (vec![Vec3::ZERO; w * h], vec![Vec3::ZERO; w * h]);
            for y in 0..h {
                for x in 0..w {
                    for c in 0..3 {
                        let v = 0.5 + 0.4 * (0.3 * x as f64 - 0.5 * y as f64 + c as f64).sin();
                        r[y * w + x][c] = v as f32;
                        t[y * w + x][c] = (v + 0.15 * (1.7 * (x * y) as f64 + c as f64).sin())
                            .clamp(0.0, 1.0) as f32;
                    }
                }
            }
            let m = ldr_flip(&r, &t, w, h, envis_cli::bench::flip::default_ppd());
            let mean = m.iter().sum::<f32>() / m.len() as f32;
            (m, mean)
        };
        let worst = got
            .iter()
            .zip(&want)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        let want_mean = case["mean"].as_f64().unwrap() as f32;
        assert!(
            (mean - want_mean).abs() <= 1e-4 + 1e-3 * want_mean,
            "{} amp {amp}: mean {mean} vs flip-evaluator {want_mean}",
            case["kind"]
        );
        assert!(
            worst < 2e-3,
            "{} amp {amp}: a pixel differs by {worst}",
            case["kind"]
        );
        if want_mean > 0.0 {
            checked += 1;
        }
    }
    assert_eq!(checked, 3, "expected three cases with a nonzero error");
}
