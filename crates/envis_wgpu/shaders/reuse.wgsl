// envis — the reuse passes of a resampled frame: temporal (render::resampling::passes::temporal,
// with `history_targets` before it) and spatial (passes::spatial). Part of the resampling module:
// its bindings, `rp` and helpers are in resampling.wgsl, the combination in reservoir.wgsl.

// Before temporal reuse, with the previous frame's shadow geometry bound: per part, the
// canonical sample's target with visibility at the history pixel in its frame
// (DomainSurface::target_visible), where the pairwise weights will ask for it.
@compute @workgroup_size(64)
fn history_targets(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = pixel_id(gid, nwg);
    if (i >= rp.width * rp.height) {
        return;
    }
    var rays = 0u;
    for (var part = 0u; part < 2u; part++) {
        var t = 0.0;
        let own = res_in[2u * i + part];
        let q = history_pixel(i, part);
        if (rp.unbiased != 0u && part_live(part) && surfaces[i].px.n.w != 0.0 && q >= 0 && own.ucw > 0.0 && own.p_hat > 0.0) {
            let h = prev_surfaces[u32(q)];
            t = luminance(target_rgb(h.px, true, part, own.dir));
            let known = sees_as_history(i, u32(q));
            if (t > 0.0 && !known && !visible_through(h.px, h.p.xyz, own.dir, rp.prev_bvh_nodes, &rays)) {
                t = 0.0;
            }
        }
        hist_targets[2u * i + part] = t;
    }
    counters[i].x += rays;
}

// The domain of reservoir `res` made elsewhere, its sample re-evaluated at pixel s and not
// known to be visible from it (Domain::reused); p_c and p_at_c are set by the caller.
fn reused_domain(res: Reservoir, s: Surface, part: u32) -> Domain {
    var r = res;
    r.visible = 0u;
    return Domain(r, target_rgb(s.px, false, part, res.dir), 0.0, 0.0);
}

// combine::canonical_target for every domain: the canonical sample's own target where live; a
// reused sample's target here with this pixel's visibility (a ray where it is positive, unless
// `known`: live samples seen from here, DomainSurface::without_rays).
fn canonical_targets(dom: ptr<function, array<Domain, MAX_DOMAINS>>, count: u32, s: Surface, known: bool, rays: ptr<function, u32>) {
    let own = (*dom)[0].res;
    (*dom)[0].p_c = select(0.0, own.p_hat, own.ucw > 0.0);
    for (var j = 1u; j < count; j++) {
        let d = (*dom)[j];
        var t = luminance(d.here);
        if (!(t > 0.0 && d.res.ucw > 0.0 && (known || visible_from(s.px, s.p.xyz, d.res.dir, rays)))) {
            t = 0.0;
        }
        (*dom)[j].p_c = t;
    }
}

// combine::combine over the domains prepared.
fn combine(dom: ptr<function, array<Domain, MAX_DOMAINS>>, count: u32, rng: ptr<function, Rng>) -> Reservoir {
    if (rp.unbiased != 0u) {
        return combine_pairwise(dom, count, rng);
    }
    return combine_biased(dom, count, rng);
}

// Pass 2 (passes::temporal): each part's reservoir combined with the history pixel's, its
// confidence capped at max_history and scaled by lobe_agreement, and the rest's by
// map_agreement (the bright part's history is of the same light, bright_history, and in the
// unbiased mode at the same point, history_pixel); no rays where sees_as_history.
@compute @workgroup_size(64)
fn temporal(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = pixel_id(gid, nwg);
    if (i >= rp.width * rp.height) {
        return;
    }
    let s = surfaces[i];
    var c = counters[i];
    for (var part = 0u; part < 2u; part++) {
        let own = res_in[2u * i + part];
        var out = own;
        let q = history_pixel(i, part);
        if (part_live(part) && s.px.n.w != 0.0 && q >= 0) {
            var old = res_hist[2u * u32(q) + part];
            old.m = min(old.m, rp.max_history) * lobe_agreement(s.px, prev_surfaces[u32(q)].px);
            if (part == 0u) {
                old.m *= rp.map_agreement;
            }
            var dom: array<Domain, MAX_DOMAINS>;
            dom[0] = Domain(own, own.rgb, 0.0, 0.0);
            dom[1] = reused_domain(old, s, part);
            if (part == 0u) {
                // passes::temporal: the biased mode trusts the rest's history's visibility.
                dom[1].res.visible = old.visible;
            }
            var rays = 0u;
            if (rp.unbiased != 0u) {
                canonical_targets(&dom, 2u, s, sees_as_history(i, u32(q)), &rays);
                dom[1].p_at_c = hist_targets[2u * i + part];
            }
            var rng = pass_rng(2u + 4u * part, i);
            out = combine(&dom, 2u, &rng);
            c.x += rays;
            if (part == 0u) {
                c.y += 1u;
            } else {
                c.w += 1u;
            }
        }
        res_out[2u * i + part] = out;
    }
    counters[i] = c;
}

// Rust's f32::round: halves away from zero (WGSL's round goes to even). Not floor(|x| + 0.5),
// which rounds 0.49999997 up. The neighbour's angle still goes through the device's sin / cos,
// not Rust's libm, so a rare offset near a half lands one pixel apart from the CPU twin's.
fn round_away(x: f32) -> f32 {
    let t = trunc(x);
    return select(t, t + sign(x), abs(x - t) >= 0.5);
}

// Pass 3 (passes::spatial), for the rest only, where the pixel's confidence is under
// SPATIAL_UNTIL_HISTORY: up to rp.spatial neighbours in a disc of SPATIAL_RADIUS pixels,
// passing the geometric tests, their confidence capped at SPATIAL_CONFIDENCE of the pixel's
// and scaled by lobe_agreement.
@compute @workgroup_size(64)
fn spatial(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = pixel_id(gid, nwg);
    if (i >= rp.width * rp.height) {
        return;
    }
    let s = surfaces[i];
    var c = counters[i];
    for (var part = 0u; part < 2u; part++) {
        let own = res_in[2u * i + part];
        var out = own;
        if (part == 0u && s.px.n.w != 0.0 && rp.spatial > 0u && own.m < SPATIAL_UNTIL_HISTORY) {
            var rng = pass_rng(3u + 4u * part, i);
            var dom: array<Domain, MAX_DOMAINS>;
            var at: array<u32, MAX_DOMAINS>;
            dom[0] = Domain(own, own.rgb, 0.0, 0.0);
            let count = spatial_domains(i, part, &dom, &at, &rng);
            if (count > 1u) {
                var rays = 0u;
                if (rp.unbiased != 0u) {
                    canonical_targets(&dom, count, s, false, &rays);
                    neighbour_targets(&dom, &at, count, part, &rays);
                }
                out = combine(&dom, count, &rng);
                c.x += rays;
                if (part == 0u) {
                    c.z += count - 1u;
                }
            }
        }
        res_out[2u * i + part] = out;
    }
    counters[i] = c;
}

// The neighbours of pixel i that pass the tests, into dom[1..] (their pixels into at); the
// domain count.
fn spatial_domains(i: u32, part: u32, dom: ptr<function, array<Domain, MAX_DOMAINS>>, at: ptr<function, array<u32, MAX_DOMAINS>>, rng: ptr<function, Rng>) -> u32 {
    let s = surfaces[i];
    let own_m = (*dom)[0].res.m;
    let w = i32(rp.width);
    let h = i32(rp.height);
    let x = i32(i % rp.width);
    let y = i32(i / rp.width);
    var count = 1u;
    for (var k = 0u; k < min(rp.spatial, MAX_DOMAINS - 1u); k++) {
        let u1 = rng_next_f32(rng);
        let u2 = rng_next_f32(rng);
        let rad = SPATIAL_RADIUS * sqrt(u1);
        let nx = x + i32(round_away(rad * cos(TAU * u2)));
        let ny = y + i32(round_away(rad * sin(TAU * u2)));
        if ((nx == x && ny == y) || nx < 0 || ny < 0 || nx >= w || ny >= h) {
            continue;
        }
        let j = u32(ny * w + nx);
        let nb = surfaces[j];
        if (nb.px.n.w == 0.0 || !similar(s.px.n.xyz, s.p.w, s.id.x, nb)) {
            continue;
        }
        var q = res_in[2u * j + part];
        q.m = min(q.m, SPATIAL_CONFIDENCE * own_m) * lobe_agreement(s.px, nb.px);
        (*dom)[count] = reused_domain(q, s, part);
        (*at)[count] = j;
        count += 1u;
    }
    return count;
}

// For the canonical sample's pairwise weight: its target with visibility at each neighbour
// (DomainSurface::target_visible), where the canonical sample can be selected.
fn neighbour_targets(dom: ptr<function, array<Domain, MAX_DOMAINS>>, at: ptr<function, array<u32, MAX_DOMAINS>>, count: u32, part: u32, rays: ptr<function, u32>) {
    let own = (*dom)[0];
    if (!(own.p_c > 0.0 && own.res.ucw > 0.0)) {
        return;
    }
    for (var j = 1u; j < count; j++) {
        let nb = surfaces[(*at)[j]];
        var t = luminance(target_rgb(nb.px, false, part, own.res.dir));
        if (t > 0.0 && !visible_from(nb.px, nb.p.xyz, own.res.dir, rays)) {
            t = 0.0;
        }
        (*dom)[j].p_at_c = t;
    }
}

// agreement::lobe_agreement: 1 where two pixels' targets are the same function of direction,
// falling as their lobes (diffuse about the normal, glossy about the mirror direction) part,
// mixed by a's albedos.
fn lobe_agreement(a: GPixel, b: GPixel) -> f32 {
    let na = normalize_or_zero(a.n.xyz);
    let nb = normalize_or_zero(b.n.xyz);
    let diffuse = agreement_near(na, nb, DIFFUSE_WIDTH);
    let lobe = u32(a.kd.w);
    if (lobe == LOBE_NONE) {
        return diffuse;
    }
    var width = 2.0 * a.ks.w;
    if (lobe == LOBE_PHONG) {
        width = sqrt(2.0 / max(a.ks.w, 1e-3));
    }
    let kd = luminance(a.kd.xyz);
    let ks = luminance(a.ks.xyz);
    if (kd + ks <= 0.0) {
        return diffuse;
    }
    let oa = normalize_or_zero(a.o.xyz);
    let ob = normalize_or_zero(b.o.xyz);
    let glossy = agreement_near(reflect_about(oa, na), reflect_about(ob, nb), width);
    return (kd * diffuse + ks * glossy) / (kd + ks);
}

// exp(-(angle / (AGREEMENT_SCALE width))^2), the squared angle as the squared chord.
fn agreement_near(x: vec3<f32>, y: vec3<f32>, width: f32) -> f32 {
    let w = max(AGREEMENT_SCALE * width, MIN_AGREEMENT_WIDTH);
    let d = x - y;
    return exp(-dot(d, d) / (w * w));
}
