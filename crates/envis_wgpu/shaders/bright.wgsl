// envis — the map's bright part as a light of its own (render::resampling::BrightLight) and its
// per-pixel reservoir (bright_reservoir). Needs common.wgsl, sampling.wgsl and reservoir.wgsl
// before it, and a module that declares `split_tex` (per cube texel of rp.n^2 faces two entries:
// the rest's radiance, then the bright part's radiance with its texel's probability in w, zero
// outside the bright part), `bright_cdf` (rp.bright_count + 1 values), `bright_ids` (the bright
// texels' cube indices) and `rp`, and `visible_from(px, point, d, rays)` (a shadow ray).

// Distribution1D::sample over bright_cdf: the largest bin i with cdf[i] <= u, and the offset in
// it (the twin of cdf.wgsl's sample_cdf, on this module's table).
fn bright_sample_cdf(u: f32) -> BinSample {
    let n = rp.bright_count;
    var lo = 0u;
    var len = n;
    while (len > 0u) {
        let half = len / 2u;
        if (bright_cdf[lo + half] <= u) {
            lo = lo + half + 1u;
            len = len - half - 1u;
        } else {
            len = half;
        }
    }
    let i = max(lo, 1u) - 1u;
    let c0 = bright_cdf[i];
    let w = bright_cdf[i + 1u] - c0;
    let du = select(0.0, clamp((u - c0) / w, 0.0, ONE_MINUS_EPSILON), w > 0.0);
    return BinSample(i, du);
}

// The bright part's entry of the texel d falls in: radiance (zero outside) and probability.
fn bright_entry(d: vec3<f32>) -> vec4<f32> {
    let n = rp.n;
    let t = dir_to_texel(d, n);
    return split_tex[2u * ((t.face * n + t.row) * n + t.col) + 1u];
}

// BrightLight::sample: a direction (xyz; w = 1, or 0 when there is no bright part). u.x chooses
// the texel and is re-stretched across it, u.y the other coordinate.
fn bright_sample(u: vec2<f32>) -> vec4<f32> {
    if (rp.bright_count == 0u) {
        return vec4(0.0);
    }
    let bin = bright_sample_cdf(u.x);
    let n = rp.n;
    let t = bright_ids[bin.i];
    let face = t / (n * n);
    let row = (t / n) % n;
    let col = t % n;
    let h = 2.0 / f32(n);
    let a = -1.0 + (f32(col) + bin.du) * h;
    let b = -1.0 + (f32(row) + u.y) * h;
    return vec4(normalize(face_ab_to_vec(face, a, b)), 1.0);
}

// BrightLight::pdf: P(texel) / (2/N)^2 (1 + a^2 + b^2)^(3/2) at d's face coordinates, 0 outside.
fn bright_pdf(d: vec3<f32>) -> f32 {
    let n = rp.n;
    let t = dir_to_texel(d, n);
    let pmf = split_tex[2u * ((t.face * n + t.row) * n + t.col) + 1u].w;
    if (pmf <= 0.0) {
        return 0.0;
    }
    let h = 2.0 / f32(n);
    let q = 1.0 + t.a * t.a + t.b * t.b;
    return pmf / (h * h) * q * sqrt(q);
}

// render::resampling::BRIGHT_LIGHT_SAMPLES, BRIGHT_LIGHT_SAMPLES_BIASED and
// BRIGHT_PENUMBRA_SAMPLES are generated from Rust: envis_wgpu::shaders::resampling_constants.

// resampling::bright_light_samples: fewer in the biased mode, more where the previous frame saw
// a penumbra (unbiased mode).
fn bright_light_samples(penumbra: bool) -> u32 {
    if (rp.unbiased == 0u) {
        return BRIGHT_LIGHT_SAMPLES_BIASED;
    }
    return select(BRIGHT_LIGHT_SAMPLES, BRIGHT_PENUMBRA_SAMPLES, penumbra);
}

// bright_reservoir's `offer`: direction d, one of the bright light's samples (light) or the
// BRDF's, shadow-tested and into the sink with the power heuristic against the other technique.
// `seen` gets bit 1 where d is seen, bit 2 where it is blocked (for the penumbra flag).
fn bright_offer(sink: Sink, at: BrightAt, d: vec3<f32>, light: bool, count: u32, seen: ptr<function, u32>, rays: ptr<function, u32>) -> Sink {
    let il = to_local(at.fr, d);
    let l = bright_entry(d).xyz;
    if (il.z <= 0.0 || all(l == vec3(0.0))) {
        return sink;
    }
    if (!visible_from(at.px, at.point, d, rays)) {
        *seen |= 2u;
        return sink;
    }
    *seen |= 1u;
    let p_light = f32(count) * bright_pdf(d);
    let p_brdf = brdf_pdf(at.mat, at.ol, il);
    var w = 0.0;
    if (light) {
        w = mis_weight_over_density(MIS_POWER, p_light, p_brdf);
    } else {
        w = mis_weight_over_density(MIS_POWER, p_brdf, p_light);
    }
    return sink_add(sink, d, brdf_eval(at.mat, at.ol, il) * l, il.z, il.z * w);
}

// The surface the bright part's candidates are drawn at.
struct BrightAt {
    px: GPixel,
    point: vec3<f32>,
    mat: Material,
    fr: Frame,
    ol: vec3<f32>,
}

// resampling::bright_reservoir: bright_light_samples(penumbra) samples of the bright light and
// one of the BRDF, each shadow-tested, one kept; flagged where some were seen and some not.
fn bright_reservoir(px: GPixel, point: vec3<f32>, penumbra: bool, rng: ptr<function, Rng>, rays: ptr<function, u32>) -> Reservoir {
    if (rp.bright_count == 0u) {
        return reservoir_empty(1.0);
    }
    let mat = Material(px.kd.xyz, px.ks.xyz, u32(px.kd.w), px.ks.w);
    let n = normalize_or_zero(px.n.xyz);
    let o = normalize_or_zero(px.o.xyz);
    if (all(n == vec3(0.0)) || all(o == vec3(0.0)) || dot(n, o) <= 0.0 || is_black(mat)) {
        return reservoir_empty(1.0);
    }
    let fr = frame_new(n);
    let at = BrightAt(px, point, mat, fr, to_local(fr, o));
    let count = bright_light_samples(penumbra);
    var u: array<f32, 2u * BRIGHT_PENUMBRA_SAMPLES + 2u>;
    for (var k = 0u; k < 2u * count + 2u; k++) {
        u[k] = rng_next_f32(rng);
    }
    var sink = sink_new(rng_new(rng_next_u32(rng), 0u));
    var seen = 0u;
    for (var k = 0u; k < count; k++) {
        let ls = bright_sample(vec2(u[2u * k], u[2u * k + 1u]));
        if (ls.w > 0.0) {
            sink = bright_offer(sink, at, ls.xyz, true, count, &seen, rays);
        }
    }
    let ub = 2u * count;
    let bs = brdf_sample(mat, at.ol, vec2(u[ub], u[ub + 1u]));
    if (bs.w > 0.0) {
        sink = bright_offer(sink, at, normalize(to_world(fr, bs.xyz)), false, count, &seen, rays);
    }
    var q = sink_finish(sink);
    // Every candidate was seen: what was kept is visible.
    q.visible = u32(q.ucw > 0.0);
    q.penumbra = u32(seen == 3u);
    return q;
}
