// envis — the `global` baseline's per-frame build on the GPU (twin of sampling::global): one
// piecewise-constant distribution over the whole sphere in lat-long (Mitsuba 3 convention) at
// 4N x 2N cells for N x N cube faces. Needs common.wgsl, scan.wgsl, cdf.wgsl and global_layout.wgsl.
// Dispatch order: global_cells, global_row_sums, global_floor, global_row_cdfs, global_marginal,
// global_pdf_table.

@group(0) @binding(0) var<storage, read> texels: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read_write> cdfs: array<f32>;
@group(0) @binding(2) var<uniform> gparams: vec4<u32>; // x: N

fn cos_band(y: u32, h: u32) -> f32 {
    let t0 = PI * f32(y) / f32(h);
    let t1 = PI * f32(y + 1u) / f32(h);
    return cos(t0) - cos(t1);
}

// Cell weight: mean luminance of 4x4 sub-points (nearest cube texel) x the cell's solid angle / dphi.
@compute @workgroup_size(256)
fn global_cells(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let g = glayout(gparams.x);
    let i = (wg.x + wg.y * nwg.x) * WG + t;
    if (i >= g.w * g.h) {
        return;
    }
    let x = i % g.w;
    let y = i / g.w;
    var acc = 0.0;
    for (var sy = 0u; sy < 4u; sy++) {
        for (var sx = 0u; sx < 4u; sx++) {
            let u = (f32(x) + (f32(sx) + 0.5) / 4.0) / f32(g.w);
            let v = (f32(y) + (f32(sy) + 0.5) / 4.0) / f32(g.h);
            let hit = dir_to_texel(latlong_to_dir(u, v), gparams.x);
            acc += luminance(texels[(hit.face * gparams.x + hit.row) * gparams.x + hit.col].xyz);
        }
    }
    cdfs[g.pdf + i] = acc / 16.0 * cos_band(y, g.h);
}

// Per row: the sum of its raw cells.
@compute @workgroup_size(256)
fn global_row_sums(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let g = glayout(gparams.x);
    let y = wg.x;
    let run = serial_run(t, g.w);
    var s = 0.0;
    for (var x = run.x; x < run.y; x++) {
        s += cdfs[g.pdf + y * g.w + x];
    }
    let _prefix = scan_partials(t, s);
    if (t == 0u) {
        cdfs[g.rowtot + y] = partial[WG - 1u];
    }
}

// The defensive floor: 1% of the mean cell weight (1 for an all-black map).
@compute @workgroup_size(256)
fn global_floor(@builtin(local_invocation_index) t: u32) {
    let g = glayout(gparams.x);
    let run = serial_run(t, g.h);
    var s = 0.0;
    for (var y = run.x; y < run.y; y++) {
        s += cdfs[g.rowtot + y];
    }
    let _prefix = scan_partials(t, s);
    if (t == 0u) {
        let mean = partial[WG - 1u] / f32(g.w * g.h);
        cdfs[g.misc] = select(1.0, 0.01 * mean, mean > 0.0);
    }
}

// Per row: add the floor (per unit solid angle), then the row's CDF over u.
@compute @workgroup_size(256)
fn global_row_cdfs(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let g = glayout(gparams.x);
    let y = wg.x;
    let add = cdfs[g.misc] * cos_band(y, g.h) * f32(g.h) / 2.0;
    let run = serial_run(t, g.w);
    var s = 0.0;
    for (var x = run.x; x < run.y; x++) {
        let c = cdfs[g.pdf + y * g.w + x] + add;
        cdfs[g.pdf + y * g.w + x] = c;
        s += c;
    }
    var acc = scan_partials(t, s);
    let total = partial[WG - 1u];
    let base = g.rows + y * (g.w + 1u);
    if (t == 0u) {
        cdfs[base] = 0.0;
        cdfs[g.rowtot + y] = total;
    }
    for (var x = run.x; x < run.y; x++) {
        acc += cdfs[g.pdf + y * g.w + x];
        var v = select(f32(x + 1u) / f32(g.w), acc / total, total > 0.0);
        if (x + 1u == g.w) {
            v = 1.0;
        }
        cdfs[base + x + 1u] = v;
    }
}

// The marginal CDF over rows (v) and the total.
@compute @workgroup_size(256)
fn global_marginal(@builtin(local_invocation_index) t: u32) {
    let g = glayout(gparams.x);
    let run = serial_run(t, g.h);
    var s = 0.0;
    for (var y = run.x; y < run.y; y++) {
        s += cdfs[g.rowtot + y];
    }
    var acc = scan_partials(t, s);
    let total = partial[WG - 1u];
    if (t == 0u) {
        cdfs[g.marg] = 0.0;
        cdfs[g.misc + 1u] = total;
    }
    for (var y = run.x; y < run.y; y++) {
        acc += cdfs[g.rowtot + y];
        var v = select(f32(y + 1u) / f32(g.h), acc / total, total > 0.0);
        if (y + 1u == g.h) {
            v = 1.0;
        }
        cdfs[g.marg + y + 1u] = v;
    }
}

// Cell weights -> p(u, v) = cell / total x w h (the pdf per unit (u, v) area).
@compute @workgroup_size(256)
fn global_pdf_table(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let g = glayout(gparams.x);
    let i = (wg.x + wg.y * nwg.x) * WG + t;
    if (i >= g.w * g.h) {
        return;
    }
    let total = cdfs[g.misc + 1u];
    cdfs[g.pdf + i] = select(0.0, cdfs[g.pdf + i] / total * f32(g.w * g.h), total > 0.0);
}
