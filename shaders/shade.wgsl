// envis — per-pixel face-weighted MIS shading (twin of render::shade_pixel). Needs common.wgsl and
// sampling.wgsl before it, and a module that declares the resources `shade` reads (the frame's
// texel table `texels`, the light `pool`, the `regions`' corners and energies, and the uniform `sp`) and
// `env_radiance(d, coarse)`, the radiance in direction d given the texel table's value there
// (render::FrameData::radiance), and `sample_blocked(px, pixel_index, d)`, whether a shadow ray
// from the pixel's surface point is blocked (render::estimator's `Pixel::blocked`):
// shade_compute.wgsl (headless backend, tests: the table's value; shadow rays through a BVH) or
// lighting.wgsl (the Bevy lighting pass: the full-resolution image; shadow rays through the
// scene's BVH). All of them are written by distribution.wgsl on the GPU; nothing is read back to
// the CPU. The `u32` codes (STRATEGY_*, POOL_*, TILE_COUNTS_*, and sampling.wgsl's) are the
// `gpu_code()`s of src/gpu/codes.rs, which a test checks them against.

struct ShadeParams {
    // Face size N and pool slots per face (M x pool_blocks).
    n: u32,
    m: u32,
    // Light and BRDF samples this strategy draws (already remapped as render::shade_pixel does).
    nl: u32,
    nb: u32,
    // STRATEGY_*.
    strategy: u32,
    // COUNTS_* and MIS_* (sampling.wgsl).
    counts: u32,
    mis: u32,
    seed: u32,
    // POOL_* (render::PoolLayout; pool_blocks blocks for POOL_BLOCKS).
    pool_layout: u32,
    pixel_count: u32,
    // 1: each pixel's material chooses the split of nl + nb (render::budget_for).
    material_budget: u32,
    // Nodes of the shadow-ray BVH (visibility.wgsl); 0: no shadow rays.
    bvh_nodes: u32,
    pool_blocks: u32,
    // Tiles per face side K (sampling::tiles; 1: whole faces). Regions: 6 K^2.
    tiles: u32,
    // TILE_COUNTS_*: sampling::TileCounts (per face, each sample drawing its tile; or per tile).
    tile_counts: u32,
    _pad2: u32,
}

// sampling::TileWeights::masses for one region: C_t I_t (C_t = 1 without the cosine).
fn region_mass(n: vec3<f32>, r: u32, use_cosine: bool) -> f32 {
    let e = regions[4u * r].w;
    if (!use_cosine) {
        return e;
    }
    var c = 0.0;
    for (var j = 0u; j < 4u; j++) {
        let d = regions[4u * r + j].xyz;
        c += max(n.x * d.x + n.y * d.y + n.z * d.z, 0.0);
    }
    return c * e;
}

// The sum over regions of region_mass, in region order (the CPU's order).
fn total_mass(n: vec3<f32>, use_cosine: bool) -> f32 {
    var total = 0.0;
    for (var r = 0u; r < 6u * sp.tiles * sp.tiles; r++) {
        total += region_mass(n, r, use_cosine);
    }
    return total;
}

// The sum of region_mass over face f's tiles, in tile order.
fn face_mass(n: vec3<f32>, f: u32, use_cosine: bool) -> f32 {
    let k2 = sp.tiles * sp.tiles;
    var s = 0.0;
    for (var t = 0u; t < k2; t++) {
        s += region_mass(n, f * k2 + t, use_cosine);
    }
    return s;
}

// sampling::tiles::draw_tile over face f's tiles: the first tile of positive mass whose running
// sum exceeds u * fm, else the last tile of positive mass (k2 when none).
fn draw_tile(n: vec3<f32>, f: u32, fm: f32, u: f32, use_cosine: bool) -> u32 {
    let k2 = sp.tiles * sp.tiles;
    let x = u * fm;
    var acc = 0.0;
    var last = k2;
    for (var t = 0u; t < k2; t++) {
        let m = region_mass(n, f * k2 + t, use_cosine);
        if (m > 0.0) {
            acc += m;
            last = t;
            if (acc > x) {
                return t;
            }
        }
    }
    return last;
}

const TILE_COUNTS_TILE: u32 = 0u;
const TILE_COUNTS_FACE: u32 = 1u;

fn face_tile_counts() -> bool {
    return sp.tiles > 1u && sp.tile_counts == TILE_COUNTS_FACE;
}

// The light density N_t of region r (render::estimator: the `density` table the light loop
// writes): per tile, or with counts per face N_f C_t I_t / (sum over the face).
fn region_density(n: vec3<f32>, r: u32, total: f32, nl: u32, len: u32, counts: u32, use_cosine: bool) -> f32 {
    if (!face_tile_counts()) {
        return face_count(region_count(n, r, total, nl, use_cosine), len, counts).density;
    }
    let fm = face_mass(n, r / (sp.tiles * sp.tiles), use_cosine);
    if (fm <= 0.0) {
        return 0.0;
    }
    var mu = 0.0;
    if (total > 0.0) {
        mu = fm / total;
    }
    let c = face_count(mu * f32(nl), len, counts);
    return c.density * (region_mass(n, r, use_cosine) / fm);
}

// N_t of region r for a pixel with normal n (render::estimator's light_pool_samples), before
// face_count clamps it: mu_t N_L.
fn region_count(n: vec3<f32>, r: u32, total: f32, nl: u32, use_cosine: bool) -> f32 {
    var mu = 0.0;
    if (total > 0.0) {
        mu = region_mass(n, r, use_cosine) / total;
    }
    return mu * f32(nl);
}

const POOL_SHARED: u32 = 0u;
const POOL_OFFSET: u32 = 1u;
const POOL_BLOCKS: u32 = 2u;

// render::estimator::PoolWindow: slots base .. base + len of each face, in order from base + start.
struct PoolWindow {
    base: u32,
    len: u32,
    start: u32,
}

// render::estimator::pool_window: the pixel's first random number picks its start (offset) or its
// block, read from its first slot (blocks); the paper's shared pool draws none.
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
    // The light samples' per-region densities are recomputed where a BRDF sample needs one
    // (a table of 6 K^2 per pixel would not fit in registers).
    let use_cosine = sp.strategy == STRATEGY_PAPER;
    var total = 0.0;
    var window_len = 0u;
    // With whole faces (K = 1) the light loop keeps each face's density, as the paper's shader
    // did; with tiles a BRDF sample recomputes its tile's (region_density).
    var face_density: array<f32, 6>;

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
        let region_count_all = 6u * sp.tiles * sp.tiles;
        res.stats.x = region_count_all * w.len;
        window_len = w.len;
        // With whole faces the six masses are kept (each is four corner loads); with tiles they
        // are recomputed where needed (6 K^2 would not fit in registers).
        var mass6: array<f32, 6>;
        if (sp.tiles == 1u) {
            for (var f = 0u; f < 6u; f++) {
                mass6[f] = region_mass(n, f, use_cosine);
                total += mass6[f];
            }
        } else {
            total = total_mass(n, use_cosine);
        }
        // Per region (render::estimator's light_pool_samples), or per face with each sample
        // drawing its tile (face_tile_samples).
        let face_mode = face_tile_counts();
        let k2 = sp.tiles * sp.tiles;
        for (var f = 0u; f < select(region_count_all, 6u, face_mode); f++) {
            var fm = 0.0;
            var c: FaceCount;
            if (face_mode) {
                fm = face_mass(n, f, use_cosine);
                var mu = 0.0;
                if (total > 0.0) {
                    mu = fm / total;
                }
                c = face_count(mu * f32(nl), w.len, counts);
            } else {
                var mu = 0.0;
                if (total > 0.0) {
                    if (sp.tiles == 1u) {
                        mu = mass6[f] / total;
                    } else {
                        mu = region_mass(n, f, use_cosine) / total;
                    }
                }
                c = face_count(mu * f32(nl), w.len, counts);
            }
            if (sp.tiles == 1u) {
                face_density[f] = c.density;
            }
            var idx = w.start;
            for (var k = 0u; k < c.taken; k++) {
                var region = f;
                var density = c.density;
                if (face_mode) {
                    let t = draw_tile(n, f, fm, rng_next_f32(&rng), use_cosine);
                    if (t == k2) {
                        break;
                    }
                    region = f * k2 + t;
                    density = c.density * (region_mass(n, region, use_cosine) / fm);
                }
                let s = region * m + w.base + idx;
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
                let n_l = density * dp.w;
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
            var density = face_density[hit.face];
            if (sp.tiles > 1u) {
                let r = tile_region(hit.face, hit.col, hit.row, size, sp.tiles);
                density = region_density(n, r, total, nl, window_len, counts, use_cosine);
            }
            n_l = density * t.w * (q * sqrt(q));
        } else if (sp.strategy == STRATEGY_GLOBAL) {
            n_l = f32(nl) * global_pdf(size, d);
        }
        sum += brdf_eval(mat, ol, il) * env_radiance(d, t.xyz) * (il.z * mis_weight_over_density(sp.mis, nb_f * bs.w, n_l));
    }
    res.color = sum;
    return res;
}
