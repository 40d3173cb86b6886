// envis — test-only compute entry points: one function of the shading stage at a time, on
// inputs the test writes, against its CPU twin (envis_wgpu/tests/gpu/functions.rs), as vello tests its
// stages. Needs the shading module before it (envis_wgpu::shaders::shade_functions_test_source): `sp`
// and `regions` are shade_compute.wgsl's bindings. Each entry reads case i from `test_in` and
// writes its results to `test_out`; one invocation per case.

@group(0) @binding(12) var<storage, read> test_in: array<vec4<f32>>;
@group(0) @binding(13) var<storage, read_write> test_out: array<vec4<f32>>;

// Per case in: (kd, lobe code), (ks, lobe parameter), (ol, u.x), (il, u.y); out: brdf_sample's
// (il, pdf) for u, then (brdf_eval(ol, il), brdf_pdf(ol, il)) for the given il.
@compute @workgroup_size(1)
fn test_brdf(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    let a = test_in[4u * i];
    let b = test_in[4u * i + 1u];
    let c = test_in[4u * i + 2u];
    let d = test_in[4u * i + 3u];
    let mat = Material(a.xyz, b.xyz, bitcast<u32>(a.w), b.w);
    test_out[2u * i] = brdf_sample(mat, c.xyz, vec2(c.w, d.w));
    test_out[2u * i + 1u] = vec4(brdf_eval(mat, c.xyz, d.xyz), brdf_pdf(mat, c.xyz, d.xyz));
}

// In: (heuristic code, na, nb, _); out: (mis_weight_over_density, 0, 0, 0).
@compute @workgroup_size(1)
fn test_mis(@builtin(global_invocation_id) gid: vec3<u32>) {
    let x = test_in[gid.x];
    test_out[gid.x] = vec4(mis_weight_over_density(bitcast<u32>(x.x), x.y, x.z), 0.0, 0.0, 0.0);
}

// In: (N_f, m, counts code, _); out: face_count's (taken, last_weight, density, 0).
@compute @workgroup_size(1)
fn test_face_count(@builtin(global_invocation_id) gid: vec3<u32>) {
    let x = test_in[gid.x];
    let c = face_count(x.x, bitcast<u32>(x.y), bitcast<u32>(x.z));
    test_out[gid.x] = vec4(bitcast<f32>(c.taken), c.last_weight, c.density, 0.0);
}

// In: (n, face), (u, use_cosine, _, _), over `regions` and sp.tiles; out: (draw_tile's tile,
// face_mass, 0, 0).
@compute @workgroup_size(1)
fn test_draw_tile(@builtin(global_invocation_id) gid: vec3<u32>) {
    let a = test_in[2u * gid.x];
    let b = test_in[2u * gid.x + 1u];
    let f = bitcast<u32>(a.w);
    let use_cosine = bitcast<u32>(b.y) != 0u;
    let fm = face_mass(a.xyz, f, use_cosine);
    let t = draw_tile(a.xyz, f, fm, b.x, use_cosine);
    test_out[gid.x] = vec4(bitcast<f32>(t), fm, 0.0, 0.0);
}

// In: (seed, pixel, m, _) as u32, with sp.pool_layout and sp.pool_blocks; out: pool_window's
// (base, len, start, the pixel's next random u32) from rng_new(seed, pixel).
@compute @workgroup_size(1)
fn test_pool_window(@builtin(global_invocation_id) gid: vec3<u32>) {
    let x = bitcast<vec4<u32>>(test_in[gid.x]);
    var rng = rng_new(x.x, x.y);
    let w = pool_window(&rng, x.z);
    test_out[gid.x] = bitcast<vec4<f32>>(vec4(w.base, w.len, w.start, rng_next_u32(&rng)));
}
