//! Shadow rays on the GPU against their CPU twins: the two-level traversal ray by ray, and
//! same-seed frames with shadows.

use super::*;

/// Shadow rays on the GPU (`visibility.wgsl`) against their CPU twin (`FlatBvh::occluded`):
/// 20,000 rays on the bunny on a plane, half of them shadow rays leaving the plane; once as one
/// mesh in world space, once as four placements of the bunny (one scaled non-uniformly) and a
/// plane under a top level. A ray may differ only where it grazes a triangle edge (the GPU may
/// fuse multiply-adds): at most 0.1%.
#[test]
fn gpu_shadow_rays_match_cpu() {
    use envis_wgpu::visibility::{GpuBvh, ShadowRay};
    let Some(ctx) = gpu() else { return };
    let (mesh, rays) = support::bunny_on_plane_rays();
    let bvh = envis::visibility::MeshBvh::build(&mesh.positions, &mesh.indices);
    let one = bvh.flatten(&mesh.positions, &mesh.indices).unwrap();
    let rays: Vec<ShadowRay> = rays
        .into_iter()
        .map(|(o, d)| ShadowRay {
            o,
            d,
            t_min: 1e-4,
            t_max: f32::MAX,
        })
        .collect();
    for (what, flat) in [
        ("one mesh", one),
        ("instances", support::instanced_bunnies(0.35).flat),
    ] {
        let got = GpuBvh::new(ctx, &flat).trace(ctx, &rays).unwrap();
        let (mut differ, mut blocked) = (0, 0);
        for (r, g) in rays.iter().zip(&got) {
            let want = flat.occluded(r.o, r.d, r.t_min, r.t_max);
            differ += (want != *g) as usize;
            blocked += want as usize;
        }
        eprintln!(
            "shadow rays, {what}: {blocked} of {} blocked, {differ} differ",
            rays.len()
        );
        assert!(
            blocked > 2_000,
            "{what}: only {blocked} rays blocked: the scene is not in the rays' way"
        );
        assert!(
            differ * 1000 <= rays.len(),
            "{what}: {differ} of {} rays differ",
            rays.len()
        );
    }
    // Layers: each instance on its own layer, the plane on layer 20 (the record's upper
    // half); rays cast for the first bunny's and the plane's layers.
    use envis::visibility::{FlatBvh, FlatInstance, Layers};
    let at = support::instanced_bunnies(0.35);
    let placed: Vec<FlatInstance> = (at.placed.iter().enumerate())
        .map(|(i, p)| FlatInstance {
            layers: Layers(if i == 4 { 1 << 20 } else { 1 << i }),
            ..*p
        })
        .collect();
    let layered = FlatBvh::build(&at.blases, &placed, &at.tlas).unwrap();
    let view = Layers(1 | 1 << 20);
    let got = GpuBvh::new(ctx, &layered)
        .trace_on(ctx, &rays, view)
        .unwrap();
    let (mut differ, mut blocked, mut all) = (0, 0, 0);
    for (r, g) in rays.iter().zip(&got) {
        let want = layered.occluded_on(r.o, r.d, r.t_min, r.t_max, view);
        differ += (want != *g) as usize;
        blocked += want as usize;
        all += layered.occluded(r.o, r.d, r.t_min, r.t_max) as usize;
    }
    eprintln!("shadow rays on layers: {blocked} blocked (all layers: {all}), {differ} differ");
    assert!(
        blocked > 1_000 && blocked + 1_000 < all,
        "{blocked} of {all}"
    );
    assert!(differ * 1000 <= rays.len(), "layers: {differ} rays differ");
    // An empty BVH blocks nothing.
    let empty = GpuBvh::new(ctx, &envis::visibility::FlatBvh::default());
    assert!(empty.trace(ctx, &rays[..10]).unwrap().iter().all(|b| !b));
}

/// Same-seed frames with shadow rays: the GPU's shading stage (`shade.wgsl` through
/// `visibility.wgsl`) against the CPU estimator with the same flattened BVH as its occluder, on a
/// torus resting on a plane seen from above its contact shadow. Per pixel near-identical, as
/// `gpu_render_matches_cpu_same_seed`, and the shadow is really there.
#[test]
fn gpu_shadows_match_cpu_same_seed() {
    use envis_wgpu::visibility::GpuBvh;
    let Some(ctx) = gpu() else { return };
    let dir = support::TempDir::new("gpu-shadows");
    let path = dir.join("torus.toml");
    std::fs::write(
        &path,
        "[environment]\nsource = \"builtin:sky:15\"\nface_size = 16\n\n[camera]\nposition = [0.0, 3.0, 3.0]\ntarget = [0.0, 0.3, 0.0]\nfov = 50.0\n\n[[object]]\nshape = \"torus\"\nposition = [0.0, 0.45, 0.0]\nmaterial = { type = \"ggx\", albedo = 0.8, alpha = 0.3 }\n\n[[object]]\nshape = \"plane\"\nsize = 6.0\nmaterial = { type = \"diffuse\", albedo = 0.6 }\n",
    )
    .unwrap();
    let sc = envis::scene::Scene::load(&path).unwrap();
    // The traced geometry, two-level: the torus's mesh and the unit square, each placed once.
    let flat = sc.shadow_bvh().unwrap();
    assert_eq!((flat.instances(), flat.tlas_nodes()), (2, 3));
    let size = 40;
    let (gbuf, points) = sc.gbuffer_points(size, size);
    let map = load_env(&EnvSource::Sky { hours: 15.0 }, 16).unwrap().cube;
    let s = Settings {
        light_samples: 16,
        brdf_samples: 16,
        seed: 5,
        pool_layout: envis::render::PoolLayout::Offset,
        ..Default::default()
    };
    let extras = envis::render::Extras {
        shadows: Some((&flat, points.as_slice())),
        ..Default::default()
    };
    let cpu = envis::render::render_with(&map, extras, &gbuf, size, size, &s).unwrap();
    let open = render(&map, &gbuf, size, size, &s).unwrap();
    let sampler = EnvSampler::for_settings(ctx, map.size, &s).unwrap();
    sampler.upload(&ctx.queue, &map);
    ctx.wait(sampler.run(ctx, pool_seed(s.seed))).unwrap();
    let pixels: Vec<GpuGPixel> = gbuf.iter().map(GpuGPixel::from).collect();
    let gpu_bvh = GpuBvh::new(ctx, &flat);
    let job = Shader::new(ctx)
        .shade_with_shadows(ctx, &sampler, &pixels, &s, Some((&gpu_bvh, &points)))
        .unwrap();
    let img: Vec<Vec3> = job
        .color
        .iter()
        .map(|c| Vec3::new(c[0], c[1], c[2]))
        .collect();
    let mut off = 0;
    for (a, b) in img.iter().zip(&cpu.image.data) {
        let d = (*a - *b).abs().max_element() / b.max_element().max(1e-3);
        off += (d > 1e-3) as usize;
    }
    assert!(
        off * 200 <= size * size,
        "{off} pixels differ by more than 0.1%"
    );
    let (mg, mc, mo) = (
        mean_lum(&img),
        mean_lum(&cpu.image.data),
        mean_lum(&open.image.data),
    );
    assert!(rel(mg, mc) < 1e-3, "image mean gpu {mg} cpu {mc}");
    assert!(mc < 0.97 * mo, "no visible shadow: {mc} with, {mo} without");
    assert!(
        cpu.stats.blocked > 0.01,
        "blocked fraction {}",
        cpu.stats.blocked
    );
}
