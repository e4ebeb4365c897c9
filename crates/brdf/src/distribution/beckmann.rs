//! Beckmann: Gaussian slopes.
//!
//! ```text
//!   D(m) = exp(−(x²/α_x² + y²/α_y²)/z²) / (π α_x α_y z⁴)
//!   Λ    = (erf(a) − 1)/2 + exp(−a²)/(2a√π),   a = z / √(α_x² x² + α_y² y²)
//! ```
//!
//! In scaled slopes the lobe is radial: P(ρ) = e^(−ρ²)/π ([`RadialLaw::Gaussian`]).

use std::f64::consts::PI;

use glam::DVec3;

use super::{
    ConeCheck, ConvergenceCheck, KindChecks, Model, RadialLaw, bisect, erf,
    normal_from_scaled_slope, scaled_slope2,
};

/// Beckmann's distribution.
pub(crate) struct Beckmann;

impl Model for Beckmann {
    const RADIAL: Option<RadialLaw> = Some(RadialLaw::Gaussian);
    const SAMPLES_VISIBLE_NORMALS: bool = true;
    // Wide cones against narrow and line-like lobes (the slope-space rule); on and off the
    // specular peak, grazing.
    const CHECKS: KindChecks = KindChecks {
        sampler_cones: &[
            ConeCheck::new((0.01, 0.01), 20.0),
            ConeCheck::new((0.0001, 0.0001), 1.0).capped(1.5),
            ConeCheck::new((0.3, 0.0001), 8.0),
        ],
        albedo_cones: &[
            ConeCheck::new((0.01, 0.01), 20.0),
            ConeCheck::new((0.01, 0.01), 40.0),
            ConeCheck::new((0.003, 0.003), 10.0),
            ConeCheck::new((0.1, 0.1), 1.0),
        ],
        convergence: &[
            ConvergenceCheck::new((0.2, 0.2), 2.0, (0.3, 0.3, PI)),
            ConvergenceCheck::new((0.2, 0.2), 2.0, (0.5, 0.2, PI + 0.3)),
            ConvergenceCheck::new((0.2, 0.2), 2.0, (1.3, 1.2, PI)),
            ConvergenceCheck::new((0.2, 0.2), 2.0, (0.2, 0.6, PI + 0.5)),
            ConvergenceCheck::new((0.05, 0.05), 0.5, (1.0, 1.0, PI)),
        ],
    };

    fn d((alpha_x, alpha_y): (f64, f64), m: DVec3) -> f64 {
        let z2 = m.z * m.z;
        let slope2 = scaled_slope2((alpha_x, alpha_y), m);
        if z2 * z2 < f64::MIN_POSITIVE {
            // Near the horizon z⁴ underflows (0/0): e^(−s²)/z⁴ = e^(−s² − 4 ln z).
            return (-slope2 - 4.0 * m.z.ln()).exp() / (PI * alpha_x * alpha_y);
        }
        (-slope2).exp() / (PI * alpha_x * alpha_y * z2 * z2)
    }

    /// D's formula is homogeneous of degree −4 in m: D(H) = D(h)/|H|⁴ without normalizing.
    fn d_of_half_vector(alpha: (f64, f64), half: DVec3) -> f64 {
        Self::d(alpha, half)
    }

    fn lambda((alpha_x, alpha_y): (f64, f64), w: DVec3) -> f64 {
        let projected_squared = (alpha_x * w.x).powi(2) + (alpha_y * w.y).powi(2);
        // For a > 6, erf(a) = 1 and exp(−a²) < 3e-16: Λ is 0 to double precision (tested
        // without the square root: a² > 36).
        if w.z * w.z > 36.0 * projected_squared {
            return 0.0;
        }
        let a = w.z / projected_squared.sqrt();
        0.5 * (erf(a) - 1.0) + (-a * a).exp() / (2.0 * a * PI.sqrt())
    }

    /// Λ·z = p·(a(erf(a) − 1)/2 + e^(−a²)/(2√π)), a = z/p: Λ grows like 1/(2a√π) at the
    /// horizon (and overflows), Λ·z tends to p/(2√π). Where a ≥ 1 (no overflow), Λ times z.
    fn lambda_times_cos(alpha: (f64, f64), w: DVec3) -> f64 {
        let projected_squared = (alpha.0 * w.x).powi(2) + (alpha.1 * w.y).powi(2);
        if w.z * w.z >= projected_squared {
            return Self::lambda(alpha, w) * w.z;
        }
        let projected = projected_squared.sqrt();
        let a = w.z / projected;
        projected * (0.5 * a * (erf(a) - 1.0) + (-a * a).exp() / (2.0 * PI.sqrt()))
    }

    /// P(t) = (1 + t)^{3/2} e^{−t/α_m²} / (π α_x α_y), whose logarithm's derivative
    /// 3/(2(1 + t)) − 1/α_m² changes sign once, at t* = 3α_m²/2 − 1.
    fn particle_density_bound((alpha_x, alpha_y): (f64, f64), t_near: f64, t_far: f64) -> f64 {
        let alpha2 = alpha_x.max(alpha_y).powi(2);
        let t = (1.5 * alpha2 - 1.0).clamp(t_near, t_far);
        (1.0 + t) * (1.0 + t).sqrt() * (-t / alpha2).exp() / (PI * alpha_x * alpha_y)
    }

    /// Gaussian slopes: radius √(−ln(1 − u₀)) in scaled slopes, stretched by (α_x, α_y).
    fn sample_normal((alpha_x, alpha_y): (f64, f64), u: [f64; 2]) -> DVec3 {
        let u0 = u[0].min(1.0 - f64::EPSILON);
        let radius = (-(1.0 - u0).ln()).sqrt();
        normal_from_scaled_slope((alpha_x, alpha_y), radius, u[1])
    }

    /// Heitz and d'Eon 2014, slope space: stretch ω_i, then for unit roughness and μ = cot θ
    /// the visible slope along the incident azimuth has density ∝ (μ − x)e^(−x²) on x < μ, with
    /// CDF ∝ μ(1 + erf x)/2 + e^(−x²)/(2√π), inverted by bisection; the perpendicular slope is
    /// Gaussian (an inverted erf); rotate to the incident azimuth, unstretch, and
    /// m = normalize(−s_x, −s_y, 1).
    fn sample_visible_normal((alpha_x, alpha_y): (f64, f64), wi: DVec3, u: [f64; 2]) -> DVec3 {
        let v = DVec3::new(alpha_x * wi.x, alpha_y * wi.y, wi.z).normalize();
        let sin_theta = (v.x * v.x + v.y * v.y).sqrt();
        let (cos_phi, sin_phi) = if sin_theta > 0.0 {
            (v.x / sin_theta, v.y / sin_theta)
        } else {
            (1.0, 0.0)
        };
        // Slopes beyond ±6 carry less than 1e-16 of the Gaussian's mass.
        let mu = if sin_theta > 0.0 {
            (v.z / sin_theta).min(1e8)
        } else {
            1e8
        };
        let sqrt_pi = PI.sqrt();
        let numerator = |x: f64| mu * 0.5 * (1.0 + erf(x)) + (-x * x).exp() / (2.0 * sqrt_pi);
        let upper = mu.min(6.0);
        let target = u[0] * numerator(upper);
        let slope_along = bisect(|x| numerator(x) - target, -6.0, upper);
        let slope_across = bisect(|y| erf(y) - (2.0 * u[1] - 1.0), -6.0, 6.0);
        let (x, y) = (
            cos_phi * slope_along - sin_phi * slope_across,
            sin_phi * slope_along + cos_phi * slope_across,
        );
        DVec3::new(-alpha_x * x, -alpha_y * y, 1.0).normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The roughness parameterization: D(n) = 1/(π α_x α_y), the peak of the lobe.
    #[test]
    fn d_at_the_normal_is_one_over_pi_alpha_x_alpha_y() {
        for (alpha_x, alpha_y) in [(0.3, 0.1), (0.02, 0.02), (1.0, 0.5)] {
            let peak = Beckmann::d((alpha_x, alpha_y), DVec3::Z);
            let expected = 1.0 / (PI * alpha_x * alpha_y);
            assert!(
                (peak - expected).abs() < 1e-12 * expected,
                "{peak} against {expected}"
            );
        }
    }
}
