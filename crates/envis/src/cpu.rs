//! Which CPU the hot loops run on. The per-pixel shading has copies compiled for AVX2 + FMA and
//! for AVX-512 beside the baseline one, the per-frame build an AVX2 copy; all round identically
//! (Rust never fuses a multiply and an add on its own), so results do not depend on the CPU.
//!
//! Why an AVX-512 copy: the BRDF samples run in structure-of-arrays chunks of
//! [`crate::sampling::LANES`] = 16 `f32`s, one 512-bit register. On an AVX-512 CPU Mitsuba 3's
//! LLVM back end JIT-compiles 16 wide, so without it the speed comparisons in `docs/` would
//! set envis's 8-wide code against Mitsuba's 16-wide.

/// The instruction sets the shading has a copy for, in increasing order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Isa {
    /// The baseline target (SSE2 on x86-64).
    Portable,
    /// AVX2 + FMA (FMA only as a feature: nothing is fused).
    Avx2,
    /// AVX-512 F, VL, BW and DQ, with AVX2 + FMA.
    Avx512,
}

impl Isa {
    /// Every copy this CPU can run, from the baseline up (for tests that compare them).
    pub fn available() -> Vec<Isa> {
        [Isa::Portable, Isa::Avx2, Isa::Avx512]
            .into_iter()
            .filter(|&i| i <= detected())
            .collect()
    }

    fn parse(s: &str) -> Option<Isa> {
        match s {
            "portable" => Some(Isa::Portable),
            "avx2" => Some(Isa::Avx2),
            "avx512" => Some(Isa::Avx512),
            _ => None,
        }
    }
}

/// The best copy this CPU supports (detected once per process).
pub fn detected() -> Isa {
    static BEST: std::sync::OnceLock<Isa> = std::sync::OnceLock::new();
    *BEST.get_or_init(detect)
}

fn detect() -> Isa {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::is_x86_feature_detected as has;
        let avx2 = has!("avx2") && has!("fma");
        let avx512 = avx2 && has!("avx512f") && has!("avx512vl") && has!("avx512bw");
        if avx512 && has!("avx512dq") {
            Isa::Avx512
        } else if avx2 {
            Isa::Avx2
        } else {
            Isa::Portable
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    Isa::Portable
}

/// The copy the hot loops run (decided once per process): the best the CPU supports, capped by
/// `ENVIS_ISA=portable|avx2|avx512` (for comparisons in one sitting; an unknown value is
/// ignored with a warning, and one above the CPU's is capped to it). `ENVIS_PORTABLE=1` is
/// `ENVIS_ISA=portable`.
pub fn isa() -> Isa {
    static ON: std::sync::OnceLock<Isa> = std::sync::OnceLock::new();
    *ON.get_or_init(|| {
        let cap = if std::env::var_os("ENVIS_PORTABLE").is_some() {
            Isa::Portable
        } else {
            match std::env::var("ENVIS_ISA") {
                Ok(v) => Isa::parse(&v).unwrap_or_else(|| {
                    eprintln!("envis: ENVIS_ISA={v:?} is not portable, avx2 or avx512; ignored");
                    Isa::Avx512
                }),
                Err(_) => Isa::Avx512,
            }
        };
        detected().min(cap)
    })
}

/// AVX2 + FMA present and not capped below them: run the AVX2 copies (the per-frame build's).
#[inline]
pub fn avx2_fma() -> bool {
    isa() >= Isa::Avx2
}
