//! The slope-space rule: the lobe's mass over an ellipse in slope space, exact along its chords,
//! for a cone above the horizon, and over its part inside the horizon's own ellipse for a cone
//! across it.
//!
//! # Derivation
//! **The set is an ellipse.** When the cone of radius γ around ω_o lies above the horizon
//! (ω_o·n ≥ sin γ), every ω′ in it has ω′_z ≥ 0, and of the three conditions of [`super`] only
//! Eq. 8's q(H) < 0 is left: a normal with h·n > 0 whose reflection ω′ of ω_i is in the cone has
//! ω_i + ω′ = 2(ω_i·h)h with (ω_i + ω′)·n > 0, so ω_i·h > 0 too. The set is also bounded in the
//! slope plane H = (x, y, 1): normals tending to the horizon reflect ω_i to ω′_z → −ω_i,z < 0,
//! outside the cone. A bounded set {q < 0} of a quadratic form on the plane is an ellipse. In
//! scaled slopes p = (x, y), H = e + x·u + y·v ([`super`]'s basis),
//!
//! ```text
//!   Q(p) = pᵀMp + 2Bᵀp + C,   M = [[q(u,u), q(u,v)], [q(u,v), q(v,v)]],   B = (q(u,e), q(v,e)),
//!   C = q(e,e);   Q(p) = (p − c)ᵀM(p − c) − μ,   c = −M⁻¹B,   μ = −(C + Bᵀc) > 0,
//! ```
//!
//! with semi-axes a = √(μ/λ_min) along M's eigenvector of its smaller eigenvalue (the major
//! axis, M̂) and b = √(μ/λ_max) along the other (the minor axis, m̂).
//!
//! **Chords.** The lobe's density in scaled slopes is radial, P(r²), the same in any rotated
//! frame. A point of the ellipse is c + s·m̂ + t·M̂ with |s| ≤ b and |t| ≤ h(s) = a√(1 − s²/b²);
//! its r² is σ² + τ² with σ = c_m + s and τ = c_M + t (c_m, c_M the centre's coordinates). The
//! mass along a chord, from τ_0 = c_M − h to τ_1 = c_M + h, is closed form:
//!
//! ```text
//!   Beckmann, P = e^(−r²)/π:       e^(−σ²)/π · ∫ e^(−τ²) dτ = e^(−σ²)/(2√π) · (erf τ_1 − erf τ_0);
//!   GGX, P = 1/(π(1 + r²)²), A = 1 + σ², τ = √A·tan θ:
//!                                  ∫ dτ/(A + τ²)² = (Δθ + sin Δθ·cos(θ_0 + θ_1)) / (2A^(3/2)).
//! ```
//!
//! Both are computed without cancellation ([`gaussian_chord`], [`ggx_chord`]).
//!
//! **Across the chords.** s = b·sin φ makes the half-length h = a·cos φ and the Jacobian
//! ds = b·cos φ dφ analytic in φ ∈ [−π/2, π/2], with no square-root edge at the ends of the
//! minor axis (and, unlike w = tan(φ/2), which makes them rational, no poles near the
//! interval to slow the rule's convergence). The integral over φ takes the adaptive
//! Gauss–Kronrod rule of [`super`]. The lobe is about 1 wide in s: the range is first cut at
//! s* ± 2, ± 8, ± 32, … (s* the chord nearest the lobe's peak), so that each piece is about as
//! wide as the lobe at its distance; a narrow ellipse (b ≤ 2, the usual case) starts as one
//! piece of 15 chords. For Beckmann, chords whose every point is farther than √(D² + 60) from
//! the peak, D the distance of a point known to be in the ellipse, carry under e^(−60) of the
//! mass near that point and are left out.
//!
//! **Cut by the horizon.** For a cone across the horizon the set is the ellipse's part inside a
//! second ellipse {G < 0}, the horizon's condition ([`super`]'s `Rays::horizon`). Both are
//! convex, so each chord keeps one interval, between the roots of G along it. The cut set's
//! range in s ends at a minor-axis end inside {G < 0}, at a point where {G < 0} touches a chord
//! inside the ellipse, or where the two boundaries cross: there the chords' ends switch from
//! one boundary to the other (a kink), and at a touching point they start with a square-root
//! edge. The crossings are given, not searched for (two crossings a few degrees apart on a
//! long ellipse are easily missed, and with them the whole set), and the range is cut at all
//! these points, each piece smoothed at its ends by the substitution of [`super`]. No chord
//! is left out: the point at distance D may lie outside the cut set.

use crate::distribution::RadialLaw;
use crate::quadrature::{Piece, adaptive_gauss_kronrod, gauss_kronrod, smoothed_gauss_kronrod};

/// Beckmann chords with σ² beyond D² + this are left out (their mass is below e^(−60) of the
/// mass near a point of the ellipse at distance D).
const BECKMANN_REACH_SQUARED: f64 = 60.0;

/// A chord whose length ℓ satisfies ℓ·(1 + 2|τ_mid|) ≤ this is integrated by the 4-point
/// Gauss–Legendre rule (relative error below 1e-8), where a difference of erfc would cancel.
const SHORT_CHORD: f64 = 0.5;

/// Nodes and weights of the 4-point Gauss–Legendre rule on [−1, 1] (each node used at ±x).
const LEGENDRE_4: [(f64, f64); 2] = [
    (0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
    (0.861_136_311_594_052_6, 0.347_854_845_137_453_9),
];

/// A quadratic form Q(p) = pᵀMp + 2Bᵀp + C in scaled slopes p = (x, y), as
/// ([m_xx, m_xy, m_yy], [b_x, b_y], c).
pub(super) type Form = ([f64; 3], [f64; 2], f64);

/// A second ellipse {G < 0} that cuts the first, with the points (in scaled slopes) where their
/// boundaries cross.
#[derive(Clone, Debug)]
pub(super) struct Cut {
    pub(super) form: Form,
    pub(super) crossings: Vec<[f64; 2]>,
}

/// The ellipse {Q < 0} in scaled slopes, in the frame of its axes.
#[derive(Clone, Copy, Debug)]
pub(super) struct Ellipse {
    /// The centre c and the unit major and minor axes M̂ and m̂, in scaled slopes.
    centre: [f64; 2],
    major_axis: [f64; 2],
    minor_axis: [f64; 2],
    /// The centre's coordinates along the minor and the major axis, c_m and c_M.
    centre_minor: f64,
    centre_major: f64,
    /// The semi-axes a (major) and b (minor).
    major: f64,
    minor: f64,
}

impl Ellipse {
    /// The ellipse {Q < 0} of Q(x, y) = m_xx x² + 2m_xy xy + m_yy y² + 2(b_x x + b_y y) + c;
    /// `None` unless that set is a nondegenerate ellipse (M positive definite, μ > 0).
    pub(super) fn from_form(([m_xx, m_xy, m_yy], [b_x, b_y], c): Form) -> Option<Self> {
        let det = m_xx * m_yy - m_xy * m_xy;
        if !(det > 0.0 && m_xx > 0.0 && det.is_finite()) {
            return None;
        }
        let centre = (
            -(m_yy * b_x - m_xy * b_y) / det,
            -(m_xx * b_y - m_xy * b_x) / det,
        );
        let mu = -(c + b_x * centre.0 + b_y * centre.1);
        if !(mu > 0.0 && mu.is_finite()) {
            return None;
        }
        let lambda_max = 0.5 * (m_xx + m_yy) + (0.5 * (m_xx - m_yy)).hypot(m_xy);
        let lambda_min = det / lambda_max;
        // The major axis solves (M − λ_min)x = 0; of the two rows' solutions the longer one is
        // the better conditioned (both vanish when M ∝ I, where any direction will do).
        let rows = [(m_xy, lambda_min - m_xx), (lambda_min - m_yy, m_xy)];
        let (x, y) = if rows[0].0.hypot(rows[0].1) >= rows[1].0.hypot(rows[1].1) {
            rows[0]
        } else {
            rows[1]
        };
        let length = x.hypot(y);
        let major_axis = if length > 0.0 {
            (x / length, y / length)
        } else {
            (1.0, 0.0)
        };
        let minor_axis = (-major_axis.1, major_axis.0);
        Some(Self {
            centre: [centre.0, centre.1],
            major_axis: [major_axis.0, major_axis.1],
            minor_axis: [minor_axis.0, minor_axis.1],
            centre_minor: centre.0 * minor_axis.0 + centre.1 * minor_axis.1,
            centre_major: centre.0 * major_axis.0 + centre.1 * major_axis.1,
            major: (mu / lambda_min).sqrt(),
            minor: (mu / lambda_max).sqrt(),
        })
    }

    /// The mass of the radial lobe `law` (unit scaled roughness) over the ellipse, or over its part
    /// inside a `cut`, to a relative `tolerance` with at most `max_pieces` pieces of φ:
    /// (mass, pieces).
    pub(super) fn mass(
        &self,
        law: RadialLaw,
        cut: Option<&Cut>,
        tolerance: f64,
        max_pieces: usize,
    ) -> (f64, usize) {
        let crossings: Vec<f64> = cut.map_or_else(Vec::new, |cut| {
            cut.crossings
                .iter()
                .map(|p| p[0] * self.minor_axis[0] + p[1] * self.minor_axis[1] - self.centre_minor)
                .collect()
        });
        let cut = cut.map(|cut| self.along_chords(cut.form));
        let cuts = self.cuts_in_s(law, cut.as_ref(), &crossings);
        let b = self.minor;
        let angle = |s: f64| (s / b).clamp(-1.0, 1.0).asin();
        let integrand = |phi: f64| self.across(law, cut.as_ref(), phi);
        // A cut's chords end where they cross the boundary of {G < 0} (kinks) or where it ends
        // (square-root edges), at the cuts: every piece is smoothed at its ends.
        let rule = |start: f64, length: f64| match cut {
            None => gauss_kronrod(start, length, integrand),
            Some(_) => smoothed_gauss_kronrod(start, length, integrand),
        };
        let pieces: Vec<Piece> = cuts
            .windows(2)
            .map(|w| (angle(w[0]), angle(w[1])))
            .filter(|(start, end)| end > start)
            .map(|(start, end)| rule(start, end - start))
            .collect();
        adaptive_gauss_kronrod(pieces, tolerance, 0.0, max_pieces, rule)
    }

    /// Where the integral over s starts, ends and is first cut, sorted; empty where the set
    /// holds no chord. The range is the ellipse's, less the Beckmann chords left out, or that of
    /// the cut set, whose ends (it is convex) are among the minor axis' ends inside {G < 0}, the
    /// points where {G < 0} touches a chord inside the ellipse, and the boundaries' `crossings`
    /// (given: a search for them misses pairs close together, and with them the whole cut set).
    /// Inside it, cuts at s* ± 2, ± 8, … and at those points.
    fn cuts_in_s(&self, law: RadialLaw, cut: Option<&ChordForm>, crossings: &[f64]) -> Vec<f64> {
        let b = self.minor;
        let nearest = (-self.centre_minor).clamp(-b, b);
        let mut inner = Vec::new();
        let (low, high) = match (cut, law) {
            (Some(cut), _) => {
                let touching = cut
                    .extent()
                    .into_iter()
                    .filter(|&s| s.abs() < b && cut.tangent(s).abs() < self.half_length(s));
                inner.extend(crossings.iter().copied().chain(touching));
                let axis_ends = [-b, b].into_iter().filter(|&s| cut.at(s, 0.0) < 0.0);
                let all = inner.iter().copied().chain(axis_ends);
                (
                    all.clone().fold(f64::INFINITY, f64::min),
                    all.fold(f64::NEG_INFINITY, f64::max),
                )
            }
            (None, RadialLaw::Gaussian) => {
                // D²: the nearer to the peak of the centre and the point nearest the peak on
                // the chord nearest it.
                let sigma = self.centre_minor + nearest;
                let along = (self.centre_major.abs() - self.half_length(nearest)).max(0.0);
                let known = (self.centre_minor * self.centre_minor
                    + self.centre_major * self.centre_major)
                    .min(sigma * sigma + along * along);
                let reach = (known + BECKMANN_REACH_SQUARED).sqrt();
                (
                    (-self.centre_minor - reach).max(-b),
                    (-self.centre_minor + reach).min(b),
                )
            }
            (None, RadialLaw::Student) => (-b, b),
        };
        if !(high > low) {
            return Vec::new();
        }
        let mut cuts = vec![low, high];
        let mut width = 2.0;
        while nearest - width > low || nearest + width < high {
            cuts.extend([nearest - width, nearest + width]);
            width *= 4.0;
        }
        cuts.extend(inner);
        cuts.retain(|s| *s >= low && *s <= high);
        cuts.sort_by(f64::total_cmp);
        cuts
    }

    /// G along the chords, in the ellipse's frame: at p = c + s·m̂ + t·M̂,
    /// G = αt² + 2(β_0 + β_1 s)t + γ_0 + 2γ_1 s + γ_2 s².
    fn along_chords(&self, ([n_xx, n_xy, n_yy], [d_x, d_y], k): Form) -> ChordForm {
        let times_n = |v: [f64; 2]| [n_xx * v[0] + n_xy * v[1], n_xy * v[0] + n_yy * v[1]];
        let dot = |v: [f64; 2], w: [f64; 2]| v[0] * w[0] + v[1] * w[1];
        let (c, major, minor) = (self.centre, self.major_axis, self.minor_axis);
        let (n_c, n_major, n_minor) = (times_n(c), times_n(major), times_n(minor));
        let d = [d_x, d_y];
        ChordForm {
            alpha: dot(major, n_major),
            beta0: dot(major, n_c) + dot(d, major),
            beta1: dot(major, n_minor),
            gamma0: dot(c, n_c) + 2.0 * dot(d, c) + k,
            gamma1: dot(minor, n_c) + dot(d, minor),
            gamma2: dot(minor, n_minor),
        }
    }

    /// h(s) = a√(1 − s²/b²), the half-length of the chord at s.
    fn half_length(&self, s: f64) -> f64 {
        let ratio = s / self.minor;
        self.major * (1.0 - ratio * ratio).max(0.0).sqrt()
    }

    /// The integrand over φ: b·cos φ times the mass along the chord at s = b·sin φ (its part
    /// inside {G < 0} for a cut).
    fn across(&self, law: RadialLaw, cut: Option<&ChordForm>, phi: f64) -> f64 {
        let (sin, cos) = sin_cos_within_quarter_turn(phi);
        let cos = cos.max(0.0);
        let s = self.minor * sin;
        let sigma = self.centre_minor + s;
        let half = self.major * cos;
        let (mut low, mut high) = (-half, half);
        if let Some(cut) = cut {
            let Some((start, end)) = cut.interval(s) else {
                return 0.0;
            };
            (low, high) = (low.max(start), high.min(end));
            if high <= low {
                return 0.0;
            }
        }
        let (tau0, tau1) = (self.centre_major + low, self.centre_major + high);
        // π times the mass along the chord.
        let chord = match law {
            RadialLaw::Gaussian => gaussian_chord(sigma * sigma, tau0, tau1),
            RadialLaw::Student => ggx_chord(1.0 + sigma * sigma, tau0, tau1),
        };
        self.minor * cos * chord / std::f64::consts::PI
    }
}

/// A second form G along the chords of an ellipse ([`Ellipse::along_chords`]).
#[derive(Clone, Copy, Debug)]
struct ChordForm {
    alpha: f64,
    beta0: f64,
    beta1: f64,
    gamma0: f64,
    gamma1: f64,
    gamma2: f64,
}

impl ChordForm {
    /// G at (s, t).
    fn at(&self, s: f64, t: f64) -> f64 {
        self.alpha * t * t
            + 2.0 * (self.beta0 + self.beta1 * s) * t
            + self.gamma0
            + s * (2.0 * self.gamma1 + self.gamma2 * s)
    }

    /// The chord at s inside {G < 0}: the t between the roots of αt² + 2βt + γ (α > 0, a
    /// definite form), computed without cancellation; `None` where the chord misses it.
    fn interval(&self, s: f64) -> Option<(f64, f64)> {
        let beta = self.beta0 + self.beta1 * s;
        let gamma = self.gamma0 + s * (2.0 * self.gamma1 + self.gamma2 * s);
        let discriminant = beta * beta - self.alpha * gamma;
        if !(discriminant > 0.0 && self.alpha > 0.0) {
            return None;
        }
        let q = -(beta + discriminant.sqrt().copysign(beta));
        let (r0, r1) = (q / self.alpha, gamma / q);
        Some((r0.min(r1), r0.max(r1)))
    }

    /// The t where the chord at s touches {G < 0} (at its ends in s): −β(s)/α.
    fn tangent(&self, s: f64) -> f64 {
        -(self.beta0 + self.beta1 * s) / self.alpha
    }

    /// The ends of {G < 0} in s: the zeros of the discriminant β(s)² − αγ(s), a quadratic.
    fn extent(&self) -> Vec<f64> {
        let c2 = self.beta1 * self.beta1 - self.alpha * self.gamma2;
        let c1 = 2.0 * (self.beta0 * self.beta1 - self.alpha * self.gamma1);
        let c0 = self.beta0 * self.beta0 - self.alpha * self.gamma0;
        let discriminant = c1 * c1 - 4.0 * c2 * c0;
        if !(discriminant >= 0.0) || c2 == 0.0 {
            return Vec::new();
        }
        let q = -0.5 * (c1 + discriminant.sqrt().copysign(c1));
        if q == 0.0 {
            return Vec::new();
        }
        vec![q / c2, c0 / q]
    }
}

/// sin φ and cos φ for |φ| ≤ π/2 by their Taylor series to x¹⁷ and x¹⁸ (errors below 1e-13),
/// cheaper than the library's, which reduce any argument.
fn sin_cos_within_quarter_turn(phi: f64) -> (f64, f64) {
    let x2 = phi * phi;
    let sin = phi
        * (1.0
            - x2 * (1.0 / 6.0)
                * (1.0
                    - x2 * (1.0 / 20.0)
                        * (1.0
                            - x2 * (1.0 / 42.0)
                                * (1.0
                                    - x2 * (1.0 / 72.0)
                                        * (1.0
                                            - x2 * (1.0 / 110.0)
                                                * (1.0
                                                    - x2 * (1.0 / 156.0)
                                                        * (1.0
                                                            - x2 * (1.0 / 210.0)
                                                                * (1.0 - x2 * (1.0 / 272.0)))))))));
    let cos = 1.0
        - x2 * (1.0 / 2.0)
            * (1.0
                - x2 * (1.0 / 12.0)
                    * (1.0
                        - x2 * (1.0 / 30.0)
                            * (1.0
                                - x2 * (1.0 / 56.0)
                                    * (1.0
                                        - x2 * (1.0 / 90.0)
                                            * (1.0
                                                - x2 * (1.0 / 132.0)
                                                    * (1.0
                                                        - x2 * (1.0 / 182.0)
                                                            * (1.0
                                                                - x2 * (1.0 / 240.0)
                                                                    * (1.0
                                                                        - x2 * (1.0
                                                                            / 306.0)))))))));
    (sin, cos)
}

/// e^(−σ²)·∫ e^(−τ²) dτ over [t0, t1] (t0 ≤ t1) for `sigma_squared` = σ², to a relative 1e-6:
/// by the 4-point Gauss–Legendre rule on a short chord, else by a difference of [`erfc`] that
/// does not cancel (both ends on the same side of 0 and far enough apart, or one end on each
/// side). Ends beyond which the rest of the line holds under e^(−40) of the chord's mass are
/// not evaluated.
fn gaussian_chord(sigma_squared: f64, t0: f64, t1: f64) -> f64 {
    // The integrand is even: take the side where most of the chord lies.
    let (t0, t1) = if t0 + t1 < 0.0 { (-t1, -t0) } else { (t0, t1) };
    let (middle, half) = (0.5 * (t0 + t1), 0.5 * (t1 - t0));
    let half_root_pi = 0.5 * std::f64::consts::PI.sqrt();
    if 2.0 * half * (1.0 + 2.0 * middle) <= SHORT_CHORD {
        let at = |x: f64| {
            let t = middle + half * x;
            (-sigma_squared - t * t).exp()
        };
        half * LEGENDRE_4
            .iter()
            .map(|&(x, weight)| weight * (at(x) + at(-x)))
            .sum::<f64>()
    } else if t0 >= 0.0 {
        // erfc(t1)/erfc(t0) < e^(−(t1² − t0²)).
        let far = if (t1 - t0) * (t1 + t0) > NEGLIGIBLE_EXPONENT {
            0.0
        } else {
            scaled_erfc(t1, sigma_squared)
        };
        half_root_pi * (scaled_erfc(t0, sigma_squared) - far)
    } else {
        let tail = |x: f64| {
            if x * x > NEGLIGIBLE_EXPONENT {
                0.0
            } else {
                scaled_erfc(x, 0.0)
            }
        };
        half_root_pi * (-sigma_squared).exp() * ((1.0 - tail(t1)) + (1.0 - tail(-t0)))
    }
}

/// Terms below e^(−this) of what they are added to are not evaluated.
const NEGLIGIBLE_EXPONENT: f64 = 40.0;

/// e^(−c)·erfc(x) for x ≥ 0 to a relative 1.2e-7: the Chebyshev fit of Press et al., Numerical
/// Recipes (2nd ed., Sec. 6.2), erfc(x) ≈ t·exp(−x² + P(t)) with t = 1/(1 + x/2); P is
/// evaluated by Estrin's scheme (the same polynomial, a shorter chain of dependent operations).
fn scaled_erfc(x: f64, c: f64) -> f64 {
    let t = 1.0 / (1.0 + 0.5 * x);
    let t2 = t * t;
    let t4 = t2 * t2;
    let t8 = t4 * t4;
    let p01 = -1.265_512_23 + t * 1.000_023_68;
    let p23 = 0.374_091_96 + t * 0.096_784_18;
    let p45 = -0.186_288_06 + t * 0.278_868_07;
    let p67 = -1.135_203_98 + t * 1.488_515_87;
    let p89 = -0.822_152_23 + t * 0.170_872_77;
    let p = (p01 + t2 * p23) + t4 * (p45 + t2 * p67) + t8 * p89;
    t * (-x * x - c + p).exp()
}

/// erfc(x) for x ≥ 0 ([`scaled_erfc`] without the factor).
#[cfg(test)]
fn erfc(x: f64) -> f64 {
    scaled_erfc(x, 0.0)
}

/// ∫ dτ/(A + τ²)² over [t0, t1] (t0 ≤ t1): with τ = √A·tan θ it is
/// (Δθ + sin Δθ·cos(θ_0 + θ_1))/(2A^(3/2)). Δθ = atan2(√A(t1 − t0), A + t0·t1) does not
/// cancel. With the chord on one side of 0, cos(θ_0 + θ_1) → −1 far out, and the sum is written
/// (Δθ − sin Δθ) + 2 sin Δθ·sin²(β̄), β̄ = π/2 − (θ_0 + θ_1)/2, whose terms are positive.
fn ggx_chord(a: f64, t0: f64, t1: f64) -> f64 {
    let (t0, t1) = if t0 + t1 < 0.0 { (-t1, -t0) } else { (t0, t1) };
    let root = a.sqrt();
    let delta = f64::atan2(root * (t1 - t0), a + t0 * t1);
    let twice = if t0 >= 0.0 {
        // β_1 = π/2 − θ_1 = atan(√A/t1), and β̄ = β_1 + Δθ/2.
        let beta = (root / t1).atan() + 0.5 * delta;
        let s = beta.sin();
        delta_minus_sine(delta) + 2.0 * delta.sin() * s * s
    } else {
        // One end on each side: θ_0 + θ_1 ∈ (−π/2, π/2), its cosine is not near −1.
        let theta1 = (t1 / root).atan();
        delta + delta.sin() * (2.0 * theta1 - delta).cos()
    };
    twice / (2.0 * a * root)
}

/// x − sin x for x ≥ 0 without cancellation: its series below 0.25 (terms to x⁹, relative error
/// under 1e-16), else directly.
fn delta_minus_sine(x: f64) -> f64 {
    if x < 0.25 {
        let x2 = x * x;
        x * x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0 * (1.0 - x2 / 72.0)))
    } else {
        x - x.sin()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distribution::{erf, erfc_continued_fraction};

    /// ∫ f over [t0, t1] by 2¹² pieces of the 4-point Gauss–Legendre rule: the reference.
    fn reference(t0: f64, t1: f64, f: impl Fn(f64) -> f64) -> f64 {
        let n = 4096;
        let step = (t1 - t0) / f64::from(n);
        (0..n)
            .map(|k| {
                let middle = t0 + step * (f64::from(k) + 0.5);
                0.5 * step
                    * LEGENDRE_4
                        .iter()
                        .map(|&(x, w)| {
                            w * (f(middle + 0.5 * step * x) + f(middle - 0.5 * step * x))
                        })
                        .sum::<f64>()
            })
            .sum()
    }

    #[test]
    fn the_series_are_sine_and_cosine() {
        for k in -1000..=1000 {
            let phi = f64::from(k) * std::f64::consts::FRAC_PI_2 / 1000.0;
            let (sin, cos) = sin_cos_within_quarter_turn(phi);
            assert!(
                (sin - phi.sin()).abs() < 1e-13 && (cos - phi.cos()).abs() < 1e-13,
                "{phi}"
            );
        }
    }

    #[test]
    fn erfc_has_its_relative_accuracy() {
        let mut worst = 0.0_f64;
        for k in 0..=2600 {
            let x = f64::from(k) * 0.01;
            let exact = if x < 2.5 {
                1.0 - erf(x)
            } else {
                erfc_continued_fraction(x, 60)
            };
            worst = worst.max((erfc(x) - exact).abs() / exact);
        }
        println!("worst relative error {worst:e}");
        assert!(worst < 1.3e-7, "{worst}");
    }

    #[test]
    fn chord_integrals_match_quadrature_without_cancelling() {
        let ends = [
            -30.0, -7.0, -3.0, -1.0, -0.3, -1e-3, 0.0, 1e-6, 0.01, 0.2, 0.9, 1.0, 1.001, 2.5, 4.0,
            8.0, 20.0, 100.0,
        ];
        let (mut gaussian, mut ggx) = (0.0_f64, 0.0_f64);
        for &t0 in &ends {
            for &t1 in &ends {
                if t1 <= t0 {
                    continue;
                }
                for sigma in [0.0, 0.7, 3.0] {
                    let exact = reference(t0, t1, |t| (-sigma * sigma - t * t).exp());
                    if exact > 1e-280 {
                        let got = gaussian_chord(sigma * sigma, t0, t1);
                        gaussian = gaussian.max((got - exact).abs() / exact);
                    }
                }
                for a in [1.0, 1.5, 50.0, 1e4] {
                    let exact = reference(t0, t1, |t| 1.0 / (a + t * t).powi(2));
                    ggx = ggx.max((ggx_chord(a, t0, t1) - exact).abs() / exact);
                }
            }
        }
        println!("worst relative errors: Gaussian {gaussian:e}, GGX {ggx:e}");
        assert!(gaussian < 1e-6, "{gaussian}");
        assert!(ggx < 1e-10, "{ggx}");
    }

    #[test]
    fn the_mass_of_the_whole_plane_is_one() {
        // A huge ellipse around the peak holds the whole lobe (GGX: all but 1/(1 + R²)).
        let radius: f64 = 1e3;
        for law in [RadialLaw::Gaussian, RadialLaw::Student] {
            // (x² + y²) − R² < 0, centred at (0.2, −0.1).
            let (cx, cy) = (0.2, -0.1);
            let ellipse = Ellipse::from_form((
                [1.0, 0.0, 1.0],
                [-cx, -cy],
                cx * cx + cy * cy - radius * radius,
            ))
            .unwrap();
            let (mass, _) = ellipse.mass(law, None, 1e-9, 4096);
            let outside = match law {
                RadialLaw::Gaussian => 0.0,
                RadialLaw::Student => 1.0 / (1.0 + radius * radius),
            };
            assert!((mass - (1.0 - outside)).abs() < 1e-6, "{law:?}: {mass}");
        }
    }

    #[test]
    fn the_axes_and_centre_are_those_of_the_form() {
        // An ellipse with semi-axes 3 and 0.5, turned by 0.7 rad, centred at (1, −2).
        let (a, b, turn, cx, cy) = (3.0_f64, 0.5_f64, 0.7_f64, 1.0, -2.0);
        let (s, c) = turn.sin_cos();
        // M = R diag(1/a², 1/b²) Rᵀ with the major axis along (c, s).
        let (p, q) = (1.0 / (a * a), 1.0 / (b * b));
        let m = [
            p * c * c + q * s * s,
            (p - q) * c * s,
            p * s * s + q * c * c,
        ];
        let bx = -(m[0] * cx + m[1] * cy);
        let by = -(m[1] * cx + m[2] * cy);
        let constant = m[0] * cx * cx + 2.0 * m[1] * cx * cy + m[2] * cy * cy - 1.0;
        let e = Ellipse::from_form((m, [bx, by], constant)).unwrap();
        assert!(
            (e.major - a).abs() < 1e-12 && (e.minor - b).abs() < 1e-12,
            "{e:?}"
        );
        // The axes' directions are known up to their sign.
        assert!(
            (e.centre_major.abs() - (cx * c + cy * s).abs()).abs() < 1e-12,
            "{e:?}"
        );
        assert!(
            (e.centre_minor.abs() - (-cx * s + cy * c).abs()).abs() < 1e-12,
            "{e:?}"
        );
        // Not an ellipse: a hyperbola, and an empty set.
        assert!(Ellipse::from_form(([1.0, 0.0, -1.0], [0.0, 0.0], -1.0)).is_none());
        assert!(Ellipse::from_form(([1.0, 0.0, 1.0], [0.0, 0.0], 1.0)).is_none());
    }
}
