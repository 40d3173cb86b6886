// envis — layout of the `global` distribution buffer and its sampling (twin of
// sampling::global::GlobalDistribution::{sample, pdf}); needs common.wgsl, cdf.wgsl and a
// module-scope `cdfs: array<f32>` bound to the global distribution.
// For N x N cube faces: w = 4N columns (u), h = 2N rows (v).
//   [marg: h + 1][rows: h (w + 1)][pdf: w h][rowtot: h][misc: 4 (floor, total)]

struct GLayout {
    w: u32,
    h: u32,
    marg: u32,
    rows: u32,
    pdf: u32,
    rowtot: u32,
    misc: u32,
}
fn glayout(n: u32) -> GLayout {
    let w = 4u * n;
    let h = 2u * n;
    let rows = h + 1u;
    let pdf = rows + h * (w + 1u);
    let rowtot = pdf + w * h;
    return GLayout(w, h, 0u, rows, pdf, rowtot, rowtot + h);
}
// Floats in the buffer for N x N faces (keep in step with envis_wgpu::sampler::global_len).
fn glen(n: u32) -> u32 {
    return glayout(n).misc + 4u;
}

// envmap::latlong_to_dir: d = (sin t sin p, cos t, -sin t cos p), p = 2 pi u, t = pi v.
fn latlong_to_dir(u: f32, v: f32) -> vec3<f32> {
    let p = 2.0 * PI * u;
    let t = PI * v;
    return vec3(sin(t) * sin(p), cos(t), -sin(t) * cos(p));
}

// Solid-angle pdf of cell (x, y) at v: p(u, v) / (2 pi^2 sin t).
fn global_pdf_cell(g: GLayout, x: u32, y: u32, v: f32) -> f32 {
    let st = sin(PI * v);
    if (st <= 0.0) {
        return 0.0;
    }
    return cdfs[g.pdf + y * g.w + x] / (2.0 * PI * PI * st);
}

// GlobalDistribution::sample: (direction, pdf); pdf 0 = no sample.
fn global_sample(n: u32, u: vec2<f32>) -> vec4<f32> {
    let g = glayout(n);
    let ys = sample_cdf(g.marg, g.h, u.y);
    let xs = sample_cdf(g.rows + ys.i * (g.w + 1u), g.w, u.x);
    let uu = (f32(xs.i) + xs.du) / f32(g.w);
    let vv = (f32(ys.i) + ys.du) / f32(g.h);
    let p = global_pdf_cell(g, xs.i, ys.i, vv);
    if (p > 0.0 && is_finite_bits(p)) {
        return vec4(latlong_to_dir(uu, vv), p);
    }
    return vec4(0.0);
}

// GlobalDistribution::pdf of a unit direction.
fn global_pdf(n: u32, d: vec3<f32>) -> f32 {
    let g = glayout(n);
    let uv = dir_to_latlong(d);
    let x = min(u32(uv.x * f32(g.w)), g.w - 1u);
    let y = min(u32(uv.y * f32(g.h)), g.h - 1u);
    return global_pdf_cell(g, x, y, uv.y);
}
