//! A pixel's window on the light pool: which slots of each region it reads, and in what order
//! ([`PoolLayout`]). The twin of `pool_window` in `shaders/shade.wgsl`.

use super::*;

/// The part of each face's pool one pixel reads: slots `base .. base + len`, in order from
/// `base + start`, wrapping.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PoolWindow {
    pub base: usize,
    pub len: usize,
    pub start: usize,
}

impl PoolWindow {
    /// The window's slots in the order a pixel takes them, wrapping (counts are clamped to the
    /// window, so no slot is taken twice).
    #[inline(always)]
    pub fn slots(self) -> impl Iterator<Item = usize> {
        let mut idx = self.start;
        std::iter::repeat_with(move || {
            let j = self.base + idx;
            // (start + k) mod len, kept in range without a division per sample.
            idx += 1;
            if idx == self.len {
                idx = 0;
            }
            j
        })
    }

    /// Where slot `j` of a region comes in this window's order, or `None` outside the window.
    pub fn position(&self, j: usize) -> Option<usize> {
        let i = j.checked_sub(self.base).filter(|&i| i < self.len)?;
        Some((i + self.len - self.start) % self.len)
    }
}

/// A pixel's window on the pool ([`PoolLayout`]), drawn as the pixel's first random number when
/// the layout draws one: the whole pool from slot 0 (`shared`), from a random slot (`offset`),
/// or one block drawn at random, from its slot 0 (`blocks`). A block is read from its start, as
/// the seed reads its pool: a random start in the block decorrelates more but, measured over 400
/// seeds on the furnace, costs 8% relMSE, as the `offset` layout's random start does
/// (`docs/benchmarks.md`, "Pool layouts").
#[inline(always)]
pub fn pool_window(rng: &mut Rng, s: &Settings, pool: &LightPool) -> PoolWindow {
    let (m, block) = (pool.per_region, pool.block);
    let whole = PoolWindow {
        base: 0,
        len: m,
        start: 0,
    };
    match s.pool_layout {
        _ if m == 0 => whole,
        PoolLayout::Shared => whole,
        PoolLayout::Offset => PoolWindow {
            start: rng.next_u32() as usize % m,
            ..whole
        },
        PoolLayout::Blocks => PoolWindow {
            base: (rng.next_u32() as usize % (m / block)) * block,
            len: block,
            start: 0,
        },
    }
}
