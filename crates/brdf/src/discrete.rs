//! The discrete multiscale BRDF (Eq. 5) and its importance sampling (Sec. 3.4).
//!
//! # Normalization (the corrected Eq. 5)
//! A particle is a mirror facet with position uniform in the texture square and normal m with
//! density p(m) = D(m)(m·n). For a footprint of area a(A) and the conic Ω_h of normals that
//! reflect ω_i into the cone Ω_o of radius γ around ω_o, the count has mean
//!
//! ```text
//!   E[count] = N · a(A) · ∫_{Ω_h} D(m)(m·n) dm,      D̂ = count / N  (Eq. 6).
//! ```
//!
//! The half-vector map ω ↦ h(ω) = (ω_i + ω)/|ω_i + ω| has Jacobian dm/dω = 1/(4 ω_i·h), so
//!
//! ```text
//!   ∫_{Ω_h} D(m)(m·n) dm = ∫_{Ω_o} D(h(ω)) (h(ω)·n) / (4 ω_i·h(ω)) dω.
//! ```
//!
//! The smooth BRDF convolved with the normalized cone kernel is
//! f̄ = (1/σ(Ω_o)) ∫_{Ω_o} F D G / (4 cos θ_i cos θ) dω, σ(Ω_o) = 2π(1 − cos γ) = 4π sin²(γ/2)
//! (the paper prints π(1 − cos γ), half the solid angle of the cone). Holding F, G, cos θ_o and
//! the ratio (ω_i·h)/(h·n) at the cone's centre (the approximation the paper makes to go from
//! Eq. 4 to Eq. 5), matching E[f̂] = f̄ requires
//!
//! ```text
//!   f̂(A, ω_i, Ω_o) = F(ω_i·h) G(ω_i, ω_o, h) (ω_i·h) D̂ / (a(A) σ(Ω_o) (h·n) cos θ_i cos θ_o),
//! ```
//!
//! which differs from the printed Eq. 5 by the factor 1/(h·n) (the particle density carries
//! m·n) and by σ(Ω_o) = 2π(1 − cos γ). As N → ∞ (or with many particles per query) f̂ tends to
//! the smooth BRDF convolved with the cone; `cargo test` and `cargo xtask validate` check the
//! mean over footprint positions against the smooth BRDF.
//!
//! # Negligible queries (an approximation, off by default)
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
//! (the far tails) this can exceed p many times over (~40× measured for Beckmann α = 0.3 at
//! 45°), so when the test is on, the material enumerates its final cells once
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
//!
//! # Without a footprint
//! Paths after the first bounce carry no ray differentials; there (as in the paper) the BRDF
//! is the smooth model of the same material: [`DiscreteBrdf::eval_at`] with `None`, and the
//! [`Bxdf`] implementation.
//!
//! # Importance sampling (Sec. 3.4)
//! Sample the smooth model with widened roughness α_s = scale·α (2 by default), reflecting ω_i
//! about the sampled normal to ω′, then ω_o uniformly in the cone of radius γ around ω′. The
//! density is p_s convolved with the cone, (1/σ(Ω_o)) ∫_{cone(ω_o)} p_s(ω′) dω′, evaluated by
//! quasi-Monte Carlo over the first `pdf_points` points of a (0, 2)-sequence (64 by default)
//! mapped area-uniformly onto the cone.

use glam::DVec3;
use glint_sphere::{ConeRadius, SphericalConic};
use glint_tree::{
    CountTree, CountTreeConfig, DirectionalLawExcess, Footprint, LEAF_CELL_ARC, MultinomialMode,
    QueryResult, QueryScratch, expected_conic_solid_angle,
};

use crate::distribution::{Microfacet, NormalSampling};
use crate::error::BrdfError;
use crate::fresnel::Fresnel;
use crate::qmc::zero_two_point;
use crate::smooth::{Bxdf, BxdfSample, MicrofacetBrdf, above_horizon};

/// The parameters of a glint material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GlintParameters {
    /// D and its roughness (α_x, α_y).
    pub distribution: Microfacet,
    /// N, particles per unit texture square.
    pub particles: u64,
    /// The cone radius γ in radians, in (0, 60°].
    pub gamma: f64,
    /// ε of Eq. 10 (0 = exact).
    pub epsilon: f64,
    /// The material seed.
    pub seed: u64,
    /// The Fresnel term.
    pub fresnel: Fresnel,
    /// Exact multinomial splits or the paper's normal approximation.
    pub multinomial: MultinomialMode,
    /// 0: each particle weighs 1/N; 3: per-channel Dirichlet particle areas (coloured glints,
    /// Fig. 8).
    pub colour_channels: usize,
    /// α_s / α of the sampling distribution (the paper: 2).
    pub sampling_scale: f64,
    /// QMC points of the sampling pdf (the paper: 64).
    pub pdf_points: usize,
    /// The expected footprint area for Eq. 11 (texture units).
    pub expected_footprint_area: f64,
    /// Queries whose expected count is provably below this are answered 0 without a tree
    /// traversal (see "Negligible queries" in the module docs); 0 disables the test.
    pub negligible_count: f64,
}

impl GlintParameters {
    /// The paper's defaults around a distribution: N = 10⁶, γ = 1°, ε = 0.1, seed 0, F = 1,
    /// exact multinomials, no colour, α_s = 2α, 64 pdf points, footprints of 10⁻⁶, every
    /// query traversed (no negligible-query test).
    #[must_use]
    pub fn new(distribution: Microfacet) -> Self {
        Self {
            distribution,
            particles: 1_000_000,
            gamma: 1f64.to_radians(),
            epsilon: 0.1,
            seed: 0,
            fresnel: Fresnel::None,
            multinomial: MultinomialMode::Exact,
            colour_channels: 0,
            sampling_scale: 2.0,
            pdf_points: 64,
            expected_footprint_area: 1e-6,
            negligible_count: 0.0,
        }
    }
}

/// One evaluation of the discrete BRDF with everything it found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GlintEvaluation {
    /// f̂ per RGB channel (the corrected Eq. 5).
    pub f_hat: DVec3,
    /// The smooth BRDF f at (ω_i, ω_o).
    pub f_smooth: DVec3,
    /// Particles found (possibly fractional).
    pub count: f64,
    /// N·a(A)·∫p over the conic: the expected count.
    pub expected_count: f64,
    /// D̂ of Eq. 6 per channel.
    pub d_hat: DVec3,
    /// Tree nodes visited (tested against the query).
    pub nodes_visited: u32,
    /// The visited nodes that meet the query.
    pub nodes_overlapping: u32,
    /// `Some(λ̄)` when the query was skipped as negligible: the bound on its expected count
    /// (below `negligible_count`); `None` when the tree was traversed.
    pub negligible: Option<f64>,
}

/// f̂ for one footprint with the size of its tree query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FootprintEvaluation {
    /// f̂ per RGB channel (the corrected Eq. 5).
    pub f_hat: DVec3,
    /// Particles found (possibly fractional).
    pub count: f64,
    /// Tree nodes visited (tested against the query).
    pub nodes_visited: u32,
    /// The visited nodes that meet the query.
    pub nodes_overlapping: u32,
    /// `Some(λ̄)` when the query was skipped as negligible (see [`GlintEvaluation::negligible`]).
    pub negligible: Option<f64>,
}

/// One tree query with the unit directions and conic it was made for.
struct ConicQuery {
    wi: DVec3,
    wo: DVec3,
    conic: SphericalConic,
    result: QueryResult,
    f_hat: DVec3,
    /// `Some(λ̄)` when the traversal was skipped as negligible.
    negligible: Option<f64>,
}

/// The discrete stochastic microfacet BRDF of a material.
#[derive(Clone, Debug)]
pub struct DiscreteBrdf {
    parameters: GlintParameters,
    tree: CountTree,
    smooth: MicrofacetBrdf,
    sampler: MicrofacetBrdf,
    cone_solid_angle: f64,
    /// The pdf's QMC points in the cone's own frame (axis +z), computed once.
    cone_points: Vec<DVec3>,
    /// γ with its trigonometry, so that building a query's conic needs none.
    cone: ConeRadius,
    /// What the negligible-query test needs (only when queries may be skipped).
    negligible_test: Option<NegligibleTest>,
}

/// The per-material constants of the negligible-query bound, computed once.
#[derive(Clone, Copy, Debug)]
struct NegligibleTest {
    /// How far the tree's directional law exceeds p.
    law_excess: DirectionalLawExcess,
    /// cos and sin of the widening 2·[`LEAF_CELL_ARC`].
    widening_cos: f64,
    widening_sin: f64,
}

impl DiscreteBrdf {
    /// Builds the material: validates the parameters and builds its count tree.
    ///
    /// # Errors
    /// A [`BrdfError`] naming the invalid parameter.
    pub fn new(parameters: GlintParameters) -> Result<Self, BrdfError> {
        let gamma = parameters.gamma;
        if !(gamma > 0.0 && gamma <= 60f64.to_radians()) {
            return Err(BrdfError::InvalidConeRadius { gamma });
        }
        if !(parameters.sampling_scale >= 1.0 && parameters.sampling_scale.is_finite()) {
            return Err(BrdfError::InvalidSamplingScale {
                scale: parameters.sampling_scale,
            });
        }
        if !(parameters.negligible_count >= 0.0 && parameters.negligible_count.is_finite()) {
            return Err(BrdfError::InvalidNegligibleCount {
                count: parameters.negligible_count,
            });
        }
        if !(1..=4096).contains(&parameters.pdf_points) {
            return Err(BrdfError::InvalidPdfPoints {
                points: parameters.pdf_points,
            });
        }
        let smooth = MicrofacetBrdf::new(
            parameters.distribution,
            parameters.fresnel,
            NormalSampling::Distribution,
        )?;
        let sampler = MicrofacetBrdf::new(
            parameters.distribution.scaled(parameters.sampling_scale),
            Fresnel::None,
            NormalSampling::Distribution,
        )?;
        let distribution = parameters.distribution;
        let config = CountTreeConfig {
            particles: parameters.particles,
            seed: parameters.seed,
            epsilon: parameters.epsilon,
            multinomial: parameters.multinomial,
            expected_query_area: parameters.expected_footprint_area,
            expected_query_solid_angle: expected_conic_solid_angle(gamma),
            colour_channels: parameters.colour_channels,
            ..CountTreeConfig::default()
        };
        let tree = CountTree::new(
            config,
            std::sync::Arc::new(move |m: DVec3| distribution.particle_density(m)),
        )?;
        let cone_points = (0..parameters.pdf_points)
            .map(|i| {
                let [a, b] = zero_two_point(i as u32);
                uniform_in_cone(DVec3::Z, gamma, a, b)
            })
            .collect();
        let negligible_test = (parameters.negligible_count > 0.0).then(|| {
            let d = parameters.distribution;
            let (widening_sin, widening_cos) = (2.0 * LEAF_CELL_ARC).sin_cos();
            NegligibleTest {
                law_excess: tree
                    .directional_law_excess(&|near, far| d.particle_density_bound(near, far)),
                widening_cos,
                widening_sin,
            }
        });
        Ok(Self {
            parameters,
            tree,
            smooth,
            sampler,
            cone_solid_angle: 4.0 * std::f64::consts::PI * (0.5 * gamma).sin().powi(2),
            cone_points,
            cone: ConeRadius::new(gamma).map_err(|_| BrdfError::InvalidConeRadius { gamma })?,
            negligible_test,
        })
    }

    /// The parameters.
    #[must_use]
    pub fn parameters(&self) -> &GlintParameters {
        &self.parameters
    }

    /// The smooth BRDF of the same material (the N → ∞ limit, and the fallback).
    #[must_use]
    pub fn smooth(&self) -> &MicrofacetBrdf {
        &self.smooth
    }

    /// The count tree.
    #[must_use]
    pub fn tree(&self) -> &CountTree {
        &self.tree
    }

    /// f̂ with every intermediate quantity, for the footprint `footprint`. Directions that are
    /// not above the horizon (or not finite) give zeros.
    pub fn evaluate(
        &self,
        wi: DVec3,
        wo: DVec3,
        footprint: &Footprint,
        scratch: &mut QueryScratch,
    ) -> GlintEvaluation {
        let Some(query) = self.query(wi, wo, footprint, scratch) else {
            return GlintEvaluation {
                f_hat: DVec3::ZERO,
                f_smooth: DVec3::ZERO,
                count: 0.0,
                expected_count: 0.0,
                d_hat: DVec3::ZERO,
                nodes_visited: 0,
                nodes_overlapping: 0,
                negligible: None,
            };
        };
        GlintEvaluation {
            f_hat: query.f_hat,
            f_smooth: self.smooth.eval(query.wi, query.wo),
            count: query.result.count,
            expected_count: self.tree.expected_count(footprint, &query.conic, scratch),
            d_hat: DVec3::from_array(query.result.d_hat),
            nodes_visited: query.result.nodes_visited,
            nodes_overlapping: query.result.nodes_overlapping,
            negligible: query.negligible,
        }
    }

    /// The tree query of Eq. 6 for (ω_i, ω_o) and f̂ from it (Eq. 5): the work every evaluation
    /// shares. `None` for directions not above the horizon or an invalid conic.
    fn query(
        &self,
        wi: DVec3,
        wo: DVec3,
        footprint: &Footprint,
        scratch: &mut QueryScratch,
    ) -> Option<ConicQuery> {
        if !(above_horizon(wi) && above_horizon(wo)) {
            return None;
        }
        // The conic normalizes and checks the directions; its unit ω_i, ω_o serve Eq. 5 too.
        let conic = SphericalConic::with_cone(wi, wo, &self.cone).ok()?;
        let (wi, wo) = (conic.wi(), conic.wo());
        if self.parameters.negligible_count > 0.0 {
            let bound = self.expected_count_bound(footprint, &conic);
            if bound < self.parameters.negligible_count {
                return Some(ConicQuery {
                    wi,
                    wo,
                    conic,
                    result: QueryResult {
                        count: 0.0,
                        d_hat: [0.0; 3],
                        nodes_visited: 0,
                        nodes_overlapping: 0,
                        truncated: false,
                    },
                    f_hat: DVec3::ZERO,
                    negligible: Some(bound),
                });
            }
        }
        let result = self.tree.query(footprint, &conic, scratch);
        let f_hat =
            self.f_hat_from_d_hat(wi, wo, DVec3::from_array(result.d_hat), footprint.area());
        Some(ConicQuery {
            wi,
            wo,
            conic,
            result,
            f_hat,
            negligible: None,
        })
    }

    /// λ̄, the upper bound on a query's expected count of the tree's particles derived in the
    /// module docs ("Negligible queries"): a few multiplications, a square root and an
    /// exponential. Infinite for hyperbolic conics (no cap holds them) and for materials built
    /// with `negligible_count` = 0 (which never need it).
    #[must_use]
    pub fn expected_count_bound(&self, footprint: &Footprint, conic: &SphericalConic) -> f64 {
        let (Some(test), Some((axis, cap_cos, cap_sin))) =
            (self.negligible_test, conic.bounding_cap())
        else {
            return f64::INFINITY;
        };
        // δ = θ_max + 2·LEAF_CELL_ARC by the angle-sum formulas.
        let (arc_cos, arc_sin) = (test.widening_cos, test.widening_sin);
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
        let density = self
            .smooth
            .distribution()
            .particle_density_bound(cos_near, cos_far);
        // 2π(1 − cos θ_max), written without cancellation for tiny caps.
        let cap_solid_angle = 2.0 * std::f64::consts::PI * cap_sin * cap_sin / (1.0 + cap_cos);
        let bound = self.parameters.particles as f64
            * footprint.area()
            * (test.law_excess.ratio * density * cap_solid_angle + test.law_excess.unbounded_mass);
        if bound.is_nan() { f64::INFINITY } else { bound }
    }

    /// f̂ for a footprint, or the smooth BRDF when there is none (paths after the first bounce).
    /// The renderer's call: one tree query and the factor of Eq. 5, nothing else.
    pub fn eval_at(
        &self,
        wi: DVec3,
        wo: DVec3,
        footprint: Option<&Footprint>,
        scratch: &mut QueryScratch,
    ) -> DVec3 {
        match footprint {
            Some(footprint) => self.eval_footprint(wi, wo, footprint, scratch).f_hat,
            None => self.smooth.eval(wi, wo),
        }
    }

    /// f̂ for a footprint with what its query found (for a renderer's statistics, as in the
    /// paper's Table 1): the work of [`DiscreteBrdf::eval_at`], without the expected count that
    /// [`DiscreteBrdf::evaluate`] adds.
    pub fn eval_footprint(
        &self,
        wi: DVec3,
        wo: DVec3,
        footprint: &Footprint,
        scratch: &mut QueryScratch,
    ) -> FootprintEvaluation {
        match self.query(wi, wo, footprint, scratch) {
            Some(query) => FootprintEvaluation {
                f_hat: query.f_hat,
                count: query.result.count,
                nodes_visited: query.result.nodes_visited,
                nodes_overlapping: query.result.nodes_overlapping,
                negligible: query.negligible,
            },
            None => FootprintEvaluation {
                f_hat: DVec3::ZERO,
                count: 0.0,
                nodes_visited: 0,
                nodes_overlapping: 0,
                negligible: None,
            },
        }
    }

    /// The corrected Eq. 5 for unit directions above the horizon, from a D̂ per channel and the
    /// footprint's area (texture units): what [`DiscreteBrdf::eval_at`] adds to its tree query.
    ///
    /// With s = ω_i + ω_o and h = s/|s|, the factor G·(ω_i·h)/(h·n) equals G·(ω_i·s)/(s·n), and
    /// ω_o·h = ω_i·h for unit directions, so only the Fresnel term needs |s|: this runs on the
    /// renderer's every evaluation that finds particles, and sqrt and division latencies are
    /// most of its cost.
    #[must_use]
    pub fn f_hat_from_d_hat(&self, wi: DVec3, wo: DVec3, d_hat: DVec3, area: f64) -> DVec3 {
        let s = wi + wo;
        let wi_dot_s = wi.dot(s);
        let valid = s.is_finite() && s.z > 0.0 && wi_dot_s > 0.0 && wi.z > 0.0 && wo.z > 0.0;
        if !(valid && area > 0.0) || d_hat == DVec3::ZERO {
            return DVec3::ZERO;
        }
        // G = 1/(1 + Λ(ω_i) + Λ(ω_o)) (χ⁺ holds: ω_i·h = ω_o·h > 0 and both above the horizon).
        let distribution = self.smooth.distribution();
        let one_plus_lambdas = 1.0 + distribution.lambda(wi) + distribution.lambda(wo);
        let scale =
            wi_dot_s / (one_plus_lambdas * area * self.cone_solid_angle * s.z * wi.z * wo.z);
        let fresnel = match self.smooth.fresnel() {
            Fresnel::None => DVec3::ONE,
            fresnel => fresnel.evaluate(wi_dot_s / s.length()),
        };
        fresnel * d_hat * scale
    }
}

impl Bxdf for DiscreteBrdf {
    /// The smooth BRDF: the value without a footprint (see [`DiscreteBrdf::eval_at`]).
    fn eval(&self, wi: DVec3, wo: DVec3) -> DVec3 {
        self.smooth.eval(wi, wo)
    }

    /// ω′ from the widened smooth model with `u`, then ω_o uniform in the cone of radius γ
    /// around ω′ from `u_lobe`, split into two 26-bit uniforms (its even and odd bits). The
    /// weight is f_smooth·cos θ_o / pdf.
    fn sample(&self, wi: DVec3, u_lobe: f64, u: [f64; 2]) -> Option<BxdfSample> {
        let wo = self.sample_direction(wi, u_lobe, u)?;
        let wi = wi.normalize();
        BxdfSample::weighted(wo, self.smooth.eval(wi, wo), self.pdf(wi, wo))
    }

    /// (1/σ) ∫ over the cone around ω_o of the widened model's density, by QMC.
    fn pdf(&self, wi: DVec3, wo: DVec3) -> f64 {
        if !(above_horizon(wi) && above_horizon(wo)) {
            return 0.0;
        }
        let (wi, wo) = (wi.normalize(), wo.normalize());
        let (t, b) = orthonormal_basis(wo);
        let distribution = self.sampler.distribution();
        let mut sum = 0.0;
        for p in &self.cone_points {
            // The widened model's density at ω′: D_s(h)(h·n)/(4 ω_i·h), h = (ω_i + ω′)/|·|.
            let w = p.x * t + p.y * b + p.z * wo;
            if w.z <= 0.0 {
                continue;
            }
            let h = (wi + w).normalize();
            let cos = wi.dot(h);
            if cos > 0.0 {
                sum += distribution.d(h) * h.z / (4.0 * cos);
            }
        }
        sum / self.cone_points.len() as f64
    }
}

impl DiscreteBrdf {
    /// The direction of [`Bxdf::sample`] alone: ω′ from the widened smooth model with `u`, then
    /// ω_o uniform in the cone of radius γ around ω′ from `u_lobe`. For a renderer that
    /// evaluates f̂ and the pdf itself (the pdf's QMC convolution is the sampler's main cost).
    #[must_use]
    pub fn sample_direction(&self, wi: DVec3, u_lobe: f64, u: [f64; 2]) -> Option<DVec3> {
        if !above_horizon(wi) {
            return None;
        }
        let wi = wi.normalize();
        let centre = self.sampler.sample_direction(wi, u)?;
        let [a, b] = split_uniform(u_lobe);
        let wo = uniform_in_cone(centre, self.parameters.gamma, a, b);
        above_horizon(wo).then_some(wo)
    }
}

/// Two uniforms from one: the even and the odd bits of its 52-bit mantissa fraction.
fn split_uniform(u: f64) -> [f64; 2] {
    let bits = (u.clamp(0.0, 1.0 - f64::EPSILON) * (1u64 << 52) as f64) as u64;
    let (mut even, mut odd) = (0u64, 0u64);
    for k in 0..26 {
        even |= ((bits >> (2 * k + 1)) & 1) << k;
        odd |= ((bits >> (2 * k)) & 1) << k;
    }
    let scale = 1.0 / (1u64 << 26) as f64;
    // Bit 2k+1 is the more significant of each pair: `even` carries the coarse half.
    [even as f64 * scale, odd as f64 * scale]
}

/// A direction uniform (in solid angle) in the cone of radius γ around unit `axis`:
/// 1 − cos θ = u·(1 − cos γ), written with 2 sin²(γ/2) for tiny γ, φ = 2πv.
#[must_use]
pub fn uniform_in_cone(axis: DVec3, gamma: f64, u: f64, v: f64) -> DVec3 {
    let one_minus_cos = u * 2.0 * (0.5 * gamma).sin().powi(2);
    let sin_theta = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
    let phi = 2.0 * std::f64::consts::PI * v;
    let (t, s) = orthonormal_basis(axis);
    ((1.0 - one_minus_cos) * axis + sin_theta * (phi.cos() * t + phi.sin() * s)).normalize()
}

/// Two unit vectors (t, b) completing unit `axis` to a right-handed orthonormal basis,
/// t × b = axis (Duff et al. 2017, "Building an Orthonormal Basis, Revisited").
#[must_use]
pub fn orthonormal_basis(axis: DVec3) -> (DVec3, DVec3) {
    let sign = 1.0_f64.copysign(axis.z);
    let a = -1.0 / (sign + axis.z);
    let b = axis.x * axis.y * a;
    (
        DVec3::new(1.0 + sign * axis.x * axis.x * a, sign * b, -sign * axis.x),
        DVec3::new(b, sign + axis.y * axis.y * a, -axis.y),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn basis_is_orthonormal_and_right_handed() {
        for n in [
            DVec3::Z,
            -DVec3::Z,
            DVec3::new(0.3, -0.4, 0.866).normalize(),
            DVec3::X,
        ] {
            let (t, b) = orthonormal_basis(n);
            assert!(t.dot(b).abs() < 1e-12 && t.dot(n).abs() < 1e-12 && b.dot(n).abs() < 1e-12);
            assert!((t.length() - 1.0).abs() < 1e-12 && (b.length() - 1.0).abs() < 1e-12);
            assert!((t.cross(b) - n).length() < 1e-12);
        }
    }

    #[test]
    fn eq5_factor_matches_its_textbook_form() {
        // f̂ = F(ω_i·h)·G(ω_i, ω_o, h)·(ω_i·h)·D̂ / (A·σ·(h·n)·(ω_i·n)·(ω_o·n)), h normalized.
        let fresnels = [
            Fresnel::None,
            Fresnel::Dielectric { eta: 1.5 },
            Fresnel::Conductor {
                eta: DVec3::new(0.2, 0.9, 1.1),
                k: DVec3::new(3.9, 2.4, 2.2),
            },
        ];
        let distributions = [
            Microfacet::new(crate::DistributionKind::Beckmann, 0.1, 0.1),
            Microfacet::new(crate::DistributionKind::Beckmann, 0.6, 0.3),
            Microfacet::new(crate::DistributionKind::Ggx, 0.4, 0.4),
        ];
        let directions = [
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::new(0.5, 0.1, 0.86).normalize(),
            DVec3::new(-0.9, 0.3, 0.05).normalize(),
            DVec3::new(0.2, -0.97, 0.1).normalize(),
        ];
        let (area, d_hat) = (3e-6, DVec3::new(2e-6, 1e-6, 5e-7));
        for distribution in distributions {
            let distribution = distribution.expect("valid roughness");
            for fresnel in fresnels {
                let mut parameters = GlintParameters::new(distribution);
                parameters.fresnel = fresnel;
                let brdf = DiscreteBrdf::new(parameters).expect("valid parameters");
                for wi in directions {
                    for wo in directions {
                        let h = (wi + wo).normalize();
                        let g = distribution.g(wi, wo, h);
                        let textbook = fresnel.evaluate(wi.dot(h)) * d_hat * g * wi.dot(h)
                            / (area * brdf.cone_solid_angle * h.z * wi.z * wo.z);
                        let fast = brdf.f_hat_from_d_hat(wi, wo, d_hat, area);
                        assert!(
                            (fast - textbook).length() <= 1e-12 * textbook.length(),
                            "{wi} {wo}: {fast} vs {textbook}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn split_uniform_gives_two_uniforms() {
        let [a, b] = split_uniform(0.75);
        assert!((0.0..1.0).contains(&a) && (0.0..1.0).contains(&b));
        // 0.75 = 0b11 followed by zeros: the two coarsest bits go one to each half.
        assert_eq!([a, b], [0.5, 0.5]);
    }

    #[test]
    fn cone_directions_stay_in_the_cone() {
        let axis = DVec3::new(0.3, -0.2, 0.9).normalize();
        for gamma in [1e-4, 0.1, 1.0] {
            for (u, v) in [(0.0, 0.0), (1.0, 0.3), (0.5, 0.9)] {
                let w = uniform_in_cone(axis, gamma, u, v);
                assert!((w.length() - 1.0).abs() < 1e-12);
                assert!(w.dot(axis) >= gamma.cos() - 1e-12);
            }
        }
    }
}
