//! Random numbers that a WGSL shader can reproduce exactly: u32 arithmetic only.
//!
//! - [`hash`]: the PCG-RXS-M-XS 32-bit output permutation applied to an LCG step (a good
//!   stateless integer hash).
//! - [`Rng`]: a tiny stateful generator (one u32 of state, same permutation) for per-pixel streams.
//! - [`permute`]: a random permutation of `0..n` evaluated one element at a time (a bijective hash
//!   on the next power of two plus cycle walking), so the stratified pool can be shuffled in
//!   parallel.

/// `x -> PCG-RXS-M-XS(747796405 x + 2891336453)`.
#[inline]
pub fn hash(x: u32) -> u32 {
    pcg_output(x.wrapping_mul(LCG_A).wrapping_add(LCG_C))
}

/// Hash of several words (order matters).
#[inline]
pub fn hash_combine(words: &[u32]) -> u32 {
    let mut h = 0x9e37_79b9u32;
    for &w in words {
        h = hash(h ^ w);
    }
    h
}

/// The largest f32 below 1 (pbrt's `OneMinusEpsilon`): where a sample coordinate computed in
/// floating point could round up to 1, it is clamped to this, keeping it in `[0, 1)`. WGSL twin:
/// `ONE_MINUS_EPSILON` in `shaders/common.wgsl`.
pub const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// Uniform float in `[0, 1)` from the top 24 bits of `x` (exactly representable, never 1).
#[inline]
pub fn to_unit(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// Per-pixel stream: `state <- LCG(state)`, output = PCG-RXS-M-XS permutation of the new state.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u32,
}

impl Rng {
    pub fn new(seed: u32, stream: u32) -> Self {
        Rng {
            state: hash_combine(&[seed, stream]),
        }
    }
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        self.state = self.state.wrapping_mul(LCG_A).wrapping_add(LCG_C);
        pcg_output(self.state)
    }
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        to_unit(self.next_u32())
    }

    /// The next `out.len()` (at most [`FILL_MAX`]) outputs, exactly as that many
    /// [`Rng::next_u32`] calls give them, but computed independently of each other (LCG
    /// jump-ahead), so the loop vectorises.
    #[inline(always)]
    pub fn fill_u32(&mut self, out: &mut [u32]) {
        let n = out.len();
        assert!((1..=FILL_MAX).contains(&n));
        let s0 = self.state;
        for (j, o) in out.iter_mut().enumerate() {
            *o = pcg_output(JUMP.0[j].wrapping_mul(s0).wrapping_add(JUMP.1[j]));
        }
        self.state = JUMP.0[n - 1].wrapping_mul(s0).wrapping_add(JUMP.1[n - 1]);
    }
}

/// LCG multiplier and increment of [`Rng`] (and of [`hash`]).
const LCG_A: u32 = 747796405;
const LCG_C: u32 = 2891336453;
/// The most outputs [`Rng::fill_u32`] draws at once.
pub const FILL_MAX: usize = 32;
/// Jump-ahead table: `state_j = A[j] state_0 + C[j]` after `j + 1` LCG steps
/// (`A[j] = a^(j+1)`, `C[j] = c (a^j + ... + 1)`, mod 2^32).
const JUMP: ([u32; FILL_MAX], [u32; FILL_MAX]) = {
    let (mut a, mut c) = ([0u32; FILL_MAX], [0u32; FILL_MAX]);
    let (mut aj, mut cj) = (LCG_A, LCG_C);
    let mut j = 0;
    while j < FILL_MAX {
        a[j] = aj;
        c[j] = cj;
        aj = aj.wrapping_mul(LCG_A);
        cj = cj.wrapping_mul(LCG_A).wrapping_add(LCG_C);
        j += 1;
    }
    (a, c)
};

/// The PCG-RXS-M-XS output permutation of an LCG state.
#[inline(always)]
fn pcg_output(s: u32) -> u32 {
    let word = ((s >> ((s >> 28) + 4)) ^ s).wrapping_mul(277803737);
    (word >> 22) ^ word
}

/// Element `i` of a pseudo-random permutation of `0..n` chosen by `seed` (`i < n`).
/// Bijective mixing on `k = ceil(log2 n)` bits (xor, odd multiply, xorshift-right, all mod 2^k),
/// repeated until the value falls below `n` (cycle walking keeps it a bijection on `0..n`).
pub fn permute(i: u32, n: u32, seed: u32) -> u32 {
    debug_assert!(i < n);
    if n <= 1 {
        return 0;
    }
    let bits = 32 - (n - 1).leading_zeros();
    let mask = if bits >= 32 {
        u32::MAX
    } else {
        (1u32 << bits) - 1
    };
    let s1 = hash(seed);
    let s2 = hash(s1);
    let mut x = i;
    loop {
        x ^= s1 & mask;
        x = x.wrapping_mul(0x9E37_79B1 | 1) & mask;
        x ^= (x & mask) >> (bits / 2 + 1).min(31);
        x = x.wrapping_add(s2) & mask;
        x = x.wrapping_mul(0x85EB_CA6B | 1) & mask;
        x ^= (x & mask) >> (bits / 3 + 1).min(31);
        if x < n {
            return x;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn permute_is_a_bijection() {
        for n in [1u32, 2, 3, 7, 16, 33, 100, 1000] {
            for seed in [0u32, 1, 12345] {
                let mut seen = vec![false; n as usize];
                for i in 0..n {
                    let p = permute(i, n, seed) as usize;
                    assert!(!seen[p], "n={n} seed={seed}: {p} twice");
                    seen[p] = true;
                }
            }
        }
    }

    #[test]
    fn fill_matches_sequential_draws() {
        for n in 1..=FILL_MAX {
            let (mut a, mut b) = (Rng::new(5, n as u32), Rng::new(5, n as u32));
            for _round in 0..3 {
                let mut out = [0u32; FILL_MAX];
                a.fill_u32(&mut out[..n]);
                for (j, &x) in out[..n].iter().enumerate() {
                    assert_eq!(x, b.next_u32(), "n={n} j={j}");
                }
            }
            assert_eq!(a.next_u32(), b.next_u32());
        }
    }

    #[test]
    fn unit_floats_in_range() {
        let mut r = Rng::new(7, 3);
        let mut mean = 0.0f64;
        for _ in 0..100_000 {
            let x = r.next_f32();
            assert!((0.0..1.0).contains(&x));
            mean += x as f64;
        }
        assert!((mean / 1e5 - 0.5).abs() < 0.005);
    }
}
