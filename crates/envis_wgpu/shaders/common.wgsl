// envis — shared WGSL: hashes, random streams, cube-face geometry, luminance, sanitising.
// Each function is the twin of a Rust function named in its comment; the Rust one is the oracle.
// Prepended to every envis shader module (see envis_wgpu/src/shaders.rs).

const PI: f32 = 3.14159265358979;
const INV_PI: f32 = 0.318309886183791;
// Largest f32 below 1 (sampling::rng::ONE_MINUS_EPSILON).
const ONE_MINUS_EPSILON: f32 = 0.99999994;
// envmap::MAX_RADIANCE
const MAX_RADIANCE: f32 = 1e30;

// sampling::rng::hash: x -> PCG-RXS-M-XS(747796405 x + 2891336453)
fn hash(x: u32) -> u32 {
    let state = x * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// sampling::rng::hash_combine for 2, 3 and 4 words: h = hash(h ^ w), h0 = 0x9e3779b9.
fn hash2(a: u32, b: u32) -> u32 {
    return hash(hash(0x9e3779b9u ^ a) ^ b);
}
fn hash3(a: u32, b: u32, c: u32) -> u32 {
    return hash(hash2(a, b) ^ c);
}
fn hash4(a: u32, b: u32, c: u32, d: u32) -> u32 {
    return hash(hash3(a, b, c) ^ d);
}

// sampling::rng::to_unit: top 24 bits -> [0, 1).
fn to_unit(x: u32) -> f32 {
    return f32(x >> 8u) * (1.0 / 16777216.0);
}

// sampling::rng::Rng: state <- LCG(state), output = PCG-RXS-M-XS(state).
struct Rng { state: u32 }
fn rng_new(seed: u32, stream: u32) -> Rng {
    return Rng(hash2(seed, stream));
}
fn rng_next_u32(r: ptr<function, Rng>) -> u32 {
    (*r).state = (*r).state * 747796405u + 2891336453u;
    let s = (*r).state;
    let word = ((s >> ((s >> 28u) + 4u)) ^ s) * 277803737u;
    return (word >> 22u) ^ word;
}
fn rng_next_f32(r: ptr<function, Rng>) -> f32 {
    return to_unit(rng_next_u32(r));
}

// sampling::rng::permute: element i of a random permutation of 0..n (bijective mixing on
// ceil(log2 n) bits, cycle walking).
fn permute(i: u32, n: u32, seed: u32) -> u32 {
    if (n <= 1u) {
        return 0u;
    }
    let bits = 32u - countLeadingZeros(n - 1u);
    let mask = select((1u << bits) - 1u, 0xffffffffu, bits >= 32u);
    let s1 = hash(seed);
    let s2 = hash(s1);
    let sh1 = min(bits / 2u + 1u, 31u);
    let sh2 = min(bits / 3u + 1u, 31u);
    var x = i;
    loop {
        x ^= s1 & mask;
        x = (x * 0x9E3779B1u) & mask;
        x ^= (x & mask) >> sh1;
        x = (x + s2) & mask;
        x = (x * 0x85EBCA6Bu) & mask;
        x ^= (x & mask) >> sh2;
        if (x < n) {
            return x;
        }
    }
    return 0u;
}

// envmap::luminance (Rec. 709).
fn luminance(c: vec3<f32>) -> f32 {
    return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
}

// envmap::sanitize_texel, per channel: NaN, +-Inf and negative -> 0, above MAX_RADIANCE -> it.
// Decided on the bits, since WGSL lets a compiler assume floats are finite.
fn is_finite_bits(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}
fn sanitize_channel(x: f32) -> f32 {
    return select(0.0, min(x, MAX_RADIANCE), is_finite_bits(x) && x > 0.0);
}
// Problem class of a texel, first in the order NaN (1), Inf (2), negative (3), huge (4); 0 if clean.
fn texel_problem(c: vec3<f32>) -> u32 {
    let b = bitcast<vec3<u32>>(c);
    let special = (b & vec3(0x7f800000u)) == vec3(0x7f800000u);
    let mant = (b & vec3(0x007fffffu)) != vec3(0u);
    if (any(special & mant)) {
        return 1u;
    }
    if (any(special)) {
        return 2u;
    }
    if (any(c < vec3(0.0))) {
        return 3u;
    }
    if (any(c > vec3(MAX_RADIANCE))) {
        return 4u;
    }
    return 0u;
}

// envmap::face_ab_to_vec: unnormalised direction of face coordinates (a, b) in [-1, 1]^2.
fn face_ab_to_vec(face: u32, a: f32, b: f32) -> vec3<f32> {
    switch face {
        case 0u: { return vec3(1.0, -b, -a); }
        case 1u: { return vec3(-1.0, -b, a); }
        case 2u: { return vec3(a, 1.0, b); }
        case 3u: { return vec3(a, -1.0, -b); }
        case 4u: { return vec3(a, -b, 1.0); }
        default: { return vec3(-a, -b, -1.0); }
    }
}

// envmap::dir_to_latlong for a unit direction: (u, v), u in [0, 1).
fn dir_to_latlong(d: vec3<f32>) -> vec2<f32> {
    let t = acos(clamp(d.y, -1.0, 1.0));
    var p = atan2(d.x, -d.z);
    if (p < 0.0) {
        p += 2.0 * PI;
    }
    var u = p / (2.0 * PI);
    if (u >= 1.0) {
        u = 0.0;
    }
    return vec2(u, t / PI);
}

// envmap::dir_to_texel: face, (a, b), column and row of direction d on n x n faces.
// Ties between axes go to X, then Y, then Z; the zero vector gives face 0, (0, 0).
struct TexelHit {
    face: u32,
    a: f32,
    b: f32,
    col: u32,
    row: u32,
}
fn dir_to_texel(d: vec3<f32>, n: u32) -> TexelHit {
    let ad = abs(d);
    let is_x = ad.x >= ad.y && ad.x >= ad.z;
    let is_y = !is_x && ad.y >= ad.z;
    var face = 0u;
    var m = 0.0;
    var a = 0.0;
    var b = 0.0;
    if (is_x) {
        m = ad.x;
        face = select(0u, 1u, d.x < 0.0);
        a = select(-d.z, d.z, d.x < 0.0);
        b = -d.y;
    } else if (is_y) {
        m = ad.y;
        face = select(2u, 3u, d.y < 0.0);
        a = d.x;
        b = select(d.z, -d.z, d.y < 0.0);
    } else {
        m = ad.z;
        face = select(4u, 5u, d.z < 0.0);
        a = select(d.x, -d.x, d.z < 0.0);
        b = -d.y;
    }
    if (m == 0.0) {
        return TexelHit(0u, 0.0, 0.0, u32(n / 2u), u32(n / 2u));
    }
    let r = 1.0 / m;
    a = a * r;
    b = b * r;
    let nf = f32(n);
    let col = u32(clamp(i32(0.5 * (a + 1.0) * nf), 0, i32(n) - 1));
    let row = u32(clamp(i32(0.5 * (b + 1.0) * nf), 0, i32(n) - 1));
    return TexelHit(face, a, b, col, row);
}

// Linear index of a thread in a 1D dispatch that was split over (x, y) workgroups.
fn linear_id(gid: vec3<u32>, nwg: vec3<u32>, wg_size: u32) -> u32 {
    return gid.x + gid.y * nwg.x * wg_size;
}

// sampling::tiles::TileGrid: tile i of a side of n texels cut into k starts at ceil(i n / k), and
// texel x lies in tile floor(x k / n).
fn tile_bound(i: u32, n: u32, k: u32) -> u32 {
    return (i * n + k - 1u) / k;
}

fn tile_of(x: u32, n: u32, k: u32) -> u32 {
    return x * k / n;
}

// TileGrid::region: the region (face-major, then tile row, then tile column) of texel (col, row).
fn tile_region(face: u32, col: u32, row: u32, n: u32, k: u32) -> u32 {
    return face * k * k + tile_of(row, n, k) * k + tile_of(col, n, k);
}

// TileGrid::span: the texel columns (x, y) and rows (z, w) of region r, half-open.
fn region_span(r: u32, n: u32, k: u32) -> vec4<u32> {
    let t = r % (k * k);
    let tx = t % k;
    let ty = t / k;
    return vec4(tile_bound(tx, n, k), tile_bound(tx + 1u, n, k), tile_bound(ty, n, k), tile_bound(ty + 1u, n, k));
}
