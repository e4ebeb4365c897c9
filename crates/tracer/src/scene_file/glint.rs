//! Glint materials (`type = "glint"`): their form in the file and their building into a
//! [`DiscreteBrdf`], every parameter checked against the count tree's and glint-brdf's ranges.

use std::sync::Arc;

use glint_brdf::{DenseCounts, DiscreteBrdf, GlintParameters, MultinomialMode, PdfQuadrature};
use serde::Deserialize;

use super::SCENE_NEGLIGIBLE_COUNT;
use super::builder::{Builder, Checked, shown};
use super::materials::{DistributionName, FresnelSection, SurfaceScale};
use super::numbers::Roughness;
use crate::material::{GlintMaterial, Material};

#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(rename_all = "snake_case")]
enum MultinomialName {
    Exact,
    Normal,
}

#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(rename_all = "snake_case")]
enum PdfQuadratureName {
    Cubature,
    Qmc,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct GlintSection {
    #[serde(default)]
    distribution: DistributionName,
    /// Required unless `alpha_texture` gives α instead.
    alpha: Option<Roughness>,
    /// N, flakes per texture square; or `flakes_per_mm2` (one of the two).
    particles: Option<f64>,
    /// Flakes per mm² of surface, converted per shape (needs the file's `metres_per_unit`).
    flakes_per_mm2: Option<f64>,
    /// The cone radius γ in degrees (required).
    gamma_degrees: Option<f64>,
    /// `gamma_degrees`'s older name, still read (deprecated); both at once are an error.
    gamma: Option<f64>,
    epsilon: Option<f64>,
    /// "lattice" (the default), "sampled" or "exact".
    dense: Option<String>,
    dense_node_scale: Option<f64>,
    seed: Option<u64>,
    fresnel: Option<FresnelSection>,
    multinomial: Option<MultinomialName>,
    #[serde(default)]
    coloured: bool,
    sampling_scale: Option<f64>,
    pdf_quadrature: Option<PdfQuadratureName>,
    pdf_points: Option<usize>,
    expected_footprint_area: Option<f64>,
    negligible_count: Option<f64>,
    uv_scale: Option<f64>,
    density_texture: Option<String>,
    alpha_texture: Option<String>,
    tint_texture: Option<String>,
    roughness_levels: Option<usize>,
    /// How `density_texture` and `alpha_texture` are reconstructed between texels:
    /// "nearest" (the default) or "bilinear".
    map_filter: Option<String>,
}

impl Builder<'_> {
    pub(super) fn glint(
        &self,
        field: &str,
        g: &GlintSection,
        surface: &SurfaceScale,
    ) -> Checked<Material> {
        if g.alpha.is_some() && g.alpha_texture.is_some() {
            return self.fail(
                format!("{field}.alpha"),
                "`alpha_texture` replaces `alpha`: give one of them",
            );
        }
        let map_filter = self.map_filter(field, g.map_filter.as_deref())?;
        let alpha_map = match &g.alpha_texture {
            Some(file) => Some(self.alpha_map(field, file, map_filter)?),
            None => None,
        };
        let alpha = match (g.alpha, &alpha_map) {
            (Some(alpha), _) => alpha,
            // The distribution's kind is what counts; its α, the map's largest, is what tables
            // of the material show.
            (None, Some(map)) => {
                let (width, height) = map.size();
                let largest = (0..width * height)
                    .map(|k| map.texel(k % width, k / width))
                    .fold(0.0, f64::max);
                Roughness(largest, largest)
            }
            (None, None) => {
                return self.fail(
                    format!("{field}.alpha"),
                    "a glint material needs `alpha` (or `alpha_texture`)",
                );
            }
        };
        let distribution = self.microfacet(field, g.distribution, alpha)?;
        let mut parameters = GlintParameters::new(distribution);
        parameters.alpha_map = alpha_map;
        if let Some(file) = &g.density_texture {
            parameters.density_map = Some(self.density_map(field, file, map_filter)?);
        }
        if let Some(file) = &g.tint_texture {
            parameters.tint_map = Some(self.tint_map(field, file)?);
        }
        if let Some(levels) = g.roughness_levels {
            if !(1..=glint_brdf::surface_maps::MAX_ROUGHNESS_LEVELS).contains(&levels) {
                return self.fail(
                    format!("{field}.roughness_levels"),
                    format!(
                        "must be in [1, {}], got {levels}",
                        glint_brdf::surface_maps::MAX_ROUGHNESS_LEVELS
                    ),
                );
            }
            parameters.roughness_levels = levels;
        }
        let uv_scale = self.positive(&format!("{field}.uv_scale"), g.uv_scale.unwrap_or(1.0))?;
        parameters.particles = self.particles(field, g, surface, uv_scale)?;
        // glint-brdf's range, [10⁻⁶ rad, 60°].
        let smallest = 1e-6f64.to_degrees();
        let gamma_degrees = match (g.gamma_degrees, g.gamma) {
            (Some(gamma), None) | (None, Some(gamma)) => gamma,
            (Some(_), Some(_)) => {
                return self.fail(
                    format!("{field}.gamma_degrees"),
                    "give the cone radius once: `gamma` is the older name of `gamma_degrees`"
                        .to_owned(),
                );
            }
            (None, None) => {
                return self.fail(
                    format!("{field}.gamma_degrees"),
                    "missing: the cone radius in degrees (for example 1)".to_owned(),
                );
            }
        };
        if !(gamma_degrees >= smallest && gamma_degrees <= 60.0) {
            return self.fail(
                format!("{field}.gamma_degrees"),
                format!(
                    "the cone radius must be in [{smallest:.3e}°, 60°] (10⁻⁶ rad to 60°), got {}°",
                    shown(gamma_degrees)
                ),
            );
        }
        parameters.gamma_radians = gamma_degrees.to_radians();
        if let Some(epsilon) = g.epsilon {
            parameters.epsilon = epsilon;
        }
        let dense = g.dense.as_deref().unwrap_or("lattice");
        parameters.dense = match DenseCounts::from_name(dense, g.dense_node_scale) {
            Ok(dense) => dense,
            Err(e) => {
                let name = if g.dense_node_scale.is_some() && DenseCounts::NAMES.contains(&dense) {
                    "dense_node_scale"
                } else {
                    "dense"
                };
                return self.fail(format!("{field}.{name}"), e.to_string());
            }
        };
        parameters.seed = g.seed.unwrap_or(0);
        parameters.fresnel = self.fresnel(&format!("{field}.fresnel"), g.fresnel.as_ref())?;
        parameters.multinomial = match g.multinomial {
            None | Some(MultinomialName::Exact) => MultinomialMode::Exact,
            Some(MultinomialName::Normal) => MultinomialMode::Normal,
        };
        parameters.colour_channels = if g.coloured { 3 } else { 0 };
        if let Some(s) = g.sampling_scale {
            parameters.sampling_scale = s;
        }
        if let Some(q) = g.pdf_quadrature {
            parameters.pdf_quadrature = match q {
                PdfQuadratureName::Cubature => PdfQuadrature::Cubature,
                PdfQuadratureName::Qmc => PdfQuadrature::QuasiMonteCarlo,
            };
        }
        if let Some(p) = g.pdf_points {
            parameters.pdf_points = p;
        }
        if let Some(a) = g.expected_footprint_area {
            parameters.expected_footprint_area = a;
        }
        let negligible_count = g.negligible_count.unwrap_or(SCENE_NEGLIGIBLE_COUNT);
        if !(negligible_count >= 0.0 && negligible_count.is_finite()) {
            return self.fail(
                format!("{field}.negligible_count"),
                format!(
                    "must be finite and ≥ 0 (0 traverses every query), got {}",
                    shown(negligible_count)
                ),
            );
        }
        parameters.negligible_count = negligible_count;
        let brdf = DiscreteBrdf::new(parameters).map_err(|e| match e {
            glint_brdf::BrdfError::MapSizesDiffer { .. } => {
                self.brdf_error(&format!("{field}.alpha_texture"), &e)
            }
            glint_brdf::BrdfError::DensityMap(_) => {
                self.brdf_error(&format!("{field}.density_texture"), &e)
            }
            other => self.brdf_error(field, &other),
        })?;
        Ok(Material::Glint(GlintMaterial {
            brdf: Arc::new(brdf),
            uv_scale,
            plan_footprint_area: g.expected_footprint_area.is_none(),
        }))
    }

    /// N of glint section `g`: its `particles`, or its `flakes_per_mm2` converted for the
    /// shape it is built for, N = ρ·10⁶·metres_per_unit²·(S/U)/uv_scale² (S/U the shape's
    /// surface area per unit of uv area), rounded: a whole number in [1, 2⁵³].
    fn particles(
        &self,
        field: &str,
        g: &GlintSection,
        surface: &SurfaceScale,
        uv_scale: f64,
    ) -> Checked<u64> {
        // 2⁵³, the count tree's limit: every whole number up to it is a double.
        const MOST: f64 = 9_007_199_254_740_992.0;
        let density_field = format!("{field}.flakes_per_mm2");
        let particles = match (g.particles, g.flakes_per_mm2) {
            (Some(n), None) => n,
            (Some(_), Some(_)) => {
                return self.fail(
                    density_field,
                    "give `particles` (per texture square) or `flakes_per_mm2`, not both",
                );
            }
            (None, None) => {
                return self.fail(
                    format!("{field}.particles"),
                    "missing: the flakes per texture square (or `flakes_per_mm2` per mm² of \
                     surface)",
                );
            }
            (None, Some(density)) => {
                let density = self.positive(&density_field, density)?;
                let Some(metres) = surface.metres_per_unit else {
                    return self.fail(
                        density_field,
                        "needs the scene's length unit: `metres_per_unit = ...` at the top of \
                         the file",
                    );
                };
                let Some(ratio) = surface.surface_per_uv else {
                    return self.fail(
                        density_field,
                        format!(
                            "{}: the shape's texture coordinates cover no area, so flakes per \
                             mm² cannot be converted (give `particles`)",
                            surface.shape
                        ),
                    );
                };
                surface.used.set(true);
                let n = (density * 1e6 * metres * metres * ratio / (uv_scale * uv_scale)).round();
                if !(1.0..=MOST).contains(&n) {
                    return self.fail(
                        density_field,
                        format!(
                            "gives {} flakes per texture square on {}, outside [1, 2^53] \
                             (surface {} units² per unit of uv area, uv_scale {})",
                            shown(n),
                            surface.shape,
                            shown(ratio),
                            shown(uv_scale)
                        ),
                    );
                }
                return Ok(n as u64);
            }
        };
        if !((1.0..=MOST).contains(&particles) && particles.fract() == 0.0) {
            return self.fail(
                format!("{field}.particles"),
                format!(
                    "must be a whole number in [1, 2^53], got {}",
                    shown(particles)
                ),
            );
        }
        Ok(particles as u64)
    }
}
