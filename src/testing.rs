//! Helpers that the unit tests of every module share (compiled for tests only).

/// xorshift64*: deterministic pseudo-random numbers, enough for test samples.
pub(crate) struct Rng(pub(crate) u64);

impl Rng {
    /// A generator from any seed (zero included), the seed scrambled first.
    pub(crate) fn new(seed: u64) -> Rng {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }

    /// Uniform in [0, 1).
    pub(crate) fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [lo, hi).
    pub(crate) fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
}

#[cfg(test)]
mod tests {
    use super::Rng;

    #[test]
    fn samples_are_in_the_unit_interval_and_spread_over_it() {
        let mut rng = Rng::new(0);
        let x: Vec<f64> = (0..10_000).map(|_| rng.next()).collect();
        assert!(x.iter().all(|v| (0.0..1.0).contains(v)));
        let mean = x.iter().sum::<f64>() / x.len() as f64;
        assert!((mean - 0.5).abs() < 0.02, "mean {mean}");
        assert!(x.iter().filter(|&&v| v < 0.1).count() > 800, "the low tenth is under-sampled");
    }
}
