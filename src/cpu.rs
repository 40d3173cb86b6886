//! Which CPU the hot loops run on. The per-pixel shading and the per-frame build each have a
//! copy compiled for AVX2 + FMA beside the baseline one; both round identically (Rust never fuses
//! a multiply and an add on its own), so results do not depend on the CPU.

/// AVX2 + FMA present and `ENVIS_PORTABLE` unset (decided once per process): run the AVX2
/// copies. `ENVIS_PORTABLE=1` forces the baseline ones (for comparisons).
#[inline]
pub fn avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
        *ON.get_or_init(|| {
            std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
                && std::env::var_os("ENVIS_PORTABLE").is_none()
        })
    }
    #[cfg(not(target_arch = "x86_64"))]
    false
}
