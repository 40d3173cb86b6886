// envis — per-frame distribution build and light-sample pool (twin of src/sampling/distribution.rs
// and src/sampling/pool.rs). Five dispatches, in this order, all on data that stays on the GPU:
//   texel_weights   one thread per texel: sanitise (count problems), w = Y * Omega
//   column_cdfs     one workgroup per (face, column, band): CDF(v|u) of the band by a prefix sum
//   marginal_cdfs   one workgroup per region (face, or tile): CDF(u) over its column totals, its
//                   energy I_t and its four corner directions
//   pdf_table       one thread per texel: pdf per unit face area, P(texel | region) (N/2)^2
//   build_pool      one thread per pool sample: stratified point -> texel -> direction, radiance, pdf
// With K x K tiles per face (src/sampling/tiles.rs) a region is a tile and each column has K
// bands, one per tile row; K = 1 is the paper's, a region per face and one band.
// Sums are hierarchical (a serial run of ceil(N/256) texels per thread, then a 256-wide scan), so the
// rounding error grows like log N, not N: a lone bright texel among 2048^2 keeps its probability.

struct Params {
    // Face size N.
    n: u32,
    // Pool slots per region M.
    m: u32,
    // Pool seed (already hashed: the CPU twin's hash(seed ^ 0xA511E9B3)).
    seed: u32,
    // Independent stratified blocks of M / blocks samples per region (1: the paper's pool).
    blocks: u32,
    // Tiles per face side K.
    tiles: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// Per texel (r, g, b, pdf_area): radiance in, sanitised radiance and the pdf table out.
@group(0) @binding(0) var<storage, read_write> texels: array<vec4<f32>>;
// Per texel of one face (n x n, shared by the six faces): exact texel solid angle.
@group(0) @binding(1) var<storage, read> solid_angle: array<f32>;
// Per texel: w = Y * Omega.
@group(0) @binding(2) var<storage, read_write> weights: array<f32>;
// All CDFs: first per (face, column) the CDFs of its K bands (n + K values: each band's rows + 1,
// from 0 to 1), then from marg_base(n) per region the CDF of its columns (n + 1 values reserved).
@group(0) @binding(3) var<storage, read_write> cdfs: array<f32>;
// Totals: per region a record of 16 floats, its four corner directions (xyz) with its energy I_t in
// the first corner's w; then from totals_columns() per (face, band, column) the column's total in
// the band, at totals_columns() + (f K + band) n + c. (One buffer for both keeps the layout within
// 8 storage buffers per stage, WebGPU's default.)
@group(0) @binding(4) var<storage, read_write> totals: array<f32>;
// Pool: per sample two vec4: (dir, pdf), (radiance, 0). Region-major: slot i of region r at r M + i.
@group(0) @binding(5) var<storage, read_write> pool: array<vec4<f32>>;
// Sanitise counters: NaN, Inf, negative, huge.
@group(0) @binding(6) var<storage, read_write> problems: array<atomic<u32>, 4>;
@group(0) @binding(7) var<uniform> params: Params;

fn marg_base(n: u32) -> u32 {
    return 6u * n * (n + params.tiles);
}

fn totals_columns() -> u32 {
    return 16u * 6u * params.tiles * params.tiles;
}

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
    let k = params.tiles;
    let id = wg.x + wg.y * nwg.x; // (f * n + c) * K + band
    if (id >= 6u * n * k) {
        return;
    }
    let col_id = id / k;
    let band = id % k;
    let f = col_id / n;
    let c = col_id % n;
    let r0 = tile_bound(band, n, k);
    let rows = tile_bound(band + 1u, n, k) - r0;
    let run = serial_run(t, rows);
    var s = 0.0;
    for (var r = run.x; r < run.y; r++) {
        s += weights[(f * n + r0 + r) * n + c];
    }
    var acc = scan_partials(t, s);
    let total = partial[WG - 1u];
    let base = col_id * (n + k) + r0 + band;
    if (t == 0u) {
        cdfs[base] = 0.0;
        totals[totals_columns() + (f * k + band) * n + c] = total;
    }
    for (var r = run.x; r < run.y; r++) {
        acc += weights[(f * n + r0 + r) * n + c];
        var v = select(f32(r + 1u) / f32(rows), acc / total, total > 0.0);
        if (r + 1u == rows) {
            v = 1.0;
        }
        cdfs[base + r + 1u] = v;
    }
}

@compute @workgroup_size(256)
fn marginal_cdfs(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let n = params.n;
    let k = params.tiles;
    let region = wg.x;
    let span = region_span(region, n, k);
    let f = region / (k * k);
    let band = (region % (k * k)) / k;
    let cols = span.y - span.x;
    let col_totals = totals_columns() + (f * k + band) * n + span.x;
    let run = serial_run(t, cols);
    var s = 0.0;
    for (var c = run.x; c < run.y; c++) {
        s += totals[col_totals + c];
    }
    var acc = scan_partials(t, s);
    let total = partial[WG - 1u];
    let base = marg_base(n) + region * (n + 1u);
    if (t == 0u) {
        cdfs[base] = 0.0;
        // The region's record: its corners (sampling::tiles::TileGrid::corners), its energy.
        let h = 2.0 / f32(n);
        for (var j = 0u; j < 4u; j++) {
            let a = -1.0 + f32(select(span.x, span.y, (j & 1u) != 0u)) * h;
            let b = -1.0 + f32(select(span.z, span.w, (j & 2u) != 0u)) * h;
            let d = normalize(face_ab_to_vec(f, a, b));
            totals[16u * region + 4u * j] = d.x;
            totals[16u * region + 4u * j + 1u] = d.y;
            totals[16u * region + 4u * j + 2u] = d.z;
        }
        totals[16u * region + 3u] = total;
    }
    for (var c = run.x; c < run.y; c++) {
        acc += totals[col_totals + c];
        var v = select(f32(c + 1u) / f32(cols), acc / total, total > 0.0);
        if (c + 1u == cols) {
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
    let n = params.n;
    let rest = i % nn;
    let e = totals[16u * tile_region(i / nn, rest % n, rest / n, n, params.tiles) + 3u];
    let scale = select(0.0, f32(nn) * 0.25 / e, e > 0.0);
    texels[i].w = weights[i] * scale;
}

// sampling::pool::pool_point: Latin hypercube with hash permutations, (p + xi) / M kept below 1.
fn pool_point(seed: u32, region: u32, i: u32, m: u32) -> vec2<f32> {
    let pu = permute(i, m, hash3(seed, region, 0x5eed0001u));
    let pv = permute(i, m, hash3(seed, region, 0x5eed0002u));
    let ju = to_unit(hash4(seed, region, i, 1u));
    let jv = to_unit(hash4(seed, region, i, 2u));
    let u = min((f32(pu) + ju) / f32(m), ONE_MINUS_EPSILON);
    let v = min((f32(pv) + jv) / f32(m), ONE_MINUS_EPSILON);
    return vec2(u, v);
}

@compute @workgroup_size(64)
fn build_pool(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let kk = linear_id(gid, nwg, 64u);
    let m = params.m;
    let n = params.n;
    let k = params.tiles;
    if (kk >= 6u * k * k * m) {
        return;
    }
    let region = kk / m;
    let i = kk % m;
    if (totals[16u * region + 3u] <= 0.0) {
        pool[2u * kk] = vec4(0.0);
        pool[2u * kk + 1u] = vec4(0.0);
        return;
    }
    let f = region / (k * k);
    let band = (region % (k * k)) / k;
    let span = region_span(region, n, k);
    // sampling::pool::block_point: a Latin-hypercube point of the slot's own block.
    let w = m / max(params.blocks, 1u);
    let block = i / w;
    let block_seed = select(hash3(params.seed, block, 0xb10cu), params.seed, block == 0u);
    let p = pool_point(block_seed, region, i % w, w);
    let cs = sample_cdf(marg_base(n) + region * (n + 1u), span.y - span.x, p.x);
    let col = span.x + cs.i;
    let rs = sample_cdf((f * n + col) * (n + k) + span.z + band, span.w - span.z, p.y);
    let row = span.z + rs.i;
    let h = 2.0 / f32(n);
    let a = -1.0 + (f32(col) + cs.du) * h;
    let b = -1.0 + (f32(row) + rs.du) * h;
    let texel = texels[(f * n + row) * n + col];
    let q = 1.0 + a * a + b * b;
    let pdf = texel.w * q * sqrt(q);
    pool[2u * kk] = vec4(normalize(face_ab_to_vec(f, a, b)), pdf);
    pool[2u * kk + 1u] = vec4(texel.xyz, 0.0);
}
