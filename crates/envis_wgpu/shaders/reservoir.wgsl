// envis — one pixel's reservoir (render::resampling::reservoir) and the combination of several
// pixels' and frames' reservoirs into one (render::resampling::combine), step for step. Needs
// common.wgsl before it. The including module (resampling.wgsl) evaluates targets and shadow
// rays; the functions here are the arithmetic and the random draws, in the CPU's order.

// render::resampling::Reservoir, 48 bytes (envis_wgpu::resampling::GpuReservoir).
struct Reservoir {
    // The selected direction; meaningless where ucw is 0.
    dir: vec3<f32>,
    // W, the unbiased contribution weight; 0: nothing selected, or blocked.
    ucw: f32,
    // The unshadowed integrand at dir, at the reservoir's pixel and frame.
    rgb: vec3<f32>,
    // p̂(dir) there: the luminance of rgb.
    p_hat: f32,
    // M, the confidence.
    m: f32,
    // 1 where dir is known to be unblocked from the pixel's surface.
    visible: u32,
    // 1 where the bright part's candidates here found it partly blocked (Reservoir::penumbra).
    penumbra: u32,
    pad: u32,
}

// An empty reservoir of confidence m (Reservoir { m, ..Default::default() }).
fn reservoir_empty(m: f32) -> Reservoir {
    return Reservoir(vec3(0.0), 0.0, vec3(0.0), 0.0, m, 0u, 0u, 0u);
}

// render::resampling::CandidateSink: weighted reservoir sampling over the samples the estimator
// emits, each of contribution fl x scale with resampling weight lum(fl) x scale. Passed by value
// (the candidate pass keeps one in a private variable, the bright part one in a local).
struct Sink {
    rng: Rng,
    w_sum: f32,
    chosen: bool,
    dir: vec3<f32>,
    rgb: vec3<f32>,
    p_hat: f32,
}

fn sink_new(rng: Rng) -> Sink {
    return Sink(rng, 0.0, false, vec3(0.0), vec3(0.0), 0.0);
}

// CandidateSink::add. (Written without a pointer into a local struct, `&s.rng`: naga 29's
// SPIR-V writer panics on it, "Expression is not cached".)
fn sink_add(sink: Sink, dir: vec3<f32>, fl: vec3<f32>, cos: f32, scale: f32) -> Sink {
    let y = luminance(fl);
    let w = y * scale;
    if (!(w > 0.0) || !is_finite_bits(w)) {
        return sink;
    }
    var rng = sink.rng;
    let w_sum = sink.w_sum + w;
    // Select with probability w / w_sum (the first live candidate always).
    if (rng_next_f32(&rng) * w_sum < w) {
        return Sink(rng, w_sum, true, dir, fl * cos, y * cos);
    }
    return Sink(rng, w_sum, sink.chosen, sink.dir, sink.rgb, sink.p_hat);
}

// CandidateSink::finish: confidence 1, visibility not known yet.
fn sink_finish(s: Sink) -> Reservoir {
    if (s.chosen && s.p_hat > 0.0 && s.w_sum > 0.0) {
        return Reservoir(s.dir, s.w_sum / s.p_hat, s.rgb, s.p_hat, 1.0, 0u, 0u, 0u);
    }
    return reservoir_empty(1.0);
}

// MAX_DOMAINS (the canonical pixel's own reservoir and at most MAX_SPATIAL others) is generated
// from Rust: envis_wgpu::shaders::resampling_constants.

// combine::Domain, with what the including module evaluated for it: `p_c`, its sample's target
// at the canonical pixel with the canonical pixel's visibility (combine's canonical_target), and
// for another domain `p_at_c`, the canonical sample's target with visibility at this domain.
struct Domain {
    res: Reservoir,
    here: vec3<f32>,
    p_c: f32,
    p_at_c: f32,
}

// combine::Pick: weighted reservoir sampling over the domains' samples.
struct Pick {
    w_sum: f32,
    selected: i32,
}

fn pick_offer(p: Pick, j: u32, w: f32, rng: ptr<function, Rng>) -> Pick {
    var q = p;
    if (!(w > 0.0 && is_finite_bits(w))) {
        return q;
    }
    q.w_sum += w;
    if (rng_next_f32(rng) * q.w_sum < w) {
        q.selected = i32(j);
    }
    return q;
}

// Pick::finish: the selected sample re-evaluated here, W = sum w / (p̂(Y) norm); biased: the
// selected domain's `visible` says whether it is known to be seen from here (pairwise: every
// selectable sample was).
fn pick_finish(p: Pick, dom: ptr<function, array<Domain, MAX_DOMAINS>>, m: f32, norm: f32, biased: bool) -> Reservoir {
    if (p.selected < 0) {
        var r = (*dom)[0].res;
        r.m = m;
        r.ucw = 0.0;
        return r;
    }
    let s = u32(p.selected);
    let here = (*dom)[s].here;
    let t = luminance(here);
    var ucw = p.w_sum / (t * norm);
    if (!is_finite_bits(ucw)) {
        ucw = 0.0;
    }
    var visible = 1u;
    if (biased) {
        visible = (*dom)[s].res.visible;
    }
    return Reservoir((*dom)[s].res.dir, ucw, here, t, m, visible, (*dom)[0].res.penumbra, 0u);
}

// combine::pair_share: (the neighbour's weight, the canonical domain's) in the pair of the
// canonical domain and neighbour i.
fn pair_share(m_i: f32, p_i: f32, m_c_share: f32, p_c: f32, c_total: f32) -> vec2<f32> {
    let share = (m_i + m_c_share) / c_total;
    let a = m_i * p_i;
    let b = m_c_share * p_c;
    if (a + b <= 0.0) {
        return vec2(0.0);
    }
    return vec2(share * a / (a + b), share * b / (a + b));
}

// combine::pairwise: generalised RIS with pairwise MIS over `count` domains.
fn combine_pairwise(dom: ptr<function, array<Domain, MAX_DOMAINS>>, count: u32, rng: ptr<function, Rng>) -> Reservoir {
    var c_total = 0.0;
    for (var j = 0u; j < count; j++) {
        c_total += (*dom)[j].res.m;
    }
    let k = f32(max(count - 1u, 1u));
    let m_c_share = (*dom)[0].res.m / k;
    var pick = Pick(0.0, -1);
    for (var j = 0u; j < count; j++) {
        let d = (*dom)[j];
        let p_here = d.p_c;
        if (!(p_here > 0.0 && d.res.ucw > 0.0)) {
            continue;
        }
        var m = 1.0;
        if (count > 1u && j == 0u) {
            m = 0.0;
            for (var i = 1u; i < count; i++) {
                m += pair_share((*dom)[i].res.m, (*dom)[i].p_at_c, m_c_share, p_here, c_total).y;
            }
        } else if (count > 1u) {
            m = pair_share(d.res.m, d.res.p_hat, m_c_share, p_here, c_total).x;
        }
        pick = pick_offer(pick, j, m * p_here * d.res.ucw, rng);
    }
    return pick_finish(pick, dom, c_total, 1.0, false);
}

// combine::biased: selection by M p̂ W, weights 1 / sum M, no rays.
fn combine_biased(dom: ptr<function, array<Domain, MAX_DOMAINS>>, count: u32, rng: ptr<function, Rng>) -> Reservoir {
    var m_total = 0.0;
    for (var j = 0u; j < count; j++) {
        m_total += (*dom)[j].res.m;
    }
    var pick = Pick(0.0, -1);
    for (var j = 0u; j < count; j++) {
        let d = (*dom)[j];
        pick = pick_offer(pick, j, d.res.m * luminance(d.here) * d.res.ucw, rng);
    }
    return pick_finish(pick, dom, m_total, m_total, true);
}
