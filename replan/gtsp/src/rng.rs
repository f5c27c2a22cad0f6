//! The solver's random numbers: SplitMix64 (a generator fixed by its
//! definition, so a seed gives the same tours on every build), with the
//! draws the search makes.

use rand_core::{Rng as _, SeedableRng};
use rand_xoshiro::SplitMix64;

#[derive(Debug, Clone)]
pub(crate) struct Rng(SplitMix64);

impl Rng {
    /// An independent stream for sub-task `index` of this seed.
    pub(crate) fn stream(seed: u64, index: u64) -> Rng {
        let mut mix = SplitMix64::seed_from_u64(seed ^ index.wrapping_mul(0xD1B5_4A32_D192_ED03));
        Rng(SplitMix64::seed_from_u64(mix.next_u64()))
    }

    pub(crate) fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// Uniform in [0, 1).
    pub(crate) fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in 0..n (n > 0).
    pub(crate) fn below(&mut self, n: usize) -> usize {
        ((self.next_u64() as u128 * n as u128) >> 64) as usize
    }

    pub(crate) fn shuffle<T>(&mut self, items: &mut [T]) {
        for i in (1..items.len()).rev() {
            items.swap(i, self.below(i + 1));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_splitmix64_as_published() {
        // SplitMix64 from state 0: its first output (Vigna's reference).
        let mut r = Rng(SplitMix64::seed_from_u64(0));
        assert_eq!(r.next_u64(), 0xe220_a839_7b1d_cdaf);
        // A stream: state = first output of SplitMix64(seed ^ index * k).
        let mut mix = SplitMix64::seed_from_u64(7 ^ 3u64.wrapping_mul(0xD1B5_4A32_D192_ED03));
        let state = mix.next_u64();
        let mut expected = SplitMix64::seed_from_u64(state);
        assert_eq!(Rng::stream(7, 3).next_u64(), expected.next_u64());
    }
}
