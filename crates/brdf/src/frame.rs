//! Local shading frames: an orthonormal basis around a unit vector, for moving directions
//! between world space and the frame (n = +z) that every BRDF here works in.

use glam::DVec3;

/// Two unit vectors (t, b) completing unit `axis` to a right-handed orthonormal basis,
/// t × b = axis (Duff et al. 2017, "Building an Orthonormal Basis, Revisited"). Continuous
/// except across the plane z = 0, where the sign of z flips the basis.
#[must_use]
pub fn orthonormal_basis(axis: DVec3) -> (DVec3, DVec3) {
    let sign = 1.0_f64.copysign(axis.z);
    let a = -1.0 / (sign + axis.z);
    let b = axis.x * axis.y * a;
    (
        DVec3::new(1.0 + sign * axis.x * axis.x * a, sign * b, -sign * axis.x),
        DVec3::new(b, sign + axis.y * axis.y * a, -axis.y),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn basis_is_orthonormal_and_right_handed() {
        for n in [
            DVec3::Z,
            -DVec3::Z,
            DVec3::new(0.3, -0.4, 0.866).normalize(),
            DVec3::X,
        ] {
            let (t, b) = orthonormal_basis(n);
            assert!(t.dot(b).abs() < 1e-12 && t.dot(n).abs() < 1e-12 && b.dot(n).abs() < 1e-12);
            assert!((t.length() - 1.0).abs() < 1e-12 && (b.length() - 1.0).abs() < 1e-12);
            assert!((t.cross(b) - n).length() < 1e-12);
        }
    }
}
