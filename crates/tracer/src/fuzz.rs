//! Test support shared by the tracer's property tests: the proptest configuration (a fixed
//! seed, deterministic) and small fixtures.

use proptest::test_runner::{Config, RngSeed};

/// The proptest configuration of the tracer's property and fuzz tests: `cases` cases from a
/// fixed seed, no regression files. For a longer search, `GLINT_FUZZ_SCALE=k` runs k times the
/// cases and `GLINT_FUZZ_SEED=n` another seed (both deterministic).
pub(crate) fn config(cases: u32) -> Config {
    let from_env = |name: &str| std::env::var(name).ok().and_then(|v| v.parse::<u64>().ok());
    let scale = from_env("GLINT_FUZZ_SCALE").unwrap_or(1).clamp(1, 10_000) as u32;
    Config {
        cases: cases.saturating_mul(scale),
        rng_seed: RngSeed::Fixed(from_env("GLINT_FUZZ_SEED").unwrap_or(0x6c69_6e74)),
        failure_persistence: None,
        max_shrink_iters: 512,
        ..Config::default()
    }
}
