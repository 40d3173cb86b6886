// envis — the workgroup prefix sum shared by the distribution builds (distribution.wgsl,
// global.wgsl). Each thread first sums a serial run of its elements, then the 256 partial sums
// are scanned here, so rounding grows like log N.

const WG: u32 = 256u;
var<workgroup> partial: array<f32, 256>;

// The run [x, y) of `count` elements that thread t sums serially before the workgroup scan.
fn serial_run(t: u32, count: u32) -> vec2<u32> {
    let k = (count + WG - 1u) / WG;
    let start = min(t * k, count);
    return vec2(start, min(start + k, count));
}

// Inclusive scan of partial[] across the workgroup (Hillis-Steele); returns the exclusive prefix of
// thread t, and leaves the total in partial[WG - 1]. Call from uniform control flow.
fn scan_partials(t: u32, s: f32) -> f32 {
    partial[t] = s;
    workgroupBarrier();
    for (var off = 1u; off < WG; off = off << 1u) {
        var v = partial[t];
        if (t >= off) {
            v += partial[t - off];
        }
        workgroupBarrier();
        partial[t] = v;
        workgroupBarrier();
    }
    return partial[t] - s;
}
