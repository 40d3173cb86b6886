//! Suite `offset`: how much shared error a per-pixel random start into the pool removes.

use super::*;

/// Suite `offset`: what the per-pixel random start offset into the pool does. For a pool of
/// M = N_L and M = 4 N_L samples per face, with and without the offset, over `--repeat` seeds:
/// per-pixel relative MSE against the reference (noise a viewer sees per pixel), and the spread
/// across seeds of the image-mean error (error shared by all pixels, i.e. correlated).
pub(super) fn offset(a: BenchArgs, dir: PathBuf) -> Result<()> {
    let env = load_env(&a.env.parse()?, a.face_size)?;
    let size = a.size;
    let k = a.repeat.max(4);
    let mut rows = Vec::new();
    for (mname, mat) in [
        ("diffuse", Material::diffuse(0.8)),
        ("ggx 0.2", Material::ggx(0.8, 0.2)),
    ] {
        let sphere = Sphere::new(&env.cube, size, mat);
        for pool_mult in [1usize, 4] {
            for pool_layout in envis::render::PoolLayout::ALL {
                let s = Settings {
                    light_samples: a.light_samples,
                    brdf_samples: a.brdf_samples,
                    pool_size: a.light_samples * pool_mult,
                    pool_layout,
                    ..Default::default()
                };
                let (relmse, mean_sd) = sphere.spread(&env.cube, size, k, s)?;
                eprintln!(
                    "  {mname:8} pool {:>3}/face {:6}: per-pixel relMSE {relmse:.4e}  image-mean rel. SD {mean_sd:.4e}",
                    s.pool_size, pool_layout
                );
                rows.push(serde_json::json!({ "material": mname, "pool_per_face": s.pool_size, "pool_layout": pool_layout, "pool_blocks": s.pool_block_count(), "relmse": relmse, "image_mean_rel_sd": mean_sd }));
            }
        }
    }
    let report = serde_json::json!({ "suite": "offset", "env": a.env, "face_size": a.face_size, "size": size, "light_samples": a.light_samples, "brdf_samples": a.brdf_samples, "seeds": k, "rows": rows });
    let path = dir.join("bench-offset.json");
    envis::render::output::write_json(&path, &report)?;
    eprintln!("wrote {}", path.display());
    Ok(())
}

/// The sphere of one material, with its reference and the reference's mean luminance.
struct Sphere {
    gbuf: Vec<Option<render::GPixel>>,
    reference: Vec<glam::DVec3>,
    /// The pixels the sphere covers.
    idx: Vec<usize>,
    ref_mean: f64,
}

impl Sphere {
    /// The `size` x `size` sphere of material `mat` and its reference in `cube`.
    fn new(cube: &CubeMap, size: usize, mat: Material) -> Self {
        let gbuf = render::sphere_gbuffer(size, size, mat);
        let (_, reference) =
            envis::render::reference::reference_image(cube, &gbuf, size, size, 1.0);
        let lum = envis::envmap::luminance_f64;
        let idx: Vec<usize> = (0..gbuf.len()).filter(|&i| gbuf[i].is_some()).collect();
        let ref_mean = idx.iter().map(|&i| lum(reference[i])).sum::<f64>() / idx.len() as f64;
        Sphere {
            gbuf,
            reference,
            idx,
            ref_mean,
        }
    }

    /// Renders settings `s` with seeds `0..k`: the per-pixel relMSE, and the relative SD across
    /// seeds of the image mean.
    fn spread(&self, cube: &CubeMap, size: usize, k: usize, s: Settings) -> Result<(f64, f64)> {
        let lum = envis::envmap::luminance_f64;
        let (mut relmse, mut means) = (0.0, Vec::new());
        for seed in 0..k {
            let out = render::render(
                cube,
                &self.gbuf,
                size,
                size,
                &Settings {
                    seed: seed as u32,
                    ..s
                },
            )?;
            let mut m = 0.0;
            for &i in &self.idx {
                let (x, r) = (lum(out.image.data[i].as_dvec3()), lum(self.reference[i]));
                relmse += (x - r) * (x - r) / (r * r + 1e-2);
                m += x;
            }
            means.push(m / self.idx.len() as f64);
        }
        relmse /= (k * self.idx.len()) as f64;
        let (_, se) = envis_stats::mean_se(&means);
        Ok((relmse, se * (k as f64).sqrt() / self.ref_mean))
    }
}
