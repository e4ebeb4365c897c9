//! The glint material's sampler (Sec. 3.4): a direction from the widened smooth model, then
//! uniform in the cone around it, and its pdf; under a roughness map, a mixture over the
//! levels weighted by their shares of the flakes at the texture position.

use glam::{DVec2, DVec3};

use crate::bxdf::{Bxdf, BxdfSample};
use crate::glint_sampling::PdfRule;
use crate::smooth::given;

use super::DiscreteBrdf;

impl DiscreteBrdf {
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
}
