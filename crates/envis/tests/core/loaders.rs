//! Real maps load and report their clamped texels; bad files give clear one-line errors.

use super::*;

#[test]
fn real_maps_load_and_report_clamped_texels() {
    let Some(maps) = support::real_maps() else {
        return;
    };
    assert!(
        maps.len() >= 18,
        "expected the 18 shared maps, found {}",
        maps.len()
    );
    let mut total_negative = 0;
    for p in &maps {
        let env = load_env(&EnvSource::File(p.clone()), 32).unwrap();
        assert!(
            env.cube
                .data
                .iter()
                .all(|c| c.is_finite() && c.min_element() >= 0.0),
            "{}",
            p.display()
        );
        total_negative += env.report.negative;
    }
    assert!(
        total_negative > 0,
        "the shared maps are known to contain negative pixels"
    );
}

/// `load_env_full` keeps the map at its own resolution beside the distribution's: a 512 x 256
/// lat-long at 128^2 faces (none when the distribution is that fine already), sanitised, and
/// never bright where the distribution's texel is 0 (the densities cover the radiance).
#[test]
fn full_resolution_map_beside_the_distribution() {
    let Some(maps) = support::real_maps() else {
        return;
    };
    for p in maps.iter().take(4) {
        let src = EnvSource::File(p.clone());
        let env = envis::envmap::load::load_env_full(&src, 32).unwrap();
        let fine = env.fine.as_ref().unwrap();
        assert_eq!((env.cube.size, fine.size), (32, 128), "{}", p.display());
        assert!(
            fine.data
                .iter()
                .all(|c| c.is_finite() && c.min_element() >= 0.0)
        );
        for face in 0..6 {
            for (row, col) in (0..128).flat_map(|r| (0..128).map(move |c| (r, c))) {
                let t = fine.data[fine.index(face, col, row)];
                let coarse = env.cube.data[env.cube.index(face, col / 4, row / 4)];
                assert!(
                    t.max_element() == 0.0 || coarse.max_element() > 0.0,
                    "{}: fine texel {face} ({col}, {row}) is bright, its coarse texel 0",
                    p.display()
                );
            }
        }
        // Energy is kept: the two are the same map at two resolutions.
        let energy = |m: &CubeMap| {
            (0..m.data.len())
                .map(|i| {
                    let (r, c) = ((i / m.size) % m.size, i % m.size);
                    luminance(m.data[i]) as f64 * texel_solid_angle(c, r, m.size)
                })
                .sum::<f64>()
        };
        let (a, b) = (energy(&env.cube), energy(fine));
        assert!((a - b).abs() < 1e-3 * b, "{}: {a} vs {b}", p.display());
        assert!(
            envis::envmap::load::load_env_full(&src, 128)
                .unwrap()
                .fine
                .is_none()
        );
        assert!(load_env(&src, 32).unwrap().fine.is_none());
    }
}

#[test]
fn bad_files_give_clear_errors() {
    let dir = tempdir();
    let missing = dir.join("missing.exr");
    let e = load_env(&EnvSource::File(missing.clone()), 16)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("missing.exr") && e.contains("cannot open"),
        "{e}"
    );

    // Truncated EXR.
    let good = dir.join("good.exr");
    envis::render::output::write_exr(&good, &Image::new(64, 32)).unwrap();
    let bytes = std::fs::read(&good).unwrap();
    let trunc = dir.join("trunc.exr");
    std::fs::write(&trunc, &bytes[..bytes.len() / 2]).unwrap();
    let e = load_env(&EnvSource::File(trunc), 16)
        .unwrap_err()
        .to_string();
    assert!(e.contains("trunc.exr") && !e.contains('\n'), "{e}");

    // Wrong channels (luminance only, written by Mitsuba 3).
    let y_only = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus/luminance_only_8x4.exr");
    let e = load_env(&EnvSource::File(y_only), 4)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("luminance_only_8x4.exr") && e.contains("needs R, G and B"),
        "{e}"
    );

    // Wrong aspect ratio.
    let odd = dir.join("odd.exr");
    envis::render::output::write_exr(&odd, &Image::new(50, 30)).unwrap();
    let e = load_env(&EnvSource::File(odd), 16).unwrap_err().to_string();
    assert!(e.contains("odd.exr") && e.contains("2:1"), "{e}");

    // Not an image at all.
    let txt = dir.join("notes.exr");
    std::fs::write(&txt, b"hello").unwrap();
    let e = load_env(&EnvSource::File(txt), 16).unwrap_err().to_string();
    assert!(e.contains("notes.exr") && e.contains("magic"), "{e}");

    // Radiance: absurd dimensions refused before allocating, truncated data named.
    let e =
        read_hdr_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 100000\n").unwrap_err();
    assert!(e.contains("absurd"), "{e}");
    let mut hdr = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 4\n".to_vec();
    hdr.extend_from_slice(&[1, 1, 1, 128].repeat(5));
    let e = read_hdr_bytes(&hdr).unwrap_err();
    assert!(e.contains("truncated"), "{e}");
    // A valid .hdr lat-long loads through the same entry point.
    let mut hdr = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 4 +X 8\n".to_vec();
    hdr.extend_from_slice(&[64, 64, 64, 129].repeat(32));
    let p = dir.join("ok.hdr");
    std::fs::write(&p, &hdr).unwrap();
    let env = load_env(&EnvSource::File(p), 4).unwrap();
    assert!((env.cube.data[0].x - 64.5 / 128.0).abs() < 1e-3);
}
