//! # glint-tests: brute-force checkers shared by `cargo test` and `cargo xtask validate`
//!
//! Invariant: **everything here checks glint against definitions, never against itself.** A
//! conic is checked through [`SphericalConic::contains_by_reflection`] (Eq. 7 evaluated
//! literally); triangles through sampled points; areas through Monte Carlo estimates. The
//! integration tests (`tests/integration.rs`) run these checkers at a size that fits in
//! `cargo test`; `cargo xtask validate` runs the same code on 10⁶ and more cases.
//!
//! Random cases are built from plain uniform numbers (`[f64; N]` in [0, 1)) so that proptest
//! strategies and the deterministic [`SplitMix64`] stream share one generator.
#![deny(missing_docs)]

#[cfg(feature = "checkers")]
pub mod counts;
#[cfg(feature = "checkers")]
pub mod dense;
pub mod geometry;
pub mod light_cones;
#[cfg(feature = "checkers")]
pub mod maps;
pub mod mirror_check;
#[cfg(feature = "checkers")]
pub mod sampling;

/// SplitMix64 (Steele, Lea and Flood 2014): a tiny, seedable generator of uniform numbers for
/// deterministic validation runs. Not for rendering (glint-tree has its own TEA streams).
#[derive(Clone, Debug)]
pub struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    /// A stream starting from `seed`.
    #[must_use]
    pub fn new(seed: u64) -> Self {
        Self { state: seed }
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A uniform number in [0, 1) with 53 random bits.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// `N` uniform numbers in [0, 1).
    pub fn uniforms<const N: usize>(&mut self) -> [f64; N] {
        std::array::from_fn(|_| self.uniform())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splitmix_is_pinned_and_uniform() {
        // Reference values of SplitMix64 from seed 0.
        let mut rng = SplitMix64::new(0);
        assert_eq!(rng.next_u64(), 0xE220_A839_7B1D_CDAF);
        assert_eq!(rng.next_u64(), 0x6E78_9E6A_A1B9_65F4);
        let mut rng = SplitMix64::new(7);
        let n = 100_000;
        let mean = (0..n).map(|_| rng.uniform()).sum::<f64>() / f64::from(n);
        // Standard error 1/sqrt(12 n) ≈ 9e-4; 5 sigma.
        assert!((mean - 0.5).abs() < 5.0 * 9.2e-4, "{mean}");
    }
}
