//! Conventions and loaders' colour handling: directions, faces and texels, EXR chromaticities and
//! Radiance headers, the lat-long mapping, resampling and the cube cross.

use super::*;

#[test]
fn direction_face_uv_round_trip() {
    let mut r = Rng::new(1, 1);
    for _ in 0..100_000 {
        let d = random_dir(&mut r);
        let (f, u, v) = dir_to_face_uv(d);
        let back = face_uv_to_dir(f, u, v);
        assert!((back - d).length() < 1e-5, "{d} -> {f} {u} {v} -> {back}");
        // ... and the lat-long mapping.
        let (lu, lv) = dir_to_latlong(d);
        assert!((latlong_to_dir(lu, lv) - d).length() < 1e-4);
    }
}

/// An 8x4 lat-long EXR of one colour `c` declaring `chromaticities` (rx ry gx gy bx by wx wy).
fn exr_with_chromaticities(path: &Path, c: Vec3, chroma: [f32; 8]) {
    use exr::prelude::*;
    let channels = SpecificChannels::rgb(|_: Vec2<usize>| (c.x, c.y, c.z));
    let mut img = Image::from_channels((8, 4), channels);
    let v = |i: usize| Vec2(chroma[i], chroma[i + 1]);
    img.attributes.chromaticities = Some(exr::meta::attribute::Chromaticities {
        red: v(0),
        green: v(2),
        blue: v(4),
        white: v(6),
    });
    img.write().to_file(path).unwrap();
}

#[test]
fn exr_chromaticities_convert_to_rec709() {
    let dir = tempdir();
    let load = |name: &str| {
        let img = envis::envmap::load::read_image(&dir.join(name)).unwrap();
        img.data[0]
    };
    // ACES2065-1 (AP0, ACES white): red and white against the published AP0 -> Rec.709 (Bradford)
    // matrix: first column (2.52169, -0.27648, -0.01538); white stays white.
    let ap0 = [0.7347, 0.2653, 0.0, 1.0, 0.0001, -0.077, 0.32168, 0.33767];
    exr_with_chromaticities(&dir.join("ap0-red.exr"), Vec3::X, ap0);
    exr_with_chromaticities(&dir.join("ap0-white.exr"), Vec3::ONE, ap0);
    let red = load("ap0-red.exr");
    assert!(
        (red - Vec3::new(2.52169, -0.27648, -0.01538))
            .abs()
            .max_element()
            < 2e-3,
        "AP0 red -> {red}"
    );
    assert!((load("ap0-white.exr") - Vec3::ONE).abs().max_element() < 1e-4);
    // Rec.709 primaries Bradford-adapted to D50, as ICC-style tools write them (the sRGB
    // profile's colorants): adapted back to D65 they are Rec.709 again, within 0.5%.
    let icc = [
        0.6484, 0.3309, 0.3212, 0.5978, 0.1559, 0.0660, 0.3457, 0.3585,
    ];
    for (k, c) in [Vec3::X, Vec3::Y, Vec3::Z, Vec3::new(0.2, 0.5, 0.9)]
        .iter()
        .enumerate()
    {
        let name = format!("icc-{k}.exr");
        exr_with_chromaticities(&dir.join(&name), *c, icc);
        let got = load(&name);
        assert!((got - *c).abs().max_element() < 5e-3, "{c} -> {got}");
    }
    // Plain Rec.709 chromaticities: untouched, bit for bit.
    let rec709 = [0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290];
    exr_with_chromaticities(&dir.join("709.exr"), Vec3::new(0.3, 0.6, 0.9), rec709);
    assert_eq!(load("709.exr"), Vec3::new(0.3, 0.6, 0.9));
}

#[test]
fn hdr_exposure_and_primaries_headers() {
    // One flat RGBE pixel: mantissas 128, 64, 32 (read at their centres, + 0.5), exponent 129.
    let pixel = [128u8, 64, 32, 129];
    let file = |header: &[&str]| {
        let mut f = String::from("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n");
        header.iter().for_each(|l| f += &format!("{l}\n"));
        let mut f = (f + "\n-Y 1 +X 1\n").into_bytes();
        f.extend_from_slice(&pixel);
        read_hdr_bytes(&f).unwrap().data[0]
    };
    let plain = file(&[]);
    assert_eq!(plain, Vec3::new(128.5, 64.5, 32.5) / 128.0);
    // EXPOSURE lines multiply; the pixels are divided by their product.
    assert_eq!(file(&["EXPOSURE=2", "EXPOSURE=0.25"]), plain * 2.0);
    // PRIMARIES in AP0: converted as for EXR files.
    let ap0 = file(&["PRIMARIES=0.7347 0.2653 0 1 0.0001 -0.077 0.32168 0.33767"]);
    let m = envis::envmap::color::to_rec709(&envis::envmap::color::Primaries::ACES_AP0)
        .unwrap()
        .unwrap();
    assert!(((m * plain.as_dvec3()).as_vec3() - ap0).abs().max_element() < 1e-6);
    let bad = |h: &str| {
        let mut f = format!("#?RADIANCE\n{h}\n\n-Y 1 +X 1\n").into_bytes();
        f.extend_from_slice(&pixel);
        read_hdr_bytes(&f).unwrap_err()
    };
    assert!(bad("EXPOSURE=-1").contains("EXPOSURE"));
    assert!(bad("PRIMARIES=1 2 3").contains("PRIMARIES"));
}

#[test]
fn latlong_bright_spot_lands_where_the_convention_says() {
    // (u, v) -> expected face, by d = (sin t sin p, cos t, -sin t cos p).
    let cases = [
        ((0.25, 0.5), 0usize),
        ((0.75, 0.5), 1),
        ((0.5, 0.5), 4),
        ((0.0, 0.5), 5),
        ((0.3, 0.02), 2),
        ((0.6, 0.98), 3),
        ((0.13, 0.31), 9),
    ];
    for ((u, v), face) in cases {
        let (w, h) = (256usize, 128usize);
        let mut img = Image::new(w, h);
        let (x, y) = (
            ((u * w as f32) as usize).min(w - 1),
            ((v * h as f32) as usize).min(h - 1),
        );
        img.data[y * w + x] = Vec3::splat(1e4);
        let dir = tempdir();
        let path = dir.join("spot.exr");
        envis::render::output::write_exr(&path, &img).unwrap();
        let cube = load_env(&EnvSource::File(path), 16).unwrap().cube;
        let brightest = (0..cube.data.len())
            .max_by(|&a, &b| {
                envis::envmap::luminance(cube.data[a])
                    .total_cmp(&envis::envmap::luminance(cube.data[b]))
            })
            .unwrap();
        let (f, row, col) = (brightest / 256, (brightest / 16) % 16, brightest % 16);
        let got = face_uv_to_dir(f, (col as f32 + 0.5) / 16.0, (row as f32 + 0.5) / 16.0);
        let want = latlong_to_dir((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
        assert!(
            got.dot(want) > (0.12f32).cos(),
            "spot at ({u},{v}) -> face {f} ({col},{row}) dir {got}, want {want}"
        );
        if face < 6 {
            assert_eq!(
                f,
                face,
                "spot at ({u},{v}) landed on {}",
                Face::from_index(f).name()
            );
        }
    }
}

#[test]
fn resampling_preserves_energy() {
    let mut img = generated_latlong(512, 3);
    img.sanitize();
    let want = latlong_integral(&img);
    for face in [8, 32, 128, 256] {
        let got = latlong_to_cube(&img, face).integral();
        let rel = ((got - want).length() / want.length()).abs();
        assert!(rel < 0.01, "face {face}: {got} vs {want} ({rel})");
    }
    if let Some(maps) = support::real_maps() {
        for p in maps.iter().take(4) {
            let mut img = envis::envmap::load::read_image(p).unwrap();
            img.sanitize();
            let want = latlong_integral(&img);
            let got = latlong_to_cube(&img, 64).integral();
            assert!(
                ((got - want).length() / want.length()) < 0.01,
                "{}: {got} vs {want}",
                p.display()
            );
        }
    }
}

#[test]
fn cube_cross_round_trip() {
    let cube = load_env(&EnvSource::Sky { hours: 8.0 }, 8).unwrap().cube;
    let cross = cube_to_cross(&cube);
    assert_eq!(
        envis::envmap::load::detect_layout(cross.width, cross.height),
        Ok(envis::envmap::load::Layout::HorizontalCross)
    );
    let back =
        envis::envmap::load::cross_to_cube(&cross, envis::envmap::load::Layout::HorizontalCross);
    assert_eq!(back.data, cube.data);
    // Faces that share an edge in the cross share it on the sphere: +Z's top row touches +Y's bottom row.
    let n = 8;
    for c in 0..n {
        let a = face_uv_to_dir(4, (c as f32 + 0.5) / n as f32, 0.0);
        let b = face_uv_to_dir(2, (c as f32 + 0.5) / n as f32, 1.0);
        assert!((a - b).length() < 1e-6);
    }
}
