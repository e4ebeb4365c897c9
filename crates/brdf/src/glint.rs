//! The glint BRDF at a shading point: a material bound to a footprint and a scratch
//! ([`DiscreteBrdf::at`]), implementing [`Bxdf`] with the discrete model: `eval` is f̂ of
//! Eq. 5 from one tree query (Eq. 6), `sample` the glint sampler of Sec. 3.4 weighed with f̂,
//! `pdf` the sampler's density.

use std::cell::RefCell;

use glam::DVec3;
use glint_tree::{Footprint, QueryScratch};

use crate::bxdf::{Bxdf, BxdfSample};
use crate::discrete::DiscreteBrdf;

/// One glint evaluation with what its tree query found (the statistics of the paper's
/// Table 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GlintEvaluation {
    /// f̂ per RGB channel (the corrected Eq. 5).
    pub f_hat: DVec3,
    /// D̂ of Eq. 6 per channel: the particles' share of the N per unit square that the query
    /// found (with coloured particles, their Dirichlet areas per channel).
    pub d_hat: DVec3,
    /// Particles found (fractional where Eq. 10 stopped early and added an expected share).
    pub count: f64,
    /// Tree nodes visited (tested against the query).
    pub nodes_visited: u32,
    /// The visited nodes that meet the query.
    pub nodes_overlapping: u32,
    /// `Some(λ̄)` when the query was skipped as negligible: the bound on its expected count
    /// (below the material's `negligible_count`); `None` when the tree was traversed.
    pub negligible: Option<f64>,
}

impl GlintEvaluation {
    /// The evaluation of directions that admit no query (below the horizon, not finite).
    const NONE: Self = Self {
        f_hat: DVec3::ZERO,
        d_hat: DVec3::ZERO,
        count: 0.0,
        nodes_visited: 0,
        nodes_overlapping: 0,
        negligible: None,
    };
}

/// A glint material at one shading point: see [`DiscreteBrdf::at`].
///
/// The scratch is borrowed mutably for the value's lifetime and used by each query, so one
/// `GlintBxdf` serves one thread (build one per shading point; it costs nothing).
#[derive(Debug)]
pub struct GlintBxdf<'a> {
    brdf: &'a DiscreteBrdf,
    footprint: &'a Footprint,
    scratch: RefCell<&'a mut QueryScratch>,
}

impl<'a> GlintBxdf<'a> {
    pub(crate) fn new(
        brdf: &'a DiscreteBrdf,
        footprint: &'a Footprint,
        scratch: &'a mut QueryScratch,
    ) -> Self {
        Self {
            brdf,
            footprint,
            scratch: RefCell::new(scratch),
        }
    }

    /// The material.
    #[must_use]
    pub fn material(&self) -> &'a DiscreteBrdf {
        self.brdf
    }

    /// The footprint.
    #[must_use]
    pub fn footprint(&self) -> &'a Footprint {
        self.footprint
    }

    /// f̂ with what its query found: the work of [`Bxdf::eval`], which returns only `f_hat`.
    /// Directions not above the horizon (or not finite) give zeros.
    #[must_use]
    pub fn evaluate(&self, wi: DVec3, wo: DVec3) -> GlintEvaluation {
        let mut scratch = self.scratch.borrow_mut();
        match self.brdf.query(wi, wo, self.footprint, &mut scratch) {
            Some(query) => GlintEvaluation {
                f_hat: query.f_hat,
                d_hat: DVec3::from_array(query.result.d_hat),
                count: query.result.count,
                nodes_visited: query.result.nodes_visited,
                nodes_overlapping: query.result.nodes_overlapping,
                negligible: query.negligible,
            },
            None => GlintEvaluation::NONE,
        }
    }

    /// The expected count N·a(A)·∫_{Ω_h} p(m) dm of the query (ω_i, ω_o), from the tree's NDF
    /// quadrature (Alg. 2): what the count of [`GlintBxdf::evaluate`] averages to over particle
    /// sets. It costs a traversal of its own; 0 for directions that admit no query.
    #[must_use]
    pub fn expected_count(&self, wi: DVec3, wo: DVec3) -> f64 {
        let Some(conic) = self.brdf.conic(wi, wo) else {
            return 0.0;
        };
        let mut scratch = self.scratch.borrow_mut();
        self.brdf
            .tree()
            .expected_count(self.footprint, &conic, &mut scratch)
    }

    /// λ̄, the negligible-query test's upper bound on the expected count of the tree's
    /// particles for (ω_i, ω_o) (see the `negligible` module of this crate). Infinite when the
    /// material skips nothing (`negligible_count` = 0) or the conic is hyperbolic; 0 for
    /// directions that admit no query.
    #[must_use]
    pub fn expected_count_bound(&self, wi: DVec3, wo: DVec3) -> f64 {
        self.brdf.conic(wi, wo).map_or(0.0, |conic| {
            self.brdf.expected_count_bound(self.footprint, &conic)
        })
    }
}

impl Bxdf for GlintBxdf<'_> {
    /// Four numbers: two choose the cone's centre from the widened smooth model, two the
    /// direction in the cone (Sec. 3.4).
    type Uniforms = [f64; 4];

    /// f̂ (Eq. 5): one tree query.
    fn eval(&self, wi: DVec3, wo: DVec3) -> DVec3 {
        self.evaluate(wi, wo).f_hat
    }

    /// ω_o from the glint sampler ([`DiscreteBrdf::sample_direction`]), weighed with f̂: the
    /// weight f̂·cos θ_o / pdf is the estimate of reflected radiance for unit radiance from ω_o.
    fn sample(&self, wi: DVec3, u: [f64; 4]) -> Option<BxdfSample> {
        let wo = self.brdf.sample_direction(wi, u)?;
        BxdfSample::weighted(wo, self.eval(wi, wo), self.pdf(wi, wo))
    }

    /// The glint sampler's density ([`DiscreteBrdf::sampling_pdf`]).
    fn pdf(&self, wi: DVec3, wo: DVec3) -> f64 {
        self.brdf.sampling_pdf(wi, wo)
    }
}
