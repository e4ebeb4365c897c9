//! Fresnel reflectance: none (F = 1), conductors (complex index per RGB channel) and
//! dielectrics (the paper's flakes with η = 1.5), for unpolarized light.

use glam::DVec3;

use crate::error::BrdfError;

/// The Fresnel term of a material, per RGB channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Fresnel {
    /// F = 1 (the paper's metallic flakes without Fresnel effects).
    None,
    /// A conductor with complex index η + ik per channel.
    Conductor {
        /// Real part η per channel.
        eta: DVec3,
        /// Imaginary part k per channel.
        k: DVec3,
    },
    /// A dielectric with relative index η (outside to inside).
    Dielectric {
        /// η.
        eta: f64,
    },
}

impl Fresnel {
    /// Checks the parameters.
    ///
    /// # Errors
    /// [`BrdfError::InvalidFresnel`] for η ≤ 0, k < 0 or anything not finite.
    pub fn validated(self) -> Result<Self, BrdfError> {
        let ok = match self {
            Self::None => true,
            Self::Conductor { eta, k } => {
                eta.is_finite()
                    && k.is_finite()
                    && eta.min_element() > 0.0
                    && k.min_element() >= 0.0
            }
            Self::Dielectric { eta } => eta.is_finite() && eta > 0.0,
        };
        if ok {
            Ok(self)
        } else {
            Err(BrdfError::InvalidFresnel)
        }
    }

    /// Whether F is the same in every channel (the BRDF is then gray).
    #[must_use]
    pub fn is_gray(&self) -> bool {
        match self {
            Self::None | Self::Dielectric { .. } => true,
            Self::Conductor { eta, k } => {
                eta.x == eta.y && eta.y == eta.z && k.x == k.y && k.y == k.z
            }
        }
    }

    /// F at the cosine `cos_theta` between the incident direction and the facet normal.
    #[must_use]
    pub fn evaluate(&self, cos_theta: f64) -> DVec3 {
        let c = cos_theta.clamp(0.0, 1.0);
        match *self {
            Self::None => DVec3::ONE,
            Self::Dielectric { eta } => DVec3::splat(dielectric(c, eta)),
            Self::Conductor { eta, k } => DVec3::new(
                conductor(c, eta.x, k.x),
                conductor(c, eta.y, k.y),
                conductor(c, eta.z, k.z),
            ),
        }
    }
}

/// Exact dielectric reflectance: Fresnel's equations, with total internal reflection giving 1.
fn dielectric(cos_i: f64, eta: f64) -> f64 {
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_s = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let r_p = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    0.5 * (r_s * r_s + r_p * r_p)
}

/// Exact conductor reflectance for unpolarized light and complex index η + ik:
/// with s² = sin²θ, a² + b² = √((η² − k² − s²)² + 4η²k²), a² = ½(a² + b² + η² − k² − s²),
/// R_s = (a² + b² − 2a cos θ + cos²θ)/(a² + b² + 2a cos θ + cos²θ) and
/// R_p = R_s·(cos²θ(a² + b²) − 2a cos θ s² + s⁴)/(cos²θ(a² + b²) + 2a cos θ s² + s⁴).
fn conductor(cos_i: f64, eta: f64, k: f64) -> f64 {
    let c2 = cos_i * cos_i;
    let s2 = 1.0 - c2;
    let t0 = eta * eta - k * k - s2;
    let a2_plus_b2 = (t0 * t0 + 4.0 * eta * eta * k * k).sqrt();
    let a = (0.5 * (a2_plus_b2 + t0)).max(0.0).sqrt();
    let t1 = a2_plus_b2 + c2;
    let t2 = 2.0 * a * cos_i;
    let r_s = (t1 - t2) / (t1 + t2);
    let t3 = c2 * a2_plus_b2 + s2 * s2;
    let t4 = t2 * s2;
    let r_p = r_s * (t3 - t4) / (t3 + t4);
    0.5 * (r_s + r_p)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_incidence_matches_the_closed_forms() {
        // Dielectric: ((η − 1)/(η + 1))²; conductor: ((η − 1)² + k²)/((η + 1)² + k²).
        let f = Fresnel::Dielectric { eta: 1.5 }.evaluate(1.0);
        assert!((f.x - 0.04).abs() < 1e-12);
        let (eta, k) = (0.2, 3.0);
        let expected = ((eta - 1.0) * (eta - 1.0) + k * k) / ((eta + 1.0) * (eta + 1.0) + k * k);
        let f = Fresnel::Conductor {
            eta: DVec3::splat(eta),
            k: DVec3::splat(k),
        }
        .evaluate(1.0);
        assert!((f.x - expected).abs() < 1e-12);
        // A conductor with k = 0 is a dielectric.
        let f = Fresnel::Conductor {
            eta: DVec3::splat(1.5),
            k: DVec3::ZERO,
        }
        .evaluate(0.4);
        assert!((f.x - Fresnel::Dielectric { eta: 1.5 }.evaluate(0.4).x).abs() < 1e-12);
        // Grazing: 1; total internal reflection: 1.
        assert!((Fresnel::Dielectric { eta: 1.5 }.evaluate(0.0).x - 1.0).abs() < 1e-12);
        assert_eq!(Fresnel::Dielectric { eta: 1.0 / 1.5 }.evaluate(0.3).x, 1.0);
        assert!(Fresnel::Dielectric { eta: -1.0 }.validated().is_err());
    }
}
