//! Cones of directions: the cone of radius γ around ω_o that the glint model reflects into
//! (Sec. 3.1), its solid angle, and directions drawn uniformly in it.

use glam::DVec3;

use crate::frame::orthonormal_basis;

/// The solid angle of a cone of radius γ, σ = 2π(1 − cos γ), written as 4π sin²(γ/2) so that it
/// keeps its precision for tiny γ. (The paper's Eq. 5 prints π(1 − cos γ), half of it.)
#[must_use]
pub fn cone_solid_angle(gamma: f64) -> f64 {
    4.0 * std::f64::consts::PI * (0.5 * gamma).sin().powi(2)
}

/// 1 − cos γ, written as 2 sin²(γ/2) so that it keeps its precision for tiny γ: the size of the
/// cone that [`uniform_in_cap`] takes.
#[must_use]
pub fn cone_versine(gamma: f64) -> f64 {
    2.0 * (0.5 * gamma).sin().powi(2)
}

/// A direction uniform (in solid angle) in the cone of radius γ around unit `axis`, from two
/// uniform numbers: 1 − cos θ = u·(1 − cos γ), φ = 2πv.
#[must_use]
pub fn uniform_in_cone(axis: DVec3, gamma: f64, u: f64, v: f64) -> DVec3 {
    uniform_in_cap(axis, cone_versine(gamma), u, v)
}

/// [`uniform_in_cone`] for a cone given by its `versine` 1 − cos γ ([`cone_versine`]), for
/// callers that draw many directions in one cone.
#[must_use]
pub fn uniform_in_cap(axis: DVec3, versine: f64, u: f64, v: f64) -> DVec3 {
    let one_minus_cos = u * versine;
    let sin_theta = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
    let phi = 2.0 * std::f64::consts::PI * v;
    let (t, s) = orthonormal_basis(axis);
    ((1.0 - one_minus_cos) * axis + sin_theta * (phi.cos() * t + phi.sin() * s)).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cone_directions_stay_in_the_cone() {
        let axis = DVec3::new(0.3, -0.2, 0.9).normalize();
        for gamma in [1e-4, 0.1, 1.0] {
            for (u, v) in [(0.0, 0.0), (1.0, 0.3), (0.5, 0.9)] {
                let w = uniform_in_cone(axis, gamma, u, v);
                assert!((w.length() - 1.0).abs() < 1e-12);
                assert!(w.dot(axis) >= gamma.cos() - 1e-12);
            }
        }
    }

    #[test]
    fn solid_angle_is_the_cap_area() {
        for gamma in [0.01, 1.0, 3.0] {
            let direct = 2.0 * std::f64::consts::PI * (1.0 - f64::cos(gamma));
            assert!((cone_solid_angle(gamma) - direct).abs() <= 1e-12 * direct);
        }
        // Tiny cones: σ = πγ²(1 − γ²/12 + …), where 1 − cos γ has lost every digit.
        let gamma = 1e-7;
        let small = std::f64::consts::PI * gamma * gamma;
        assert!((cone_solid_angle(gamma) - small).abs() <= 1e-12 * small);
    }
}
