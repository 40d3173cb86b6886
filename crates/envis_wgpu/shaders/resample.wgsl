// envis — an `Image` texture -> the sampler's cube texel table (twin of
// envmap::resample::cube_from_fetch with the image_source.wgsl lookups): each n x n face texel is
// the solid-angle-weighted mean of s x s bilinear sub-points. Writes radiance only; the
// distribution build (distribution.wgsl) then sanitises, counts and weights the texels. Needs
// common.wgsl and image_source.wgsl before it.

struct ResampleParams {
    // Cube face size of the texel table, sub-points per axis, SOURCE_LATLONG / SOURCE_CUBE.
    n: u32,
    s: u32,
    kind: u32,
    _pad: u32,
}

@group(0) @binding(0) var source: texture_2d_array<f32>;
@group(0) @binding(1) var<storage, read_write> texels: array<vec4<f32>>;
@group(0) @binding(2) var<uniform> rp: ResampleParams;

@compute @workgroup_size(64)
fn resample(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = linear_id(gid, nwg, 64u);
    let n = rp.n;
    if (i >= 6u * n * n) {
        return;
    }
    let face = i / (n * n);
    let row = (i / n) % n;
    let col = i % n;
    let h = 2.0 / f32(n);
    let s = f32(rp.s);
    var sum = vec3(0.0);
    var wsum = 0.0;
    for (var sy = 0u; sy < rp.s; sy++) {
        for (var sx = 0u; sx < rp.s; sx++) {
            let a = -1.0 + (f32(col) + (f32(sx) + 0.5) / s) * h;
            let b = -1.0 + (f32(row) + (f32(sy) + 0.5) / s) * h;
            let q = 1.0 + a * a + b * b;
            let w = 1.0 / (q * sqrt(q));
            sum += w * source_radiance(source, rp.kind, normalize(face_ab_to_vec(face, a, b)));
            wsum += w;
        }
    }
    texels[i] = vec4(sum / wsum, 0.0);
}
