//! Eq. 8's conic in slope space, where the lattice's directional cells are squares.
//!
//! A facet normal m (m_z > 0) has slope s = (m_x, m_y)/m_z, and m ∝ (s, 1). The conic's scaled
//! form q(m) = Σ_k c_k (f_k·m)² (Eq. 9's standard frame f_k, coefficients c_k) is a quadratic
//! form, so on the plane m_z = 1 the conic is {s : sᵀBs + 2bᵀs + c < 0}, with B, b, c the
//! blocks of A = Σ_k c_k f_k f_kᵀ. Where B is positive definite that set is an ellipse (the
//! valid nappe's section by the plane); the lattice needs that, and answers no other conic.

use glam::{DMat2, DVec2, DVec3};
use glint_sphere::SphericalConic;

/// The conic {s : sᵀBs + 2bᵀs + c < 0, ω_i·(s, 1) > 0} in slope space, an ellipse.
#[derive(Clone, Copy, Debug)]
pub(super) struct SlopeEllipse {
    quadratic: DMat2,
    linear: DVec2,
    constant: f64,
    wi: DVec3,
    /// The ellipse's centre −B⁻¹b.
    pub(super) center: DVec2,
    /// Half its bounding box's sides: √(−c′·(B⁻¹)_xx), √(−c′·(B⁻¹)_yy), c′ the form at the
    /// centre.
    pub(super) half_extent: DVec2,
    /// Its area π·√(c′²/det B).
    pub(super) area: f64,
}

impl SlopeEllipse {
    /// The conic in slope space, if it is an ellipse there (`None` for hyperbolic conics and
    /// for those whose section by m_z = 1 is unbounded: cones that reach the horizon).
    pub(super) fn of(conic: &SphericalConic) -> Option<Self> {
        let frame = conic.frame();
        let k = conic.scaled_coefficients();
        let mut a = [[0.0f64; 3]; 3];
        for (axis, coefficient) in frame.iter().zip([k.x, k.y, k.z]) {
            let v = axis.to_array();
            for (i, row) in a.iter_mut().enumerate() {
                for (j, entry) in row.iter_mut().enumerate() {
                    *entry += coefficient * v[i] * v[j];
                }
            }
        }
        let quadratic =
            DMat2::from_cols(DVec2::new(a[0][0], a[1][0]), DVec2::new(a[0][1], a[1][1]));
        let determinant = quadratic.determinant();
        if !(a[0][0] > 0.0 && determinant > 0.0) {
            return None;
        }
        let linear = DVec2::new(a[0][2], a[1][2]);
        let inverse = quadratic.inverse();
        let center = -(inverse * linear);
        let at_center = a[2][2] + linear.dot(center);
        let valid = conic.wi().dot(center.extend(1.0)) > 0.0;
        if !(at_center < 0.0 && valid && center.is_finite()) {
            return None;
        }
        let half_extent = DVec2::new(
            (-at_center * inverse.x_axis.x).sqrt(),
            (-at_center * inverse.y_axis.y).sqrt(),
        );
        let area = std::f64::consts::PI * -at_center / determinant.sqrt();
        half_extent.is_finite().then_some(Self {
            quadratic,
            linear,
            constant: a[2][2],
            wi: conic.wi(),
            center,
            half_extent,
            area,
        })
    }

    /// The form sᵀBs + 2bᵀs + c.
    #[inline]
    fn form(&self, s: DVec2) -> f64 {
        s.dot(self.quadratic * s) + 2.0 * self.linear.dot(s) + self.constant
    }

    /// The interval of x where the row at height `y` meets the ellipse, if it does: the
    /// roots of B₁₁x² + 2(B₁₂y + b₁)x + (B₂₂y² + 2b₂y + c).
    pub(super) fn row(&self, y: f64) -> Option<(f64, f64)> {
        let a = self.quadratic.x_axis.x;
        let half_b = self.quadratic.y_axis.x * y + self.linear.x;
        let c = (self.quadratic.y_axis.y * y + 2.0 * self.linear.y) * y + self.constant;
        let discriminant = half_b * half_b - a * c;
        (discriminant > 0.0).then(|| {
            let root = discriminant.sqrt();
            ((-half_b - root) / a, (-half_b + root) / a)
        })
    }

    /// Whether the normal of slope `s` lies in the conic (as [`SphericalConic::contains`]).
    #[inline]
    pub(super) fn contains(&self, s: DVec2) -> bool {
        self.form(s) < 0.0 && self.wi.dot(s.extend(1.0)) > 0.0
    }

    /// Whether the square [lo, lo + side]² meets the ellipse: the convex form's minimum over
    /// the square is negative (at the centre if the square holds it, else on an edge).
    pub(super) fn meets_square(&self, lo: DVec2, side: f64) -> bool {
        let hi = lo + DVec2::splat(side);
        if self.center.cmpge(lo).all() && self.center.cmple(hi).all() {
            return true;
        }
        // The minimum of f(p + t·d), t ∈ [0, 1]: t² dᵀBd + 2t dᵀ(Bp + b) + f(p).
        let edge_minimum = |p: DVec2, d: DVec2| {
            let curvature = d.dot(self.quadratic * d);
            let slope = d.dot(self.quadratic * p + self.linear);
            self.form(p + (-slope / curvature).clamp(0.0, 1.0) * d)
        };
        let (dx, dy) = (DVec2::new(side, 0.0), DVec2::new(0.0, side));
        edge_minimum(lo, dx) < 0.0
            || edge_minimum(lo, dy) < 0.0
            || edge_minimum(lo + dy, dx) < 0.0
            || edge_minimum(lo + dx, dy) < 0.0
    }

    /// Whether the square [lo, lo + side]² lies inside the conic: its four corners do (the
    /// ellipse is convex; the half-plane ω_i·(s, 1) > 0 too).
    pub(super) fn holds_square(&self, lo: DVec2, side: f64) -> bool {
        [
            lo,
            lo + DVec2::new(side, 0.0),
            lo + DVec2::new(0.0, side),
            lo + DVec2::splat(side),
        ]
        .iter()
        .all(|&corner| self.contains(corner))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn conic(theta_h: f64, phi: f64, theta_d: f64, gamma: f64) -> SphericalConic {
        let h = DVec3::new(
            theta_h.sin() * phi.cos(),
            theta_h.sin() * phi.sin(),
            theta_h.cos(),
        );
        let t = h.cross(DVec3::Z).try_normalize().unwrap_or(DVec3::X);
        let wi = (theta_d.cos() * h + theta_d.sin() * t).normalize();
        let wo = 2.0 * wi.dot(h) * h - wi;
        SphericalConic::new(wi, wo, gamma).expect("a valid conic")
    }

    /// The ellipse (and its rows) contain exactly the slopes whose normals the conic
    /// contains, and its bounding box and area are those of the set.
    #[test]
    fn the_ellipse_is_the_conic_in_slope_space() {
        let mut state = 7u64;
        let mut uniform = || {
            state = crate::node::mix64(state.wrapping_add(0x9E37_79B9_7F4A_7C15));
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut tested = 0;
        for &(theta_h, theta_d, gamma) in &[
            (0.1, 0.3, 0.02),
            (0.4, 0.9, 0.1),
            (0.0, 0.0, 0.05),
            (0.8, 0.2, 0.3),
        ] {
            let conic = conic(theta_h, 0.7, theta_d, gamma);
            let ellipse = SlopeEllipse::of(&conic).expect("an ellipse in slope space");
            let lo = ellipse.center - 1.5 * ellipse.half_extent;
            let size = 3.0 * ellipse.half_extent;
            let (mut inside, mut total) = (0u32, 0u32);
            let (mut min, mut max) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
            for _ in 0..40_000 {
                let s = lo + size * DVec2::new(uniform(), uniform());
                let by_conic = conic.contains(s.extend(1.0));
                assert_eq!(ellipse.contains(s), by_conic);
                let in_row = ellipse.row(s.y).is_some_and(|(a, b)| a < s.x && s.x < b);
                assert_eq!(in_row, by_conic);
                if by_conic {
                    inside += 1;
                    min = min.min(s);
                    max = max.max(s);
                }
                total += 1;
            }
            let area = f64::from(inside) / f64::from(total) * size.x * size.y;
            assert!(
                (area / ellipse.area - 1.0).abs() < 0.03,
                "{area} {}",
                ellipse.area
            );
            let (box_min, box_max) = (
                ellipse.center - ellipse.half_extent,
                ellipse.center + ellipse.half_extent,
            );
            assert!(min.cmpge(box_min).all() && max.cmple(box_max).all());
            assert!(((max - min) / (box_max - box_min)).min_element() > 0.95);
            tested += 1;
        }
        assert_eq!(tested, 4);
    }

    /// A square meets the ellipse exactly when some of its points are inside (grid check),
    /// and is held by it exactly when all are.
    #[test]
    fn squares_meet_and_lie_in_the_ellipse_as_their_points_do() {
        let conic = conic(0.3, 1.1, 0.5, 0.08);
        let ellipse = SlopeEllipse::of(&conic).expect("an ellipse");
        let side = 0.4 * ellipse.half_extent.min_element();
        let start = ellipse.center - 2.0 * ellipse.half_extent;
        let steps = (4.0 * ellipse.half_extent / side).ceil();
        let (mut met, mut held) = (0, 0);
        for j in 0..steps.y as i32 {
            for i in 0..steps.x as i32 {
                let lo = start + side * DVec2::new(f64::from(i), f64::from(j));
                let mut any = false;
                let mut all = true;
                for b in 0..=24 {
                    for a in 0..=24 {
                        let s = lo + side * DVec2::new(f64::from(a), f64::from(b)) / 24.0;
                        let inside = ellipse.contains(s);
                        any |= inside;
                        all &= inside;
                    }
                }
                // The grid can miss a sliver the square meets, never the other way round.
                if any {
                    assert!(ellipse.meets_square(lo, side));
                }
                assert_eq!(ellipse.holds_square(lo, side), all);
                met += usize::from(ellipse.meets_square(lo, side));
                held += usize::from(all);
            }
        }
        assert!(met > held && held > 0, "{met} {held}");
    }
}
