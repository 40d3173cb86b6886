// envis — reservoir resampling of a frame (render::resampling::resample_frame), one entry point
// per pass, each over every pixel: `candidates` and `shade_reservoirs` here, `history_targets`
// (bound with the previous frame's shadow geometry), `temporal` and `spatial` in reuse.wgsl,
// which reads this file's bindings and helpers. Needs common.wgsl, sampling.wgsl, cdf.wgsl,
// global_layout.wgsl, shade.wgsl, visibility.wgsl, reservoir.wgsl and bright.wgsl before it. A pixel's two reservoirs (render::resampling::Part: the rest, then the
// bright part) sit side by side: reservoir 2 i + part.

// The paper's sampler, built on the rest of the map (shade.wgsl reads these).
@group(0) @binding(0) var<storage, read> texels: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read> pool: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> regions: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> cdfs: array<f32>;
@group(0) @binding(4) var<uniform> sp: ShadeParams;
@group(0) @binding(5) var<uniform> rp: ResampleParams;
// This frame's and the previous frame's surfaces, and their maps split (per cube texel: the rest's
// radiance, then the bright part's with its probability in w).
@group(0) @binding(6) var<storage, read> surfaces: array<Surface>;
@group(0) @binding(7) var<storage, read> prev_surfaces: array<Surface>;
@group(0) @binding(8) var<storage, read> split_tex: array<vec4<f32>>;
@group(0) @binding(9) var<storage, read> prev_split_tex: array<vec4<f32>>;
@group(0) @binding(10) var<storage, read> bright_cdf: array<f32>;
@group(0) @binding(11) var<storage, read> bright_ids: array<u32>;
// Shadow geometry: this frame's, except in `history_targets` (the previous frame's).
@group(0) @binding(12) var<storage, read> bvh_nodes: array<BvhNode>;
@group(0) @binding(13) var<storage, read> bvh_triangles: array<array<vec4<f32>, 3>>;
// The pass's input reservoirs, the previous frame's (the history), and its output.
@group(0) @binding(14) var<storage, read> res_in: array<Reservoir>;
@group(0) @binding(15) var<storage, read> res_hist: array<Reservoir>;
@group(0) @binding(16) var<storage, read_write> res_out: array<Reservoir>;
// Per pixel: the previous pixel (x, u32 max: none) and the distance from the previous camera
// its point had then (y, bits of an f32).
@group(0) @binding(17) var<storage, read> reproject: array<vec2<u32>>;
// Per reservoir: the canonical sample's target with visibility at the history pixel, in the
// previous frame (written by history_targets, read by temporal).
@group(0) @binding(18) var<storage, read_write> hist_targets: array<f32>;
// Per pixel: (shadow rays so far, history accepted, neighbours accepted, bright history
// accepted).
@group(0) @binding(19) var<storage, read_write> counters: array<vec4<u32>>;
// Per pixel: the estimate (r, g, b, 1 where shaded), and the candidates' (available, green,
// yellow, brdf) sample counts.
@group(0) @binding(20) var<storage, read_write> out_color: array<vec4<f32>>;
@group(0) @binding(21) var<storage, read_write> out_stats: array<vec4<u32>>;

// envis_wgpu::resampling::ResampleParams.
struct ResampleParams {
    width: u32,
    height: u32,
    // Face size of split_tex and prev_split_tex.
    n: u32,
    prev_n: u32,
    // Texels of this frame's bright part (0: none; its reservoirs then stay empty and unused).
    bright_count: u32,
    // 1 where there is a previous frame, and where its bright part is this one's (same_light).
    history: u32,
    bright_history: u32,
    temporal: u32,
    spatial: u32,
    max_history: f32,
    unbiased: u32,
    seed: u32,
    bvh_nodes: u32,
    prev_bvh_nodes: u32,
    // The shadow casters the camera sees (visibility::Layers; ALL_LAYERS headless).
    layers: u32,
    // How far this frame's map and the history's agree as light (agreement::map_agreement,
    // computed on the CPU): the rest's history confidence is scaled by it.
    map_agreement: f32,
    // 1 where nothing that casts shadows moved since the previous frame (History::still_geometry).
    still_geometry: u32,
    // Surfaces' normals and view directions, and samples' directions, are in the map's frame
    // (the Bevy pass rotates them there, as its lighting pass does); points and the shadow BVH
    // are in the world's. Identity headless.
    world_from_map: mat3x3<f32>,
}

// A pixel as reuse sees it: the G-buffer texel (n.w = 1 where shaded), its surface point (xyz)
// and distance from the camera (w), its object (id.x).
struct Surface {
    px: GPixel,
    p: vec4<f32>,
    id: vec4<u32>,
}

// render::resampling's tuning constants (SPATIAL_RADIUS, NORMAL_COS, AGREEMENT_SCALE, ...) are
// generated from Rust: envis_wgpu::shaders::resampling_constants.
const TAU: f32 = 6.28318530717959;

// The candidates' sink (resample's CandidateSink); emit (shade.wgsl) streams into it.
var<private> cand: Sink;

fn emit(res: ptr<function, Shaded>, dir: vec3<f32>, fl: vec3<f32>, cos: f32, scale: f32) {
    cand = sink_add(cand, dir, fl, cos, scale);
}

// The candidates cast no shadow rays (the selected one does, below).
fn sample_blocked(px: GPixel, pixel_index: u32, d: vec3<f32>) -> bool {
    return false;
}

// Radiance from the texel table (the rest of the map, at the sampler's resolution).
fn env_radiance(d: vec3<f32>, coarse: vec3<f32>) -> vec3<f32> {
    return coarse;
}
fn env_radiance_factor(d: vec3<f32>, coarse: vec3<f32>) -> vec4<f32> {
    return vec4(coarse, 1.0);
}

// combine::DomainSurface::visible through the bound BVH of `nodes` nodes: whether d is unblocked
// from the surface (true, and no ray, without geometry).
fn visible_through(px: GPixel, point: vec3<f32>, d: vec3<f32>, nodes: u32, rays: ptr<function, u32>) -> bool {
    if (nodes == 0u) {
        return true;
    }
    *rays += 1u;
    let dw = rp.world_from_map * d;
    let o = shadow_origin(point, rp.world_from_map * normalize_or_zero(px.n.xyz), dw);
    return !bvh_occluded(o, dw, 1e-4, 3.4028235e38, nodes, rp.layers);
}

// This frame's visibility (bright.wgsl's and the passes' shadow ray).
fn visible_from(px: GPixel, point: vec3<f32>, d: vec3<f32>, rays: ptr<function, u32>) -> bool {
    return visible_through(px, point, d, rp.bvh_nodes, rays);
}

// The radiance of a split map's part in direction d (Split::radiance).
fn split_radiance(prev: bool, part: u32, d: vec3<f32>) -> vec3<f32> {
    let n = select(rp.n, rp.prev_n, prev);
    let t = dir_to_texel(d, n);
    let k = 2u * ((t.face * n + t.row) * n + t.col) + part;
    if (prev) {
        return prev_split_tex[k].xyz;
    }
    return split_tex[k].xyz;
}

// resampling::target_rgb: the unshadowed integrand f L cos at a pixel, L the part's radiance.
fn target_rgb(px: GPixel, prev: bool, part: u32, d: vec3<f32>) -> vec3<f32> {
    let mat = Material(px.kd.xyz, px.ks.xyz, u32(px.kd.w), px.ks.w);
    let n = normalize_or_zero(px.n.xyz);
    let o = normalize_or_zero(px.o.xyz);
    if (all(n == vec3(0.0)) || all(o == vec3(0.0)) || dot(n, o) <= 0.0 || is_black(mat)) {
        return vec3(0.0);
    }
    let cosv = dot(n, d);
    if (cosv <= 0.0) {
        return vec3(0.0);
    }
    let fr = frame_new(n);
    return brdf_eval(mat, to_local(fr, o), to_local(fr, d)) * split_radiance(prev, part, d) * cosv;
}

// resampling::similar: the same object, normals within NORMAL_COS, depths within DEPTH_REL.
fn similar(n_a: vec3<f32>, depth_a: f32, id_a: u32, b: Surface) -> bool {
    return id_a == b.id.x
        && dot(normalize_or_zero(n_a), normalize_or_zero(b.px.n.xyz)) >= NORMAL_COS
        && abs(depth_a - b.p.w) <= DEPTH_REL * max(depth_a, b.p.w);
}

// Whether a part's reservoirs are resampled at all (the bright part only where there is one).
fn part_live(part: u32) -> bool {
    return part == 0u || rp.bright_count > 0u;
}

// passes::temporal's history pixel for pixel i and part: the reprojected pixel where it passes
// the geometric tests (and, for the unbiased mode's bright part, same_point), -1 otherwise.
fn history_pixel(i: u32, part: u32) -> i32 {
    if (rp.history == 0u || rp.temporal == 0u || (part == 1u && rp.bright_history == 0u)) {
        return -1;
    }
    let r = reproject[i];
    if (r.x == 0xffffffffu) {
        return -1;
    }
    let h = prev_surfaces[r.x];
    let s = surfaces[i];
    if (h.px.n.w == 0.0 || !similar(s.px.n.xyz, bitcast<f32>(r.y), s.id.x, h)) {
        return -1;
    }
    // The unbiased mode's bright history only where the point has not moved (same_point).
    if (part == 1u && rp.unbiased != 0u && !same_point(s, h)) {
        return -1;
    }
    return i32(r.x);
}

// resampling::same_point: b's point is a's, within BRIGHT_SAME_POINT of a's camera distance.
fn same_point(a: Surface, b: Surface) -> bool {
    return distance(a.p.xyz, b.p.xyz) <= BRIGHT_SAME_POINT * a.p.w;
}

// passes::temporal: pixel i and its history pixel q see the same directions (the same point,
// nothing moved), so the unbiased combination's rays between them are known without casting.
fn sees_as_history(i: u32, q: u32) -> bool {
    return rp.unbiased != 0u && rp.still_geometry != 0u && same_point(surfaces[i], prev_surfaces[q]);
}

// passes::penumbra_before: whether the previous frame's bright candidates found a penumbra at
// pixel i's place (no geometric test) or at a pixel beside it.
fn penumbra_before(i: u32) -> bool {
    if (rp.history == 0u || rp.temporal == 0u) {
        return false;
    }
    let q = reproject[i].x;
    if (q == 0xffffffffu) {
        return false;
    }
    let x = i32(q % rp.width);
    let y = i32(q / rp.width);
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let a = x + dx;
            let b = y + dy;
            if (a >= 0 && b >= 0 && a < i32(rp.width) && b < i32(rp.height)
                && res_hist[2u * u32(b * i32(rp.width) + a) + 1u].penumbra != 0u) {
                return true;
            }
        }
    }
    return false;
}

// A pass's per-pixel random stream (resample_frame's `stream(pass, i)`).
fn pass_rng(stage: u32, i: u32) -> Rng {
    return rng_new(hash3(rp.seed, stage, 0x5e57u), i);
}

fn pixel_id(gid: vec3<u32>, nwg: vec3<u32>) -> u32 {
    return linear_id(gid, nwg, 64u);
}

// Pass 1 (passes::candidates): the rest's reservoir from the paper's samples, the bright part's
// (bright_reservoir), each selected sample shadow-tested.
@compute @workgroup_size(64)
fn candidates(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = pixel_id(gid, nwg);
    if (i >= rp.width * rp.height) {
        return;
    }
    let s = surfaces[i];
    if (s.px.n.w == 0.0) {
        res_out[2u * i] = reservoir_empty(0.0);
        res_out[2u * i + 1u] = reservoir_empty(0.0);
        counters[i] = vec4(0u);
        out_stats[i] = vec4(0u);
        return;
    }
    var rng = pass_rng(1u, i);
    var bright_rng = rng_new(rng_next_u32(&rng), i);
    cand = sink_new(rng);
    let shaded = shade(s.px, i);
    var q = sink_finish(cand);
    var rays = 0u;
    if (q.ucw > 0.0) {
        q.visible = u32(visible_from(s.px, s.p.xyz, q.dir, &rays));
        if (q.visible == 0u) {
            q.ucw = 0.0;
        }
    }
    res_out[2u * i] = q;
    res_out[2u * i + 1u] = bright_reservoir(s.px, s.p.xyz, penumbra_before(i), &bright_rng, &rays);
    counters[i] = vec4(rays, 0u, 0u, 0u);
    out_stats[i] = shaded.stats;
}

// Pass 4 (resampling's shade): per pixel f(Y) V(Y) W summed over the parts, a final sample
// shadow-tested where its visibility is not known yet (the biased mode).
@compute @workgroup_size(64)
fn shade_reservoirs(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = pixel_id(gid, nwg);
    if (i >= rp.width * rp.height) {
        return;
    }
    let s = surfaces[i];
    var sum = vec3(0.0);
    var rays = 0u;
    for (var part = 0u; part < 2u; part++) {
        var q = res_in[2u * i + part];
        if (s.px.n.w != 0.0 && q.ucw > 0.0 && q.visible == 0u) {
            q.visible = u32(visible_from(s.px, s.p.xyz, q.dir, &rays));
            if (q.visible == 0u) {
                q.ucw = 0.0;
            }
        }
        if (q.ucw > 0.0) {
            sum += q.rgb * q.ucw;
        }
        res_out[2u * i + part] = q;
    }
    counters[i].x += rays;
    // w: the rest's confidence (its history length; 0 where nothing is shaded), for the mean
    // history and the Bevy pass's history overlay.
    out_color[i] = vec4(sum, select(0.0, res_in[2u * i].m, s.px.n.w != 0.0));
}
