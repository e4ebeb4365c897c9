//! Microfacet distributions: Beckmann and GGX, isotropic and anisotropic (α_x, α_y).
//!
//! All directions are in the local shading frame (n = +z). For a unit normal m with
//! slopes (x/z, y/z):
//!
//! ```text
//!   Beckmann:  D(m) = exp(−(x²/α_x² + y²/α_y²)/z²) / (π α_x α_y z⁴)
//!   GGX:       D(m) = 1 / (π α_x α_y z⁴ (1 + (x²/α_x² + y²/α_y²)/z²)²)
//! ```
//!
//! Both satisfy ∫ D(m)(m·n) dm = 1 over the hemisphere: p(m) = D(m)(m·n) is the density of
//! particle normals the count tree uses ([`Microfacet::particle_density`]).
//!
//! Smith's Λ for a direction ω with a = 1/(α_ω tan θ) and α_ω² = cos²φ α_x² + sin²φ α_y², i.e.
//! a = z / √(α_x² x² + α_y² y²):
//!
//! ```text
//!   Beckmann:  Λ = (erf(a) − 1)/2 + exp(−a²)/(2a√π)
//!   GGX:       Λ = (−1 + √(1 + 1/a²))/2
//! ```
//!
//! G1(ω, m) = χ⁺(ω·m)/(1 + Λ(ω)); G(ω_i, ω_o, m) is the height-correlated form
//! χ⁺(ω_i·m)χ⁺(ω_o·m)/(1 + Λ(ω_i) + Λ(ω_o)) (Heitz 2014), exact for these distributions.

use glam::DVec3;

use crate::error::BrdfError;

/// Which microfacet distribution.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DistributionKind {
    /// Beckmann (Gaussian slopes).
    Beckmann,
    /// GGX / Trowbridge–Reitz.
    Ggx,
}

/// How normals are sampled.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum NormalSampling {
    /// From p(m) = D(m)(m·n), the standard method (Walter et al. 2007).
    #[default]
    Distribution,
    /// From the distribution of normals visible from ω_i (Heitz 2018 for GGX, Heitz and
    /// d'Eon 2014 for Beckmann).
    Visible,
}

/// A microfacet distribution with its roughness (α_x, α_y).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Microfacet {
    kind: DistributionKind,
    alpha_x: f64,
    alpha_y: f64,
}

/// The smallest roughness accepted; below it the distributions are numerically a delta.
pub const MIN_ALPHA: f64 = 1e-4;

impl Microfacet {
    /// A distribution with roughness (α_x, α_y) in [1e-4, 1] (α_x = α_y is isotropic).
    ///
    /// # Errors
    /// [`BrdfError::InvalidRoughness`] for α outside [1e-4, 1] or not finite.
    pub fn new(kind: DistributionKind, alpha_x: f64, alpha_y: f64) -> Result<Self, BrdfError> {
        for alpha in [alpha_x, alpha_y] {
            if !(MIN_ALPHA..=1.0).contains(&alpha) {
                return Err(BrdfError::InvalidRoughness { alpha });
            }
        }
        Ok(Self {
            kind,
            alpha_x,
            alpha_y,
        })
    }

    /// The distribution kind.
    #[must_use]
    pub fn kind(&self) -> DistributionKind {
        self.kind
    }

    /// (α_x, α_y).
    #[must_use]
    pub fn alpha(&self) -> (f64, f64) {
        (self.alpha_x, self.alpha_y)
    }

    /// The same distribution with both roughnesses scaled by `factor`, clamped to [1e-4, 1]
    /// (the widened sampling distribution of Sec. 3.4).
    #[must_use]
    pub fn scaled(&self, factor: f64) -> Self {
        Self {
            kind: self.kind,
            alpha_x: (self.alpha_x * factor).clamp(MIN_ALPHA, 1.0),
            alpha_y: (self.alpha_y * factor).clamp(MIN_ALPHA, 1.0),
        }
    }

    /// D(m) for a unit normal m (0 below the horizon).
    #[must_use]
    pub fn d(&self, m: DVec3) -> f64 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let z2 = m.z * m.z;
        let slope2 = (m.x * m.x / (self.alpha_x * self.alpha_x)
            + m.y * m.y / (self.alpha_y * self.alpha_y))
            / z2;
        let normalization = std::f64::consts::PI * self.alpha_x * self.alpha_y * z2 * z2;
        match self.kind {
            DistributionKind::Beckmann => (-slope2).exp() / normalization,
            DistributionKind::Ggx => 1.0 / (normalization * (1.0 + slope2) * (1.0 + slope2)),
        }
    }

    /// D(h)(h·n)/(4 ω_i·h), the density of ω_o = reflect(ω_i, h) for normals h drawn from
    /// D(h)(h·n), from the unnormalized half vector H = ω_i + ω_o (0 unless H.z > 0 and
    /// ω_i·H > 0). No square root: [`Microfacet::d`] of H is D(h)/|H|⁴ (its slope term depends
    /// on H's direction only, its normalization on H_z⁴), and (h·n)/(ω_i·h) = H_z/(ω_i·H).
    #[inline]
    #[must_use]
    pub fn reflected_density(&self, wi: DVec3, half: DVec3) -> f64 {
        let cos = wi.dot(half);
        if !(half.z > 0.0 && cos > 0.0) {
            return 0.0;
        }
        let length2 = half.length_squared();
        self.d(half) * length2 * length2 * half.z / (4.0 * cos)
    }

    /// p(m) = D(m)(m·n): the density of particle normals, which integrates to 1.
    #[must_use]
    pub fn particle_density(&self, m: DVec3) -> f64 {
        self.d(m) * m.z.max(0.0)
    }

    /// An upper bound on p(m) = D(m)(m·n) over the unit normals whose angle θ from n lies
    /// between the angles of `cos_near` and `cos_far` (cos_near ≥ cos_far; cos_far ≤ 0 reaches
    /// the horizon). For the negligible-query test of [`crate::DiscreteBrdf`].
    ///
    /// With t = tan²θ and α_m = max(α_x, α_y), the slope term obeys
    /// (x²/α_x² + y²/α_y²)/z² ≥ t/α_m², so for both distributions
    ///
    /// ```text
    ///   Beckmann:  p ≤ P(t) = (1 + t)^{3/2} e^{−t/α_m²}      / (π α_x α_y)
    ///   GGX:       p ≤ P(t) = (1 + t)^{3/2} / (1 + t/α_m²)²  / (π α_x α_y)
    /// ```
    ///
    /// using z⁻³ = (1 + t)^{3/2}. Each P is unimodal in t: d ln P/dt is 3/(2(1 + t)) − 1/α_m²
    /// (Beckmann) or 3/(2(1 + t)) − 2/(α_m² + t) (GGX), which changes sign once, at
    /// t* = 3α_m²/2 − 1 and t* = 3α_m² − 4 respectively (t* ≤ 0 means P decreases from the
    /// normal on). The maximum over [t_near, t_far] is therefore P(clamp(t*, t_near, t_far)).
    #[must_use]
    pub fn particle_density_bound(&self, cos_near: f64, cos_far: f64) -> f64 {
        let tan2 = |c: f64| {
            if c <= 0.0 {
                f64::INFINITY
            } else {
                (1.0 - c * c).max(0.0) / (c * c)
            }
        };
        let (t_near, t_far) = (tan2(cos_near.min(1.0)), tan2(cos_far));
        let alpha2 = self.alpha_x.max(self.alpha_y).powi(2);
        let t_peak = match self.kind {
            DistributionKind::Beckmann => 1.5 * alpha2 - 1.0,
            DistributionKind::Ggx => 3.0 * alpha2 - 4.0,
        };
        let t = t_peak.clamp(t_near, t_far.max(t_near));
        if !t.is_finite() {
            return 0.0;
        }
        let normalization = std::f64::consts::PI * self.alpha_x * self.alpha_y;
        let rise = (1.0 + t) * (1.0 + t).sqrt();
        match self.kind {
            DistributionKind::Beckmann => rise * (-t / alpha2).exp() / normalization,
            DistributionKind::Ggx => {
                let fall = 1.0 + t / alpha2;
                rise / (fall * fall * normalization)
            }
        }
    }

    /// Smith's Λ(ω) for a unit direction ω above the horizon.
    #[must_use]
    pub fn lambda(&self, w: DVec3) -> f64 {
        if w.z <= 0.0 {
            return f64::INFINITY;
        }
        // a = cos θ / (α(φ) sin θ) = w.z / √projected².
        let projected_squared = (self.alpha_x * w.x).powi(2) + (self.alpha_y * w.y).powi(2);
        if projected_squared == 0.0 {
            return 0.0;
        }
        match self.kind {
            DistributionKind::Beckmann => {
                // For a > 6, erf(a) = 1 and exp(−a²) < 3e-16: Λ is 0 to double precision
                // (tested without the square root: a² > 36).
                if w.z * w.z > 36.0 * projected_squared {
                    return 0.0;
                }
                let a = w.z / projected_squared.sqrt();
                0.5 * (erf(a) - 1.0) + (-a * a).exp() / (2.0 * a * std::f64::consts::PI.sqrt())
            }
            // 1/a² = projected²/w.z².
            DistributionKind::Ggx => 0.5 * ((1.0 + projected_squared / (w.z * w.z)).sqrt() - 1.0),
        }
    }

    /// G1(ω, m) = χ⁺(ω·m)/(1 + Λ(ω)).
    #[must_use]
    pub fn g1(&self, w: DVec3, m: DVec3) -> f64 {
        if w.dot(m) <= 0.0 || w.z <= 0.0 {
            return 0.0;
        }
        1.0 / (1.0 + self.lambda(w))
    }

    /// The height-correlated G(ω_i, ω_o, m).
    #[must_use]
    pub fn g(&self, wi: DVec3, wo: DVec3, m: DVec3) -> f64 {
        if wi.dot(m) <= 0.0 || wo.dot(m) <= 0.0 || wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        1.0 / (1.0 + self.lambda(wi) + self.lambda(wo))
    }

    /// A normal drawn from p(m) = D(m)(m·n), from two uniforms: the slopes are drawn from
    /// their distribution (Gaussian for Beckmann, the bivariate Student-like P22 for GGX),
    /// stretched by (α_x, α_y), and m = normalize(−s_x, −s_y, 1).
    #[must_use]
    pub fn sample_normal(&self, u: [f64; 2]) -> DVec3 {
        let u0 = u[0].min(1.0 - f64::EPSILON);
        let radius = match self.kind {
            DistributionKind::Beckmann => (-(1.0 - u0).ln()).sqrt(),
            DistributionKind::Ggx => (u0 / (1.0 - u0)).sqrt(),
        };
        let phi = 2.0 * std::f64::consts::PI * u[1];
        let slope_x = self.alpha_x * radius * phi.cos();
        let slope_y = self.alpha_y * radius * phi.sin();
        DVec3::new(-slope_x, -slope_y, 1.0).normalize()
    }

    /// The density of [`Microfacet::sample_normal`] in solid angle: D(m)(m·n).
    #[must_use]
    pub fn normal_pdf(&self, m: DVec3) -> f64 {
        self.particle_density(m)
    }

    /// A normal drawn from the visible normals seen from ω_i.
    ///
    /// GGX: Heitz 2018, "Sampling the GGX Distribution of Visible Normals": stretch ω_i to the
    /// unit-roughness configuration, sample the projected hemisphere, unstretch.
    ///
    /// Beckmann: Heitz and d'Eon 2014, slope space: stretch ω_i, then for unit roughness and
    /// μ = cot θ the visible slope along the incident azimuth has density ∝ (μ − x)e^(−x²) on
    /// x < μ, with CDF ∝ μ(1 + erf x)/2 + e^(−x²)/(2√π), inverted by bisection; the
    /// perpendicular slope is Gaussian (an inverted erf); rotate to the incident azimuth,
    /// unstretch, and m = normalize(−s_x, −s_y, 1).
    #[must_use]
    pub fn sample_visible_normal(&self, wi: DVec3, u: [f64; 2]) -> DVec3 {
        match self.kind {
            DistributionKind::Ggx => self.sample_visible_ggx(wi, u),
            DistributionKind::Beckmann => self.sample_visible_beckmann(wi, u),
        }
    }

    fn sample_visible_ggx(&self, wi: DVec3, u: [f64; 2]) -> DVec3 {
        let v = DVec3::new(self.alpha_x * wi.x, self.alpha_y * wi.y, wi.z).normalize();
        let length2 = v.x * v.x + v.y * v.y;
        let t1 = if length2 > 0.0 {
            DVec3::new(-v.y, v.x, 0.0) / length2.sqrt()
        } else {
            DVec3::X
        };
        let t2 = v.cross(t1);
        let r = u[0].sqrt();
        let phi = 2.0 * std::f64::consts::PI * u[1];
        let p1 = r * phi.cos();
        let s = 0.5 * (1.0 + v.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
        let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * v;
        DVec3::new(self.alpha_x * nh.x, self.alpha_y * nh.y, nh.z.max(1e-12)).normalize()
    }

    fn sample_visible_beckmann(&self, wi: DVec3, u: [f64; 2]) -> DVec3 {
        let v = DVec3::new(self.alpha_x * wi.x, self.alpha_y * wi.y, wi.z).normalize();
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
        let sqrt_pi = std::f64::consts::PI.sqrt();
        let numerator = |x: f64| mu * 0.5 * (1.0 + erf(x)) + (-x * x).exp() / (2.0 * sqrt_pi);
        let upper = mu.min(6.0);
        let target = u[0] * numerator(upper);
        let slope_along = bisect(|x| numerator(x) - target, -6.0, upper);
        let slope_across = bisect(|y| erf(y) - (2.0 * u[1] - 1.0), -6.0, 6.0);
        let (x, y) = (
            cos_phi * slope_along - sin_phi * slope_across,
            sin_phi * slope_along + cos_phi * slope_across,
        );
        DVec3::new(-self.alpha_x * x, -self.alpha_y * y, 1.0).normalize()
    }

    /// The density of [`Microfacet::sample_visible_normal`]: G1(ω_i, m)·max(0, ω_i·m)·D(m)/ω_i.z.
    #[must_use]
    pub fn visible_normal_pdf(&self, wi: DVec3, m: DVec3) -> f64 {
        if wi.z <= 0.0 {
            return 0.0;
        }
        self.g1(wi, m) * wi.dot(m).max(0.0) * self.d(m) / wi.z
    }
}

/// The root of increasing `f` in [lo, hi] by bisection to double precision.
fn bisect(f: impl Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> f64 {
    for _ in 0..64 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if f(mid) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The error function, to ~1e-15: for |x| < 2.5 the series
/// erf(x) = 2/√π·e^(−x²)·Σ 2ⁿx^(2n+1)/(1·3·…·(2n+1)) (positive terms, no cancellation), beyond
/// 1 − erfc(x) with erfc's continued fraction e^(−x²)/√π · 1/(x + ½/(x + 1/(x + (3/2)/(x + …)))),
/// truncated at ⌈200/x²⌉ levels.
#[must_use]
pub fn erf(x: f64) -> f64 {
    let a = x.abs();
    let value = if a < 2.5 {
        let two_x2 = 2.0 * a * a;
        let mut term = a;
        let mut sum = a;
        let mut n = 0.0;
        while term > 1e-17 * sum {
            n += 1.0;
            term *= two_x2 / (2.0 * n + 1.0);
            sum += term;
        }
        2.0 / std::f64::consts::PI.sqrt() * (-a * a).exp() * sum
    } else {
        // ⌈200/x²⌉ levels reach 2e-17 absolute on erfc for x ≥ 2.5 (29 levels at 2.5, 3 at 5;
        // checked against a 40-digit evaluation).
        1.0 - erfc_continued_fraction(a, (200.0 / (a * a)).ceil().min(80.0) as u32)
    };
    value.copysign(x)
}

/// erfc(x) for x ≥ 2.5 by its continued fraction e^(−x²)/√π · 1/(x + ½/(x + 1/(x + (3/2)/(x +
/// …)))) truncated at `levels` levels: [`erf`]'s tail, and with 60 levels a reference to a
/// relative 1e-15 for faster approximations.
pub(crate) fn erfc_continued_fraction(x: f64, levels: u32) -> f64 {
    let mut fraction = x;
    for k in (1..=levels).rev() {
        fraction = x + (f64::from(k) * 0.5) / fraction;
    }
    (-x * x).exp() / (std::f64::consts::PI.sqrt() * fraction)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn erf_matches_reference_values() {
        for (x, expected) in [
            (0.0, 0.0),
            (0.1, 0.112_462_916_018_284_9),
            (1.0, 0.842_700_792_949_714_9),
            (2.0, 0.995_322_265_018_952_7),
            (2.49, 0.999_570_712_132_266_1),
            (2.51, 0.999_614_294_518_275_8),
            (3.5, 0.999_999_256_901_627_6),
            (-1.5, -0.966_105_146_475_310_8),
            (2.6, 0.999_763_965_583_470_7),
            (2.75, 0.999_899_378_077_880_3),
            (3.2, 0.999_993_974_238_848_3),
            (4.5, 0.999_999_999_803_383_9),
            (5.5, 0.999_999_999_999_992_7),
        ] {
            let got = erf(x);
            assert!(
                (got - expected).abs() < 2e-15,
                "erf({x}) = {got}, expected {expected}"
            );
        }
    }

    #[test]
    fn known_values() {
        for kind in [DistributionKind::Beckmann, DistributionKind::Ggx] {
            let d = Microfacet::new(kind, 0.3, 0.1).unwrap();
            // D(n) = 1/(π α_x α_y) for both.
            assert!((d.d(DVec3::Z) - 1.0 / (std::f64::consts::PI * 0.03)).abs() < 1e-12);
            assert_eq!(d.lambda(DVec3::Z), 0.0);
            assert_eq!(d.d(DVec3::new(0.0, 0.6, -0.8)), 0.0);
        }
        assert!(Microfacet::new(DistributionKind::Ggx, 0.0, 0.1).is_err());
        assert!(Microfacet::new(DistributionKind::Ggx, 0.1, f64::NAN).is_err());
        assert!(Microfacet::new(DistributionKind::Beckmann, 1.5, 0.1).is_err());
    }

    /// The square-root-free density against its definition with the normalized half vector,
    /// for any length of H.
    #[test]
    fn reflected_density_is_d_times_the_jacobian() {
        for kind in [DistributionKind::Beckmann, DistributionKind::Ggx] {
            let d = Microfacet::new(kind, 0.3, 0.1).unwrap();
            for (wi, wo) in [
                (DVec3::new(0.2, -0.1, 0.9), DVec3::new(-0.3, 0.2, 0.8)),
                (DVec3::new(0.9, 0.1, 0.05), DVec3::new(-0.5, 0.4, 0.3)),
                (DVec3::Z, DVec3::new(0.1, 0.0, 1.0)),
            ] {
                let (wi, wo) = (wi.normalize(), wo.normalize());
                let h = (wi + wo).normalize();
                let expected = d.d(h) * h.z / (4.0 * wi.dot(h));
                for scale in [1.0, 1e-3, 7.0] {
                    let got = d.reflected_density(wi, scale * (wi + wo));
                    assert!(
                        (got - expected).abs() <= 1e-13 * expected,
                        "{kind:?}: {got} against {expected}"
                    );
                }
            }
            // Below the horizon, and facing away from ω_i: 0.
            assert_eq!(
                d.reflected_density(DVec3::Z, DVec3::new(0.3, 0.0, -0.1)),
                0.0
            );
            let wi = DVec3::new(0.8, 0.0, 0.6);
            assert_eq!(d.reflected_density(wi, DVec3::new(-0.9, 0.0, 0.1)), 0.0);
        }
    }
}
