//! The spherical conic of reflection geometry (Sec. 3.2, Eq. 7–9).
//!
//! # Definition
//! A microfacet with unit normal m reflects ω_i into ω_r = 2(m·ω_i)m − ω_i (Eq. 7). It sends
//! light into the cone of radius γ around ω_o when ω_r·ω_o > cos γ, which for unit m reads
//! 2(m·ω_i)(m·ω_o) − ω_i·ω_o > cos γ, the quadric inequality
//! mᵀ(I(cos γ + ω_i·ω_o)/2 − ω_iω_oᵀ)m < 0 of Eq. 8 (symmetrized). Because ω_r is the same for
//! m and −m, the quadric is a *double* cone; the facet counts only when its front faces the light
//! and the surface, m·ω_i > 0 and m·n > 0. [`SphericalConic::contains`] implements exactly that
//! set, and [`SphericalConic::contains_by_reflection`] evaluates the definition literally (for
//! tests).
//!
//! # Standard form (Eq. 9) and its derivation
//! Let θ be the angle between ω_i and ω_o, a = cos(θ/2) = |ω_i+ω_o|/2 and b = sin(θ/2) =
//! |ω_i−ω_o|/2. In the frame x̂ = ω_i×ω_o/|·|, ŷ = (ω_i−ω_o)/|·|, ẑ = (ω_i+ω_o)/|·| we have
//! ω_i = aẑ + bŷ and ω_o = aẑ − bŷ, so (m·ω_i)(m·ω_o) = a²z² − b²y² and ω_i·ω_o = a² − b².
//! Substituting into Eq. 8 and using a² + b² = 1 gives the diagonal form
//!
//! ```text
//!   (cos γ + ω_i·ω_o)/2 · x²  +  (1 + cos γ)/2 · y²  −  (1 − cos γ)/2 · z²  < 0.
//! ```
//!
//! Dividing by (1 − cos γ)/2 normalizes the third eigenvalue to −1 and yields the paper's
//! λ1 = (ω_i·ω_o + cos γ)/(1 − cos γ) and λ2 = cot²(γ/2).
//!
//! # Accurate forms as γ → 0
//! With s = sin²(γ/2) we have (1 − cos γ)/2 = s, (1 + cos γ)/2 = 1 − s = cos²(γ/2) and
//! (cos γ + ω_i·ω_o)/2 = a² − s, where a² = |ω_i+ω_o|²/4 is computed from the sum vector and so
//! keeps its precision when ω_i ≈ −ω_o. The code evaluates the *scaled* form
//! q(m) = k1·x² + k2·y² − s·z² with k1 = a² − s and k2 = 1 − s, whose coefficients are all of
//! magnitude ≤ 1 and free of the cancellation in 1 − cos γ; λ1 = k1/s and λ2 = k2/s.
//!
//! # Shapes
//! - ω_i = ω_o: λ1 = λ2, a spherical circle of radius γ/2 around ω_i.
//! - k1 > 0 ([`ConicKind::Elliptic`]): the valid set is the convex cap E⁺ = {q < 0, z > 0}
//!   around ẑ. (On it m·ω_i > 0 automatically: |y| < z·tan(γ/2) gives
//!   m·ω_i = az + by > z(a − b·tan(γ/2)) ∝ cos((θ+γ)/2) > 0.)
//! - k1 ≤ 0 ([`ConicKind::Hyperbolic`], ω_i·ω_o ≤ −cos γ, i.e. −ω_i inside the cone around
//!   ω_o): {q < 0} is a band around the sphere, the complement of the two convex caps
//!   D^± = {q ≥ 0, ±y ≥ 0} around ±ŷ. The valid set is the hemisphere H = {m·ω_i > 0} minus D⁺.
//!   (D⁺ lies inside H and D⁻ outside it when k1 < 0: on the great circle m·ω_i = 0,
//!   z = −(b/a)y, and λ2·y² ≥ z² would need cot(γ/2) ≥ tan(θ/2), i.e. θ + γ ≤ π. At k1 = 0, D⁺
//!   touches that great circle and lies in the closure of H.)
//! - The transition k1 = 0 (ω_i·ω_o = −cos γ) belongs to the hyperbolic description, which is
//!   exact there too.
//!
//! # Degenerate frames
//! When ω_i = ω_o the vector ŷ is undefined, but then λ1 = λ2 and any unit ŷ ⟂ ẑ gives the same
//! conic. When ω_i = −ω_o, ẑ is undefined, but then k1 = −s, the form is symmetric in x and z,
//! and any unit ẑ ⟂ ω_i serves. Near these cases the frame is built from the longer of
//! ω_i ± ω_o, and the shorter is orthogonalized against it: its rounding error then only turns
//! the frame within the plane where the form is nearly symmetric, so the conic stays accurate
//! (building ẑ from a short ω_i + ω_o and orthogonalizing ŷ against it would instead turn the
//! frame in the y–z plane, where the coefficients 1 − s and −s differ, by ~1e-16/|ω_i + ω_o|).

use glam::DVec3;

use crate::error::{SphereError, unit_direction};

/// A cone radius γ with its half-angle sine and cosine, validated and computed once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConeRadius {
    gamma: f64,
    sin_half: f64,
    cos_half: f64,
}

impl ConeRadius {
    /// γ in radians.
    ///
    /// # Errors
    /// [`SphereError::ConeRadiusOutOfRange`] unless 0 < γ < π.
    pub fn new(gamma: f64) -> Result<Self, SphereError> {
        if !(gamma > 0.0 && gamma < std::f64::consts::PI) {
            return Err(SphereError::ConeRadiusOutOfRange { gamma });
        }
        let (sin_half, cos_half) = (0.5 * gamma).sin_cos();
        Ok(Self {
            gamma,
            sin_half,
            cos_half,
        })
    }

    /// γ in radians.
    #[must_use]
    pub fn gamma(&self) -> f64 {
        self.gamma
    }
}

/// Which description of the valid set applies (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConicKind {
    /// λ1 > 0: a convex spherical ellipse (a circle when ω_i = ω_o) around ẑ.
    Elliptic,
    /// λ1 ≤ 0: the band {q < 0} cut by the hemisphere m·ω_i > 0.
    Hyperbolic,
}

/// The set of facet normals that reflect ω_i into the cone of radius γ around ω_o and face
/// both the light and the surface normal n = +z (Eq. 7, 8), held in the standard form of Eq. 9.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphericalConic {
    wi: DVec3,
    wo: DVec3,
    gamma: f64,
    /// Rows x̂, ŷ, ẑ of the standard frame (Eq. 9's Q, transposed).
    frame: [DVec3; 3],
    /// Scaled diagonal coefficients (k1, k2, −s): q = k1·x² + k2·y² − s·z².
    coefficients: DVec3,
    /// cos(θ/2) and sin(θ/2): ω_i = half_cos·ẑ + half_sin·ŷ.
    half_cos: f64,
    half_sin: f64,
    kind: ConicKind,
    /// Elliptic conics: cos and sin of the angular radius of the cap around ẑ that holds the
    /// valid set (its major half-axis; see [`SphericalConic::bounding_cap`]).
    cap_cos: f64,
    cap_sin: f64,
}

impl SphericalConic {
    /// Builds the conic for incident direction `wi`, central outgoing direction `wo` (both in the
    /// local shading frame, any length) and cone radius `gamma` in radians.
    ///
    /// # Errors
    /// [`SphereError::NonFiniteDirection`] / [`SphereError::ZeroDirection`] for an unusable
    /// direction; [`SphereError::ConeRadiusOutOfRange`] unless 0 < γ < π.
    pub fn new(wi: DVec3, wo: DVec3, gamma: f64) -> Result<Self, SphereError> {
        Self::with_cone(wi, wo, &ConeRadius::new(gamma)?)
    }

    /// [`SphericalConic::new`] for a cone whose trigonometry is already computed: no
    /// trigonometry per call (for renderers that build a conic per query).
    ///
    /// # Errors
    /// [`SphereError::NonFiniteDirection`] / [`SphereError::ZeroDirection`] for an unusable
    /// direction.
    pub fn with_cone(wi: DVec3, wo: DVec3, cone: &ConeRadius) -> Result<Self, SphereError> {
        let wi = unit_direction(wi, "wi")?;
        let wo = unit_direction(wo, "wo")?;
        let gamma = cone.gamma;
        let sum = wi + wo;
        let difference = wi - wo;
        let sum_length = sum.length();
        let difference_length = difference.length();
        // Below this length a vector names no direction (see "Degenerate frames").
        const NO_DIRECTION: f64 = 1e-150;
        // The longer of ω_i ± ω_o keeps full precision; the shorter is Gram–Schmidted against
        // it. Then the shorter's rounding error only rotates the frame about the longer axis,
        // in the plane where the form is nearly symmetric (x–y near ω_i = ω_o, where
        // k1 ≈ k2; x–z near ω_i = −ω_o, where k1 ≈ −s), so it perturbs q by ~1e-16 times
        // the small eigenvalue gap instead of 1e-16 / |ω_i ± ω_o|.
        let orthogonalized = |v: DVec3, against: DVec3, fallback: DVec3| {
            let w = v - v.dot(against) * against;
            if w.length() > NO_DIRECTION {
                w.normalize()
            } else {
                fallback
            }
        };
        let (y_axis, z_axis) = if sum_length >= difference_length {
            let z = sum / sum_length;
            (orthogonalized(difference, z, any_perpendicular(z)), z)
        } else {
            let y = difference / difference_length;
            (y, orthogonalized(sum, y, any_perpendicular(y)))
        };
        let x_axis = y_axis.cross(z_axis);

        let (sin_half, cos_half) = (cone.sin_half, cone.cos_half);
        let s = sin_half * sin_half;
        let a = 0.5 * sum_length;
        let k1 = a * a - s;
        let k2 = cos_half * cos_half;
        let kind = if k1 > 0.0 {
            ConicKind::Elliptic
        } else {
            ConicKind::Hyperbolic
        };
        // The elliptic set k1·x² + k2·y² < s·z² with k1 ≤ k2 lies within tan²θ < s/k1 of ẑ,
        // so cos θ_max = √(k1/(k1 + s)) = √k1/a and sin θ_max = √s/a (k1 + s = a²).
        let (cap_cos, cap_sin) = match kind {
            ConicKind::Elliptic => (k1.sqrt() / a, sin_half / a),
            ConicKind::Hyperbolic => (-1.0, 0.0),
        };
        Ok(Self {
            wi,
            wo,
            gamma,
            frame: [x_axis, y_axis, z_axis],
            coefficients: DVec3::new(k1, k2, -s),
            half_cos: a,
            half_sin: 0.5 * difference_length,
            kind,
            cap_cos,
            cap_sin,
        })
    }

    /// The incident direction ω_i (unit).
    #[must_use]
    pub fn wi(&self) -> DVec3 {
        self.wi
    }

    /// The central outgoing direction ω_o (unit).
    #[must_use]
    pub fn wo(&self) -> DVec3 {
        self.wo
    }

    /// The cone radius γ in radians.
    #[must_use]
    pub fn gamma(&self) -> f64 {
        self.gamma
    }

    /// Elliptic or hyperbolic (see the module docs).
    #[must_use]
    pub fn kind(&self) -> ConicKind {
        self.kind
    }

    /// For an elliptic conic, the cap around ẑ that holds its valid set: (ẑ, cos θ_max,
    /// sin θ_max), θ_max the angle of the major half-axis, atan √(1/λ1). `None` for a
    /// hyperbolic conic.
    #[must_use]
    pub fn bounding_cap(&self) -> Option<(DVec3, f64, f64)> {
        (self.kind == ConicKind::Elliptic).then_some((self.frame[2], self.cap_cos, self.cap_sin))
    }

    /// The standard frame (x̂, ŷ, ẑ) of Eq. 9.
    #[must_use]
    pub fn frame(&self) -> [DVec3; 3] {
        self.frame
    }

    /// λ1 = (ω_i·ω_o + cos γ)/(1 − cos γ) of Eq. 9, computed as (a² − sin²(γ/2))/sin²(γ/2).
    #[must_use]
    pub fn lambda1(&self) -> f64 {
        -self.coefficients.x / self.coefficients.z
    }

    /// λ2 = cot²(γ/2) of Eq. 9, computed as cos²(γ/2)/sin²(γ/2).
    #[must_use]
    pub fn lambda2(&self) -> f64 {
        -self.coefficients.y / self.coefficients.z
    }

    /// The scaled diagonal coefficients (k1, k2, −s) with q = k1·x² + k2·y² − s·z² = s·mᵀCm.
    #[must_use]
    pub fn scaled_coefficients(&self) -> DVec3 {
        self.coefficients
    }

    /// cos(θ/2) and sin(θ/2), θ the angle between ω_i and ω_o; ω_i = cos(θ/2)ẑ + sin(θ/2)ŷ.
    #[must_use]
    pub fn half_angle_cos_sin(&self) -> (f64, f64) {
        (self.half_cos, self.half_sin)
    }

    /// The matrix C = QΛQᵀ of Eq. 9 in the local shading frame: mᵀCm ≤ 0 on the double cone.
    #[must_use]
    pub fn matrix(&self) -> glam::DMat3 {
        let q = glam::DMat3::from_cols(self.frame[0], self.frame[1], self.frame[2]);
        let lambda = glam::DMat3::from_diagonal(DVec3::new(self.lambda1(), self.lambda2(), -1.0));
        q * lambda * q.transpose()
    }

    /// Coordinates of `m` in the standard frame.
    #[inline]
    #[must_use]
    pub fn to_frame(&self, m: DVec3) -> DVec3 {
        DVec3::new(
            self.frame[0].dot(m),
            self.frame[1].dot(m),
            self.frame[2].dot(m),
        )
    }

    /// The scaled quadratic form q(m) = sin²(γ/2)·mᵀCm, evaluated in the standard frame.
    /// Negative inside the double cone of Eq. 8.
    #[inline]
    #[must_use]
    pub fn quadratic_form(&self, m: DVec3) -> f64 {
        scaled_form(self.coefficients, self.to_frame(m))
    }

    /// Whether facet normal `m` (any nonzero length) is in the conic: q(m) < 0, m·ω_i > 0 and
    /// m·n > 0 (Eq. 8 restricted to the valid part of the double cone).
    #[inline]
    #[must_use]
    pub fn contains(&self, m: DVec3) -> bool {
        m.z > 0.0 && self.wi.dot(m) > 0.0 && self.quadratic_form(m) < 0.0
    }

    /// The definition, evaluated literally for a unit normal `m`: m·n > 0, m·ω_i > 0 and the
    /// mirror reflection ω_r = 2(m·ω_i)m − ω_i (Eq. 7) within γ of ω_o, tested as the chord
    /// |ω_r − ω_o| < 2 sin(γ/2) so that tiny γ keeps its precision. For tests and validation.
    #[must_use]
    pub fn contains_by_reflection(&self, m: DVec3) -> bool {
        let m = m.normalize();
        let m_dot_wi = m.dot(self.wi);
        if m.z <= 0.0 || m_dot_wi <= 0.0 {
            return false;
        }
        let reflected = 2.0 * m_dot_wi * m - self.wi;
        let chord = 2.0 * (0.5 * self.gamma).sin();
        (reflected - self.wo).length_squared() < chord * chord
    }
}

/// q = k1·x² + k2·y² − s·z² for frame coordinates `f` and coefficients (k1, k2, −s).
#[inline]
pub(crate) fn scaled_form(k: DVec3, f: DVec3) -> f64 {
    k.x * f.x * f.x + k.y * f.y * f.y + k.z * f.z * f.z
}

/// The symmetric bilinear form of [`scaled_form`]: q(f, g).
#[inline]
pub(crate) fn scaled_bilinear(k: DVec3, f: DVec3, g: DVec3) -> f64 {
    k.x * f.x * g.x + k.y * f.y * g.y + k.z * f.z * g.z
}

/// A unit vector perpendicular to unit `v`, continuous except where the sign of v.z flips
/// (the branchless construction of Duff et al. 2017, "Building an Orthonormal Basis, Revisited").
fn any_perpendicular(v: DVec3) -> DVec3 {
    let sign = 1.0_f64.copysign(v.z);
    let a = -1.0 / (sign + v.z);
    let b = v.x * v.y * a;
    DVec3::new(1.0 + sign * v.x * v.x * a, sign * b, -sign * v.x)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(theta_deg: f64, phi_deg: f64) -> DVec3 {
        let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
        DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
    }

    #[test]
    fn eigenvalues_match_eq_9() {
        for (wi, wo, gamma_deg) in [
            (dir(30.0, 0.0), dir(40.0, 170.0), 5.0),
            (dir(10.0, 20.0), dir(10.0, 20.0), 1.0),
            (dir(80.0, 0.0), dir(80.0, 180.0), 30.0),
        ] {
            let gamma = f64::to_radians(gamma_deg);
            let c = SphericalConic::new(wi, wo, gamma).unwrap();
            let lambda1 = (wi.normalize().dot(wo.normalize()) + gamma.cos()) / (1.0 - gamma.cos());
            let lambda2 = 1.0 / (0.5 * gamma).tan().powi(2);
            assert!((c.lambda1() - lambda1).abs() < 1e-10 * lambda1.abs().max(1.0));
            assert!((c.lambda2() - lambda2).abs() < 1e-10 * lambda2);
            // C = QΛQᵀ agrees with Eq. 8's matrix up to the scale (1 − cos γ)/2.
            let eq8 = glam::DMat3::IDENTITY * (0.5 * (gamma.cos() + wi.dot(wo)))
                - 0.5
                    * (glam::DMat3::from_cols(wi * wo.x, wi * wo.y, wi * wo.z)
                        + glam::DMat3::from_cols(wo * wi.x, wo * wi.y, wo * wi.z));
            let scaled = c.matrix() * (0.5 * (1.0 - gamma.cos()));
            for col in 0..3 {
                assert!((scaled.col(col) - eq8.col(col)).abs().max_element() < 1e-12);
            }
        }
    }

    #[test]
    fn circle_when_wi_equals_wo() {
        let w = dir(35.0, 60.0);
        let gamma = 0.1;
        let c = SphericalConic::new(w, w, gamma).unwrap();
        assert_eq!(c.kind(), ConicKind::Elliptic);
        assert!((c.lambda1() - c.lambda2()).abs() < 1e-12 * c.lambda2());
        // Radius γ/2 around ω_i: just inside and just outside along any direction.
        let t = any_perpendicular(w);
        let at = |angle: f64| w * angle.cos() + t * angle.sin();
        assert!(c.contains(at(0.499 * gamma)));
        assert!(!c.contains(at(0.501 * gamma)));
    }

    #[test]
    fn band_when_wi_is_minus_wo() {
        let wi = dir(60.0, 0.0);
        let c = SphericalConic::new(wi, -wi, 0.2).unwrap();
        assert_eq!(c.kind(), ConicKind::Hyperbolic);
        assert!((c.lambda1() + 1.0).abs() < 1e-12);
        // Valid normals: 0 < m·ω_i < sin(γ/2) and m·n > 0.
        let perp = any_perpendicular(wi);
        let m_in = (perp + 0.05 * wi).normalize();
        let m_out = (perp + 0.2 * wi).normalize();
        let m_in = if m_in.z > 0.0 {
            m_in
        } else {
            (-perp + 0.05 * wi).normalize()
        };
        assert!(c.contains_by_reflection(m_in) && c.contains(m_in));
        assert!(!c.contains_by_reflection(m_out) && !c.contains(m_out));
    }

    /// Near ω_i = −ω_o the frame must not turn in the plane where the form is asymmetric:
    /// normals reflecting ω_i to 1e-6 inside or outside the cone's rim are classified right.
    #[test]
    fn accurate_when_wi_is_nearly_minus_wo() {
        let wi = dir(60.0, 10.0);
        let gamma = 1f64.to_radians();
        let perpendicular = any_perpendicular(wi);
        for offset in [1e-3, 1e-6, 1e-9, 1e-12] {
            let wo = (-wi + offset * perpendicular).normalize();
            let c = SphericalConic::new(wi, wo, gamma).unwrap();
            let rim_axis = any_perpendicular(wo);
            for k in 0..64 {
                let angle = f64::from(k) / 64.0 * std::f64::consts::TAU;
                let side = rim_axis * angle.cos() + wo.cross(rim_axis) * angle.sin();
                for (scale, inside) in [(1.0 - 1e-6, true), (1.0 + 1e-6, false)] {
                    let g = gamma * scale;
                    let reflected = wo * g.cos() + side * g.sin();
                    let m = (wi + reflected).normalize();
                    if m.z > 1e-3 && m.dot(wi) > 1e-3 {
                        assert_eq!(c.contains(m), inside, "offset {offset}, angle {angle}");
                    }
                }
            }
        }
    }

    #[test]
    fn rejects_bad_input() {
        assert_eq!(
            SphericalConic::new(DVec3::Z, DVec3::Z, 0.0),
            Err(SphereError::ConeRadiusOutOfRange { gamma: 0.0 })
        );
        assert!(matches!(
            SphericalConic::new(DVec3::Z, DVec3::Z, f64::NAN),
            Err(SphereError::ConeRadiusOutOfRange { .. })
        ));
        assert_eq!(
            SphericalConic::new(DVec3::new(f64::INFINITY, 0.0, 1.0), DVec3::Z, 0.1),
            Err(SphereError::NonFiniteDirection { name: "wi" })
        );
        assert_eq!(
            SphericalConic::new(DVec3::Z, DVec3::ZERO, 0.1),
            Err(SphereError::ZeroDirection { name: "wo" })
        );
    }

    #[test]
    fn perpendicular_is_orthonormal() {
        for v in [
            DVec3::Z,
            DVec3::NEG_Z,
            DVec3::X,
            dir(91.0, 33.0),
            dir(1e-9, 0.0),
        ] {
            let p = any_perpendicular(v);
            assert!(
                (p.length() - 1.0).abs() < 1e-14 && p.dot(v).abs() < 1e-14,
                "{v}"
            );
        }
    }

    /// The bounding cap holds every direction of the valid set, and its radius is attained
    /// (the ends of the major half-axis, ±x̂ tilted by θ_max, lie on the conic's boundary).
    #[test]
    fn bounding_cap_is_the_tightest_cap_around_z() {
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut uniform = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut elliptic = 0;
        for _ in 0..400 {
            let wi = dir(89.0 * uniform(), 360.0 * uniform());
            let wo = dir(89.0 * uniform(), 360.0 * uniform());
            let gamma = (0.01 + 40.0 * uniform() * uniform()).to_radians();
            let conic = SphericalConic::new(wi, wo, gamma).expect("valid");
            let Some((axis, cos_max, sin_max)) = conic.bounding_cap() else {
                assert_eq!(conic.kind(), ConicKind::Hyperbolic);
                continue;
            };
            elliptic += 1;
            assert!((cos_max * cos_max + sin_max * sin_max - 1.0).abs() < 1e-12);
            // Directions around the axis out to twice the cap's radius.
            let [x, y, _] = conic.frame();
            let radius = sin_max.atan2(cos_max);
            for _ in 0..500 {
                let (angle, phi) = (2.0 * radius * uniform(), std::f64::consts::TAU * uniform());
                let m = angle.cos() * axis + angle.sin() * (phi.cos() * x + phi.sin() * y);
                if conic.quadratic_form(m) < 0.0 && m.dot(axis) > 0.0 {
                    assert!(m.dot(axis) >= cos_max - 1e-12, "{conic:?} {m}");
                }
            }
            let tip = cos_max * axis + sin_max * x;
            assert!(conic.quadratic_form(tip).abs() < 1e-12, "{conic:?}");
        }
        assert!(elliptic > 300, "{elliptic}");
    }
}
