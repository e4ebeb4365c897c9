//! The glint material: the discrete multiscale BRDF of Eq. 5 and its parameters.
//!
//! A [`DiscreteBrdf`] is a material: its parameters, its count tree (the particle set) and its
//! sampler. It is evaluated at a shading point through [`DiscreteBrdf::at`], which binds a
//! footprint and a per-thread scratch into a [`GlintBxdf`] whose [`Bxdf`](crate::Bxdf) methods are the
//! glint model. Its smooth limit is [`DiscreteBrdf::smooth`].
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
//! # Without a footprint
//! Paths after the first bounce carry no ray differentials; there (as in the paper) a renderer
//! uses the smooth model of the same material, [`DiscreteBrdf::smooth`], and may keep the glint
//! sampler ([`DiscreteBrdf::sample_direction`], [`DiscreteBrdf::sampling_pdf`]) so that its
//! sampling does not depend on whether a footprint is known.

use std::sync::Arc;

use glam::{DVec2, DVec3};
use glint_sphere::{ConeRadius, SphericalConic};
use glint_tree::{
    CountTree, CountTreeConfig, DenseCounts, DensityMap, Footprint, LEAF_CELL_ARC, MultinomialMode,
    QueryResult, QueryScratch, expected_conic_solid_angle,
};

use crate::bxdf::{Bxdf, BxdfSample};
use crate::cone::cone_solid_angle;
use crate::distribution::{Microfacet, NormalSampling};
use crate::error::BrdfError;
use crate::fresnel::Fresnel;
use crate::glint::GlintBxdf;
use crate::glint_sampling::{GlintSampler, PdfQuadrature, PdfRule};
use crate::map_budget::MapBytes;
use crate::negligible::NegligibleTest;
use crate::smooth::{MicrofacetBrdf, above_horizon, given};
use crate::surface_maps::{RoughnessLevel, RoughnessMap, TintMap, WeightedTint, roughness_levels};

/// The parameters of a glint material.
///
/// | field | meaning | default ([`GlintParameters::new`]) |
/// |---|---|---|
/// | `distribution` | D and its roughness (α_x, α_y) | — |
/// | `particles` | N, flakes per unit texture square | 10⁶ |
/// | `gamma_radians` | the cone radius γ in radians, in [10⁻⁶, 60°] (C, Python, `eval` and scene files take `gamma_degrees`) | 1° |
/// | `epsilon` | ε of Eq. 10: a partial node whose binomial spread is below ε × the count adds its expected share (0 = off) | 0.1 |
/// | `dense` | how queries expecting many particles are answered: a Poisson process drawn at the query's scale ([`DenseCounts::Lattice`], the exact counts' statistics at a cost that stops growing with N), rescaled samples of dense partial nodes ([`DenseCounts::Sampled`], the same at a bounded cost) or every particle ([`DenseCounts::Exact`]) | lattice, node scale 1 |
/// | `seed` | the particle set | 0 |
/// | `fresnel` | F | none (F = 1) |
/// | `multinomial` | exact splits or the paper's normal approximation | exact |
/// | `colour_channels` | 0, or 3 for Dirichlet-coloured flakes (Fig. 8) | 0 |
/// | `sampling_scale` | α_s/α of the sampler (Sec. 3.4) | 2 |
/// | `pdf_quadrature` | the sampling pdf's rule over narrow cones (wide ones: slope space) | cubature (7 or 32 points) |
/// | `pdf_points` | QMC points of the sampling pdf, when `pdf_quadrature` is QMC | 64 |
/// | `expected_footprint_area` | the footprint area Eq. 11 plans for | 10⁻⁶ |
/// | `negligible_count` | skip queries whose expected count is below this | 0 (off) |
/// | `density_map` | d(x) ∈ [0, 1]: N·d(x) flakes per unit area; 0 masks ([`DensityMap`]) | none (d = 1) |
/// | `alpha_map` | α(x), isotropic, replacing the distribution's ([`RoughnessMap`]) | none |
/// | `tint_map` | t(x) ∈ [0, 1]³ scaling the flakes' reflectance ([`TintMap`]) | none |
/// | `roughness_levels` | K, the most count trees an `alpha_map` gets (exact up to K distinct α) | 8 |
///
/// The maps are described in [`crate::surface_maps`].
#[derive(Clone, Debug, PartialEq)]
pub struct GlintParameters {
    /// D and its roughness (α_x, α_y).
    pub distribution: Microfacet,
    /// N, particles per unit texture square.
    pub particles: u64,
    /// The cone radius γ in radians, in [10⁻⁶, 60°] (`1f64.to_radians()` for 1°).
    pub gamma_radians: f64,
    /// ε of Eq. 10 (0 = off: no partial node is replaced by its expected share).
    pub epsilon: f64,
    /// How queries expecting many particles, and partial nodes at the query's scale that hold
    /// many, are answered (the dense regime of `glint_tree`).
    pub dense: DenseCounts,
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
    /// How the sampling pdf integrates over the cone: cubature rules (default) or the
    /// paper's QMC over `pdf_points` points.
    pub pdf_quadrature: PdfQuadrature,
    /// QMC points of the sampling pdf when `pdf_quadrature` is QMC (the paper: 64).
    pub pdf_points: usize,
    /// The expected footprint area for Eq. 11 (texture units).
    pub expected_footprint_area: f64,
    /// Queries whose expected count is provably below this are answered 0 without a tree
    /// traversal (see the `negligible` module); 0 disables the test.
    pub negligible_count: f64,
    /// The particle density N·d(x) over the square (`None`: d = 1 everywhere).
    pub density_map: Option<Arc<DensityMap>>,
    /// The flakes' roughness α(x), isotropic, in place of the distribution's (α_x, α_y)
    /// (`None`: the distribution's everywhere).
    pub alpha_map: Option<Arc<RoughnessMap>>,
    /// A tint t(x) that scales the flakes' reflectance (`None`: no tint).
    pub tint_map: Option<Arc<TintMap>>,
    /// K: the most roughness levels (count trees) an `alpha_map` gets. Exact where the map
    /// takes at most K distinct values; else levels interpolated in log α.
    pub roughness_levels: usize,
}

impl GlintParameters {
    /// The paper's defaults around a distribution: N = 10⁶, γ = 1°, ε = 0.1, queries expecting
    /// many particles answered by the lattice regime (elsewhere dense nodes from their samples,
    /// node scale 1; Eq. 10 then only for long queries), seed 0, F = 1,
    /// exact multinomials, no colour, α_s = 2α, cubature rules for the sampling pdf
    /// (64 QMC points when switched to QMC), footprints of 10⁻⁶, every
    /// query traversed (no negligible-query test), no maps (8 roughness levels for one).
    #[must_use]
    pub fn new(distribution: Microfacet) -> Self {
        Self {
            distribution,
            particles: 1_000_000,
            gamma_radians: 1f64.to_radians(),
            epsilon: 0.1,
            dense: DenseCounts::DEFAULT,
            seed: 0,
            fresnel: Fresnel::None,
            multinomial: MultinomialMode::Exact,
            colour_channels: 0,
            sampling_scale: 2.0,
            pdf_quadrature: PdfQuadrature::Cubature,
            pdf_points: 64,
            expected_footprint_area: 1e-6,
            negligible_count: 0.0,
            density_map: None,
            alpha_map: None,
            tint_map: None,
            roughness_levels: 8,
        }
    }
}

/// The discrete stochastic microfacet BRDF of a material: its particle set (a count tree per
/// roughness level), its sampler and its smooth limit. Evaluate it at a shading point with
/// [`DiscreteBrdf::at`].
#[derive(Clone, Debug)]
pub struct DiscreteBrdf {
    parameters: GlintParameters,
    /// One per roughness level: a single one without an `alpha_map`.
    layers: Vec<Layer>,
    /// σ(Ω_o) of Eq. 5.
    cone_solid_angle: f64,
    /// γ with its trigonometry, so that building a query's conic needs none.
    cone: ConeRadius,
    /// The tint weighted by the density map, when both are given with one size.
    weighted_tint: Option<WeightedTint>,
}

/// One roughness level of a material: the particles whose normals follow D(α_k), with density
/// N·d_k(x) (see [`crate::surface_maps`]), and what evaluates them.
#[derive(Clone, Debug)]
struct Layer {
    tree: CountTree,
    smooth: MicrofacetBrdf,
    sampler: GlintSampler,
    /// What the negligible-query test needs (only when queries may be skipped).
    negligible_test: Option<NegligibleTest>,
    /// ∫d_k over the square: the level's share of the material's flakes.
    mean_density: f64,
}

impl Layer {
    /// d_k at `uv` (1 without a density map).
    fn density_at(&self, uv: DVec2) -> f64 {
        self.tree.density_map().map_or(1.0, |map| map.value_at(uv))
    }
}

/// What a renderer needs to run the negligible-query test (`crate::negligible`) in its own
/// kernels before asking for f̂, for a material of one roughness level without a density map:
/// the query of (ω_i, ω_o) over a footprint of area a(A) is skipped, f̂ = 0, when
///
/// ```text
///   λ̄ = particles·a(A)·( law_excess_ratio·B[θ_a − δ, θ_a + δ]·σ_cap + unbounded_mass ) < threshold,
/// ```
///
/// with the conic's bounding cap (`glint_sphere::SphericalConic::bounding_cap`: axis h =
/// (ω_i + ω_o)/|ω_i + ω_o|, cos θ_max = √(a² − sin²(γ/2))/a and sin θ_max = sin(γ/2)/a,
/// a = |ω_i + ω_o|/2; always traversed when a² ≤ sin²(γ/2)), σ_cap = 2π sin²θ_max/(1 + cos θ_max),
/// δ = θ_max + `widening_arc`, θ_a the angle of h from the normal, and B
/// [`Microfacet::particle_density_bound`] of the material's distribution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NegligibleTestConstants {
    /// N, particles per unit square.
    pub particles: f64,
    /// τ, the material's `negligible_count`.
    pub threshold: f64,
    /// W: how far the tree's directional law exceeds p.
    pub law_excess_ratio: f64,
    /// M: the mass of the final cells where the bound on p is 0.
    pub unbounded_mass: f64,
    /// 2·LEAF_CELL_ARC (radians): the cap's widening.
    pub widening_arc: f64,
}

/// One tree query (Eq. 6) with f̂ from it (Eq. 5).
pub(crate) struct ConicQuery {
    /// What the tree found (zeros when the query was skipped).
    pub(crate) result: QueryResult,
    /// f̂ per channel.
    pub(crate) f_hat: DVec3,
    /// `Some(λ̄)` when the traversal was skipped as negligible.
    pub(crate) negligible: Option<f64>,
}

impl ConicQuery {
    /// The answer of a query skipped as negligible, with its bound λ̄.
    fn skipped(bound: f64) -> Self {
        Self {
            result: QueryResult {
                count: 0.0,
                d_hat: [0.0; 3],
                nodes_visited: 0,
                nodes_overlapping: 0,
                truncated: false,
                periodic_average: false,
            },
            f_hat: DVec3::ZERO,
            negligible: Some(bound),
        }
    }

    /// This answer with another roughness level's added.
    fn plus(self, other: QueryResult, f_hat: DVec3) -> Self {
        let mine = self.result;
        Self {
            result: QueryResult {
                count: mine.count + other.count,
                d_hat: std::array::from_fn(|c| mine.d_hat[c] + other.d_hat[c]),
                nodes_visited: mine.nodes_visited + other.nodes_visited,
                nodes_overlapping: mine.nodes_overlapping + other.nodes_overlapping,
                truncated: mine.truncated || other.truncated,
                periodic_average: mine.periodic_average || other.periodic_average,
            },
            f_hat: self.f_hat + f_hat,
            negligible: None,
        }
    }
}

impl Layer {
    /// Roughness level `k` of a material with `parameters` (validated but for the level's
    /// own): its distribution (D(α_k), or the material's), tree, sampler and negligible test.
    fn new(
        parameters: &GlintParameters,
        k: usize,
        level: RoughnessLevel,
    ) -> Result<Self, BrdfError> {
        let gamma = parameters.gamma_radians;
        let distribution = match level.alpha {
            Some(alpha) => Microfacet::new(parameters.distribution.kind(), alpha, alpha)?,
            None => parameters.distribution,
        };
        // A distribution that tabulates Λ builds its table here, once per process and level,
        // rather than in a render's first shading calls.
        let _ = distribution.smith_table();
        let smooth = MicrofacetBrdf::new(
            distribution,
            parameters.fresnel,
            NormalSampling::Distribution,
        )?;
        let sampler = GlintSampler::new(
            distribution,
            parameters.sampling_scale,
            gamma,
            parameters.pdf_quadrature,
            parameters.pdf_points,
        )?;
        let config = CountTreeConfig {
            particles: parameters.particles,
            seed: layer_seed(parameters.seed, k),
            epsilon: parameters.epsilon,
            dense: parameters.dense,
            multinomial: parameters.multinomial,
            expected_query_area: parameters.expected_footprint_area,
            expected_query_solid_angle: expected_conic_solid_angle(gamma),
            colour_channels: parameters.colour_channels,
            ..CountTreeConfig::default()
        };
        let mean_density = level.density.as_ref().map_or(1.0, |map| map.mean());
        let tree = CountTree::with_density_map(
            config,
            Arc::new(move |m: DVec3| distribution.particle_density(m)),
            level.density,
        )?;
        let negligible_test =
            (parameters.negligible_count > 0.0).then(|| NegligibleTest::new(&tree, distribution));
        Ok(Self {
            tree,
            smooth,
            sampler,
            negligible_test,
            mean_density,
        })
    }
}

/// The seed of roughness level `k`'s particles: the material's for the first, then seeds that
/// differ from it by multiples of the golden-ratio constant (independent particle sets).
#[must_use]
pub fn layer_seed(seed: u64, k: usize) -> u64 {
    seed.wrapping_add((k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15))
}

impl DiscreteBrdf {
    /// Builds the material: validates the parameters and builds its count tree (2–4 ms; the
    /// negligible-query test adds 0.3–6 ms, about 12 ms for strongly anisotropic GGX, the
    /// first time the process meets the distribution and α, nothing for later materials of
    /// that law; Ashikhmin–Shirley's Λ table adds 15–30 ms isotropic, 0.4–0.8 s anisotropic,
    /// the first time too).
    ///
    /// # Errors
    /// A [`BrdfError`] naming the invalid parameter.
    pub fn new(parameters: GlintParameters) -> Result<Self, BrdfError> {
        Self::within_map_budget(parameters, crate::MAX_MAP_BYTES)
    }

    /// [`Self::new`] refusing maps that would hold more than `budget` bytes (the tests' way to
    /// reach the refusal with maps of a test's size).
    pub(crate) fn within_map_budget(
        parameters: GlintParameters,
        budget: u64,
    ) -> Result<Self, BrdfError> {
        let gamma = parameters.gamma_radians;
        if !(gamma >= 1e-6 && gamma <= 60f64.to_radians()) {
            return Err(BrdfError::InvalidConeRadius { gamma });
        }
        let area = parameters.expected_footprint_area;
        if !(area > 0.0 && area.is_finite()) {
            return Err(BrdfError::InvalidExpectedFootprintArea { area });
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
        // The levels' weights are made once: the budget counts their maps, then they are built.
        let level_weights = MapBytes::level_weights(&parameters)?;
        let bytes = MapBytes::with_level_weights(&parameters, level_weights.as_ref())
            .check_within(budget)?;
        let levels = roughness_levels(
            parameters.density_map.as_ref(),
            level_weights,
            parameters.roughness_levels,
            bytes.shared_levels,
        )?;
        let layers = levels
            .into_iter()
            .enumerate()
            .map(|(k, level)| Layer::new(&parameters, k, level))
            .collect::<Result<Vec<_>, _>>()?;
        let weighted_tint = match (&parameters.tint_map, &parameters.density_map) {
            (Some(tint), Some(density)) => WeightedTint::new(tint, density)?,
            _ => None,
        };
        Ok(Self {
            parameters,
            layers,
            cone_solid_angle: cone_solid_angle(gamma),
            cone: ConeRadius::new(gamma).map_err(|_| BrdfError::InvalidConeRadius { gamma })?,
            weighted_tint,
        })
    }

    /// The same material with another particle set of the same law: `seed` and the expected
    /// footprint area of Eq. 11 replaced, what [`DiscreteBrdf::new`] builds with them, but
    /// faster: Alg. 2's table, the directional splits, the sampler, the smooth limit and the
    /// negligible-query test (which depend on the law of normals only) are shared, and only the
    /// tree's top levels are built again.
    ///
    /// # Errors
    /// [`BrdfError::InvalidExpectedFootprintArea`] unless the area is positive and finite.
    pub fn with_realization(
        &self,
        seed: u64,
        expected_footprint_area: f64,
    ) -> Result<Self, BrdfError> {
        let area = expected_footprint_area;
        if !(area > 0.0 && area.is_finite()) {
            return Err(BrdfError::InvalidExpectedFootprintArea { area });
        }
        let layers = self
            .layers
            .iter()
            .enumerate()
            .map(|(k, layer)| {
                Ok(Layer {
                    tree: layer
                        .tree
                        .with_realization(layer_seed(seed, k), expected_footprint_area)?,
                    ..layer.clone()
                })
            })
            .collect::<Result<Vec<_>, BrdfError>>()?;
        Ok(Self {
            parameters: GlintParameters {
                seed,
                expected_footprint_area,
                ..self.parameters.clone()
            },
            layers,
            cone_solid_angle: self.cone_solid_angle,
            cone: self.cone,
            weighted_tint: self.weighted_tint.clone(),
        })
    }

    /// The parameters.
    #[must_use]
    pub fn parameters(&self) -> &GlintParameters {
        &self.parameters
    }

    /// The smooth BRDF of the same material: the N → ∞ limit, and the model where no footprint
    /// is known. Under maps, this is the first roughness level's model without the maps: use
    /// [`DiscreteBrdf::smooth_at`], which weighs the levels, the density and the tint at a
    /// texture position.
    #[must_use]
    pub fn smooth(&self) -> &MicrofacetBrdf {
        &self.layers[0].smooth
    }

    /// The heap memory its maps hold, in bytes: the maps it was given and those it built from
    /// them (the roughness levels', the density-weighted tint's). Never more than
    /// [`crate::MAX_MAP_BYTES`] ([`crate::map_budget`]).
    #[must_use]
    pub fn map_bytes(&self) -> u64 {
        let p = &self.parameters;
        let given = p
            .density_map
            .as_ref()
            .map_or(0, |m| m.heap_bytes_with_texels())
            + p.alpha_map.as_ref().map_or(0, |m| m.heap_bytes())
            + p.tint_map.as_ref().map_or(0, |m| m.heap_bytes());
        // Without a roughness map the one level's density map is the given one. Levels that
        // share a family of texels hold it once.
        let levels: usize = if p.alpha_map.is_some() {
            let maps = || {
                self.layers
                    .iter()
                    .filter_map(|layer| layer.tree.density_map())
            };
            let family = maps()
                .find_map(|map| map.level_texels())
                .map_or(0, |texels| texels.heap_bytes());
            family + maps().map(|map| map.heap_bytes()).sum::<usize>()
        } else {
            0
        };
        let weighted_tint = self
            .weighted_tint
            .as_ref()
            .map_or(0, WeightedTint::heap_bytes);
        (given + levels + weighted_tint) as u64
    }

    /// Whether every answer is the same in the three channels: a grey Fresnel term, no
    /// coloured (Dirichlet) flakes and no tint map or a grey one. Interfaces that answer one
    /// number for grey materials ask this, not the Fresnel term alone.
    #[must_use]
    pub fn is_gray(&self) -> bool {
        let p = &self.parameters;
        p.fresnel.is_gray()
            && p.colour_channels == 0
            && p.tint_map.as_ref().is_none_or(|tint| tint.is_gray())
    }

    /// Whether a density, roughness or tint map varies the material over its square.
    #[must_use]
    pub fn has_maps(&self) -> bool {
        self.parameters.density_map.is_some()
            || self.parameters.alpha_map.is_some()
            || self.parameters.tint_map.is_some()
    }

    /// The smooth limit at texture position `uv`: Σ_k d_k(uv)·f_k(ω_i, ω_o), the roughness
    /// levels' smooth BRDFs weighted by their densities there (d(uv)·f(α(uv)) where the
    /// roughness map is exact), times the tint t(uv). Without maps, [`DiscreteBrdf::smooth`]'s
    /// value, bit for bit.
    #[must_use]
    pub fn smooth_at(&self, wi: DVec3, wo: DVec3, uv: DVec2) -> DVec3 {
        if !self.has_maps() {
            return self.layers[0].smooth.eval(wi, wo);
        }
        let sum = self
            .layers
            .iter()
            .map(|layer| {
                let density = layer.density_at(uv);
                if density > 0.0 {
                    layer.smooth.eval(wi, wo) * density
                } else {
                    DVec3::ZERO
                }
            })
            .fold(DVec3::ZERO, |a, b| a + b);
        self.tint_at(uv) * sum
    }

    /// The smooth limit averaged over the texture square: t̄·Σ_k m_k·f_k(ω_i, ω_o), the roughness
    /// levels' smooth BRDFs weighted by their shares of the flakes m_k = ∫d_k, times the flakes'
    /// mean tint t̄ over the square. It is what f̂ tends to over a footprint that covers many
    /// tiles (its count is N·a(A)·Σ_k m_k·∫p_k and its tint the square's), and what a footprint
    /// too large to query ([`Footprint::MAX_EDGE`]) shades. Without maps,
    /// [`DiscreteBrdf::smooth`]'s value, bit for bit.
    #[must_use]
    pub fn smooth_mean(&self, wi: DVec3, wo: DVec3) -> DVec3 {
        if !self.has_maps() {
            return self.layers[0].smooth.eval(wi, wo);
        }
        let sum = self
            .layers
            .iter()
            .map(|layer| layer.smooth.eval(wi, wo) * layer.mean_density)
            .fold(DVec3::ZERO, |a, b| a + b);
        self.mean_tint() * sum
    }

    /// The flakes' mean tint over the square (density-weighted where the density map has the
    /// tint's size, as [`DiscreteBrdf::at`] weighs it over a footprint), or 1 without a tint.
    fn mean_tint(&self) -> DVec3 {
        match (&self.weighted_tint, &self.parameters.tint_map) {
            (Some(weighted), _) => weighted.mean(),
            (None, Some(tint)) => tint.mean(),
            (None, None) => DVec3::ONE,
        }
    }

    /// The count tree (the particle set) of the first roughness level (the only one without
    /// an `alpha_map`), for research and diagnostics.
    #[must_use]
    pub fn tree(&self) -> &CountTree {
        &self.layers[0].tree
    }

    /// The count trees of the roughness levels, with each level's α (`None`: the
    /// distribution's own, without an `alpha_map`).
    pub fn level_trees(&self) -> impl Iterator<Item = (Option<f64>, &CountTree)> {
        self.layers.iter().map(|layer| {
            let alpha = self
                .parameters
                .alpha_map
                .as_ref()
                .map(|_| layer.smooth.distribution().alpha().0);
            (alpha, &layer.tree)
        })
    }

    /// The glint BRDF at a shading point: `footprint` is the pixel's texture-space
    /// parallelogram there, `scratch` this thread's working memory (reuse it across queries).
    /// The returned value implements [`Bxdf`](crate::Bxdf) with the glint model.
    #[must_use]
    pub fn at<'a>(
        &'a self,
        footprint: &'a Footprint,
        scratch: &'a mut QueryScratch,
    ) -> GlintBxdf<'a> {
        GlintBxdf::new(self, footprint, scratch)
    }

    /// The glint sampler's direction alone (Sec. 3.4): ω′ from the widened smooth model with
    /// `u[0..2]`, then ω_o uniform in the cone of radius γ around ω′ with `u[2..4]`. It does not
    /// depend on the footprint. For a renderer that needs f̂ or the pdf only for some samples;
    /// [`Bxdf::sample`](crate::Bxdf::sample) on [`DiscreteBrdf::at`] gives all three. Under a
    /// roughness map, the levels are chosen by their shares of the material's flakes: use
    /// [`DiscreteBrdf::sample_direction_at`] where the texture position is known.
    #[must_use]
    pub fn sample_direction(&self, wi: DVec3, u: [f64; 4]) -> Option<DVec3> {
        self.sample_from_mixture(wi, u, None)
    }

    /// The density of [`DiscreteBrdf::sample_direction`] in solid angle.
    #[must_use]
    pub fn sampling_pdf(&self, wi: DVec3, wo: DVec3) -> f64 {
        self.mixture_pdf(wi, wo, None)
    }

    /// The rule [`DiscreteBrdf::sampling_pdf`] takes for `wi` and `wo` (under a roughness map,
    /// the first level's; each level has its own sampler): which regime of the pdf a renderer's
    /// directions fall in, and so what the pdf costs them.
    #[must_use]
    pub fn sampling_pdf_rule(&self, wi: DVec3, wo: DVec3) -> PdfRule {
        self.layers[0].sampler.rule(given(wi), given(wo))
    }

    /// [`DiscreteBrdf::sample_direction`] at texture position `uv`: under a roughness map, the
    /// level is chosen with probability d_k(uv)/Σ d_j(uv) by `u[0]` (rescaled to choose within
    /// it), so the sampler follows the lobe mixture at the shading point (by the flakes' shares
    /// where d(uv) = 0). The same as [`DiscreteBrdf::sample_direction`] with one level.
    #[must_use]
    pub fn sample_direction_at(&self, wi: DVec3, u: [f64; 4], uv: DVec2) -> Option<DVec3> {
        self.sample_from_mixture(wi, u, Some(uv))
    }

    /// The density of [`DiscreteBrdf::sample_direction_at`] in solid angle (the same as
    /// [`Bxdf::pdf`](crate::Bxdf::pdf) on [`DiscreteBrdf::at`] for a footprint centred at `uv`).
    #[must_use]
    pub fn sampling_pdf_at(&self, wi: DVec3, wo: DVec3, uv: DVec2) -> f64 {
        self.mixture_pdf(wi, wo, Some(uv))
    }

    /// A direction from the glint sampler weighed with the smooth limit, f·cos θ_o/pdf: the
    /// sample a path without a footprint takes. At texture position `uv` a material with maps
    /// samples and weighs the lobes there ([`DiscreteBrdf::sample_direction_at`],
    /// [`DiscreteBrdf::smooth_at`]); without `uv`, by its levels' shares, with
    /// [`DiscreteBrdf::smooth`]. `None` when no direction is sampled.
    #[must_use]
    pub fn sample_smooth(&self, wi: DVec3, u: [f64; 4], uv: Option<DVec2>) -> Option<BxdfSample> {
        match uv {
            Some(uv) => self.sample_direction_at(wi, u, uv).and_then(|wo| {
                BxdfSample::weighted(
                    wo,
                    self.smooth_at(wi, wo, uv),
                    self.sampling_pdf_at(wi, wo, uv),
                )
            }),
            None => self.sample_direction(wi, u).and_then(|wo| {
                BxdfSample::weighted(wo, self.smooth().eval(wi, wo), self.sampling_pdf(wi, wo))
            }),
        }
    }

    /// The levels' sampling weights at `uv` (their flake shares when `uv` is `None` or every
    /// level's density is 0 there), summing to 1.
    fn mixture_weights(&self, uv: Option<DVec2>) -> impl Iterator<Item = f64> + '_ {
        let at = uv.map(|uv| self.layers.iter().map(|l| l.density_at(uv)).sum::<f64>());
        let (local, total) = match at {
            Some(total) if total > 0.0 => (uv, total),
            _ => (None, self.layers.iter().map(|l| l.mean_density).sum()),
        };
        self.layers.iter().map(move |layer| {
            let weight = local.map_or(layer.mean_density, |uv| layer.density_at(uv));
            weight / total
        })
    }

    fn sample_from_mixture(&self, wi: DVec3, u: [f64; 4], uv: Option<DVec2>) -> Option<DVec3> {
        let wi = given(wi);
        if let [layer] = self.layers.as_slice() {
            return layer.sampler.sample_direction(wi, u);
        }
        // The level whose interval of cumulative weights holds u[0], and u[0] rescaled within it.
        let mut below = 0.0;
        let mut chosen = (self.layers.len() - 1, 0.0, 1.0);
        for (k, weight) in self.mixture_weights(uv).enumerate() {
            if weight > 0.0 {
                chosen = (k, below, weight);
                if u[0] < below + weight {
                    break;
                }
            }
            below += weight;
        }
        let (k, start, weight) = chosen;
        let u0 = ((u[0] - start) / weight).clamp(0.0, 1.0 - f64::EPSILON / 2.0);
        self.layers[k]
            .sampler
            .sample_direction(wi, [u0, u[1], u[2], u[3]])
    }

    fn mixture_pdf(&self, wi: DVec3, wo: DVec3, uv: Option<DVec2>) -> f64 {
        let (wi, wo) = (given(wi), given(wo));
        if let [layer] = self.layers.as_slice() {
            return layer.sampler.pdf(wi, wo);
        }
        self.mixture_weights(uv)
            .zip(&self.layers)
            .filter(|(weight, _)| *weight > 0.0)
            .map(|(weight, layer)| weight * layer.sampler.pdf(wi, wo))
            .sum()
    }

    /// t(uv), or 1 without a tint map.
    fn tint_at(&self, uv: DVec2) -> DVec3 {
        self.parameters
            .tint_map
            .as_ref()
            .map_or(DVec3::ONE, |tint| tint.value_at(uv))
    }

    /// The tree query of Eq. 6 for (ω_i, ω_o) and f̂ from it (Eq. 5): the work every glint
    /// evaluation shares. `None` for directions not above the horizon or an invalid conic.
    pub(crate) fn query(
        &self,
        wi: DVec3,
        wo: DVec3,
        footprint: &Footprint,
        scratch: &mut QueryScratch,
    ) -> Option<ConicQuery> {
        self.query_if(wi, wo, footprint, scratch, || true).flatten()
    }

    /// [`Self::query`] where `traverse()` holds, asking it only before a traversal: a query
    /// that needs none (no conic, or skipped as negligible) answers without it. `None` when
    /// `traverse()` said no.
    pub(crate) fn query_if(
        &self,
        wi: DVec3,
        wo: DVec3,
        footprint: &Footprint,
        scratch: &mut QueryScratch,
        traverse: impl FnOnce() -> bool,
    ) -> Option<Option<ConicQuery>> {
        let Some(conic) = self.conic(wi, wo) else {
            return Some(None);
        };
        self.query_conic(&conic, footprint, scratch, self.cone_solid_angle, traverse)
            .map(Some)
    }

    /// The query of `conic` in every roughness level, with f̂ for a cone of solid angle
    /// `solid_angle` (the material's σ(Ω_o), or a light's cone), the levels' answers summed
    /// and the tint filtered over the footprint applied. A level whose negligible-query bound
    /// is below the material's threshold is skipped (answered 0); `traverse()` is asked once,
    /// before the first traversal, and `None` returned if it says no.
    pub(crate) fn query_conic(
        &self,
        conic: &SphericalConic,
        footprint: &Footprint,
        scratch: &mut QueryScratch,
        solid_angle: f64,
        traverse: impl FnOnce() -> bool,
    ) -> Option<ConicQuery> {
        let (wi, wo) = (conic.wi(), conic.wo());
        let mut traverse = Some(traverse);
        let mut answer: Option<ConicQuery> = None;
        let mut skipped = 0.0;
        for layer in &self.layers {
            let bound = self.layer_bound(layer, footprint, conic);
            if bound < self.parameters.negligible_count {
                skipped += bound;
                continue;
            }
            if let Some(traverse) = traverse.take()
                && !traverse()
            {
                return None;
            }
            let result = layer.tree.query(footprint, conic, scratch);
            let f_hat = self.f_hat_from_d_hat(
                layer,
                wi,
                wo,
                DVec3::from_array(result.d_hat),
                footprint.area(),
            ) * (self.cone_solid_angle / solid_angle);
            answer = Some(match answer {
                None => ConicQuery {
                    result,
                    f_hat,
                    negligible: None,
                },
                Some(sum) => sum.plus(result, f_hat),
            });
        }
        let Some(mut answer) = answer else {
            return Some(ConicQuery::skipped(skipped));
        };
        if let Some(tint) = &self.parameters.tint_map
            && answer.f_hat != DVec3::ZERO
        {
            let flakes_tint = self
                .weighted_tint
                .as_ref()
                .and_then(|weighted| weighted.mean_over(footprint));
            answer.f_hat *= flakes_tint.unwrap_or_else(|| tint.mean_over(footprint));
        }
        Some(answer)
    }

    /// λ̄ of the negligible-query test for one level: its flakes, at most N·max_A d_k per unit
    /// area over the footprint ([`DensityMap::max_over`]); infinite when the material skips
    /// nothing or the conic is hyperbolic.
    fn layer_bound(&self, layer: &Layer, footprint: &Footprint, conic: &SphericalConic) -> f64 {
        layer.negligible_test.map_or(f64::INFINITY, |test| {
            let density = layer
                .tree
                .density_map()
                .map_or(1.0, |map| map.max_over(footprint));
            test.bound(
                layer.smooth.distribution(),
                self.parameters.particles,
                footprint.area() * density,
                conic,
            )
        })
    }

    /// The negligible-query test's constants ([`NegligibleTestConstants`]), for a material of
    /// one roughness level without a density map whose test is on; `None` otherwise.
    #[must_use]
    pub fn negligible_test(&self) -> Option<NegligibleTestConstants> {
        let [layer] = self.layers.as_slice() else {
            return None;
        };
        if layer.tree.density_map().is_some() {
            return None;
        }
        let excess = layer.negligible_test?.law_excess();
        Some(NegligibleTestConstants {
            particles: self.parameters.particles as f64,
            threshold: self.parameters.negligible_count,
            law_excess_ratio: excess.ratio,
            unbounded_mass: excess.unbounded_mass,
            widening_arc: 2.0 * LEAF_CELL_ARC,
        })
    }

    /// The expected count N·∫_A d·∫p over the conic, summed over the roughness levels.
    pub(crate) fn expected_count(
        &self,
        footprint: &Footprint,
        conic: &SphericalConic,
        scratch: &mut QueryScratch,
    ) -> f64 {
        self.layers
            .iter()
            .map(|layer| layer.tree.expected_count(footprint, conic, scratch))
            .sum()
    }

    /// The conic of normals reflecting ω_i into the cone around ω_o (Eq. 8), which normalizes
    /// and checks the directions; `None` unless both are above the horizon.
    pub(crate) fn conic(&self, wi: DVec3, wo: DVec3) -> Option<SphericalConic> {
        let (wi, wo) = (given(wi), given(wo));
        if !(above_horizon(wi) && above_horizon(wo)) {
            return None;
        }
        SphericalConic::with_cone(wi, wo, &self.cone).ok()
    }

    /// The conic of normals reflecting ω_i into the cone of half-angle `cone` around `axis`:
    /// [`DiscreteBrdf::conic`] with another cone than the material's γ (for light cones, see
    /// [`GlintBxdf::evaluate_in_cone`]). `None` unless both directions are above the horizon.
    pub(crate) fn conic_in_cone(
        &self,
        wi: DVec3,
        axis: DVec3,
        cone: &ConeRadius,
    ) -> Option<SphericalConic> {
        let (wi, axis) = (given(wi), given(axis));
        if !(above_horizon(wi) && above_horizon(axis)) {
            return None;
        }
        SphericalConic::with_cone(wi, axis, cone).ok()
    }

    /// λ̄ of the negligible-query test for a footprint and conic, summed over the roughness
    /// levels; infinite when the material skips nothing (`negligible_count` = 0) or the conic
    /// is hyperbolic.
    pub(crate) fn expected_count_bound(
        &self,
        footprint: &Footprint,
        conic: &SphericalConic,
    ) -> f64 {
        self.layers
            .iter()
            .map(|layer| self.layer_bound(layer, footprint, conic))
            .sum()
    }

    /// The corrected Eq. 5 for unit directions above the horizon, from a D̂ per channel and the
    /// footprint's area (texture units): what a glint evaluation adds to its tree query.
    ///
    /// With s = ω_i + ω_o and h = s/|s|, the factor G·(ω_i·h)/(h·n) equals G·(ω_i·s)/(s·n), and
    /// ω_o·h = ω_i·h for unit directions, so only the Fresnel term needs |s|: this runs on the
    /// renderer's every evaluation that finds particles, where sqrt and division latencies are
    /// most of its cost.
    fn f_hat_from_d_hat(
        &self,
        layer: &Layer,
        wi: DVec3,
        wo: DVec3,
        d_hat: DVec3,
        area: f64,
    ) -> DVec3 {
        let s = wi + wo;
        let wi_dot_s = wi.dot(s);
        let valid = s.is_finite() && s.z > 0.0 && wi_dot_s > 0.0 && wi.z > 0.0 && wo.z > 0.0;
        if !(valid && area > 0.0) || d_hat == DVec3::ZERO {
            return DVec3::ZERO;
        }
        // G = 1/(1 + Λ(ω_i) + Λ(ω_o)) (χ⁺ holds: ω_i·h = ω_o·h > 0 and both above the horizon).
        let distribution = layer.smooth.distribution();
        let one_plus_lambdas = 1.0 + distribution.lambda(wi) + distribution.lambda(wo);
        let denominator = one_plus_lambdas * area * self.cone_solid_angle * s.z * wi.z * wo.z;
        let scale = if one_plus_lambdas.is_finite() && denominator >= f64::MIN_POSITIVE {
            wi_dot_s / denominator
        } else {
            // Near the horizon the denominator underflows (or a Λ overflows): the same factor
            // from G/(4 cos θ_i cos θ_o), which stays finite, in an order that does not
            // underflow (clamped where the true value exceeds the largest finite number).
            let h = s / s.length();
            let g_over_cosines = 4.0 * distribution.g_over_cosines(wi, wo, h);
            ((wi_dot_s / s.z) * g_over_cosines / (area * self.cone_solid_angle)).min(f64::MAX)
        };
        let fresnel = match layer.smooth.fresnel() {
            Fresnel::None => DVec3::ONE,
            fresnel => fresnel.evaluate(wi_dot_s / s.length()),
        };
        (fresnel * d_hat * scale).min(DVec3::splat(f64::MAX))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Bxdf;
    use glam::DVec2;

    /// Footprints up to the largest edges a footprint may have (±`Footprint::MAX_EDGE`, an area
    /// of 10³⁰ tiles) give finite, non-negative counts, D̂, f̂ and expectations, the averaged
    /// f̂ that of one tile; larger edges, whose area or count would overflow, are refused.
    #[test]
    fn the_largest_footprints_give_finite_answers() {
        let distribution = Microfacet::new(crate::DistributionKind::Beckmann, 0.2, 0.2).unwrap();
        let mut parameters = GlintParameters::new(distribution);
        parameters.particles = 1 << 53;
        let brdf = DiscreteBrdf::new(parameters).unwrap();
        let mut scratch = QueryScratch::new();
        let (wi, wo) = (DVec3::Z, DVec3::new(0.1, 0.0, 1.0).normalize());
        let tile = Footprint::new(DVec2::splat(0.5), DVec2::X, DVec2::Y).unwrap();
        let one_tile = brdf.at(&tile, &mut scratch).evaluate(wi, wo);
        let edge = Footprint::MAX_EDGE;
        for (dx, dy) in [
            (DVec2::new(edge, 0.0), DVec2::new(0.0, edge)),
            (DVec2::new(-edge, edge), DVec2::new(edge, edge)),
            (DVec2::new(edge, 1e-300), DVec2::new(1.0, 0.0)),
        ] {
            let footprint = Footprint::new(DVec2::new(0.3, 0.4), dx, dy).unwrap();
            let bxdf = brdf.at(&footprint, &mut scratch);
            let e = bxdf.evaluate(wi, wo);
            let values = [e.count, e.d_hat.x, e.f_hat.x, bxdf.expected_count(wi, wo)];
            assert!(
                values.iter().all(|v| v.is_finite() && *v >= 0.0),
                "{dx} {dy}: {e:?}"
            );
            assert!(brdf.tree().config().many_tiles.averages(&footprint));
            if footprint.area() > 1.0 {
                assert!(e.count > 0.0);
                let relative = (e.f_hat.x - one_tile.f_hat.x).abs() / one_tile.f_hat.x;
                assert!(
                    relative < 1e-12,
                    "{dx} {dy}: {} against {}",
                    e.f_hat.x,
                    one_tile.f_hat.x
                );
            }
            assert!(bxdf.eval(wi, wo).is_finite());
        }
        for huge in [edge * 1.000_001, 1e154, 1e300, f64::MAX] {
            assert_eq!(
                Footprint::new(DVec2::ZERO, DVec2::new(huge, 0.0), DVec2::new(0.0, 1.0)),
                Err(glint_tree::TreeError::FootprintTooLarge { component: huge })
            );
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
                        let fast = brdf.f_hat_from_d_hat(&brdf.layers[0], wi, wo, d_hat, area);
                        assert!(
                            (fast - textbook).length() <= 1e-12 * textbook.length(),
                            "{wi} {wo}: {fast} vs {textbook}"
                        );
                    }
                }
            }
        }
    }
}
