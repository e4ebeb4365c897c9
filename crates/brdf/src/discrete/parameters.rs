//! A glint material's parameters: [`GlintParameters`] and its defaults.

use std::sync::Arc;

use glint_tree::{DenseCounts, DensityMap, MultinomialMode};

use crate::distribution::Microfacet;
use crate::fresnel::Fresnel;
use crate::glint_sampling::PdfQuadrature;
use crate::surface_maps::{RoughnessMap, TintMap};

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
