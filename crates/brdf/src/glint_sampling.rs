//! Importance sampling of the glint model (Sec. 3.4).
//!
//! Sample the smooth model with widened roughness α_s = scale·α (2 by default): draw a facet
//! normal from p_s with two uniform numbers and reflect ω_i about it to ω′, then draw ω_o
//! uniformly in the cone of radius γ around ω′ with two more. The density of ω_o is p_s
//! convolved with the cone,
//!
//! ```text
//!   pdf(ω_o) = (1/σ(Ω_o)) ∫_{cone(ω_o, γ)} p_s(ω′) dω′,   p_s(ω′) = D_s(h)(h·n) / (4 ω_i·h),
//! ```
//!
//! evaluated by quasi-Monte Carlo over the first `pdf_points` points of a (0, 2)-sequence
//! (64 by default) mapped area-uniformly onto the cone. The sampler does not depend on the
//! footprint: the particles only enter the weight, through f̂.

use glam::DVec3;

use crate::cone::uniform_in_cone;
use crate::distribution::Microfacet;
use crate::distribution::NormalSampling;
use crate::error::BrdfError;
use crate::frame::orthonormal_basis;
use crate::fresnel::Fresnel;
use crate::qmc::zero_two_point;
use crate::smooth::{MicrofacetBrdf, above_horizon};

/// The sampler of Sec. 3.4 for one material.
#[derive(Clone, Debug)]
pub(crate) struct GlintSampler {
    /// The widened smooth model (F = 1) that chooses the cone's centre.
    widened: MicrofacetBrdf,
    /// γ, the cone's radius.
    gamma: f64,
    /// The pdf's QMC points in the cone's own frame (axis +z), computed once.
    cone_points: Vec<DVec3>,
}

impl GlintSampler {
    /// The sampler of `distribution` widened by `scale`, with cone radius `gamma` and
    /// `pdf_points` quadrature points (all validated by the caller).
    pub(crate) fn new(
        distribution: Microfacet,
        scale: f64,
        gamma: f64,
        pdf_points: usize,
    ) -> Result<Self, BrdfError> {
        let widened = MicrofacetBrdf::new(
            distribution.scaled(scale),
            Fresnel::None,
            NormalSampling::Distribution,
        )?;
        let cone_points = (0..pdf_points)
            .map(|i| {
                let [a, b] = zero_two_point(i as u32);
                uniform_in_cone(DVec3::Z, gamma, a, b)
            })
            .collect();
        Ok(Self {
            widened,
            gamma,
            cone_points,
        })
    }

    /// ω′ from the widened model with `u[0..2]`, then ω_o uniform in the cone of radius γ
    /// around ω′ with `u[2..4]`; `None` below the horizon.
    pub(crate) fn sample_direction(&self, wi: DVec3, u: [f64; 4]) -> Option<DVec3> {
        if !above_horizon(wi) {
            return None;
        }
        let wi = wi.normalize();
        let centre = self.widened.sample_direction(wi, [u[0], u[1]])?;
        let wo = uniform_in_cone(centre, self.gamma, u[2], u[3]);
        above_horizon(wo).then_some(wo)
    }

    /// The density of [`GlintSampler::sample_direction`]: the cone average of the widened
    /// model's density, by QMC.
    pub(crate) fn pdf(&self, wi: DVec3, wo: DVec3) -> f64 {
        if !(above_horizon(wi) && above_horizon(wo)) {
            return 0.0;
        }
        let (wi, wo) = (wi.normalize(), wo.normalize());
        let (t, b) = orthonormal_basis(wo);
        let distribution = self.widened.distribution();
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

/// The widened model's own density, for the tests: the cone average must tend to it as γ → 0.
#[cfg(test)]
impl GlintSampler {
    fn widened_pdf(&self, wi: DVec3, wo: DVec3) -> f64 {
        crate::Bxdf::pdf(&self.widened, wi, wo)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::DistributionKind;

    #[test]
    fn a_narrow_cone_has_the_widened_models_density() {
        let d = Microfacet::new(DistributionKind::Beckmann, 0.2, 0.2).unwrap();
        let sampler = GlintSampler::new(d, 2.0, 1e-5, 64).unwrap();
        let wi = DVec3::new(0.3, 0.1, 0.9).normalize();
        for wo in [DVec3::Z, DVec3::new(-0.4, 0.2, 0.8).normalize()] {
            let (cone, point) = (sampler.pdf(wi, wo), sampler.widened_pdf(wi, wo));
            assert!((cone - point).abs() <= 1e-4 * point, "{cone} vs {point}");
        }
    }

    #[test]
    fn samples_use_all_four_numbers() {
        let d = Microfacet::new(DistributionKind::Ggx, 0.3, 0.3).unwrap();
        let sampler = GlintSampler::new(d, 2.0, 0.2, 64).unwrap();
        let wi = DVec3::new(0.2, 0.0, 1.0).normalize();
        let base = sampler.sample_direction(wi, [0.3, 0.6, 0.2, 0.9]).unwrap();
        for k in 0..4 {
            let mut u = [0.3, 0.6, 0.2, 0.9];
            u[k] = 0.5;
            let moved = sampler.sample_direction(wi, u).unwrap();
            assert!(
                moved.dot(base) < 1.0 - 1e-9,
                "u[{k}] does not move the sample"
            );
        }
    }
}
