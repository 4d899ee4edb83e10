//! A uniform `f32` strategy that does not go through proptest's float sampler.

use proptest::prelude::*;

/// Uniform `f32` in `[lo, hi)` from 24 random bits. proptest 1.12's own `f32` range
/// sampler can trip its internal assertion `self.low - result < initial.step` on some
/// draws, which aborts the run; integers do not.
pub fn uniform(lo: f32, hi: f32) -> impl Strategy<Value = f32> {
    const STEPS: u32 = 1 << 24;
    (0..STEPS).prop_map(move |i| lo + (hi - lo) * (i as f32 / STEPS as f32))
}
