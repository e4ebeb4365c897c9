//! # glint-benches: the case pools the criterion benchmarks run on
//!
//! Invariant: **benchmarks measure the public APIs on fixed, seeded inputs**, so figures from
//! two runs (or two machines) time the same work. `cargo xtask bench` runs them and writes the
//! summary table that the README quotes.
#![deny(missing_docs)]

use glint_sphere::{Classification, SphericalConic, SphericalTriangle};
use glint_tests::SplitMix64;
use glint_tests::geometry::ConicCase;

/// `n` random cases of every kind the validation draws (extremes included).
#[must_use]
pub fn mixed_cases(n: usize, seed: u64) -> Vec<ConicCase> {
    let mut rng = SplitMix64::new(seed);
    (0..n)
        .map(|_| ConicCase::from_uniforms(&rng.uniforms()))
        .collect()
}

/// `n` cases the count tree meets in practice: a conic and a subdivided octant triangle at
/// depth 2..=8 (edges of 0.4 to 0.006 rad), reached by descending towards the conic, so that
/// the answers mix disjoint, inside and partial.
#[must_use]
pub fn tree_cases(n: usize, seed: u64) -> Vec<(SphericalConic, SphericalTriangle)> {
    let mut rng = SplitMix64::new(seed);
    let mut cases = Vec::with_capacity(n);
    while cases.len() < n {
        let conic = ConicCase::from_uniforms(&rng.uniforms()).conic;
        let depth = 2 + (rng.uniform() * 7.0) as usize;
        let mut triangle =
            SphericalTriangle::upper_hemisphere_octants()[(rng.uniform() * 4.0) as usize];
        for _ in 0..depth {
            let children = triangle.subdivide();
            // Prefer a child that is not disjoint, as the tree's traversal does.
            let start = (rng.uniform() * 4.0) as usize;
            triangle = (0..4)
                .map(|k| children[(start + k) % 4])
                .find(|c| conic.classify(c) != Classification::Disjoint)
                .unwrap_or(children[start]);
        }
        cases.push((conic, triangle));
    }
    cases
}

/// `n` tree cases whose classification is partial: the inputs of an overlap computation.
#[must_use]
pub fn partial_tree_cases(n: usize, seed: u64) -> Vec<(SphericalConic, SphericalTriangle)> {
    let mut out = Vec::with_capacity(n);
    let mut round = seed;
    while out.len() < n {
        out.extend(
            tree_cases(n, round)
                .into_iter()
                .filter(|(c, t)| c.classify(t) == Classification::Partial),
        );
        round += 1;
    }
    out.truncate(n);
    out
}
