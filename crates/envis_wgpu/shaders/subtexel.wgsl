// envis — sub-texel sampling (twin of src/sampling/subtexel.rs): each light-pool sample moved from
// its coarse texel to one of the r x r texels of the map at its own resolution that the coarse
// texel covers, in proportion to their luminance, by its offsets inside the coarse texel (which
// are uniform there). One thread per pool slot, after distribution.wgsl's build_pool.

struct RefineParams {
    // Face size N of the distribution.
    n: u32,
    // Face size of the map at its own resolution, r N.
    fine_n: u32,
    // Pool slots in all.
    count: u32,
    _pad: u32,
}

// The pool (distribution.wgsl's): per sample (dir, pdf), (radiance, 0).
@group(0) @binding(0) var<storage, read_write> pool: array<vec4<f32>>;
// The texel table: (r, g, b, pdf_area) per coarse texel.
@group(0) @binding(1) var<storage, read> texels: array<vec4<f32>>;
// The map at its own resolution: (r, g, b, factor) per fine texel (SubTexels::factors).
@group(0) @binding(2) var<storage, read> fine: array<vec4<f32>>;
@group(0) @binding(3) var<uniform> params: RefineParams;

// A bin and the offset in it.
struct Bin {
    k: u32,
    f: f32,
}

// subtexel::texel_offset: the texel of face coordinate a on faces of n texels, the offset in it.
fn texel_offset(a: f32, n: u32) -> Bin {
    let x = clamp((a + 1.0) * 0.5 * f32(n), 0.0, f32(n) - 1e-3);
    let c = u32(x);
    return Bin(c, clamp(x - f32(c), 0.0, ONE_MINUS_EPSILON));
}

// SubTexels::y_in: luminance of fine texel (x, y) of face, negatives as 0.
fn fine_y(face: u32, x: u32, y: u32) -> f32 {
    let n = params.fine_n;
    return max(luminance(fine[(face * n + y) * n + x].xyz), 0.0);
}

// Bin k's weight in the block from fine texel (x0, y0): over columns, the sum down column k
// (SubTexels::column_sum); else row k of column j.
fn bin_weight(face: u32, x0: u32, y0: u32, r: u32, columns: bool, j: u32, k: u32) -> f32 {
    if (!columns) {
        return fine_y(face, x0 + j, y0 + k);
    }
    var s = 0.0;
    for (var i = 0u; i < r; i++) {
        s += fine_y(face, x0 + k, y0 + i);
    }
    return s;
}

// subtexel::pick: one of r bins for u in [0, 1) (uniform when they sum to 0), u remapped in it.
fn pick(face: u32, x0: u32, y0: u32, r: u32, columns: bool, j: u32, u: f32) -> Bin {
    var total = 0.0;
    for (var k = 0u; k < r; k++) {
        total += bin_weight(face, x0, y0, r, columns, j, k);
    }
    if (total <= 0.0) {
        let x = u * f32(r);
        let k = min(u32(x), r - 1u);
        return Bin(k, clamp(x - f32(k), 0.0, ONE_MINUS_EPSILON));
    }
    let goal = u * total;
    var acc = 0.0;
    var last = 0u;
    for (var k = 0u; k < r; k++) {
        let wk = bin_weight(face, x0, y0, r, columns, j, k);
        if (wk <= 0.0) {
            continue;
        }
        if (goal < acc + wk) {
            return Bin(k, clamp((goal - acc) / wk, 0.0, ONE_MINUS_EPSILON));
        }
        acc += wk;
        last = k;
    }
    return Bin(last, ONE_MINUS_EPSILON);
}

// SubTexels::refine, one pool slot: its coarse texel and offsets from its direction, a fine
// texel by luminance, the density pdf_area * factor * Jacobian. An empty slot stays empty.
@compute @workgroup_size(64)
fn refine_pool(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let s = linear_id(gid, nwg, 64u);
    if (s >= params.count || pool[2u * s].w <= 0.0) {
        return;
    }
    let n = params.n;
    let fine_n = params.fine_n;
    let r = fine_n / n;
    let hit = dir_to_texel(pool[2u * s].xyz, n);
    let cu = texel_offset(hit.a, n);
    let cv = texel_offset(hit.b, n);
    let x0 = cu.k * r;
    let y0 = cv.k * r;
    let j = pick(hit.face, x0, y0, r, true, 0u, cu.f);
    let i = pick(hit.face, x0, y0, r, false, j.k, cv.f);
    let h = 2.0 / f32(fine_n);
    let a = -1.0 + (f32(x0 + j.k) + j.f) * h;
    let b = -1.0 + (f32(y0 + i.k) + i.f) * h;
    let q = 1.0 + a * a + b * b;
    let ft = fine[(hit.face * fine_n + y0 + i.k) * fine_n + x0 + j.k];
    let pdf_area = texels[(hit.face * n + cv.k) * n + cu.k].w;
    pool[2u * s] = vec4(normalize(face_ab_to_vec(hit.face, a, b)), pdf_area * ft.w * (q * sqrt(q)));
    pool[2u * s + 1u] = vec4(ft.xyz, 0.0);
}
