// envis — sampling a tabulated CDF (twin of sampling::distribution::Distribution1D::sample).
// Needs a module-scope `cdfs: array<f32>`: the face CDFs in distribution.wgsl, the `global`
// distribution in the shading and global modules.

// Distribution1D::sample on cdfs[base .. base + n + 1]: the largest bin i with cdf[i] <= u, and
// the offset (u - cdf[i]) / (cdf[i+1] - cdf[i]) in [0, 1).
struct BinSample {
    i: u32,
    du: f32,
}
fn sample_cdf(base: u32, n: u32, u: f32) -> BinSample {
    // Count of cdf[0..n) values <= u (cdf[0] = 0 <= u always), by binary search.
    var lo = 0u;
    var len = n;
    while (len > 0u) {
        let half = len / 2u;
        if (cdfs[base + lo + half] <= u) {
            lo = lo + half + 1u;
            len = len - half - 1u;
        } else {
            len = half;
        }
    }
    let i = max(lo, 1u) - 1u;
    let c0 = cdfs[base + i];
    let w = cdfs[base + i + 1u] - c0;
    let du = select(0.0, clamp((u - c0) / w, 0.0, ONE_MINUS_EPSILON), w > 0.0);
    return BinSample(i, du);
}
