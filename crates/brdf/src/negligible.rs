//! Negligible queries (an approximation, off by default).
//!
//! Far from a highlight a query expects almost nothing, yet the tree must split until the
//! nodes meeting it are empty or disjoint. With `negligible_count` = τ > 0 a query is answered
//! 0 without a traversal when a cheap upper bound λ̄ on its expected count is below τ. A count
//! is a non-negative integer with mean λ ≤ λ̄, so P(count ≥ 1) ≤ λ (Markov): the skipped query
//! differs from its traversal with probability below τ, and a render of Q queries differs from
//! the exact one anywhere with probability at most Σλ̄ < Q·τ (the tracer reports Σλ̄).
//!
//! The bound, for an elliptic conic (hyperbolic ones are always traversed): the valid set lies
//! in the cap of radius θ_max around its axis ([`SphericalConic::bounding_cap`]), of solid angle
//! σ_cap = 2π(1 − cos θ_max). The count is of the tree's particles, whose normals do not follow
//! p exactly: a normal descends the directional hierarchy with the split probabilities (Alg. 2's
//! table, the one-point rule elsewhere) to a final cell L of diameter at most [`LEAF_CELL_ARC`]
//! and lands uniformly in it, with density P(L)/σ(L). Where Alg. 2 accepted a cell by δ_abs
//! (the far tails) this can exceed p many times over (~40× for Beckmann α = 0.3 at 45°), so
//! when the test is on, the material enumerates its final cells once per law in a process
//! ([`CountTree::directional_law_excess_with`], with p's symmetry under turns about n, on up to
//! 4 threads: 0.3–6 ms for isotropic laws, about 12 ms for strongly anisotropic GGX, remembered for the 64 latest
//! laws) for W = max_L P(L)/(σ(L)·B_L), B_L the bound of
//! [`Microfacet::particle_density_bound`] over L's circumscribed cap, and M, the mass of the
//! cells where B_L = 0. A final cell meeting the conic's cap lies, with its circumscribed cap,
//! within 2·[`LEAF_CELL_ARC`] of it; with θ_a the axis's angle from n and
//! δ = θ_max + 2·[`LEAF_CELL_ARC`],
//!
//! ```text
//!   λ = N·a(A)·Σ_L P(L)·σ(L ∩ Ω_h)/σ(L)  ≤  λ̄ = N·a(A)·( W·B[θ_a − δ, θ_a + δ]·σ_cap + M ).
//! ```
//!
//! This is exact for ε = 0. With ε > 0 a traversal may also add expected shares where Eq. 10
//! stops early (assuming p uniform over a coarse cell); for a query that finds nothing those
//! are below ε²E² per node, E the tree's own estimate of the expected count.

use std::sync::Mutex;

use glint_sphere::SphericalConic;
use glint_tree::{CountTree, DirectionalLawExcess, LEAF_CELL_ARC, TurnSymmetry};

use crate::distribution::{DistributionKind, Microfacet};

/// A directional law: the distribution's kind, α_x and α_y (as bits) and the tree's Alg. 2
/// tolerances (δ_abs, δ_rel as bits, the deepest table level). W and M depend on nothing else:
/// not on N, the seed, γ, ε or the maps (they describe how normals descend the directional
/// hierarchy, which those do not change).
type LawKey = (DistributionKind, u64, u64, u64, u64, u32);

/// The most laws [`LAW_EXCESSES`] remembers.
const REMEMBERED_LAWS: usize = 64;

/// The law excesses computed in this process, the most recent last: materials of one law
/// (realizations with other seeds, `eval`'s one-query materials, N or γ varied) enumerate the
/// final cells once (0.3–12 ms), and every later build reads W and M here, bit for bit what
/// the enumeration gives (it is deterministic).
static LAW_EXCESSES: Mutex<Vec<(LawKey, DirectionalLawExcess)>> = Mutex::new(Vec::new());

/// W and M of `tree`'s particles, whose normals follow `distribution`'s p: remembered by law.
fn law_excess(tree: &CountTree, distribution: Microfacet) -> DirectionalLawExcess {
    let (alpha_x, alpha_y) = distribution.alpha();
    let tolerance = tree.config().quadrature;
    let key: LawKey = (
        distribution.kind(),
        alpha_x.to_bits(),
        alpha_y.to_bits(),
        tolerance.absolute.to_bits(),
        tolerance.relative.to_bits(),
        tolerance.max_depth,
    );
    let remembered = |memo: &Vec<(LawKey, DirectionalLawExcess)>| {
        memo.iter()
            .find(|(k, _)| *k == key)
            .map(|(_, excess)| *excess)
    };
    // A panic elsewhere while the lock was held leaves the memo as valid as before.
    let lock = || LAW_EXCESSES.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(excess) = remembered(&lock()) {
        return excess;
    }
    // Computed without the lock: two threads may both compute a new law, to the same values.
    let bound = |near, far| distribution.particle_density_bound(near, far);
    // Every kind's p reads m_x and m_y only through their squares, so a half turn about n
    // leaves it unchanged bit for bit, and a quarter turn too where α_x = α_y (the contract of
    // `distribution.rs`, tested for every kind).
    let symmetry = if alpha_x == alpha_y {
        TurnSymmetry::QuarterTurn
    } else {
        TurnSymmetry::HalfTurn
    };
    let excess = tree.directional_law_excess_with(&bound, symmetry);
    let mut memo = lock();
    if remembered(&memo).is_none() {
        if memo.len() == REMEMBERED_LAWS {
            memo.remove(0);
        }
        memo.push((key, excess));
    }
    excess
}

/// The per-material constants of the bound λ̄, computed once.
#[derive(Clone, Copy, Debug)]
pub(crate) struct NegligibleTest {
    /// How far the tree's directional law exceeds p.
    law_excess: DirectionalLawExcess,
    /// cos and sin of the widening 2·[`LEAF_CELL_ARC`].
    widening_cos: f64,
    widening_sin: f64,
}

impl NegligibleTest {
    /// The constants for the particles of `tree`, whose normals follow `distribution`'s p.
    pub(crate) fn new(tree: &CountTree, distribution: Microfacet) -> Self {
        let (widening_sin, widening_cos) = (2.0 * LEAF_CELL_ARC).sin_cos();
        Self {
            law_excess: law_excess(tree, distribution),
            widening_cos,
            widening_sin,
        }
    }

    /// The constants W and M of the bound (module docs).
    pub(crate) fn law_excess(&self) -> DirectionalLawExcess {
        self.law_excess
    }

    /// λ̄ for a footprint of `area` holding N = `particles` per unit square: a few
    /// multiplications, a square root and an exponential. Infinite for hyperbolic conics (no
    /// cap holds them).
    pub(crate) fn bound(
        &self,
        distribution: &Microfacet,
        particles: u64,
        area: f64,
        conic: &SphericalConic,
    ) -> f64 {
        let Some((axis, cap_cos, cap_sin)) = conic.bounding_cap() else {
            return f64::INFINITY;
        };
        // δ = θ_max + 2·LEAF_CELL_ARC by the angle-sum formulas.
        let (arc_cos, arc_sin) = (self.widening_cos, self.widening_sin);
        let (delta_cos, delta_sin) = (
            cap_cos * arc_cos - cap_sin * arc_sin,
            cap_sin * arc_cos + cap_cos * arc_sin,
        );
        let (axis_cos, axis_sin) = (axis.z, (1.0 - axis.z * axis.z).max(0.0).sqrt());
        let cos_near = if axis_cos >= delta_cos {
            1.0
        } else {
            axis_cos * delta_cos + axis_sin * delta_sin
        };
        let cos_far = axis_cos * delta_cos - axis_sin * delta_sin;
        let density = distribution.particle_density_bound(cos_near, cos_far);
        // 2π(1 − cos θ_max), written without cancellation for tiny caps.
        let cap_solid_angle = 2.0 * std::f64::consts::PI * cap_sin * cap_sin / (1.0 + cap_cos);
        let bound = particles as f64
            * area
            * (self.law_excess.ratio * density * cap_solid_angle + self.law_excess.unbounded_mass);
        if bound.is_nan() { f64::INFINITY } else { bound }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{DiscreteBrdf, GlintParameters};

    /// Materials of one law (other seeds, N, γ, ε) read the remembered W and M, which are the
    /// enumeration's, bit for bit; another α is another law.
    #[test]
    fn the_law_excess_is_remembered_by_law() {
        let distribution = Microfacet::new(DistributionKind::Ggx, 0.137, 0.211).unwrap();
        let material = |seed: u64, particles: u64, gamma_degrees: f64| {
            let mut parameters = GlintParameters::new(distribution);
            parameters.seed = seed;
            parameters.particles = particles;
            parameters.gamma_radians = gamma_degrees.to_radians();
            parameters.negligible_count = 1e-12;
            DiscreteBrdf::new(parameters).unwrap()
        };
        let first = material(1, 1_000_000, 1.0);
        let fresh = first
            .tree()
            .directional_law_excess(&|near, far| distribution.particle_density_bound(near, far));
        for other in [material(2, 1_000_000, 1.0), material(3, 1 << 40, 4.0)] {
            let (a, b) = (first.negligible_test(), other.negligible_test());
            assert_eq!(a.map(|c| c.law_excess_ratio), b.map(|c| c.law_excess_ratio));
            assert_eq!(a.map(|c| c.unbounded_mass), b.map(|c| c.unbounded_mass));
        }
        let constants = first.negligible_test().unwrap();
        assert_eq!(constants.law_excess_ratio.to_bits(), fresh.ratio.to_bits());
        assert_eq!(
            constants.unbounded_mass.to_bits(),
            fresh.unbounded_mass.to_bits()
        );
        let rougher = Microfacet::new(DistributionKind::Ggx, 0.3, 0.211).unwrap();
        let mut parameters = GlintParameters::new(rougher);
        parameters.negligible_count = 1e-12;
        let other_law = DiscreteBrdf::new(parameters).unwrap();
        assert_ne!(
            other_law.negligible_test().unwrap().law_excess_ratio,
            constants.law_excess_ratio
        );
    }
}
