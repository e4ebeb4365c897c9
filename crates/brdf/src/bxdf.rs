//! The BxDF interface ([`Bxdf`]) and its samples.

use glam::DVec3;

/// A sampled direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BxdfSample {
    /// The sampled outgoing direction (unit, above the horizon).
    pub wo: DVec3,
    /// The BRDF value f(ω_i, ω_o) per RGB channel.
    pub f: DVec3,
    /// The density of ω_o in solid angle.
    pub pdf: f64,
    /// The Monte Carlo weight f·cos θ_o / pdf: the reflected radiance estimate for unit
    /// incident radiance from ω_o.
    pub weight: DVec3,
}

impl BxdfSample {
    /// The sample of direction `wo` with BRDF value `f` and density `pdf`, or `None` when the
    /// density is not a positive finite number or the weight f·cos θ_o/pdf is not finite (a
    /// subnormal density such as 6·10⁻³¹⁷ overflows it): the sample could not be weighted.
    #[must_use]
    pub fn weighted(wo: DVec3, f: DVec3, pdf: f64) -> Option<Self> {
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        let weight = f * (wo.z / pdf);
        weight.is_finite().then_some(Self { wo, f, pdf, weight })
    }
}

/// A BRDF: [`Bxdf::eval`], [`Bxdf::sample`] (from uniform numbers, not a generator) and
/// [`Bxdf::pdf`], shaped like pbrt-v4's `BxDF` but with **the paper's and Mitsuba's names for
/// the directions, the reverse of pbrt-v4's**:
///
/// - **ω_i (`wi`) points toward the viewer** (the camera, or the previous path vertex): the
///   direction the path arrived from, reversed. pbrt-v4 calls it `wo`.
/// - **ω_o (`wo`) points toward the light** (the next path vertex): the direction
///   [`Bxdf::sample`] draws given ω_i. pbrt-v4 calls it `wi`.
///
/// Both are in the local shading frame (n = +z) and point away from the surface. Every BRDF
/// here is reciprocal, so the order only matters for sampling. Directions need not be unit
/// vectors: every entry point normalizes them ([`crate::frame::given_direction`]: a vector of
/// unit length to rounding is used as it is), in Rust as in C, Python and `eval`. Invalid
/// directions (zero, non-finite, or at or below the horizon) give a zero value, a zero pdf and
/// no sample: never NaN.
pub trait Bxdf {
    /// The uniform numbers in [0, 1) that one sample uses, `[f64; k]`: exactly as many as the
    /// sampler consumes, so that a renderer's sample dimensions map one to one.
    type Uniforms: Copy;

    /// f(ω_i, ω_o) per RGB channel.
    fn eval(&self, wi: DVec3, wo: DVec3) -> DVec3;
    /// A direction ω_o for ω_i from the uniform numbers `u`, with f and the density there, or
    /// `None` when no valid direction is sampled (below the horizon, zero density).
    fn sample(&self, wi: DVec3, u: Self::Uniforms) -> Option<BxdfSample>;
    /// The density of `sample` choosing ω_o, in solid angle.
    fn pdf(&self, wi: DVec3, wo: DVec3) -> f64;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_that_cannot_be_weighted_are_none() {
        let wo = DVec3::new(0.0, 0.6, 0.8);
        let f = DVec3::splat(2.0);
        assert!(BxdfSample::weighted(wo, f, 0.0).is_none());
        assert!(BxdfSample::weighted(wo, f, f64::NAN).is_none());
        // A subnormal density overflows the weight.
        assert!(BxdfSample::weighted(wo, f, 6e-317).is_none());
        let s = BxdfSample::weighted(wo, f, 0.5).unwrap();
        assert_eq!(s.weight, DVec3::splat(3.2));
    }
}
