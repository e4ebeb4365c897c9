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
        self.fresnel.evaluate(wi.dot(h)) * (d * g / (4.0 * wi.z * wo.z))
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
