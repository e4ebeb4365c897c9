//! The glint material: the discrete multiscale BRDF of Eq. 5 and its parameters.
//!
//! A [`DiscreteBrdf`] is a material: its parameters, its count tree (the particle set) and its
//! sampler. It is evaluated at a shading point through [`DiscreteBrdf::at`], which binds a
//! footprint and a per-thread scratch into a [`GlintBxdf`] whose [`Bxdf`](crate::Bxdf) methods are the
//! glint model. Its smooth limit is [`DiscreteBrdf::smooth`].
//!
//! Its parts, one idea each:
//!
//! - `parameters`: [`GlintParameters`], what a material is made of, and its defaults;
//! - this file: the material itself, its roughness levels (one count tree each), its smooth
//!   limit and [`DiscreteBrdf::at`];
//! - `sampling`: the glint sampler (Sec. 3.4) and its pdf, over a roughness map's levels;
//! - `query`: the tree query of Eq. 6 and f̂ from it by the corrected Eq. 5 (derived there),
//!   with the negligible-query test.
//!
//! # Without a footprint
//! Paths after the first bounce carry no ray differentials; there (as in the paper) a renderer
//! uses the smooth model of the same material, [`DiscreteBrdf::smooth`], and may keep the glint
//! sampler ([`DiscreteBrdf::sample_direction`], [`DiscreteBrdf::sampling_pdf`]) so that its
//! sampling does not depend on whether a footprint is known.

mod parameters;
mod query;
mod sampling;

pub use parameters::GlintParameters;
pub(crate) use query::ConicQuery;
pub use query::NegligibleTestConstants;

use std::sync::Arc;

use glam::{DVec2, DVec3};
use glint_sphere::ConeRadius;
use glint_tree::{CountTree, CountTreeConfig, Footprint, QueryScratch, expected_conic_solid_angle};

use crate::bxdf::Bxdf;
use crate::cone::cone_solid_angle;
use crate::distribution::{Microfacet, NormalSampling};
use crate::error::BrdfError;
use crate::glint::GlintBxdf;
use crate::glint_sampling::GlintSampler;
use crate::map_budget::MapBytes;
use crate::negligible::NegligibleTest;
use crate::smooth::MicrofacetBrdf;
use crate::surface_maps::{RoughnessLevel, WeightedTint, roughness_levels};

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

    /// t(uv), or 1 without a tint map.
    fn tint_at(&self, uv: DVec2) -> DVec3 {
        self.parameters
            .tint_map
            .as_ref()
            .map_or(DVec3::ONE, |tint| tint.value_at(uv))
    }
}
