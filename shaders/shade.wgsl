// envis — per-pixel face-weighted MIS shading (twin of render::shade_pixel). Needs common.wgsl and
// sampling.wgsl before it, and a module that declares the resources `shade` reads (the frame's
// texel table `texels`, the light `pool`, `face_energy`, and the uniform `sp`) and
// `env_radiance(d, coarse)`, the radiance in direction d given the texel table's value there
// (render::FrameData::radiance), and `sample_blocked(px, pixel_index, d)`, whether a shadow ray
// from the pixel's surface point is blocked (render::estimator's `Pixel::blocked`):
// shade_compute.wgsl (headless backend, tests: the table's value; shadow rays through a BVH) or
// lighting.wgsl (the Bevy lighting pass: the full-resolution image; no shadow rays yet). All of them are
// written by distribution.wgsl on the GPU; nothing is read back to the CPU.

struct ShadeParams {
    // Face size N and pool slots per face (M x pool_blocks).
    n: u32,
    m: u32,
    // Light and BRDF samples this strategy draws (already remapped as render::shade_pixel does).
    nl: u32,
    nb: u32,
    // 0 paper (cosine face weights), 1 light (energy only), 2 brdf only.
    strategy: u32,
    counts: u32,
    mis: u32,
    seed: u32,
    // render::PoolLayout: 0 shared, 1 offset, 2 blocks (pool_blocks of them).
    pool_layout: u32,
    pixel_count: u32,
    // 1: each pixel's material chooses the split of nl + nb (render::budget_for).
    material_budget: u32,
    // Nodes of the shadow-ray BVH (visibility.wgsl); 0: no shadow rays.
    bvh_nodes: u32,
    pool_blocks: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

const POOL_OFFSET: u32 = 1u;
const POOL_BLOCKS: u32 = 2u;

// render::estimator::PoolWindow: slots base .. base + len of each face, in order from base + start.
struct PoolWindow {
    base: u32,
    len: u32,
    start: u32,
}

// render::estimator::pool_window: the pixel's first random number picks its start (offset) or its
// block, read from its first slot (blocks); the seed's shared pool draws none.
fn pool_window(rng: ptr<function, Rng>, m: u32) -> PoolWindow {
    var w = PoolWindow(0u, m, 0u);
    if (m == 0u) {
        return w;
    }
    if (sp.pool_layout == POOL_OFFSET) {
        w.start = rng_next_u32(rng) % m;
    } else if (sp.pool_layout == POOL_BLOCKS) {
        w.len = m / sp.pool_blocks;
        w.base = (rng_next_u32(rng) % sp.pool_blocks) * w.len;
    }
    return w;
}

// render::budget_for: diffuse -> all light samples; near-mirror with no diffuse part -> all BRDF.
fn budget_for(mat: Material, nl: u32, nb: u32) -> vec2<u32> {
    let near_mirror = (mat.lobe == LOBE_PHONG && mat.param >= NEAR_MIRROR_EXPONENT) || (is_ggx(mat.lobe) && mat.param <= NEAR_MIRROR_ALPHA);
    if (mat.lobe == LOBE_NONE || max(max(mat.ks.x, mat.ks.y), mat.ks.z) <= 0.0) {
        return vec2(nl + nb, 0u);
    }
    if (near_mirror && max(max(mat.kd.x, mat.kd.y), mat.kd.z) <= 0.0) {
        return vec2(0u, nl + nb);
    }
    return vec2(nl, nb);
}
// render::NEAR_MIRROR_EXPONENT and render::NEAR_MIRROR_ALPHA (the material budget's near-mirror
// lobes; a test checks the values match).
const NEAR_MIRROR_EXPONENT: f32 = 1000.0;
const NEAR_MIRROR_ALPHA: f32 = 0.02;
const STRATEGY_PAPER: u32 = 0u;
const STRATEGY_LIGHT: u32 = 1u;
const STRATEGY_BRDF: u32 = 2u;
// One lat-long distribution for the whole sphere (global_layout.wgsl), N_L samples per pixel.
const STRATEGY_GLOBAL: u32 = 3u;

// One G-buffer texel: normal (w = 1 where there is geometry), view direction, kd (w = lobe kind),
// ks (w = Phong exponent or GGX alpha).
struct GPixel {
    n: vec4<f32>,
    o: vec4<f32>,
    kd: vec4<f32>,
    ks: vec4<f32>,
}

struct Shaded {
    color: vec3<f32>,
    stats: vec4<u32>,
}

// Light samples above the horizon that a shadow ray found blocked, in this invocation
// (render::PixelStats::blocked; the compute entry point reports it).
var<private> light_blocked: u32;

fn shade(px: GPixel, pixel_index: u32) -> Shaded {
    return shade_counts(px, pixel_index, sp.counts);
}

// `shade` with the counts mode given (the debug overlay compares fractional and integer).
fn shade_counts(px: GPixel, pixel_index: u32, counts: u32) -> Shaded {
    var res = Shaded(vec3(0.0), vec4(0u));
    let mat = Material(px.kd.xyz, px.ks.xyz, u32(px.kd.w), px.ks.w);
    let n = normalize_or_zero(px.n.xyz);
    let o = normalize_or_zero(px.o.xyz);
    if (all(n == vec3(0.0)) || all(o == vec3(0.0)) || dot(n, o) <= 0.0 || is_black(mat)) {
        return res;
    }
    let fr = frame_new(n);
    let ol = to_local(fr, o);
    var rng = rng_new(sp.seed, pixel_index);
    var sum = vec3(0.0);
    var nl = sp.nl;
    var nb = sp.nb;
    if (sp.material_budget != 0u && sp.strategy == STRATEGY_PAPER) {
        let b = budget_for(mat, nl, nb);
        nl = b.x;
        nb = b.y;
    }
    let nb_f = f32(nb);
    let size = sp.n;
    let m = sp.m;
    var density: array<f32, 6>;

    // Section `global_samples` of render/estimator.rs.
    if (sp.strategy == STRATEGY_GLOBAL) {
        res.stats.x = nl;
        for (var j = 0u; j < nl; j++) {
            let u1 = rng_next_f32(&rng);
            let u2 = rng_next_f32(&rng);
            let gs = global_sample(size, vec2(u1, u2));
            if (gs.w <= 0.0) {
                continue;
            }
            let cosv = dot(n, gs.xyz);
            if (cosv <= 0.0) {
                res.stats.z += 1u;
                continue;
            }
            if (sample_blocked(px, pixel_index, gs.xyz)) {
                light_blocked += 1u;
                continue;
            }
            res.stats.y += 1u;
            let il = to_local(fr, gs.xyz);
            var n_b = 0.0;
            if (nb > 0u) {
                n_b = nb_f * brdf_pdf(mat, ol, il);
            }
            let hit = dir_to_texel(gs.xyz, size);
            let radiance = env_radiance(gs.xyz, texels[(hit.face * size + hit.row) * size + hit.col].xyz);
            sum += brdf_eval(mat, ol, il) * radiance * (cosv * mis_weight_over_density(sp.mis, f32(nl) * gs.w, n_b));
        }
    } else if (sp.strategy != STRATEGY_BRDF) {
        // Section `light_pool_samples` of render/estimator.rs.
        let w = pool_window(&rng, m);
        res.stats.x = 6u * w.len;
        var energy: array<f32, 6>;
        for (var f = 0u; f < 6u; f++) {
            energy[f] = face_energy[f];
        }
        let mu = face_weights(n, energy, sp.strategy == STRATEGY_PAPER);
        for (var f = 0u; f < 6u; f++) {
            let c = face_count(mu[f] * f32(nl), w.len, counts);
            density[f] = c.density;
            var idx = w.start;
            for (var k = 0u; k < c.taken; k++) {
                let s = f * m + w.base + idx;
                idx += 1u;
                if (idx == w.len) {
                    idx = 0u;
                }
                let dp = pool[2u * s];
                if (dp.w <= 0.0) {
                    continue;
                }
                let cosv = dot(n, dp.xyz);
                if (cosv <= 0.0) {
                    res.stats.z += 1u;
                    continue;
                }
                if (sample_blocked(px, pixel_index, dp.xyz)) {
                    light_blocked += 1u;
                    continue;
                }
                res.stats.y += 1u;
                let weight = select(1.0, c.last_weight, k + 1u == c.taken);
                let il = to_local(fr, dp.xyz);
                let n_l = c.density * dp.w;
                var n_b = 0.0;
                if (nb > 0u) {
                    n_b = nb_f * brdf_pdf(mat, ol, il);
                }
                sum += brdf_eval(mat, ol, il) * env_radiance(dp.xyz, pool[2u * s + 1u].xyz) * (weight * cosv * mis_weight_over_density(sp.mis, n_l, n_b));
            }
        }
    }

    // Section `brdf_samples` of render/estimator.rs (one sample at a time: the GPU's lanes are
    // its pixels).
    for (var j = 0u; j < nb; j++) {
        res.stats.w += 1u;
        let u1 = rng_next_f32(&rng);
        let u2 = rng_next_f32(&rng);
        let bs = brdf_sample(mat, ol, vec2(u1, u2));
        if (bs.w <= 0.0) {
            continue;
        }
        let il = bs.xyz;
        let d = to_world(fr, il);
        if (sample_blocked(px, pixel_index, d)) {
            continue;
        }
        let hit = dir_to_texel(d, size);
        let t = texels[(hit.face * size + hit.row) * size + hit.col];
        let q = 1.0 + hit.a * hit.a + hit.b * hit.b;
        var n_l = 0.0;
        if (sp.strategy == STRATEGY_PAPER) {
            n_l = density[hit.face] * t.w * (q * sqrt(q));
        } else if (sp.strategy == STRATEGY_GLOBAL) {
            n_l = f32(nl) * global_pdf(size, d);
        }
        sum += brdf_eval(mat, ol, il) * env_radiance(d, t.xyz) * (il.z * mis_weight_over_density(sp.mis, nb_f * bs.w, n_l));
    }
    res.color = sum;
    return res;
}
