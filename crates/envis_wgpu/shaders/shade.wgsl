// envis — per-pixel face-weighted MIS shading (twin of render::shade_pixel). Needs common.wgsl and
// sampling.wgsl before it, and a module that declares the resources `shade` reads (the frame's
// texel table `texels`, the light `pool`, the `regions`' corners and energies, and the uniform `sp`) and
// `env_radiance(d, coarse)`, the radiance in direction d given the texel table's value there
// (render::FrameData::radiance), `env_radiance_factor(d, coarse)`, the same with the sub-texel
// factor of the light density in w (sampling::SubTexels::radiance_and_factor), and `sample_blocked(px, pixel_index, d)`, whether a shadow ray
// from the pixel's surface point is blocked (render::estimator's `Pixel::blocked`), and
// `emit(res, dir, fl, cos, scale)`, where each used sample goes (render::estimator's `Sink`: its
// contribution is fl x scale; the shading modules sum it into res.color, resampling.wgsl streams
// it into a reservoir):
// shade_compute.wgsl (headless backend, tests: the table's value; shadow rays through a BVH) or
// lighting.wgsl (the Bevy lighting pass: the full-resolution image; shadow rays through the
// scene's BVH). All of them are written by distribution.wgsl on the GPU; nothing is read back to
// the CPU. The `u32` codes (STRATEGY_*, POOL_*, TILE_COUNTS_*, and sampling.wgsl's) are the
// `GpuCode`s of envis_wgpu/src/codes.rs, which a test checks them against.

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
    // Face size of the radiance table at full resolution (shade_compute.wgsl's `fine`); 0: none,
    // radiance comes from the texel table (render::FrameData::fine is the CPU twin).
    fine_n: u32,
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

// What the sample loops of one visible pixel share (render::estimator's `Pixel`).
struct Pixel {
    px: GPixel,
    index: u32,
    mat: Material,
    n: vec3<f32>,
    fr: Frame,
    // The view direction in the shading frame.
    ol: vec3<f32>,
    // N_L and N_B for this pixel.
    nl: u32,
    nb: u32,
    // COUNTS_*.
    counts: u32,
    // The paper's strategy weights regions by their corner cosines too.
    use_cosine: bool,
}

// What the light samples leave for the BRDF samples' MIS weights: each face's density (whole
// faces; with tiles a BRDF sample recomputes its tile's, as a table of 6 K^2 per pixel would not
// fit in registers), the regions' total mass and the pool window's length.
struct LightDensities {
    face: array<f32, 6>,
    total: f32,
    window_len: u32,
}

// `shade` with the counts mode given (the debug overlay compares fractional and integer); twin
// of render::estimator's shade_with: the light samples (from the pool, or from the global
// distribution), then the BRDF samples, in the same order with the same random draws.
fn shade_counts(px: GPixel, pixel_index: u32, counts: u32) -> Shaded {
    var res = Shaded(vec3(0.0), vec4(0u));
    let mat = Material(px.kd.xyz, px.ks.xyz, u32(px.kd.w), px.ks.w);
    let n = normalize_or_zero(px.n.xyz);
    let o = normalize_or_zero(px.o.xyz);
    if (all(n == vec3(0.0)) || all(o == vec3(0.0)) || dot(n, o) <= 0.0 || is_black(mat)) {
        return res;
    }
    let fr = frame_new(n);
    var budget = vec2(sp.nl, sp.nb);
    if (sp.material_budget != 0u && sp.strategy == STRATEGY_PAPER) {
        budget = budget_for(mat, sp.nl, sp.nb);
    }
    let p = Pixel(px, pixel_index, mat, n, fr, to_local(fr, o), budget.x, budget.y, counts, sp.strategy == STRATEGY_PAPER);
    var rng = rng_new(sp.seed, pixel_index);
    var dens = LightDensities(array<f32, 6>(), 0.0, 0u);
    if (sp.strategy == STRATEGY_GLOBAL) {
        global_samples(p, &rng, &res);
    } else if (sp.strategy != STRATEGY_BRDF) {
        dens = light_pool_samples(p, &rng, &res);
    }
    brdf_samples(p, &rng, dens, &res);
    return res;
}

// A light sample in direction dir that passed the horizon and the shadow ray: its BRDF value and
// the scale of f x radiance (weight x cos x MIS weight over density).
struct LightHit {
    used: bool,
    f: vec3<f32>,
    cos: f32,
    scale: f32,
}

// render::estimator's Pixel::light_sample: a light sample in direction dir of weight `weight`
// and light density n_l, counted green or yellow (or blocked); the caller reads its radiance only
// when it is used.
fn light_sample(p: Pixel, dir: vec3<f32>, weight: f32, n_l: f32, res: ptr<function, Shaded>) -> LightHit {
    var hit = LightHit(false, vec3(0.0), 0.0, 0.0);
    let cosv = dot(p.n, dir);
    if (cosv <= 0.0) {
        (*res).stats.z += 1u;
        return hit;
    }
    if (sample_blocked(p.px, p.index, dir)) {
        light_blocked += 1u;
        return hit;
    }
    (*res).stats.y += 1u;
    let il = to_local(p.fr, dir);
    var n_b = 0.0;
    if (p.nb > 0u) {
        n_b = f32(p.nb) * brdf_pdf(p.mat, p.ol, il);
    }
    hit.used = true;
    hit.f = brdf_eval(p.mat, p.ol, il);
    hit.cos = cosv;
    hit.scale = weight * cosv * mis_weight_over_density(sp.mis, n_l, n_b);
    return hit;
}

// render::estimator's pool_sample: pool slot `slot` of region r as a light sample of weight
// `weight` from a region sampled with density `density` (N_t); an empty slot adds nothing.
fn pool_sample(p: Pixel, r: u32, slot: u32, weight: f32, density: f32, res: ptr<function, Shaded>) {
    let s = r * sp.m + slot;
    let dp = pool[2u * s];
    if (dp.w <= 0.0) {
        return;
    }
    let hit = light_sample(p, dp.xyz, weight, density * dp.w, res);
    if (hit.used) {
        emit(res, dp.xyz, hit.f * env_radiance(dp.xyz, pool[2u * s + 1u].xyz), hit.cos, hit.scale);
    }
}

// The slot after `idx` in the pool window, wrapping (render::estimator's PoolWindow::slots).
fn next_in_window(w: PoolWindow, idx: u32) -> u32 {
    return select(idx + 1u, 0u, idx + 1u == w.len);
}

// render::estimator's light_pool_samples: each region (face, or tile) weighted by mu_t,
// N_t = mu_t N_L, fractional or integer counts, taken from its part of the pool (from the pixel's
// window, wrapping): per region, or per face with each sample drawing its tile
// (face_tile_samples).
fn light_pool_samples(p: Pixel, rng: ptr<function, Rng>, res: ptr<function, Shaded>) -> LightDensities {
    let w = pool_window(rng, sp.m);
    let regions = 6u * sp.tiles * sp.tiles;
    (*res).stats.x = regions * w.len;
    var dens = LightDensities(array<f32, 6>(), 0.0, w.len);
    // With whole faces the six masses are kept (each is four corner loads); with tiles they are
    // recomputed where needed (6 K^2 would not fit in registers).
    var mass6: array<f32, 6>;
    if (sp.tiles == 1u) {
        for (var f = 0u; f < 6u; f++) {
            mass6[f] = region_mass(p.n, f, p.use_cosine);
            dens.total += mass6[f];
        }
    } else {
        dens.total = total_mass(p.n, p.use_cosine);
    }
    if (face_tile_counts()) {
        for (var f = 0u; f < 6u; f++) {
            face_tile_samples(p, rng, w, f, dens.total, res);
        }
        return dens;
    }
    for (var r = 0u; r < regions; r++) {
        var mu = 0.0;
        if (dens.total > 0.0) {
            if (sp.tiles == 1u) {
                mu = mass6[r] / dens.total;
            } else {
                mu = region_mass(p.n, r, p.use_cosine) / dens.total;
            }
        }
        let c = face_count(mu * f32(p.nl), w.len, p.counts);
        if (sp.tiles == 1u) {
            dens.face[r] = c.density;
        }
        var idx = w.start;
        for (var k = 0u; k < c.taken; k++) {
            let weight = select(1.0, c.last_weight, k + 1u == c.taken);
            pool_sample(p, r, w.base + idx, weight, c.density, res);
            idx = next_in_window(w, idx);
        }
    }
    return dens;
}

// render::estimator's face_tile_samples (TileCounts::Face) for face f: the face's count N_f,
// each sample's tile drawn with one random number (draw_tile), the tile's next slot in the
// window, its density N_f C_t I_t / (the face's mass).
fn face_tile_samples(p: Pixel, rng: ptr<function, Rng>, w: PoolWindow, f: u32, total: f32, res: ptr<function, Shaded>) {
    let k2 = sp.tiles * sp.tiles;
    let fm = face_mass(p.n, f, p.use_cosine);
    var mu = 0.0;
    if (total > 0.0) {
        mu = fm / total;
    }
    let c = face_count(mu * f32(p.nl), w.len, p.counts);
    var idx = w.start;
    for (var k = 0u; k < c.taken; k++) {
        let t = draw_tile(p.n, f, fm, rng_next_f32(rng), p.use_cosine);
        if (t == k2) {
            return;
        }
        let region = f * k2 + t;
        let density = c.density * (region_mass(p.n, region, p.use_cosine) / fm);
        let weight = select(1.0, c.last_weight, k + 1u == c.taken);
        pool_sample(p, region, w.base + idx, weight, density, res);
        idx = next_in_window(w, idx);
    }
}

// render::estimator's global_samples: the pbrt-style baseline's N_L draws from one lat-long
// distribution (global_layout.wgsl).
fn global_samples(p: Pixel, rng: ptr<function, Rng>, res: ptr<function, Shaded>) {
    (*res).stats.x = p.nl;
    for (var j = 0u; j < p.nl; j++) {
        let u1 = rng_next_f32(rng);
        let u2 = rng_next_f32(rng);
        let gs = global_sample(sp.n, vec2(u1, u2));
        if (gs.w <= 0.0) {
            continue;
        }
        // Weight 1: 1 x cos is cos exactly, so this is the plain one-sample estimate.
        let hit = light_sample(p, gs.xyz, 1.0, f32(p.nl) * gs.w, res);
        if (hit.used) {
            let t = dir_to_texel(gs.xyz, sp.n);
            let coarse = texels[(t.face * sp.n + t.row) * sp.n + t.col].xyz;
            emit(res, gs.xyz, hit.f * env_radiance(gs.xyz, coarse), hit.cos, hit.scale);
        }
    }
}

// render::estimator's brdf_samples, one sample at a time (the GPU's lanes are its pixels): N_B
// draws from the BRDF, each weighted by MIS against the light density in its direction.
fn brdf_samples(p: Pixel, rng: ptr<function, Rng>, dens: LightDensities, res: ptr<function, Shaded>) {
    let size = sp.n;
    let nb_f = f32(p.nb);
    for (var j = 0u; j < p.nb; j++) {
        (*res).stats.w += 1u;
        let u1 = rng_next_f32(rng);
        let u2 = rng_next_f32(rng);
        let bs = brdf_sample(p.mat, p.ol, vec2(u1, u2));
        if (bs.w <= 0.0) {
            continue;
        }
        let il = bs.xyz;
        let d = to_world(p.fr, il);
        if (sample_blocked(p.px, p.index, d)) {
            continue;
        }
        let hit = dir_to_texel(d, size);
        let t = texels[(hit.face * size + hit.row) * size + hit.col];
        let q = 1.0 + hit.a * hit.a + hit.b * hit.b;
        let env = env_radiance_factor(d, t.xyz);
        var n_l = 0.0;
        if (sp.strategy == STRATEGY_PAPER) {
            var density = dens.face[hit.face];
            if (sp.tiles > 1u) {
                let r = tile_region(hit.face, hit.col, hit.row, size, sp.tiles);
                density = region_density(p.n, r, dens.total, p.nl, dens.window_len, p.counts, p.use_cosine);
            }
            n_l = density * t.w * (q * sqrt(q)) * env.w;
        } else if (sp.strategy == STRATEGY_GLOBAL) {
            n_l = f32(p.nl) * global_pdf(size, d);
        }
        emit(res, d, brdf_eval(p.mat, p.ol, il) * env.xyz, il.z, il.z * mis_weight_over_density(sp.mis, nb_f * bs.w, n_l));
    }
}
