// envis — per-frame distribution build and light-sample pool (twin of src/sampling/distribution.rs
// and src/sampling/pool.rs). Five dispatches, in this order, all on data that stays on the GPU:
//   texel_weights   one thread per texel: sanitise (count problems), w = Y * Omega
//   column_cdfs     one workgroup per (face, column): CDF(v|u) by a workgroup prefix sum
//   marginal_cdfs   one workgroup per face: CDF(u) over the column totals, face energy I_f
//   pdf_table       one thread per texel: pdf per unit face area, P(texel) (N/2)^2
//   build_pool      one thread per pool sample: stratified point -> texel -> direction, radiance, pdf
// Sums are hierarchical (a serial run of ceil(N/256) texels per thread, then a 256-wide scan), so the
// rounding error grows like log N, not N: a lone bright texel among 2048^2 keeps its probability.

struct Params {
    // Face size N.
    n: u32,
    // Pool samples per face M.
    m: u32,
    // Pool seed (already hashed: the CPU twin's hash(seed ^ 0xA511E9B3)).
    seed: u32,
    // Independent stratified blocks of M / blocks samples per face (1: the seed's pool).
    blocks: u32,
}

// Per texel (r, g, b, pdf_area): radiance in, sanitised radiance and the pdf table out.
@group(0) @binding(0) var<storage, read_write> texels: array<vec4<f32>>;
// Per texel of one face (n x n, shared by the six faces): exact texel solid angle.
@group(0) @binding(1) var<storage, read> solid_angle: array<f32>;
// Per texel: w = Y * Omega.
@group(0) @binding(2) var<storage, read_write> weights: array<f32>;
// All CDFs, each n + 1 values with cdf[0] = 0, cdf[n] = 1: first per (face, column) the CDF of
// rows (conditional), then from marg_base(n) per face the CDF of columns (marginal).
@group(0) @binding(3) var<storage, read_write> cdfs: array<f32>;
// Totals: [0, 8) face energies I_f (6 used), then per (face, column) the column total at 8 + f n + c.
// (One buffer for both keeps the layout within 8 storage buffers per stage, WebGPU's default.)
@group(0) @binding(4) var<storage, read_write> totals: array<f32>;
// Pool: per sample two vec4: (dir, pdf), (radiance, 0). Face-major: sample i of face f at f M + i.
@group(0) @binding(5) var<storage, read_write> pool: array<vec4<f32>>;
// Sanitise counters: NaN, Inf, negative, huge.
@group(0) @binding(6) var<storage, read_write> problems: array<atomic<u32>, 4>;
@group(0) @binding(7) var<uniform> params: Params;

fn marg_base(n: u32) -> u32 {
    return 6u * n * (n + 1u);
}

const TOTALS_COLUMNS: u32 = 8u;

@compute @workgroup_size(256)
fn texel_weights(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let i = (wg.x + wg.y * nwg.x) * WG + t;
    let nn = params.n * params.n;
    if (i >= 6u * nn) {
        return;
    }
    let raw = texels[i].xyz;
    let problem = texel_problem(raw);
    var c = raw;
    if (problem != 0u) {
        atomicAdd(&problems[problem - 1u], 1u);
        c = vec3(sanitize_channel(raw.x), sanitize_channel(raw.y), sanitize_channel(raw.z));
        texels[i] = vec4(c, 0.0);
    }
    weights[i] = max(luminance(c), 0.0) * solid_angle[i % nn];
}

@compute @workgroup_size(256)
fn column_cdfs(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let n = params.n;
    let col_id = wg.x + wg.y * nwg.x; // f * n + c
    if (col_id >= 6u * n) {
        return;
    }
    let f = col_id / n;
    let c = col_id % n;
    let run = serial_run(t, n);
    var s = 0.0;
    for (var r = run.x; r < run.y; r++) {
        s += weights[(f * n + r) * n + c];
    }
    var acc = scan_partials(t, s);
    let total = partial[WG - 1u];
    let base = col_id * (n + 1u);
    if (t == 0u) {
        cdfs[base] = 0.0;
        totals[TOTALS_COLUMNS + col_id] = total;
    }
    for (var r = run.x; r < run.y; r++) {
        acc += weights[(f * n + r) * n + c];
        var v = select(f32(r + 1u) / f32(n), acc / total, total > 0.0);
        if (r + 1u == n) {
            v = 1.0;
        }
        cdfs[base + r + 1u] = v;
    }
}

@compute @workgroup_size(256)
fn marginal_cdfs(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let n = params.n;
    let f = wg.x;
    let run = serial_run(t, n);
    var s = 0.0;
    for (var c = run.x; c < run.y; c++) {
        s += totals[TOTALS_COLUMNS + f * n + c];
    }
    var acc = scan_partials(t, s);
    let total = partial[WG - 1u];
    let base = marg_base(n) + f * (n + 1u);
    if (t == 0u) {
        cdfs[base] = 0.0;
        totals[f] = total;
    }
    for (var c = run.x; c < run.y; c++) {
        acc += totals[TOTALS_COLUMNS + f * n + c];
        var v = select(f32(c + 1u) / f32(n), acc / total, total > 0.0);
        if (c + 1u == n) {
            v = 1.0;
        }
        cdfs[base + c + 1u] = v;
    }
}

@compute @workgroup_size(256)
fn pdf_table(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let i = (wg.x + wg.y * nwg.x) * WG + t;
    let nn = params.n * params.n;
    if (i >= 6u * nn) {
        return;
    }
    let e = totals[i / nn];
    let scale = select(0.0, f32(nn) * 0.25 / e, e > 0.0);
    texels[i].w = weights[i] * scale;
}

// sampling::pool::pool_point: Latin hypercube with hash permutations, (p + xi) / M kept below 1.
fn pool_point(seed: u32, face: u32, i: u32, m: u32) -> vec2<f32> {
    let pu = permute(i, m, hash3(seed, face, 0x5eed0001u));
    let pv = permute(i, m, hash3(seed, face, 0x5eed0002u));
    let ju = to_unit(hash4(seed, face, i, 1u));
    let jv = to_unit(hash4(seed, face, i, 2u));
    let u = min((f32(pu) + ju) / f32(m), ONE_MINUS_EPSILON);
    let v = min((f32(pv) + jv) / f32(m), ONE_MINUS_EPSILON);
    return vec2(u, v);
}

@compute @workgroup_size(64)
fn build_pool(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let k = linear_id(gid, nwg, 64u);
    let m = params.m;
    let n = params.n;
    if (k >= 6u * m) {
        return;
    }
    let f = k / m;
    let i = k % m;
    if (totals[f] <= 0.0) {
        pool[2u * k] = vec4(0.0);
        pool[2u * k + 1u] = vec4(0.0);
        return;
    }
    // sampling::pool::block_point: a Latin-hypercube point of the slot's own block.
    let w = m / max(params.blocks, 1u);
    let block = i / w;
    let block_seed = select(hash3(params.seed, block, 0xb10cu), params.seed, block == 0u);
    let p = pool_point(block_seed, f, i % w, w);
    let cs = sample_cdf(marg_base(n) + f * (n + 1u), n, p.x);
    let rs = sample_cdf((f * n + cs.i) * (n + 1u), n, p.y);
    let h = 2.0 / f32(n);
    let a = -1.0 + (f32(cs.i) + cs.du) * h;
    let b = -1.0 + (f32(rs.i) + rs.du) * h;
    let texel = texels[(f * n + rs.i) * n + cs.i];
    let q = 1.0 + a * a + b * b;
    let pdf = texel.w * q * sqrt(q);
    pool[2u * k] = vec4(normalize(face_ab_to_vec(f, a, b)), pdf);
    pool[2u * k + 1u] = vec4(texel.xyz, 0.0);
}
