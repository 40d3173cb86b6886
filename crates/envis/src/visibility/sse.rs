//! Four-lane SSE arithmetic for the CPU's ray tests ([`super::WideBvh`]'s slab tests, a mesh's
//! triangle packets), named as the scalar code they mirror. SSE2 is part of every x86-64 CPU, so
//! these need no runtime check. Each operation rounds as its scalar `f32` counterpart does
//! (there are no fused multiply-adds here), so a lane gives the scalar code's bits; `max` and
//! `min` are `maxps` / `minps`: `a > b ? a : b`, the scalar walk's own definition.

use glam::Vec3;
use std::arch::x86_64::*;

pub type V = __m128;
/// A vector of four lanes per axis.
pub type V3 = [V; 3];

#[inline(always)]
pub fn load(a: &[f32; 4]) -> V {
    // SAFETY: `a` is four readable f32s; the unaligned load has no alignment need.
    unsafe { _mm_loadu_ps(a.as_ptr()) }
}

#[inline(always)]
pub fn load3(a: &[[f32; 4]; 3]) -> V3 {
    [load(&a[0]), load(&a[1]), load(&a[2])]
}

#[inline(always)]
pub fn store(v: V) -> [f32; 4] {
    let mut out = [0.0f32; 4];
    // SAFETY: `out` is four writable f32s; the unaligned store has no alignment need.
    unsafe { _mm_storeu_ps(out.as_mut_ptr(), v) };
    out
}

#[inline(always)]
pub fn splat(x: f32) -> V {
    unsafe { _mm_set1_ps(x) }
}

#[inline(always)]
pub fn splat3(v: Vec3) -> V3 {
    [splat(v.x), splat(v.y), splat(v.z)]
}

#[inline(always)]
pub fn add(a: V, b: V) -> V {
    unsafe { _mm_add_ps(a, b) }
}

#[inline(always)]
pub fn sub(a: V, b: V) -> V {
    unsafe { _mm_sub_ps(a, b) }
}

#[inline(always)]
pub fn mul(a: V, b: V) -> V {
    unsafe { _mm_mul_ps(a, b) }
}

#[inline(always)]
pub fn div(a: V, b: V) -> V {
    unsafe { _mm_div_ps(a, b) }
}

#[inline(always)]
pub fn max(a: V, b: V) -> V {
    unsafe { _mm_max_ps(a, b) }
}

#[inline(always)]
pub fn min(a: V, b: V) -> V {
    unsafe { _mm_min_ps(a, b) }
}

#[inline(always)]
pub fn abs(a: V) -> V {
    unsafe { _mm_andnot_ps(_mm_set1_ps(-0.0), a) }
}

#[inline(always)]
pub fn sub3(a: V3, b: V3) -> V3 {
    [sub(a[0], b[0]), sub(a[1], b[1]), sub(a[2], b[2])]
}

/// glam's `Vec3::dot`: `(x x' + y y') + z z'`.
#[inline(always)]
pub fn dot(a: V3, b: V3) -> V {
    add(add(mul(a[0], b[0]), mul(a[1], b[1])), mul(a[2], b[2]))
}

/// glam's `Vec3::cross`, term for term.
#[inline(always)]
pub fn cross(a: V3, b: V3) -> V3 {
    [
        sub(mul(a[1], b[2]), mul(b[1], a[2])),
        sub(mul(a[2], b[0]), mul(b[2], a[0])),
        sub(mul(a[0], b[1]), mul(b[0], a[1])),
    ]
}

// Comparisons give all-ones lanes where true; NaNs compare as the scalar operators do.
#[inline(always)]
pub fn ge(a: V, b: V) -> V {
    unsafe { _mm_cmpge_ps(a, b) }
}

#[inline(always)]
pub fn le(a: V, b: V) -> V {
    unsafe { _mm_cmple_ps(a, b) }
}

#[inline(always)]
pub fn gt(a: V, b: V) -> V {
    unsafe { _mm_cmpgt_ps(a, b) }
}

#[inline(always)]
pub fn lt(a: V, b: V) -> V {
    unsafe { _mm_cmplt_ps(a, b) }
}

/// `!(a < b)`: true for NaNs.
#[inline(always)]
pub fn not_lt(a: V, b: V) -> V {
    unsafe { _mm_cmpnlt_ps(a, b) }
}

/// `!(a > b)`: true for NaNs.
#[inline(always)]
pub fn not_gt(a: V, b: V) -> V {
    unsafe { _mm_cmpngt_ps(a, b) }
}

#[inline(always)]
pub fn and(a: V, b: V) -> V {
    unsafe { _mm_and_ps(a, b) }
}

/// Bit `k` set where lane `k` is true.
#[inline(always)]
pub fn mask(a: V) -> u32 {
    (unsafe { _mm_movemask_ps(a) }) as u32
}
