//! The shading stage's WGSL functions, one at a time, against their CPU twins on a real Vulkan
//! device (as vello tests its stages): `brdf_sample` / `brdf_eval` / `brdf_pdf`,
//! `mis_weight_over_density`, `face_count`, `draw_tile` and `pool_window`, through the test-only
//! entry points of `shaders/shade_functions_test.wgsl`. A whole frame can hide a wrong function
//! behind the others' noise; here each answer is compared case by case.

use super::*;
use envis::render::{PoolLayout, Settings};
use envis::sampling::brdf::{Lobe, Material};
use envis::sampling::tiles::{TileGrid, TileWeights, draw_tile};
use envis_wgpu::GpuCode;
use envis_wgpu::shading::ShadeParams;
use glam::{Vec2, Vec4};
use wgpu::util::DeviceExt;

/// What one test entry binds besides its input and output: the uniform `sp` and the `regions`.
#[derive(Default)]
struct Bound<'a> {
    sp: Option<ShadeParams>,
    regions: Option<&'a [[f32; 4]]>,
}

/// The device and the shading module with its test entry points, compiled once for all of them.
struct Functions<'a> {
    ctx: &'a GpuContext,
    module: wgpu::ShaderModule,
}

impl<'a> Functions<'a> {
    fn new(ctx: &'a GpuContext) -> Self {
        let source = envis_wgpu::shaders::shade_functions_test_source();
        let module = envis_wgpu::shaders::module(&ctx.device, "shade functions test", &source);
        Functions { ctx, module }
    }
}

/// Run the test entry `entry` over `cases` invocations with `input`; `out_per_case` vec4s back
/// per case.
fn run_entry(
    functions: &Functions,
    entry: &str,
    input: &[[f32; 4]],
    (cases, out_per_case): (usize, usize),
    bound: Bound,
) -> Vec<[f32; 4]> {
    let ctx = functions.ctx;
    let device = &ctx.device;
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(entry),
        layout: None,
        module: &functions.module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    });
    let storage = |label, data: &[u8], usage| {
        let usage = usage | wgpu::BufferUsages::STORAGE;
        let contents = if data.is_empty() {
            &[0u8; 16][..]
        } else {
            data
        };
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents,
            usage,
        })
    };
    let input = storage(
        "test_in",
        bytemuck::cast_slice(input),
        wgpu::BufferUsages::empty(),
    );
    let zeros = vec![0u8; 16 * cases * out_per_case];
    let output = storage("test_out", &zeros, wgpu::BufferUsages::COPY_SRC);
    let sp = bound.sp.map(|sp| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("sp"),
            contents: bytemuck::bytes_of(&sp),
            usage: wgpu::BufferUsages::UNIFORM,
        })
    });
    let regions = bound.regions.map(|r| {
        storage(
            "regions",
            bytemuck::cast_slice(r),
            wgpu::BufferUsages::empty(),
        )
    });
    let mut entries = vec![(12, &input), (13, &output)];
    entries.extend(sp.iter().map(|b| (6, b)));
    entries.extend(regions.iter().map(|b| (2, b)));
    let entries: Vec<_> = (entries.iter())
        .map(|&(binding, b)| wgpu::BindGroupEntry {
            binding,
            resource: b.as_entire_binding(),
        })
        .collect();
    let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(entry),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &entries,
    });
    let mut enc = device.create_command_encoder(&Default::default());
    {
        let mut pass = enc.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(cases as u32, 1, 1);
    }
    ctx.wait(ctx.queue.submit([enc.finish()])).unwrap();
    ctx.read::<[f32; 4]>(&output, 0, cases * out_per_case)
        .unwrap()
}

/// `a` and `b` agree to `tol` relative to their size (at least 1), or are the same non-finite.
fn near(a: f32, b: f32, tol: f32) -> bool {
    (a.is_nan() && b.is_nan()) || a == b || (a - b).abs() <= tol * a.abs().max(b.abs()).max(1.0)
}

/// A direction in the upper hemisphere from two uniform numbers (`z` from `zmin` up).
fn upper(u: f32, v: f32, zmin: f32) -> Vec3 {
    let z = zmin + (1.0 - zmin) * u;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let p = std::f32::consts::TAU * v;
    Vec3::new(r * p.cos(), r * p.sin(), z)
}

/// `brdf_sample`, `brdf_eval` and `brdf_pdf` against `Material::sample_local` / `eval_local` /
/// `pdf_local` for every lobe (a near-mirror GGX, a mixed diffuse + glossy, a back-facing view
/// and directions below the surface among them): the same sample taken or refused, the same
/// direction, value and density. A GPU that took the lobe by the wrong `u` re-stretch, or an
/// `eval` without the diffuse part, fails here at once.
fn brdf_functions_match(functions: &Functions) {
    let materials = [
        Material {
            kd: Vec3::splat(0.8),
            ks: Vec3::ZERO,
            lobe: Lobe::None,
        },
        Material {
            kd: Vec3::splat(0.3),
            ks: Vec3::splat(0.5),
            lobe: Lobe::Phong { exponent: 20.0 },
        },
        Material {
            kd: Vec3::ZERO,
            ks: Vec3::ONE,
            lobe: Lobe::Ggx { alpha: 0.3 },
        },
        Material {
            kd: Vec3::splat(0.2),
            ks: Vec3::splat(0.04),
            lobe: Lobe::GgxSchlick { alpha: 0.05 },
        },
        Material {
            kd: Vec3::ZERO,
            ks: Vec3::new(0.9, 0.6, 0.3),
            lobe: Lobe::Ggx { alpha: 0.02 },
        },
    ];
    let mut rng = envis::sampling::rng::Rng::new(7, 0);
    let mut cases = Vec::new();
    for m in &materials {
        for k in 0..24 {
            let mut r = || rng.next_f32();
            let ol = match k {
                0 => Vec3::new(0.6, 0.0, -0.8), // back-facing view: no sample
                1 => upper(0.0, r(), 0.02),     // grazing
                _ => upper(r(), r(), 0.0),
            };
            let il = if k == 2 {
                Vec3::new(0.0, 0.6, -0.8)
            } else {
                upper(r(), r(), 0.0)
            };
            cases.push((*m, ol.normalize(), il.normalize(), Vec2::new(r(), r())));
        }
    }
    let input: Vec<[f32; 4]> = (cases.iter())
        .flat_map(|(m, ol, il, u)| {
            let code = f32::from_bits(m.lobe.gpu_code());
            [
                m.kd.extend(code),
                m.ks.extend(envis_wgpu::codes::lobe_param(m.lobe)),
                ol.extend(u.x),
                il.extend(u.y),
            ]
            .map(|v| v.to_array())
        })
        .collect();
    let out = run_entry(
        functions,
        "test_brdf",
        &input,
        (cases.len(), 2),
        Bound::default(),
    );
    for (i, (m, ol, il, u)) in cases.iter().enumerate() {
        let [gs, ge] = [Vec4::from(out[2 * i]), Vec4::from(out[2 * i + 1])];
        let what = format!("case {i}: {m:?} ol {ol} il {il} u {u}");
        match m.sample_local(*ol, *u) {
            None => assert!(gs.w == 0.0, "{what}: the GPU sampled {gs}, the CPU refused"),
            Some((cil, cpdf)) => {
                assert!(
                    gs.w > 0.0,
                    "{what}: the GPU refused the CPU's {cil} (pdf {cpdf})"
                );
                assert!(
                    (gs.truncate() - cil).length() < 1e-4,
                    "{what}: sample {gs} vs {cil}"
                );
                // The density of a near-mirror lobe moves fast with the direction.
                assert!(
                    near(gs.w, cpdf, 2e-3),
                    "{what}: sample pdf {} vs {cpdf}",
                    gs.w
                );
            }
        }
        let (f, p) = (m.eval_local(*ol, *il), m.pdf_local(*ol, *il));
        assert!(
            (ge.truncate() - f).abs().max_element() <= 1e-4 * f.max_element().max(1.0),
            "{what}: eval {ge} vs {f}"
        );
        assert!(near(ge.w, p, 1e-4), "{what}: pdf {} vs {p}", ge.w);
    }
}

/// `mis_weight_over_density` against `mis::weight_over_density`: both heuristics, equal and far
/// apart densities, one side 0.
fn mis_matches(functions: &Functions) {
    use envis::sampling::mis::{Heuristic, weight_over_density};
    let pairs = [
        (1.0, 0.0),
        (0.0, 2.0),
        (3.0, 5.0),
        (1e-30, 1e30),
        (1e20, 1e20),
        (0.25, 4096.0),
    ];
    let cases: Vec<(Heuristic, f32, f32)> = [Heuristic::Balance, Heuristic::Power]
        .into_iter()
        .flat_map(|h| pairs.map(|(a, b)| (h, a, b)))
        .collect();
    let input: Vec<[f32; 4]> = (cases.iter())
        .map(|&(h, a, b)| [f32::from_bits(h.gpu_code()), a, b, 0.0])
        .collect();
    let out = run_entry(
        functions,
        "test_mis",
        &input,
        (cases.len(), 1),
        Bound::default(),
    );
    for (&(h, a, b), o) in cases.iter().zip(&out) {
        let cpu = weight_over_density(h, a, b);
        assert!(
            near(o[0], cpu, 1e-5),
            "{h:?} ({a}, {b}): GPU {} CPU {cpu}",
            o[0]
        );
    }
}

/// `face_count` against `counts::face_count` exactly: both count modes, pool sizes 1, 8 and 32,
/// counts at and between integers, at and past the pool's size, negative and non-finite.
fn face_count_matches(functions: &Functions) {
    use envis::sampling::{Counts, face_count};
    let n_f = [
        0.0,
        -1.0,
        0.3,
        1.0,
        2.5,
        3.5,
        7.99,
        8.0,
        100.0,
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
    ];
    let mut cases = Vec::new();
    for counts in [Counts::Fractional, Counts::Integer] {
        for m in [1u32, 8, 32] {
            cases.extend(n_f.map(|n| (n, m, counts)));
        }
    }
    let input: Vec<[f32; 4]> = (cases.iter())
        .map(|&(n, m, c)| [n, f32::from_bits(m), f32::from_bits(c.gpu_code()), 0.0])
        .collect();
    let out = run_entry(
        functions,
        "test_face_count",
        &input,
        (cases.len(), 1),
        Bound::default(),
    );
    for (&(n, m, counts), o) in cases.iter().zip(&out) {
        let c = face_count(n, m as usize, counts);
        let gpu = (o[0].to_bits() as usize, o[1], o[2]);
        assert_eq!(
            gpu,
            (c.taken, c.last_weight, c.density),
            "N_f {n}, M {m}, {counts:?}"
        );
    }
}

/// `draw_tile` (with `face_mass`) against `tiles::draw_tile` over `TileWeights::masses`, K = 2,
/// with and without the corner cosines, on energies with zeros (a face with none left: no tile).
fn draw_tile_matches(functions: &Functions) {
    let grid = TileGrid::new(8, 2);
    let energy: Vec<f64> = (0..grid.regions())
        .map(|r| {
            if r % 5 == 1 || r / 4 == 3 {
                0.0
            } else {
                0.5 + r as f64
            }
        })
        .collect();
    let weights = TileWeights::new(grid, &energy);
    let regions: Vec<[f32; 4]> = (0..grid.regions())
        .flat_map(|r| {
            let (c, e) = (grid.corners(r), energy[r] as f32);
            (0..4).map(move |j| c[j].extend(if j == 0 { e } else { 0.0 }).to_array())
        })
        .collect();
    let s = Settings {
        tiles: 2,
        ..Settings::default()
    };
    let sp = ShadeParams::new(&s, grid.size, 4, 1);
    let mut rng = envis::sampling::rng::Rng::new(11, 0);
    let mut cases = Vec::new();
    for use_cosine in [false, true] {
        for k in 0..36 {
            let n = upper(rng.next_f32(), rng.next_f32(), -1.0);
            let u = [0.0, 1.0 - f32::EPSILON / 2.0]
                .get(k / 6)
                .copied()
                .unwrap_or(rng.next_f32());
            cases.push((n, k % 6, u, use_cosine));
        }
    }
    let input: Vec<[f32; 4]> = (cases.iter())
        .flat_map(|&(n, f, u, c)| {
            [
                n.extend(f32::from_bits(f as u32)).to_array(),
                [u, f32::from_bits(c as u32), 0.0, 0.0],
            ]
        })
        .collect();
    let bound = Bound {
        sp: Some(sp),
        regions: Some(&regions),
    };
    let out = run_entry(functions, "test_draw_tile", &input, (cases.len(), 1), bound);
    let mut mass = vec![0.0f32; grid.regions()];
    for (&(n, f, u, use_cosine), o) in cases.iter().zip(&out) {
        weights.masses(n, use_cosine, &mut mass);
        let face = &mass[f * 4..][..4];
        let fm: f32 = face.iter().sum();
        let cpu = draw_tile(face, fm, u).unwrap_or(4) as u32;
        let what = format!("n {n}, face {f}, u {u}, cosine {use_cosine}");
        assert!(near(o[1], fm, 1e-5), "{what}: face mass {} vs {fm}", o[1]);
        assert_eq!(o[0].to_bits(), cpu, "{what}: masses {face:?}");
    }
}

/// `pool_window` against the estimator's `pool_window` for every layout (blocks: 4 of 8 slots),
/// and the pixel's random stream after it: the same window from the same draws.
fn pool_window_matches(functions: &Functions) {
    use envis::render::estimator::pool_window;
    for layout in [PoolLayout::Shared, PoolLayout::Offset, PoolLayout::Blocks] {
        let s = Settings {
            pool_layout: layout,
            pool_blocks: 4,
            ..Settings::default()
        };
        let pool = envis::sampling::LightPool {
            per_region: 32,
            block: if layout == PoolLayout::Blocks { 8 } else { 32 },
            samples: Vec::new(),
        };
        let sp = ShadeParams::new(&s, 8, pool.per_region, 1);
        let cases: Vec<[u32; 4]> = (0..40).map(|p| [s.seed ^ (p * 7919), p, 32, 0]).collect();
        let input: Vec<[f32; 4]> = cases.iter().map(|c| c.map(f32::from_bits)).collect();
        let bound = Bound {
            sp: Some(sp),
            ..Bound::default()
        };
        let out = run_entry(
            functions,
            "test_pool_window",
            &input,
            (cases.len(), 1),
            bound,
        );
        for (c, o) in cases.iter().zip(&out) {
            let mut rng = envis::sampling::rng::Rng::new(c[0], c[1]);
            let w = pool_window(&mut rng, &s, &pool);
            let cpu = [w.base as u32, w.len as u32, w.start as u32, rng.next_u32()];
            assert_eq!(
                o.map(f32::to_bits),
                cpu,
                "{layout:?}, seed {}, pixel {}",
                c[0],
                c[1]
            );
        }
    }
}

/// Each function of the shading stage against its CPU twin (one test: one device, one module).
#[test]
fn gpu_shading_functions_match_cpu_twins() {
    let Some(ctx) = gpu() else { return };
    let functions = Functions::new(ctx);
    brdf_functions_match(&functions);
    mis_matches(&functions);
    face_count_matches(&functions);
    draw_tile_matches(&functions);
    pool_window_matches(&functions);
}
