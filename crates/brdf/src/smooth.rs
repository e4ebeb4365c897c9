//! The smooth microfacet BRDF of Eq. 3: the N → ∞ limit of the glint model, and the model
//! paths use where no footprint is known.

use glam::DVec3;

use crate::bxdf::{Bxdf, BxdfSample};
use crate::distribution::{Microfacet, NormalSampling};
use crate::error::BrdfError;
use crate::frame::given_direction;
use crate::fresnel::Fresnel;

/// A direction as every entry point of this crate takes it: [`given_direction`] (unit vectors
/// as they are, others normalized), or the zero vector, which no horizon test admits, for a
/// zero or non-finite one. So an unnormalized ω gives the answer of its unit vector everywhere
/// (the glint model's conic normalizes its directions the same way).
pub(crate) fn given(w: DVec3) -> DVec3 {
    given_direction(w).unwrap_or(DVec3::ZERO)
}

/// Whether a direction is usable: finite and strictly above the horizon.
pub(crate) fn above_horizon(w: DVec3) -> bool {
    w.is_finite() && w.z > 0.0
}

/// The mirror reflection of ω_i about m.
pub(crate) fn reflect(wi: DVec3, m: DVec3) -> DVec3 {
    2.0 * wi.dot(m) * m - wi
}

/// The smooth microfacet BRDF of Eq. 3: f = F(ω_i·h) D(h) G(ω_i, ω_o, h) / (4 cos θ_i cos θ_o).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MicrofacetBrdf {
    distribution: Microfacet,
    fresnel: Fresnel,
    sampling: NormalSampling,
}

impl MicrofacetBrdf {
    /// The BRDF of `distribution` with `fresnel`, sampling normals by `sampling`.
    ///
    /// # Errors
    /// Invalid Fresnel parameters, or [`NormalSampling::Visible`] for a kind without it.
    pub fn new(
        distribution: Microfacet,
        fresnel: Fresnel,
        sampling: NormalSampling,
    ) -> Result<Self, BrdfError> {
        if sampling == NormalSampling::Visible && !distribution.kind().samples_visible_normals() {
            return Err(BrdfError::VisibleSamplingUnavailable {
                distribution: distribution.kind().name(),
            });
        }
        Ok(Self {
            distribution,
            fresnel: fresnel.validated()?,
            sampling,
        })
    }

    /// The microfacet distribution.
    #[must_use]
    pub fn distribution(&self) -> &Microfacet {
        &self.distribution
    }

    /// The Fresnel term.
    #[must_use]
    pub fn fresnel(&self) -> &Fresnel {
        &self.fresnel
    }

    /// The direction of [`Bxdf::sample`] alone (no evaluation, no pdf).
    #[must_use]
    pub fn sample_direction(&self, wi: DVec3, u: [f64; 2]) -> Option<DVec3> {
        let wi = given(wi);
        if !above_horizon(wi) {
            return None;
        }
        let m = match self.sampling {
            NormalSampling::Distribution => self.distribution.sample_normal(u),
            NormalSampling::Visible => self.distribution.sample_visible_normal(wi, u),
        };
        let wo = reflect(wi, m);
        (above_horizon(wo) && wi.dot(m) > 0.0).then_some(wo)
    }

    /// The density of the facet normal m that `sample` draws for ω_i.
    fn normal_pdf(&self, wi: DVec3, m: DVec3) -> f64 {
        match self.sampling {
            NormalSampling::Distribution => self.distribution.normal_pdf(m),
            NormalSampling::Visible => self.distribution.visible_normal_pdf(wi, m),
        }
    }
}

impl Bxdf for MicrofacetBrdf {
    /// Two numbers: the facet normal's.
    type Uniforms = [f64; 2];

    fn eval(&self, wi: DVec3, wo: DVec3) -> DVec3 {
        let (wi, wo) = (given(wi), given(wo));
        if !(above_horizon(wi) && above_horizon(wo)) {
            return DVec3::ZERO;
        }
        let h = (wi + wo).normalize();
        if !h.is_finite() {
            return DVec3::ZERO;
        }
        let d = self.distribution.d(h);
        let g = self.distribution.g(wi, wo, h);
        let cosines = 4.0 * wi.z * wo.z;
        let shadowed = if g > 0.0 && cosines >= f64::MIN_POSITIVE {
            d * g / cosines
        } else {
            // Near the horizon G/(4 cos θ_i cos θ_o) is 0/0 term by term.
            (d * self.distribution.g_over_cosines(wi, wo, h)).min(f64::MAX)
        };
        self.fresnel.evaluate(wi.dot(h)) * shadowed
    }

    /// Draws m (from p(m) or the visible normals) with `u` and reflects ω_i about it.
    fn sample(&self, wi: DVec3, u: [f64; 2]) -> Option<BxdfSample> {
        let wo = self.sample_direction(wi, u)?;
        BxdfSample::weighted(wo, self.eval(wi, wo), self.pdf(wi, wo))
    }

    /// The normal density times the reflection Jacobian dm/dω_o = 1/(4 ω_i·h).
    fn pdf(&self, wi: DVec3, wo: DVec3) -> f64 {
        let (wi, wo) = (given(wi), given(wo));
        if !(above_horizon(wi) && above_horizon(wo)) {
            return 0.0;
        }
        let h = (wi + wo).normalize();
        let cos = wi.dot(h);
        if !(cos > 0.0) {
            return 0.0;
        }
        self.normal_pdf(wi, h) / (4.0 * cos)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distribution::DistributionKind;
    use crate::{DiscreteBrdf, Footprint, GlintParameters};
    use glam::DVec2;
    use proptest::prelude::*;

    fn fresnels() -> [Fresnel; 3] {
        [
            Fresnel::None,
            Fresnel::Dielectric { eta: 1.5 },
            Fresnel::Conductor {
                eta: DVec3::new(0.18, 0.42, 1.37),
                k: DVec3::new(3.42, 2.35, 1.77),
            },
        ]
    }

    /// The directions, 1e-200 above the horizon: f_smooth was NaN for every kind (D
    /// formed z⁴, which underflows, and G/(4 cos θ_i cos θ_o) was 0/0).
    #[test]
    fn f_smooth_is_finite_for_directions_1e_200_from_the_horizon() {
        for kind in DistributionKind::ALL {
            for alpha in [1e-4, 0.1, 0.5, 1.0] {
                for z in [1e-100, 1e-200, 1e-300] {
                    let (wi, wo) = (DVec3::new(0.6, -0.8, z), DVec3::new(-0.6, 0.3, z));
                    for fresnel in fresnels() {
                        let distribution = Microfacet::new(kind, alpha, alpha).unwrap();
                        let brdf =
                            MicrofacetBrdf::new(distribution, fresnel, NormalSampling::default())
                                .unwrap();
                        let f = brdf.eval(wi, wo);
                        let pdf = brdf.pdf(wi, wo);
                        assert!(
                            f.is_finite()
                                && f.min_element() >= 0.0
                                && pdf.is_finite()
                                && pdf >= 0.0,
                            "{kind} α = {alpha}, z = {z}: f = {f}, pdf = {pdf}"
                        );
                    }
                }
            }
        }
    }

    /// The glint sampler's pdf for GGX, γ = 60°, ω_i 1e-300 above the horizon: was NaN.
    #[test]
    fn glint_pdf_is_finite_for_wi_1e_300_from_the_horizon() {
        for kind in DistributionKind::ALL {
            let mut parameters = GlintParameters::new(Microfacet::new(kind, 0.2, 0.2).unwrap());
            parameters.gamma_radians = 60f64.to_radians();
            let brdf = DiscreteBrdf::new(parameters).unwrap();
            let wi = DVec3::new(0.6, -0.8, 1e-300);
            for wo in [
                DVec3::new(-0.6, 0.3, 0.5),
                DVec3::new(-0.6, 0.8, 1e-300),
                DVec3::Z,
                DVec3::new(0.6, 0.8, 0.2),
            ] {
                let pdf = brdf.sampling_pdf(wi, wo);
                assert!(pdf.is_finite() && pdf >= 0.0, "{kind}: {wo}: pdf = {pdf}");
            }
        }
    }

    /// A unit direction whose height above the horizon is 10^−`exponent`.
    fn grazing(azimuth: f64, exponent: f64) -> DVec3 {
        let z = 10f64.powf(-exponent);
        let (sin, cos) = azimuth.sin_cos();
        DVec3::new(cos, sin, z)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]

        /// Every kind answers finite, non-negative numbers for directions down to 1e-300 from
        /// the horizon: the smooth BRDF and its pdf, the glint BRDF (f̂ and its smooth limit)
        /// and the glint sampler's pdf.
        #[test]
        fn every_kind_is_finite_down_to_1e_300_from_the_horizon(
            azimuth_i in 0.0..std::f64::consts::TAU,
            azimuth_o in 0.0..std::f64::consts::TAU,
            exponent_i in 0.0..300.0f64,
            exponent_o in 0.0..300.0f64,
            alpha_x in -4.0..0.0f64,
            alpha_y in -4.0..0.0f64,
            gamma_deg in 0.01..60.0f64,
            uv in (0.0..1.0f64, 0.0..1.0f64),
        ) {
            let (wi, wo) = (grazing(azimuth_i, exponent_i), grazing(azimuth_o, exponent_o));
            let alpha = (10f64.powf(alpha_x), 10f64.powf(alpha_y));
            let footprint = Footprint::new(
                DVec2::new(uv.0, uv.1),
                DVec2::new(1e-3, 0.0),
                DVec2::new(0.0, 1e-3),
            )
            .unwrap();
            for kind in DistributionKind::ALL {
                let distribution = Microfacet::new(kind, alpha.0, alpha.1).unwrap();
                for fresnel in fresnels() {
                    let brdf =
                        MicrofacetBrdf::new(distribution, fresnel, NormalSampling::default())
                            .unwrap();
                    let (f, pdf) = (brdf.eval(wi, wo), brdf.pdf(wi, wo));
                    prop_assert!(
                        f.is_finite() && f.min_element() >= 0.0 && pdf.is_finite() && pdf >= 0.0,
                        "{kind} {alpha:?} {wi} {wo}: f = {f}, pdf = {pdf}"
                    );
                }
                let mut parameters = GlintParameters::new(distribution);
                parameters.gamma_radians = gamma_deg.to_radians();
                parameters.particles = 1_000_000_000_000;
                let glint = DiscreteBrdf::new(parameters).unwrap();
                let mut scratch = crate::QueryScratch::new();
                let evaluation = glint.at(&footprint, &mut scratch).evaluate(wi, wo);
                let smooth = glint.smooth().eval(wi, wo);
                let pdf = glint.sampling_pdf(wi, wo);
                prop_assert!(
                    evaluation.f_hat.is_finite()
                        && evaluation.f_hat.min_element() >= 0.0
                        && smooth.is_finite()
                        && smooth.min_element() >= 0.0
                        && pdf.is_finite()
                        && pdf >= 0.0,
                    "{kind} {alpha:?} γ = {gamma_deg}° {wi} {wo}: f̂ = {}, f = {smooth}, \
                     pdf = {pdf}",
                    evaluation.f_hat
                );
            }
        }
    }
}
