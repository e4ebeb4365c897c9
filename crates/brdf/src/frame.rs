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

/// `v` scaled to unit length, or `None` for a zero or non-finite vector. Any finite magnitude
/// works: a vector whose squared length overflows or underflows (`[1e200, 0, 1e200]`) is first
/// divided by its largest component; any other is normalized as `DVec3::normalize` does.
#[must_use]
pub fn unit_direction(v: DVec3) -> Option<DVec3> {
    if !v.is_finite() || v == DVec3::ZERO {
        return None;
    }
    let squared = v.length_squared();
    let v = if squared.is_finite() && squared >= f64::MIN_POSITIVE {
        v
    } else {
        v / v.abs().max_element()
    };
    Some(v.normalize())
}

/// A direction as a caller gives it: a vector of unit length to rounding (its squared length
/// within 4ε of 1) is used as it is, any other finite, non-zero vector is normalized by
/// [`unit_direction`]; `None` for a zero or non-finite vector. Every interface that takes
/// directions from another language (glint-eval, and so `cargo xtask eval` and Python; the C
/// API) goes through it, so that they answer bit for bit alike, and a sampled direction passed
/// back gives the sample's own pdf (normalizing a unit vector again may move its last bit).
#[must_use]
pub fn given_direction(v: DVec3) -> Option<DVec3> {
    /// A few roundings of a computed unit vector.
    const UNIT_TOLERANCE: f64 = 4.0 * f64::EPSILON;
    if v.is_finite() && (v.length_squared() - 1.0).abs() <= UNIT_TOLERANCE {
        return Some(v);
    }
    unit_direction(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_directions_of_any_finite_magnitude() {
        for scale in [1e-310, 1e-200, 1.0, 3.0, 1e200, f64::MAX] {
            let d = unit_direction(DVec3::new(scale, 0.0, scale)).unwrap();
            assert!(
                (d - DVec3::new(1.0, 0.0, 1.0).normalize()).length() < 1e-15,
                "{scale}"
            );
        }
        let v = DVec3::new(0.3, -0.2, 0.7);
        assert_eq!(unit_direction(v), Some(v.normalize()));
        assert_eq!(unit_direction(DVec3::ZERO), None);
        assert_eq!(unit_direction(DVec3::new(f64::NAN, 0.0, 1.0)), None);
    }

    /// Unit vectors to rounding pass unchanged, even where normalizing would move a bit; any
    /// other vector is `unit_direction`'s.
    #[test]
    fn given_directions_keep_unit_vectors() {
        let mut moved = 0;
        for i in 0..1000 {
            let t = f64::from(i) * 0.01;
            let unit = DVec3::new(
                t.sin() * (3.0 * t).cos(),
                t.sin() * (3.0 * t).sin(),
                t.cos(),
            );
            assert_eq!(given_direction(unit), Some(unit));
            moved += usize::from(unit.normalize() != unit);
        }
        assert!(moved > 0, "the case is not vacuous");
        for v in [
            DVec3::new(3.0, 0.0, 4.0),
            DVec3::new(1e200, 0.0, 1e200),
            DVec3::new(0.0, 0.0, 1.0 + 1e-14),
        ] {
            assert_eq!(given_direction(v), unit_direction(v));
        }
        assert_eq!(given_direction(DVec3::ZERO), None);
        assert_eq!(given_direction(DVec3::new(f64::NAN, 0.0, 1.0)), None);
    }

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
