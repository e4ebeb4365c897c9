//! Ashikhmin and Shirley's anisotropic Phong distribution (2000), the paper's Sec. 5 ornament.
//!
//! **Exponents from α.** glint takes every kind's roughness as (α_x, α_y) in [10⁻⁴, 1]; this
//! kind's exponents are e = 2/α² − 2 (Walter et al. 2007's match of Phong to Beckmann: near the
//! normal cos^e θ ≈ e^(−(1/α² − 1) tan²θ), so both lobes have the same width for small α, and
//! the same peak D(n) = 1/(π α_x α_y)). The paper's ornament, α = [0.1, 0.4], is
//! e = (198, 10.5).
//!
//! **D.** With φ the normal's azimuth and e(φ) = e_x cos²φ + e_y sin²φ,
//!
//! ```text
//!   D(m) = √((e_x + 2)(e_y + 2)) / (2π) · cos^{e(φ)} θ.
//! ```
//!
//! Ashikhmin and Shirley normalize their half-vector density √((e_x + 1)(e_y + 1))/(2π)·
//! cos^{e(φ)} θ in solid angle; a microfacet D is normalized with the projection,
//! ∫ D(m)(m·n) dm = 1, which is the same integral with e + 1 for e: ∫₀^{π/2} cos^{e+1}θ sin θ dθ
//! = 1/(e(φ) + 2) and ∫₀^{2π} dφ/((e_x + 2)cos²φ + (e_y + 2)sin²φ) = 2π/√((e_x + 2)(e_y + 2)),
//! hence e + 2 in the constant. In slopes (x, y) = (m_x, m_y)/m_z, r² = x² + y²,
//! cos^{e(φ)}θ = exp(−½(e_x x² + e_y y²)·ln(1 + r²)/r²): no azimuth, no 0/0.
//!
//! **Sampling p.** The azimuth's marginal is ∝ 1/(e(φ) + 2): in the first quadrant
//! tan φ = √((e_x + 2)/(e_y + 2))·tan(πv/2) for v uniform, mirrored into the other three
//! (p is even in x and y); then P(cos θ ≤ c | φ) = c^{e(φ)+2}, so cos θ = u^{1/(e(φ)+2)}, i.e.
//! tan²θ = expm1(−2 ln u/(e(φ) + 2)).
//!
//! **Λ, by quadrature.** There is no closed form. With P22 = D cos⁴θ = C(1 + r²)^{−k(φ)},
//! k = e(φ)/2 + 2, C the constant above, and t = tan θ_o, Smith's Λ is
//! ∫∫ P22 (t·(x cos φ_o + y sin φ_o) − 1)⁺ dx dy. In polar slopes, on the half plane
//! |φ − φ_o| < π/2 where c = t cos(φ − φ_o) > 0, the radial integral from r_0 = 1/c is, with
//! 1 + r² = (1 + r_0²)e^{v/K}, K = k − 1,
//!
//! ```text
//!   J(φ) = ∫_{r_0}^∞ (1 + r²)^{−k} (c r − 1) r dr
//!        = (1 + 1/c²)^{−K}/(2K) · ∫_0^∞ e^{−v} (√(1 + (1 + c²)·expm1(v/K)) − 1) dv,
//! ```
//!
//! whose integrand never cancels, and Λ = C ∫ J(φ) dφ: the tests' reference. A render reads Λ
//! from a table per roughness built from the slope marginal ([`smith`]), within 1.3e-7 of
//! 1 + Λ of the reference for moderate anisotropy. `tests/tests/brdf.rs` and this module's
//! tests check Smith's identity (1 + Λ(ω)) cos θ_o = ∫ D(m) max(0, ω·m) dm against a direct
//! integration of D.
//!
//! **The pdf's rays.** Along a ray of scaled slopes (α_x ρ cos ψ, α_y ρ sin ψ) the azimuth is
//! fixed, so with A² = α_x² cos²ψ + α_y² sin²ψ the mass per unit ψ is closed form:
//! C α_x α_y ∫ ρ(1 + A²ρ²)^{−k} dρ = C α_x α_y (1 + A²ρ²)^{−K}/(2A²K) between the ends.
//! The lobe is not radial in scaled slopes, so the slope-space pdf takes its ray rule.
//!
//! **Not available:** visible-normal sampling (no inverse is known; the glint sampler does not
//! use it).

use std::sync::Arc;

use std::f64::consts::PI;

use glam::DVec3;

use super::{ConeCheck, ConvergenceCheck, KindChecks, Model, RadialLaw};

mod smith;

pub use smith::SmithTable;

/// Ashikhmin and Shirley's distribution.
pub(crate) struct AshikhminShirley;

/// The exponent e = 2/α² − 2 of a roughness α.
fn exponent(alpha: f64) -> f64 {
    2.0 / (alpha * alpha) - 2.0
}

/// (e_x, e_y) and the constant C = √((e_x + 2)(e_y + 2))/(2π) = 1/(π α_x α_y).
pub(super) fn exponents((alpha_x, alpha_y): (f64, f64)) -> (f64, f64, f64) {
    (
        exponent(alpha_x),
        exponent(alpha_y),
        1.0 / (PI * alpha_x * alpha_y),
    )
}

/// ln(1 + r²)/r², 1 at r = 0.
fn log_ratio(r2: f64) -> f64 {
    if r2 == 0.0 { 1.0 } else { r2.ln_1p() / r2 }
}

/// ln cos^{e(φ)}θ = −½(e_x x² + e_y y²)·ln(1 + r²)/r² for squared slopes x², y²: D's shape,
/// which D and the slope density P22 = D cos⁴θ share.
pub(super) fn log_phong((e_x, e_y): (f64, f64), x2: f64, y2: f64) -> f64 {
    -0.5 * (e_x * x2 + e_y * y2) * log_ratio(x2 + y2)
}

impl Model for AshikhminShirley {
    const RADIAL: Option<RadialLaw> = None;
    const SAMPLES_VISIBLE_NORMALS: bool = false;
    // Not radial in scaled slopes: the slope-space pdf's ray rule; the paper's anisotropic
    // ornament, on and off the peak.
    const CHECKS: KindChecks = KindChecks {
        sampler_cones: &[ConeCheck {
            alpha: (0.01, 0.04),
            gamma_degrees: 20.0,
            cap_degrees: None,
        }],
        albedo_cones: &[ConeCheck {
            alpha: (0.01, 0.04),
            gamma_degrees: 20.0,
            cap_degrees: None,
        }],
        convergence: &[
            ConvergenceCheck::new((0.1, 0.4), 5.0, (0.5, 0.5, PI)),
            ConvergenceCheck::new((0.1, 0.4), 5.0, (0.4, 0.7, PI + 0.6)),
        ],
    };

    fn d(alpha: (f64, f64), m: DVec3) -> f64 {
        let (e_x, e_y, c) = exponents(alpha);
        let (x2, y2) = ((m.x / m.z).powi(2), (m.y / m.z).powi(2));
        if (x2 + y2).is_finite() {
            return c * log_phong((e_x, e_y), x2, y2).exp();
        }
        // Near the horizon the slopes overflow (∞·0 or ∞/∞ in `log_phong`): cos^{e(φ)}θ read
        // from m itself, e(φ) = (e_x m_x² + e_y m_y²)/(m_x² + m_y²), ln cos θ = ln m_z − ½ ln|m|².
        let (mx2, my2) = (m.x * m.x, m.y * m.y);
        let e = (e_x * mx2 + e_y * my2) / (mx2 + my2);
        let log_cos = m.z.ln() - 0.5 * m.length_squared().ln();
        c * (e * log_cos).exp()
    }

    /// D reads H through the ratios H_x/H_z and H_y/H_z only.
    fn d_of_half_vector(alpha: (f64, f64), half: DVec3) -> f64 {
        let length2 = half.length_squared();
        Self::d(alpha, half) / (length2 * length2)
    }

    /// From the table of [`smith`], built once per roughness.
    fn lambda(alpha: (f64, f64), w: DVec3) -> f64 {
        SmithTable::lambda_of(alpha, w)
    }

    fn lambda_times_cos(alpha: (f64, f64), w: DVec3) -> f64 {
        SmithTable::lambda_times_cos_of(alpha, w)
    }

    fn smith_table(alpha: (f64, f64)) -> Option<Arc<SmithTable>> {
        Some(SmithTable::of(alpha))
    }

    /// p = C cos^{e(φ)+1}θ ≤ C cos^{e_m+1}θ with e_m = min(e_x, e_y), decreasing in θ: its value
    /// at t_near, C (1 + t_near)^{−(e_m+1)/2}.
    fn particle_density_bound(alpha: (f64, f64), t_near: f64, _t_far: f64) -> f64 {
        let (e_x, e_y, c) = exponents(alpha);
        c * (-0.5 * (e_x.min(e_y) + 1.0) * t_near.ln_1p()).exp()
    }

    fn sample_normal(alpha: (f64, f64), u: [f64; 2]) -> DVec3 {
        let (e_x, e_y, _) = exponents(alpha);
        let quadrant = (4.0 * u[1]).floor().clamp(0.0, 3.0);
        let v = 4.0 * u[1] - quadrant;
        let first = ((e_x + 2.0) / (e_y + 2.0)).sqrt() * (std::f64::consts::FRAC_PI_2 * v).tan();
        let phi = first.atan();
        let (sin, cos) = phi.sin_cos();
        let (cos, sin) = match quadrant as u8 {
            0 => (cos, sin),
            1 => (-cos, sin),
            2 => (-cos, -sin),
            _ => (cos, -sin),
        };
        let e = e_x * cos * cos + e_y * sin * sin;
        let u0 = (1.0 - u[0]).max(f64::MIN_POSITIVE);
        let tan = (-2.0 * u0.ln() / (e + 2.0)).exp_m1().sqrt();
        DVec3::new(tan * cos, tan * sin, 1.0).normalize()
    }

    fn ray_mass(
        (alpha_x, alpha_y): (f64, f64),
        (cos_psi, sin_psi): (f64, f64),
        a: f64,
        b: f64,
    ) -> f64 {
        let (e_x, e_y, _) = exponents((alpha_x, alpha_y));
        let (x2, y2) = ((alpha_x * cos_psi).powi(2), (alpha_y * sin_psi).powi(2));
        let a2 = x2 + y2;
        let k_minus_one = 0.5 * (e_x * x2 + e_y * y2) / a2 + 1.0;
        // 2π · C α_x α_y / (2A²K) = 1/(A²K), times (1 + A²a²)^{−K} − (1 + A²b²)^{−K}.
        let near = -k_minus_one * (a2 * a * a).ln_1p();
        let difference = if b.is_infinite() {
            near.exp()
        } else {
            let between = (a2 * (b - a) * (b + a) / (1.0 + a2 * a * a)).ln_1p();
            -near.exp() * (-k_minus_one * between).exp_m1()
        };
        difference / (a2 * k_minus_one)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distribution::{DistributionKind, Microfacet};

    fn lobe(alpha_x: f64, alpha_y: f64) -> Microfacet {
        Microfacet::new(DistributionKind::AshikhminShirley, alpha_x, alpha_y).unwrap()
    }

    /// ∫ f(θ, φ) sin θ dθ dφ over the hemisphere by the midpoint rule in (cos θ, φ), with cos θ
    /// spaced as 1 − s² so that narrow lobes at the normal get points.
    fn hemisphere(f: impl Fn(DVec3) -> f64, rings: usize, spokes: usize) -> f64 {
        let mut sum = 0.0;
        for i in 0..rings {
            let s = (i as f64 + 0.5) / rings as f64;
            let cos = 1.0 - s * s;
            let sin = (1.0 - cos * cos).max(0.0).sqrt();
            let weight = 2.0 * s / rings as f64 * std::f64::consts::TAU / spokes as f64;
            for j in 0..spokes {
                let phi = std::f64::consts::TAU * (j as f64 + 0.5) / spokes as f64;
                sum += weight * f(DVec3::new(sin * phi.cos(), sin * phi.sin(), cos));
            }
        }
        sum
    }

    /// The exponents' map and D's constant: the same peak as Beckmann, D(n) = 1/(π α_x α_y),
    /// and near the normal the same lobe for small α.
    #[test]
    fn the_lobe_is_beckmanns_near_the_normal() {
        let (ashikhmin, beckmann) = (
            lobe(0.02, 0.05),
            Microfacet::new(DistributionKind::Beckmann, 0.02, 0.05).unwrap(),
        );
        assert!((ashikhmin.d(DVec3::Z) / beckmann.d(DVec3::Z) - 1.0).abs() < 1e-14);
        for (x, y) in [(0.01, 0.0), (0.0, 0.04), (0.02, -0.05)] {
            let m = DVec3::new(x, y, 1.0).normalize();
            let ratio = ashikhmin.d(m) / beckmann.d(m);
            assert!((ratio - 1.0).abs() < 5e-3, "{x} {y}: {ratio}");
        }
        let (e_x, e_y, _) = exponents((0.1, 0.4));
        assert!((e_x - 198.0).abs() < 1e-12 && (e_y - 10.5).abs() < 1e-12);
    }

    /// ∫ p = 1, and Smith's identity (1 + Λ(ω)) cos θ = ∫ D(m) max(0, ω·m) dm, both against a
    /// fine quadrature of D itself: Λ's own quadrature is checked against its definition.
    #[test]
    fn p_integrates_to_one_and_lambda_is_smiths() {
        for (alpha_x, alpha_y) in [(0.1, 0.4), (0.3, 0.3), (1.0, 0.5), (0.05, 0.05)] {
            let d = lobe(alpha_x, alpha_y);
            let total = hemisphere(|m| d.particle_density(m), 4000, 512);
            assert!(
                (total - 1.0).abs() < 1e-5,
                "({alpha_x}, {alpha_y}): ∫p = {total}"
            );
            for (theta, phi) in [
                (0.5f64, 0.3f64),
                (1.2, 1.0),
                (1.5, 2.5),
                (1.56, 0.0),
                (1.3, std::f64::consts::FRAC_PI_2),
            ] {
                let w = DVec3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                );
                let projected = hemisphere(|m| d.d(m) * w.dot(m).max(0.0), 4000, 2048);
                let lambda = d.lambda(w);
                let expected = projected / w.z - 1.0;
                assert!(
                    (lambda - expected).abs() < 1e-4 * (1.0 + expected),
                    "({alpha_x}, {alpha_y}) θ {theta} φ {phi}: Λ {lambda} vs {expected}"
                );
            }
        }
    }

    /// The rays' closed form against the radial integral of p along each ray, and their total
    /// mass over ψ is 1.
    #[test]
    fn ray_mass_is_the_lobes_mass_along_the_ray() {
        let (alpha_x, alpha_y) = (0.1, 0.4);
        let d = lobe(alpha_x, alpha_y);
        let mut total = 0.0;
        let spokes = 4096;
        for j in 0..spokes {
            let psi = std::f64::consts::TAU * (j as f64 + 0.5) / spokes as f64;
            let direction = (psi.cos(), psi.sin());
            let whole = d.ray_mass(direction, 0.0, f64::INFINITY);
            total += whole / spokes as f64;
            // p(m) dm = P22 α_x α_y ρ dρ dψ with P22 = D cos⁴θ, from 0.5 to 2.
            let (a, b, steps) = (0.5, 2.0, 20_000);
            let mut sum = 0.0;
            for k in 0..steps {
                let rho = a + (b - a) * (k as f64 + 0.5) / steps as f64;
                let m = DVec3::new(
                    alpha_x * rho * direction.0,
                    alpha_y * rho * direction.1,
                    1.0,
                )
                .normalize();
                sum += d.d(m) * m.z.powi(4) * alpha_x * alpha_y * rho * (b - a) / steps as f64;
            }
            let part = d.ray_mass(direction, a, b);
            if j % 97 == 0 {
                assert!(
                    (part - std::f64::consts::TAU * sum).abs() < 1e-7 * part.max(1e-30),
                    "ψ {psi}: {part} vs {}",
                    std::f64::consts::TAU * sum
                );
            }
        }
        assert!((total - 1.0).abs() < 1e-9, "{total}");
    }
}
