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
//! when the test is on, the material enumerates its final cells once
//! ([`CountTree::directional_law_excess`], 20–40 ms) for W = max_L P(L)/(σ(L)·B_L), B_L the bound
//! of [`Microfacet::particle_density_bound`] over L's circumscribed cap, and M, the mass of the
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

use glint_sphere::SphericalConic;
use glint_tree::{CountTree, DirectionalLawExcess, LEAF_CELL_ARC};

use crate::distribution::Microfacet;

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
            law_excess: tree.directional_law_excess(&|near, far| {
                distribution.particle_density_bound(near, far)
            }),
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
