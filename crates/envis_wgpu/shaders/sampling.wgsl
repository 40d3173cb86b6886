// envis — BRDFs, warps, MIS and sample counts (twins of src/sampling/{warp,brdf/,mis,counts}.rs).
// Every routine has its pdf beside it; directions are in the shading frame (z = normal) unless
// the name says world.

// sampling::warp::Frame::new (Duff et al. 2017); sign(z) taken from the bits, as copysign does.
struct Frame {
    t: vec3<f32>,
    b: vec3<f32>,
    n: vec3<f32>,
}
fn frame_new(n: vec3<f32>) -> Frame {
    let sign = bitcast<f32>((bitcast<u32>(n.z) & 0x80000000u) | 0x3f800000u);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    return Frame(vec3(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x), vec3(b, sign + n.y * n.y * a, -n.y), n);
}
fn to_local(fr: Frame, v: vec3<f32>) -> vec3<f32> {
    return vec3(dot(v, fr.t), dot(v, fr.b), dot(v, fr.n));
}
fn to_world(fr: Frame, v: vec3<f32>) -> vec3<f32> {
    return fr.t * v.x + fr.b * v.y + fr.n * v.z;
}

// glam's normalize_or_zero: v / |v|, or 0 when |v| is 0 or not finite.
fn normalize_or_zero(v: vec3<f32>) -> vec3<f32> {
    let r = 1.0 / length(v);
    return select(vec3(0.0), v * r, is_finite_bits(r) && r > 0.0);
}

// sampling::warp::sin_cos_fast: fold to [-pi/2, pi/2], Taylor polynomials of degree 11 / 12.
fn sin_cos_fast(x: f32) -> vec2<f32> {
    let fold = abs(x) > 0.5 * PI;
    let y = select(x, select(-PI, PI, x >= 0.0) - x, fold);
    let y2 = y * y;
    let s = y * (1.0 + y2 * (-1.0 / 6.0 + y2 * (1.0 / 120.0 + y2 * (-1.0 / 5040.0 + y2 * (1.0 / 362880.0 + y2 * (-1.0 / 39916800.0))))));
    let c = 1.0 + y2 * (-0.5 + y2 * (1.0 / 24.0 + y2 * (-1.0 / 720.0 + y2 * (1.0 / 40320.0 + y2 * (-1.0 / 3628800.0 + y2 * (1.0 / 479001600.0))))));
    return vec2(s, select(c, -c, fold));
}

// Cosine-weighted hemisphere (Malley, polar disk): r = sqrt(u1), phi = 2 pi u2 - pi; pdf = cos / pi.
fn sample_cosine_hemisphere(u: vec2<f32>) -> vec3<f32> {
    let r = sqrt(u.x);
    let sc = sin_cos_fast(2.0 * PI * u.y - PI);
    return vec3(r * sc.y, r * sc.x, sqrt(max(1.0 - u.x, 0.0)));
}
fn cosine_hemisphere_pdf(v: vec3<f32>) -> f32 {
    return max(v.z, 0.0) * INV_PI;
}

// Phong lobe around +z: cos a = u1^(1/(e+1)), phi = 2 pi u2; pdf = (e+1)/(2 pi) cos^e a.
fn sample_phong_lobe(u: vec2<f32>, e: f32) -> vec3<f32> {
    let c = pow(u.x, 1.0 / (e + 1.0));
    let s = sqrt(max((1.0 - c) * (1.0 + c), 0.0));
    let phi = 2.0 * PI * u.y;
    return vec3(s * cos(phi), s * sin(phi), c);
}
fn phong_lobe_pdf(cos_a: f32, e: f32) -> f32 {
    return select((e + 1.0) * 0.5 * INV_PI * pow(cos_a, e), 0.0, cos_a <= 0.0);
}

// GGX D(m) = a^2 / (pi (m_x^2 + m_y^2 + a^2 m_z^2)^2).
fn ggx_d(m: vec3<f32>, alpha: f32) -> f32 {
    if (m.z <= 0.0) {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let t = m.x * m.x + m.y * m.y + a2 * m.z * m.z;
    return a2 / (PI * t * t);
}
// s(z) = sqrt(z^2 (1 - a^2) + a^2).
fn ggx_s(z: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    return sqrt(max(z * z * (1.0 - a2) + a2, 0.0));
}
// Visible normals by spherical caps (Dupuy & Benyoub 2023); reflected pdf D(m) / (2 (o.z + s(o.z))).
fn sample_ggx_vndf(o: vec3<f32>, alpha: f32, u: vec2<f32>) -> vec3<f32> {
    let vh = normalize(vec3(alpha * o.x, alpha * o.y, o.z));
    let phi = 2.0 * PI * u.x;
    let z = (1.0 - u.y) * (1.0 + vh.z) - vh.z;
    let st = sqrt(clamp(1.0 - z * z, 0.0, 1.0));
    let h = vec3(st * cos(phi), st * sin(phi), z) + vh;
    let m = normalize_or_zero(vec3(alpha * h.x, alpha * h.y, max(h.z, 0.0)));
    return select(m, vec3(0.0, 0.0, 1.0), all(m == vec3(0.0)));
}
fn ggx_vndf_reflect_pdf(o: vec3<f32>, i: vec3<f32>, alpha: f32) -> f32 {
    if (o.z <= 0.0 || i.z <= 0.0) {
        return 0.0;
    }
    let m = normalize_or_zero(o + i);
    if (all(m == vec3(0.0))) {
        return 0.0;
    }
    return ggx_d(m, alpha) / (2.0 * (o.z + ggx_s(o.z, alpha)));
}
fn reflect_about(o: vec3<f32>, m: vec3<f32>) -> vec3<f32> {
    return 2.0 * dot(o, m) * m - o;
}

// sampling::brdf::Material: Lambert kd plus a glossy lobe (0 none, 1 Phong exponent, 2 GGX alpha).
struct Material {
    kd: vec3<f32>,
    ks: vec3<f32>,
    lobe: u32,
    param: f32,
}
const LOBE_NONE: u32 = 0u;
const LOBE_PHONG: u32 = 1u;
const LOBE_GGX: u32 = 2u;
// GGX with Schlick's Fresnel (F0 = ks) and Bevy's f90: brdf::Lobe::GgxSchlick.
const LOBE_GGX_SCHLICK: u32 = 3u;

fn is_ggx(lobe: u32) -> bool {
    return lobe == LOBE_GGX || lobe == LOBE_GGX_SCHLICK;
}
// brdf::fresnel_schlick: F0 + (f90 - F0) (1 - <o, m>)^5 with f90 = saturate(16.5 (F0.r + F0.g + F0.b)).
fn fresnel_schlick(f0: vec3<f32>, o_m: f32) -> vec3<f32> {
    let f90 = clamp(dot(f0, vec3(50.0 * 0.33)), 0.0, 1.0);
    let x = clamp(1.0 - o_m, 0.0, 1.0);
    let x2 = x * x;
    return f0 + (vec3(f90) - f0) * (x2 * x2 * x);
}

fn mirror_cos(ol: vec3<f32>, il: vec3<f32>) -> f32 {
    return il.z * ol.z - il.x * ol.x - il.y * ol.y;
}
fn diffuse_weight(mat: Material) -> f32 {
    if (mat.lobe == LOBE_NONE) {
        return 1.0;
    }
    let d = luminance(mat.kd);
    let s = luminance(mat.ks);
    return select(d / (d + s), 0.0, d + s <= 0.0);
}
fn is_black(mat: Material) -> bool {
    return max(max(mat.kd.x, mat.kd.y), mat.kd.z) <= 0.0 && (mat.lobe == LOBE_NONE || max(max(mat.ks.x, mat.ks.y), mat.ks.z) <= 0.0);
}
// f(o, i) without the cosine.
fn brdf_eval(mat: Material, ol: vec3<f32>, il: vec3<f32>) -> vec3<f32> {
    if (ol.z <= 0.0 || il.z <= 0.0) {
        return vec3(0.0);
    }
    var v = mat.kd * INV_PI;
    if (mat.lobe == LOBE_PHONG) {
        let c = mirror_cos(ol, il);
        if (c > 0.0) {
            let e = mat.param;
            v += mat.ks * ((e + 2.0) * 0.5 * INV_PI * pow(c, e));
        }
    } else if (is_ggx(mat.lobe)) {
        let alpha = mat.param;
        let m = normalize_or_zero(ol + il);
        let den = 2.0 * (il.z * ggx_s(ol.z, alpha) + ol.z * ggx_s(il.z, alpha));
        if (den > 0.0) {
            var f = mat.ks;
            if (mat.lobe == LOBE_GGX_SCHLICK) {
                f = fresnel_schlick(mat.ks, dot(ol, m));
            }
            v += f * (ggx_d(m, alpha) / den);
        }
    }
    return v;
}
// Solid-angle pdf of brdf_sample (one-sample lobe mixture).
fn brdf_pdf(mat: Material, ol: vec3<f32>, il: vec3<f32>) -> f32 {
    if (ol.z <= 0.0) {
        return 0.0;
    }
    let wd = diffuse_weight(mat);
    var p = wd * cosine_hemisphere_pdf(il);
    if (wd < 1.0) {
        var ps = 0.0;
        if (mat.lobe == LOBE_PHONG) {
            ps = phong_lobe_pdf(mirror_cos(ol, il), mat.param);
        } else if (is_ggx(mat.lobe)) {
            ps = ggx_vndf_reflect_pdf(ol, il, mat.param);
        }
        p += (1.0 - wd) * ps;
    }
    return p;
}
// Sample: u.x chooses the lobe and is re-stretched. Returns (i_local, pdf); pdf 0 = no sample.
fn brdf_sample(mat: Material, ol: vec3<f32>, u: vec2<f32>) -> vec4<f32> {
    if (ol.z <= 0.0) {
        return vec4(0.0);
    }
    let wd = diffuse_weight(mat);
    var il: vec3<f32>;
    if (u.x < wd) {
        il = sample_cosine_hemisphere(vec2(min(u.x / wd, ONE_MINUS_EPSILON), u.y));
    } else {
        let ux = clamp((u.x - wd) / (1.0 - wd), 0.0, ONE_MINUS_EPSILON);
        if (mat.lobe == LOBE_PHONG) {
            let r = frame_new(vec3(-ol.x, -ol.y, ol.z));
            il = to_world(r, sample_phong_lobe(vec2(ux, u.y), mat.param));
        } else if (is_ggx(mat.lobe)) {
            il = reflect_about(ol, sample_ggx_vndf(ol, mat.param, vec2(ux, u.y)));
        } else {
            return vec4(0.0);
        }
    }
    if (il.z <= 0.0) {
        return vec4(0.0);
    }
    let p = brdf_pdf(mat, ol, il);
    if (p > 0.0 && is_finite_bits(p)) {
        return vec4(il, p);
    }
    return vec4(0.0);
}

// sampling::mis::weight_over_density: balance 1 / (na + nb); power na / (na^2 + nb^2), scaled.
const MIS_BALANCE: u32 = 0u;
const MIS_POWER: u32 = 1u;
fn mis_weight_over_density(h: u32, na: f32, nb: f32) -> f32 {
    if (h == MIS_BALANCE) {
        return 1.0 / (na + nb);
    }
    let m = max(na, nb);
    let a = na / m;
    let b = nb / m;
    return a / (m * (a * a + b * b));
}

// sampling::counts::face_count: N_f -> (taken, weight of the last, density).
const COUNTS_FRACTIONAL: u32 = 0u;
const COUNTS_INTEGER: u32 = 1u;
struct FaceCount {
    taken: u32,
    last_weight: f32,
    density: f32,
}
fn face_count(n_f_in: f32, m: u32, counts: u32) -> FaceCount {
    var n_f = 0.0;
    if (is_finite_bits(n_f_in)) {
        n_f = clamp(n_f_in, 0.0, f32(m));
    }
    if (n_f <= 0.0) {
        return FaceCount(0u, 0.0, 0.0);
    }
    let whole = floor(n_f);
    if (counts == COUNTS_FRACTIONAL) {
        let frac = n_f - whole;
        if (frac > 0.0) {
            return FaceCount(u32(whole) + 1u, frac, n_f);
        }
        return FaceCount(u32(whole), 1.0, n_f);
    }
    // Rust's round(): half away from zero (WGSL's round() is half to even).
    let r = select(whole, whole + 1.0, n_f - whole >= 0.5);
    return FaceCount(min(u32(r), m), 1.0, n_f);
}

// One G-buffer texel: normal (w = 1 where there is geometry), view direction, kd (w = lobe kind),
// ks (w = Phong exponent or GGX alpha). Here, not in shade.wgsl, so that modules without the
// shading (the Bevy pass's gather) can decode into it.
struct GPixel {
    n: vec4<f32>,
    o: vec4<f32>,
    kd: vec4<f32>,
    ks: vec4<f32>,
}
