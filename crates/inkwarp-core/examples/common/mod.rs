//! What the development examples share.
#![allow(dead_code)]

use inkwarp_core::Sample;

/// A deterministic xorshift generator of numbers in [0, 1).
pub fn rng(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// `count` samples at random positions of a `width × height` grid, each displaced by up to
/// 20 px in both directions.
pub fn random_samples(count: usize, width: usize, height: usize, seed: u64) -> Vec<Sample> {
    let mut rnd = rng(seed);
    (0..count)
        .map(|_| Sample {
            rest: [rnd() * (width - 1) as f64, rnd() * (height - 1) as f64],
            displacement: [rnd() * 40.0 - 20.0, rnd() * 40.0 - 20.0],
        })
        .collect()
}
