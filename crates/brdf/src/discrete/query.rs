//! The glint material's query: the tree's count of Eq. 6 over a footprint and a conic, and
//! f̂ from it by the corrected Eq. 5, with the negligible-query test that skips the count.
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

use glam::DVec3;
use glint_sphere::{ConeRadius, SphericalConic};
use glint_tree::{Footprint, LEAF_CELL_ARC, QueryResult, QueryScratch};

use crate::fresnel::Fresnel;
use crate::smooth::{above_horizon, given};

use super::{DiscreteBrdf, Layer};

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
/// [`Microfacet::particle_density_bound`](crate::Microfacet::particle_density_bound) of the material's distribution.
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

impl DiscreteBrdf {
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
    use crate::{Bxdf, GlintParameters, Microfacet};
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
