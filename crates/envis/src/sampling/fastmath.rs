//! Branch-free elementary functions for the samplers' lane loops. `f32::sin_cos` and
//! `f32::powf` call libm, which LLVM does not vectorise; these are plain arithmetic and bit
//! operations, so a loop of them over [`crate::sampling::LANES`] samples does. Each states its
//! accuracy and has a test against the f64 library function.

/// `c[0] + x (c[1] + x (c[2] + ...))`, Horner's rule from the innermost coefficient out. Written
/// as a loop over a fixed-size array (which LLVM unrolls) rather than as nested parentheses:
/// rustfmt takes minutes on a dozen nested levels. The operations are the nested form's, in its
/// order, so results are bit-identical to it.
#[inline(always)]
fn horner<T, const N: usize>(x: T, c: [T; N]) -> T
where
    T: Copy + std::ops::Add<Output = T> + std::ops::Mul<Output = T>,
{
    let mut acc = c[N - 1];
    for k in (0..N - 1).rev() {
        acc = c[k] + x * acc;
    }
    acc
}

/// Taylor coefficients of `sin(y) / y` in `y^2`, to degree 10.
const SIN_TAYLOR: [f32; 6] = [
    1.0,
    -1.0 / 6.0,
    1.0 / 120.0,
    -1.0 / 5040.0,
    1.0 / 362_880.0,
    -1.0 / 39_916_800.0,
];

/// Taylor coefficients of `cos(y)` in `y^2`, to degree 12.
const COS_TAYLOR: [f32; 7] = [
    1.0,
    -0.5,
    1.0 / 24.0,
    -1.0 / 720.0,
    1.0 / 40_320.0,
    -1.0 / 3_628_800.0,
    1.0 / 479_001_600.0,
];

/// `atanh(s) / s` in `s^2`: `1 / (2k + 1)`, to `s^16`.
const ATANH_SERIES: [f64; 9] = [
    1.0,
    1.0 / 3.0,
    1.0 / 5.0,
    1.0 / 7.0,
    1.0 / 9.0,
    1.0 / 11.0,
    1.0 / 13.0,
    1.0 / 15.0,
    1.0 / 17.0,
];

/// `e^z`'s Taylor coefficients `1 / k!`, to degree 11.
const EXP_TAYLOR: [f64; 12] = [
    1.0,
    1.0,
    1.0 / 2.0,
    1.0 / 6.0,
    1.0 / 24.0,
    1.0 / 120.0,
    1.0 / 720.0,
    1.0 / 5040.0,
    1.0 / 40_320.0,
    1.0 / 362_880.0,
    1.0 / 3_628_800.0,
    1.0 / 39_916_800.0,
];

/// `(sin x, cos x)` for `x` in `[-pi, pi]`, branch-free: fold to `[-pi/2, pi/2]` with
/// `sin(x) = sin(pi - x)`, `cos(x) = -cos(pi - x)`, then Taylor polynomials of degree 11 / 12
/// (absolute error < 1e-7 there, below f32 rounding of the result).
#[inline]
pub fn sin_cos_fast(x: f32) -> (f32, f32) {
    use std::f32::consts::{FRAC_PI_2, PI};
    let fold = x.abs() > FRAC_PI_2;
    let y = if fold { PI.copysign(x) - x } else { x };
    let y2 = y * y;
    let s = y * horner(y2, SIN_TAYLOR);
    let c = horner(y2, COS_TAYLOR);
    (s, if fold { -c } else { c })
}

/// `(cos, sin)` of the azimuth `2 pi u` for `u` in `[0, 1]`, branch-free: minus those of
/// `2 pi u - pi`, which lies in [`sin_cos_fast`]'s range (negation is exact).
#[inline(always)]
pub fn azimuth(u: f32) -> (f32, f32) {
    let (s, c) = sin_cos_fast(2.0 * std::f32::consts::PI * u - std::f32::consts::PI);
    (-c, -s)
}

/// `x^y` for `x >= 0` and `y >= 0` (the Phong lobe's powers, `x` a cosine or a uniform draw),
/// branch-free. Computed in f64: `log2 x` from the exponent bits and an atanh series on the
/// mantissa, `exp2` from the nearest integer (by the 1.5 * 2^52 rounding trick) and a Taylor
/// polynomial; both with relative error below 1e-14, so the f32 result is `x^y` correctly
/// rounded but for values within ~1e-14 of a rounding boundary: at most 1 ulp from `powf`.
/// Results beyond f32's range saturate to 0 / infinity; `0^0 = 1`. For lane loops only: one at a
/// time, libm's table-driven `powf` is faster (the Phong estimator ran 2.3x slower with this in
/// its scalar light-sample loop, measured).
#[inline(always)]
pub fn pow_unit(x: f32, y: f32) -> f32 {
    let t = (f64::from(y) * log2_f64(f64::from(x))).clamp(-1000.0, 1000.0);
    let p = exp2_f64(t) as f32;
    // log2 0 comes out as -1023, not -infinity: zero's powers by selection.
    let zero_pow = if y == 0.0 { 1.0 } else { 0.0 };
    if x > 0.0 { p } else { zero_pow }
}

/// `log2 x` for finite `x > 0`: `x = 2^k m` with `m` in `[sqrt(1/2), sqrt(2))`, and
/// `ln m = 2 atanh(s)`, `s = (m - 1) / (m + 1)`, `|s| <= 0.1716`, by its series to `s^17`
/// (the first term left out is below 1e-15 relative).
#[inline(always)]
fn log2_f64(x: f64) -> f64 {
    const MANTISSA: u64 = (1 << 52) - 1;
    const ONE: u64 = 1023 << 52;
    let bits = x.to_bits();
    let k = ((bits >> 52) as i32 & 0x7ff) - 1023;
    let m = f64::from_bits((bits & MANTISSA) | ONE);
    let big = m > std::f64::consts::SQRT_2;
    let (m, k) = if big { (0.5 * m, k + 1) } else { (m, k) };
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let series = horner(s2, ATANH_SERIES);
    f64::from(k) + 2.0 * s * series * std::f64::consts::LOG2_E
}

/// `2^t` for `|t| <= 1000`: `t = n + f` with `n` the nearest integer, so `|f| <= 1/2`; `2^n`
/// built from its bits and `2^f = e^(f ln 2)` by Taylor to degree 11 (error below 1e-14).
#[inline(always)]
fn exp2_f64(t: f64) -> f64 {
    // Adding 1.5 * 2^52 rounds t to an integer n held in the low mantissa bits.
    const SHIFT: f64 = 6_755_399_441_055_744.0;
    let shifted = t + SHIFT;
    let n = shifted - SHIFT;
    // 2^n's bits: the biased exponent n + 1023 in place (n = bits - SHIFT's bits, wrapping).
    let scale = f64::from_bits(
        shifted
            .to_bits()
            .wrapping_sub(SHIFT.to_bits())
            .wrapping_add(1023)
            << 52,
    );
    let z = (t - n) * std::f64::consts::LN_2;
    let e = horner(z, EXP_TAYLOR);
    e * scale
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::PI;

    #[test]
    fn sin_cos_fast_is_accurate() {
        let mut worst = 0.0f64;
        for i in 0..=100_000 {
            let x = -PI + 2.0 * PI * i as f32 / 100_000.0;
            let (s, c) = sin_cos_fast(x);
            let (xs, xc) = (x as f64).sin_cos();
            worst = worst.max((s as f64 - xs).abs()).max((c as f64 - xc).abs());
        }
        assert!(worst < 3e-7, "worst error {worst}");
    }

    /// `f32` values one ulp apart from `a` count 1.
    fn ulps(a: f32, b: f32) -> u32 {
        (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs() as u32
    }

    #[test]
    fn pow_unit_is_within_one_ulp_of_f64_powf() {
        // Cosines and draws over (0, 1] (dense near 1, where a lobe's mass is, and down to
        // 2^-32, the smallest nonzero draw), against the exponents and inverse exponents used.
        let mut worst = 0;
        let mut checked = 0;
        for y in [
            0.5f32,
            1.0,
            2.0,
            10.0,
            150.0,
            1e4,
            1e6,
            1.0 / 151.0,
            1.0 / 1e6,
            0.37,
        ] {
            for i in 1..=20_000u32 {
                let f = i as f32 / 20_000.0;
                for x in [f, 1.0 - f * 1e-3, f.powi(8), (f * 32.0 - 32.0).exp2()] {
                    let want = (x as f64).powf(y as f64) as f32;
                    let got = pow_unit(x, y);
                    worst = worst.max(ulps(got, want));
                    checked += 1;
                }
            }
        }
        assert!(worst <= 1, "worst {worst} ulp over {checked} values");
    }

    #[test]
    fn pow_unit_edge_cases() {
        assert_eq!(pow_unit(0.0, 0.0), 1.0);
        assert_eq!(pow_unit(0.0, 1e-6), 0.0);
        assert_eq!(pow_unit(0.0, 150.0), 0.0);
        assert_eq!(pow_unit(1.0, 1e6), 1.0);
        assert_eq!(pow_unit(0.5, 0.0), 1.0);
        assert_eq!(pow_unit(0.5, 200.0), 0.0, "underflows to zero");
        assert_eq!(pow_unit(1e-30, 1.0), 1e-30);
        // A subnormal base, and a base rounded just above 1 (a cosine of unit vectors).
        assert_eq!(pow_unit(1e-40, 1.0), 1e-40);
        assert!(
            ulps(
                pow_unit(1.000_000_1, 150.0),
                (1.000_000_1f32 as f64).powf(150.0) as f32
            ) <= 1
        );
    }
}
