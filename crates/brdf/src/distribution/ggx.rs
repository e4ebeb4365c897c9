//! GGX (Trowbridge–Reitz).
//!
//! ```text
//!   D(m) = 1 / (π α_x α_y z⁴ (1 + (x²/α_x² + y²/α_y²)/z²)²)
//!   Λ    = (−1 + √(1 + 1/a²))/2,   a = z / √(α_x² x² + α_y² y²)
//! ```
//!
//! In scaled slopes the lobe is radial: P(ρ) = 1/(π(1 + ρ²)²) ([`RadialLaw::Student`]).

use std::f64::consts::PI;

use glam::DVec3;

use super::{
    ConeCheck, ConvergenceCheck, KindChecks, Model, RadialLaw, normal_from_scaled_slope,
    scaled_slope2,
};

/// The GGX distribution.
pub(crate) struct Ggx;

impl Model for Ggx {
    const RADIAL: Option<RadialLaw> = Some(RadialLaw::Student);
    const SAMPLES_VISIBLE_NORMALS: bool = true;
    // The widest cone, a lobe narrow against the bins and an extremely anisotropic one;
    // a rough lobe and an anisotropic one.
    const CHECKS: KindChecks = KindChecks {
        sampler_cones: &[
            ConeCheck::new((0.01, 0.01), 60.0),
            ConeCheck::new((0.003, 0.003), 10.0).capped(15.0),
            ConeCheck::new((0.0001, 0.5), 10.0),
        ],
        albedo_cones: &[
            ConeCheck::new((0.01, 0.01), 60.0),
            ConeCheck::new((0.0001, 0.3), 5.0),
        ],
        convergence: &[
            ConvergenceCheck::new((0.5, 0.5), 5.0, (0.7, 0.4, PI + 0.8)),
            ConvergenceCheck::new((0.1, 0.3), 1.0, (0.4, 0.35, PI + 0.1)),
        ],
    };

    fn d((alpha_x, alpha_y): (f64, f64), m: DVec3) -> f64 {
        let z2 = m.z * m.z;
        if z2 * z2 < f64::MIN_POSITIVE {
            // Near the horizon z⁴ underflows (and the slope overflows): the same D without
            // them, z⁴(1 + s²/z²)² = (z² + q)², q = x²/α_x² + y²/α_y².
            let q = (m.x / alpha_x).powi(2) + (m.y / alpha_y).powi(2);
            let sum = z2 + q;
            return 1.0 / (PI * alpha_x * alpha_y * sum * sum);
        }
        let slope2 = scaled_slope2((alpha_x, alpha_y), m);
        let normalization = PI * alpha_x * alpha_y * z2 * z2;
        1.0 / (normalization * (1.0 + slope2) * (1.0 + slope2))
    }

    /// D's formula is homogeneous of degree −4 in m: D(H) = D(h)/|H|⁴ without normalizing.
    fn d_of_half_vector(alpha: (f64, f64), half: DVec3) -> f64 {
        Self::d(alpha, half)
    }

    /// 1/a² = projected²/w.z².
    fn lambda((alpha_x, alpha_y): (f64, f64), w: DVec3) -> f64 {
        let projected_squared = (alpha_x * w.x).powi(2) + (alpha_y * w.y).powi(2);
        0.5 * ((1.0 + projected_squared / (w.z * w.z)).sqrt() - 1.0)
    }

    /// Λ·z = (√(z² + p²) − z)/2 = p²/(2(√(z² + p²) + z)), p² = (α_x x)² + (α_y y)²: no
    /// cancellation, and finite down to the horizon (Λ itself grows like p/(2z)).
    fn lambda_times_cos((alpha_x, alpha_y): (f64, f64), w: DVec3) -> f64 {
        let projected_squared = (alpha_x * w.x).powi(2) + (alpha_y * w.y).powi(2);
        0.5 * projected_squared / ((w.z * w.z + projected_squared).sqrt() + w.z)
    }

    /// P(t) = (1 + t)^{3/2} / (1 + t/α_m²)² / (π α_x α_y), whose logarithm's derivative
    /// 3/(2(1 + t)) − 2/(α_m² + t) changes sign once, at t* = 3α_m² − 4.
    fn particle_density_bound((alpha_x, alpha_y): (f64, f64), t_near: f64, t_far: f64) -> f64 {
        let alpha2 = alpha_x.max(alpha_y).powi(2);
        let t = (3.0 * alpha2 - 4.0).clamp(t_near, t_far);
        let fall = 1.0 + t / alpha2;
        (1.0 + t) * (1.0 + t).sqrt() / (fall * fall * (PI * alpha_x * alpha_y))
    }

    /// The bivariate Student-like P22: radius √(u₀/(1 − u₀)) in scaled slopes, stretched by
    /// (α_x, α_y).
    fn sample_normal((alpha_x, alpha_y): (f64, f64), u: [f64; 2]) -> DVec3 {
        let u0 = u[0].min(1.0 - f64::EPSILON);
        let radius = (u0 / (1.0 - u0)).sqrt();
        normal_from_scaled_slope((alpha_x, alpha_y), radius, u[1])
    }

    /// Heitz 2018, "Sampling the GGX Distribution of Visible Normals": stretch ω_i to the
    /// unit-roughness configuration, sample the projected hemisphere, unstretch.
    fn sample_visible_normal((alpha_x, alpha_y): (f64, f64), wi: DVec3, u: [f64; 2]) -> DVec3 {
        let v = DVec3::new(alpha_x * wi.x, alpha_y * wi.y, wi.z).normalize();
        let length2 = v.x * v.x + v.y * v.y;
        let t1 = if length2 > 0.0 {
            DVec3::new(-v.y, v.x, 0.0) / length2.sqrt()
        } else {
            DVec3::X
        };
        let t2 = v.cross(t1);
        let r = u[0].sqrt();
        let phi = 2.0 * PI * u[1];
        let p1 = r * phi.cos();
        let s = 0.5 * (1.0 + v.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
        let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * v;
        DVec3::new(alpha_x * nh.x, alpha_y * nh.y, nh.z.max(1e-12)).normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The roughness parameterization: D(n) = 1/(π α_x α_y), the peak of the lobe.
    #[test]
    fn d_at_the_normal_is_one_over_pi_alpha_x_alpha_y() {
        for (alpha_x, alpha_y) in [(0.3, 0.1), (0.02, 0.02), (1.0, 0.5)] {
            let peak = Ggx::d((alpha_x, alpha_y), DVec3::Z);
            let expected = 1.0 / (PI * alpha_x * alpha_y);
            assert!(
                (peak - expected).abs() < 1e-12 * expected,
                "{peak} against {expected}"
            );
        }
    }
}
