//! The simulator's random numbers: SplitMix64 (a generator fixed by its
//! definition, so the output depends only on the seed, never on a library's
//! version), with the draws the simulator makes.

use rand_core::{Rng as _, SeedableRng};
use rand_xoshiro::SplitMix64;

pub struct Rng(SplitMix64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(SplitMix64::seed_from_u64(seed ^ 0x9e37_79b9_7f4a_7c15))
    }

    /// An independent stream for a named purpose, so adding draws in one
    /// place does not change another's.
    pub fn stream(seed: u64, purpose: &str) -> Self {
        let h = purpose.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
            (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3)
        });
        Self::new(seed ^ h)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    /// Standard normal (Box-Muller).
    pub fn normal(&mut self) -> f64 {
        let u = self.uniform().max(1e-300);
        let v = self.uniform();
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// A deterministic hash of integer coordinates to [0, 1), for textures.
pub fn hash3(x: i64, y: i64, z: i64, salt: u64) -> f64 {
    let mut r = Rng::new(
        (x as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
            ^ (y as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f)
            ^ (z as u64).wrapping_mul(0x1656_67b1_9e37_79f9)
            ^ salt,
    );
    r.uniform()
}
