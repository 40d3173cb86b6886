// envis — compute entry point of the shading stage over a G-buffer buffer (headless backend and
// the CPU-twin tests). Needs common.wgsl, sampling.wgsl and shade.wgsl before it.

@group(0) @binding(0) var<storage, read> texels: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read> pool: array<vec4<f32>>;
// Per region (face, or tile) four vec4: its corners (xyz), its energy in the first one's w.
@group(0) @binding(2) var<storage, read> regions: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> gbuf: array<GPixel>;
// Per pixel: (r, g, b, 1 where shaded).
@group(0) @binding(4) var<storage, read_write> out_color: array<vec4<f32>>;
// Per pixel: (available, green, yellow, brdf) sample counts (the paper's red / green / yellow).
@group(0) @binding(5) var<storage, read_write> out_stats: array<vec4<u32>>;
@group(0) @binding(6) var<uniform> sp: ShadeParams;
// The `global` distribution (global_layout.wgsl); a dummy unless the strategy is global.
@group(0) @binding(7) var<storage, read> cdfs: array<f32>;
// Shadow rays (visibility.wgsl): the BVH, and each pixel's surface point (xyz); bound to
// placeholders when sp.bvh_nodes is 0.
@group(0) @binding(8) var<storage, read> bvh_nodes: array<BvhNode>;
@group(0) @binding(9) var<storage, read> bvh_triangles: array<array<vec4<f32>, 3>>;
@group(0) @binding(10) var<storage, read> points: array<vec4<f32>>;
// Per pixel: (shadow rays cast, light samples blocked) (render::PixelStats).
@group(0) @binding(11) var<storage, read_write> out_rays: array<vec2<u32>>;
// The map at its own resolution, one (r, g, b, sub-texel factor) per texel of sp.fine_n^2 faces;
// a placeholder when sp.fine_n is 0.
@group(0) @binding(12) var<storage, read> fine: array<vec4<f32>>;

var<private> shadow_rays: u32;

@compute @workgroup_size(64)
fn shade_gbuffer(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = linear_id(gid, nwg, 64u);
    if (i >= sp.pixel_count) {
        return;
    }
    let px = gbuf[i];
    if (px.n.w == 0.0) {
        out_color[i] = vec4(0.0);
        out_stats[i] = vec4(0u);
        out_rays[i] = vec2(0u);
        return;
    }
    let r = shade(px, i);
    out_color[i] = vec4(r.color, 1.0);
    out_stats[i] = r.stats;
    out_rays[i] = vec2(shadow_rays, light_blocked);
}

// A shadow ray through the BVH (the CPU's FlatBvh as render::FrameData::occluder): t_min 1e-4,
// unbounded.
fn sample_blocked(px: GPixel, pixel_index: u32, d: vec3<f32>) -> bool {
    if (sp.bvh_nodes == 0u) {
        return false;
    }
    shadow_rays += 1u;
    let o = shadow_origin(points[pixel_index].xyz, normalize_or_zero(px.n.xyz), d);
    return bvh_occluded(o, d, 1e-4, 3.4028235e38, sp.bvh_nodes, ALL_LAYERS);
}

// Radiance from the map at its own resolution (the texel d falls in), or from the texel table
// itself when there is none (CPU twin: render::FrameData::radiance).
fn env_radiance(d: vec3<f32>, coarse: vec3<f32>) -> vec3<f32> {
    if (sp.fine_n == 0u) {
        return coarse;
    }
    let n = sp.fine_n;
    let hit = dir_to_texel(d, n);
    return fine[(hit.face * n + hit.row) * n + hit.col].xyz;
}

// The radiance (xyz) and the factor the coarse texel's density takes (w) in the fine texel d
// falls in, from one lookup (sub-texel sampling, subtexel.wgsl: the factor is kept in the fine
// table's w and is 1 where the pool was not refined); without a fine table, `coarse` and 1
// (CPU twin: SubTexels::radiance_and_factor).
fn env_radiance_factor(d: vec3<f32>, coarse: vec3<f32>) -> vec4<f32> {
    if (sp.fine_n == 0u) {
        return vec4(coarse, 1.0);
    }
    let n = sp.fine_n;
    let hit = dir_to_texel(d, n);
    return fine[(hit.face * n + hit.row) * n + hit.col];
}

// Where a used sample goes (render::estimator's Sink for Vec3): summed into the pixel's colour.
fn emit(res: ptr<function, Shaded>, dir: vec3<f32>, fl: vec3<f32>, cos: f32, scale: f32) {
    (*res).color += fl * scale;
}
