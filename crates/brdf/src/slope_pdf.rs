//! The glint sampler's density for cones wide against the lobe: the widened lobe's mass inside
//! Eq. 8's conic, integrated in slope space, exactly in one of its two dimensions. The conic is
//! an ellipse in slope space, integrated along its chords ([`ellipse`]; a cone across the
//! horizon cuts it by the horizon's own ellipse): 1.5–3 µs per pdf above the horizon, 6–13 µs
//! across it (Beckmann, `cargo xtask validate --only "pdf cost"`). The rays from the lobe's peak
//! below (10–36 µs) take the conics that are not ellipses, and are the tests' reference.
//!
//! # Derivation
//! The sampler of Sec. 3.4 ([`crate::glint_sampling`]) draws a facet normal h from
//! p_s(h) = D_s(h)(h·n), reflects ω_i about it to ω′ = 2(ω_i·h)h − ω_i (rejecting ω_i·h ≤ 0 and
//! ω′ below the horizon), then ω_o uniform in the cone of radius γ around ω′. So
//!
//! ```text
//!   pdf(ω_o) = (1/σ) · P[ω′ within γ of ω_o] = (1/σ) ∫_{Ω} D_s(h)(h·n) dh,   σ = 2π(1 − cos γ),
//! ```
//!
//! where Ω is the set of valid normals whose reflection of ω_i lies within γ of ω_o: the
//! spherical conic of Eq. 8 for (ω_i, ω_o, γ), cut by ω_i·h > 0 and ω′·n > 0. A rule over the
//! cone around ω_o (the cubature of [`crate::glint_sampling`]) resolves this only while the lobe
//! of ω′ is wide against the cone; when γ is wide against α_s, or at grazing incidence where
//! the lobe of ω′ is compressed by cos θ_i across the plane of incidence, the lobe falls between
//! the rule's points and the pdf is wrong by orders of magnitude. This rule integrates over the
//! lobe instead, exactly in one of its two dimensions.
//!
//! # The ray rule
//! **Slope space.** Write h ∝ H = (α_x ρ cos ψ, α_y ρ sin ψ, 1): ρ is the scaled slope radius
//! and ψ its angle (the sampler's own map, [`crate::Microfacet::sample_normal`], up to the sign
//! of the slope, which a symmetric lobe ignores). Then D_s(h)(h·n) dh = P(ρ) ρ dρ dψ with
//! P(ρ) = e^(−ρ²)/π (Beckmann) or 1/(π(1 + ρ²)²) (GGX), whose mass beyond ρ on a ray is
//! T(ρ)/(2π) per unit ψ, T(ρ) = e^(−ρ²) or 1/(1 + ρ²). Hence
//!
//! ```text
//!   σ·pdf = (1/2π) ∫_0^{2π} Σ_{[ρ_a, ρ_b] ⊂ ray(ψ) ∩ Ω} (T(ρ_a) − T(ρ_b)) dψ.
//! ```
//!
//! **Each ray exactly.** Along H(ρ) = e_z + ρ·d, d = (α_x cos ψ, α_y sin ψ, 0), the three
//! conditions are polynomials in ρ: Eq. 8's scaled form q(H) < 0 (a quadratic, from
//! [`SphericalConic`]'s cancellation-free coefficients), ω_i·H > 0 (linear) and
//! ω′_z ∝ 2(ω_i·H)H_z − ω_{i,z}|H|² > 0 (a quadratic). Their positive roots cut the ray into
//! pieces; each piece is in Ω or not as its midpoint is, and T gives its mass in closed form.
//!
//! **Over ψ.** The ray's mass G(ψ) is smooth except where a ray grazes the conic's boundary,
//! the zeros of the discriminant of q(H) in ρ, a quadratic form in (cos ψ, sin ψ); there G has a
//! square-root edge. The circle is cut at those angles (and at the quarter turns, so no arc is
//! longer than π/2); arcs whose rays all miss the conic carry no mass and are dropped; where
//! the conic's boundary crosses the horizon's (ω′_z = 0) on a ray, G has a kink, and the live
//! arcs are cut there too. Each arc takes the 15-point Gauss–Kronrod rule after the substitution
//! ψ = ψ_0 + (ψ_1 − ψ_0)(3t² − 2t³), which turns a square-root edge into a smooth one. G can
//! still change quickly inside an arc (a very anisotropic lobe stretches the conic into a
//! sliver in scaled slopes), so the rule is adaptive: the piece with the largest Kronrod–Gauss
//! difference is halved until the differences add up to less than [`RELATIVE_TOLERANCE`] of
//! the mass, or [`MAX_PIECES`] pieces bound the work (48 pieces of 15 rays).

use glam::DVec3;
use glint_sphere::SphericalConic;

use crate::distribution::Microfacet;
use crate::quadrature::{Piece, adaptive_gauss_kronrod, smoothed_gauss_kronrod};

/// The adaptive rule stops when its estimated error is below this fraction of the mass.
const RELATIVE_TOLERANCE: f64 = 1e-4;

/// At most this many pieces of ψ (15 rays each): the work per pdf is bounded.
const MAX_PIECES: usize = 48;

/// Steps per arc at which [`Rays::horizon_crossings`] looks for a change of sign, and the
/// bisections that then place a crossing (to a 2³⁰th of a step).
const CROSSING_SCAN: usize = 12;
const CROSSING_BISECTIONS: usize = 30;

mod ellipse;

/// σ·pdf(ω_o): the mass of `lobe`'s p(h) = D(h)(h·n) over the valid normals of `conic` (Eq. 8
/// for ω_i, ω_o and γ) that reflect ω_i above the horizon. `wi` is the unit ω_i of the conic.
pub(crate) fn conic_mass(lobe: &Microfacet, conic: &SphericalConic, wi: DVec3) -> f64 {
    conic_mass_to(lobe, conic, wi, RELATIVE_TOLERANCE, MAX_PIECES)
}

/// [`conic_mass`] to a relative `tolerance` with at most `max_pieces` pieces of ψ.
pub(crate) fn conic_mass_to(
    lobe: &Microfacet,
    conic: &SphericalConic,
    wi: DVec3,
    tolerance: f64,
    max_pieces: usize,
) -> f64 {
    conic_mass_and_pieces(lobe, conic, wi, tolerance, max_pieces).0
}

/// Where the cone lies, which decides how [`conic_mass`] integrates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ConeSide {
    /// Above the horizon (ω_o·n ≥ sin γ): the ellipse's chords ([`ellipse`]).
    AboveTheHorizon,
    /// Across it: the ellipse's chords cut by the horizon's condition ω′_z > 0, itself an
    /// ellipse in slope space ([`Rays::horizon`]).
    AcrossTheHorizon,
}

/// Where the cone of `conic` lies.
pub(crate) fn cone_side(conic: &SphericalConic) -> ConeSide {
    if conic.wo().z >= conic.gamma().sin() {
        ConeSide::AboveTheHorizon
    } else {
        ConeSide::AcrossTheHorizon
    }
}

/// [`conic_mass_to`] and the number of pieces it took. Conics that are not ellipses in slope
/// space (a cone across the horizon seen from within about γ of it) take the ray rule.
fn conic_mass_and_pieces(
    lobe: &Microfacet,
    conic: &SphericalConic,
    wi: DVec3,
    tolerance: f64,
    max_pieces: usize,
) -> (f64, usize) {
    let rays = Rays::new(*lobe, conic, wi);
    // Radial lobes integrate the ellipse's chords in closed form.
    if let (Some(law), Some(ellipse)) = (lobe.kind().radial_law(), rays.ellipse()) {
        let cut = match cone_side(conic) {
            ConeSide::AboveTheHorizon => None,
            ConeSide::AcrossTheHorizon => Some(rays.horizon(conic)),
        };
        return ellipse.mass(law, cut.as_ref(), tolerance, max_pieces);
    }
    ray_mass_and_pieces(&rays, tolerance, max_pieces)
}

/// The ray rule: (mass, pieces).
fn ray_mass_and_pieces(rays: &Rays, tolerance: f64, max_pieces: usize) -> (f64, usize) {
    let mut cuts = rays.grazing_angles();
    cuts.extend((0..4).map(|k| f64::from(k) * std::f64::consts::FRAC_PI_2));
    cuts.sort_by(f64::total_cmp);
    cuts.push(cuts[0] + std::f64::consts::TAU);
    // Arcs whose rays all miss the conic hold no mass: dropped. The others are cut where the
    // conic's boundary crosses the horizon's.
    let arcs: Vec<(f64, f64)> = cuts
        .windows(2)
        .filter(|arc| arc[1] > arc[0] && !rays.misses_the_conic(0.5 * (arc[0] + arc[1])))
        .flat_map(|arc| {
            let mut ends = vec![arc[0]];
            ends.extend(rays.horizon_crossings(arc[0], arc[1]));
            ends.push(arc[1]);
            ends.windows(2).map(|w| (w[0], w[1])).collect::<Vec<_>>()
        })
        .collect();
    let rule = |start: f64, length: f64| rays.piece(start, length);
    let pieces: Vec<Piece> = arcs
        .iter()
        .filter(|(start, end)| end > start)
        .map(|&(start, end)| rule(start, end - start))
        .collect();
    let (integral, pieces) = adaptive_gauss_kronrod(pieces, tolerance, 0.0, max_pieces, rule);
    (integral / std::f64::consts::TAU, pieces)
}

/// The conditions of Ω along rays H = e_z + ρ·d(ψ) in slope space, as polynomial coefficients
/// in ρ built from their values on the basis vectors e_z, u = (α_x, 0, 0), v = (0, α_y, 0).
struct Rays {
    lobe: Microfacet,
    /// (k1, k2, −s) of [`SphericalConic::scaled_coefficients`].
    k: DVec3,
    /// e_z, u, v in the conic's frame.
    e: DVec3,
    u: DVec3,
    v: DVec3,
    wi: DVec3,
    alpha: (f64, f64),
}

impl Rays {
    fn new(lobe: Microfacet, conic: &SphericalConic, wi: DVec3) -> Self {
        let (alpha_x, alpha_y) = lobe.alpha();
        let frame = conic.frame();
        let to_frame = |m: DVec3| DVec3::new(frame[0].dot(m), frame[1].dot(m), frame[2].dot(m));
        Self {
            lobe,
            k: conic.scaled_coefficients(),
            e: to_frame(DVec3::Z),
            u: to_frame(DVec3::new(alpha_x, 0.0, 0.0)),
            v: to_frame(DVec3::new(0.0, alpha_y, 0.0)),
            wi,
            alpha: (alpha_x, alpha_y),
        }
    }

    /// The scaled form's bilinear version q(f, g) for frame coordinates.
    fn q(&self, f: DVec3, g: DVec3) -> f64 {
        self.k.x * f.x * g.x + self.k.y * f.y * g.y + self.k.z * f.z * g.z
    }

    /// ∫ G(ψ) dψ over [start, start + length] by the Gauss–Kronrod pair after the substitution
    /// ψ = start + length·(3t² − 2t³), t ∈ [0, 1].
    fn piece(&self, start: f64, length: f64) -> Piece {
        smoothed_gauss_kronrod(start, length, |psi| self.mass(psi))
    }

    /// The cone's condition q(e + x·u + y·v) < 0 as an ellipse in scaled slopes (x, y), when it
    /// is one ([`ellipse`]).
    fn ellipse(&self) -> Option<ellipse::Ellipse> {
        ellipse::Ellipse::from_form((
            [
                self.q(self.u, self.u),
                self.q(self.u, self.v),
                self.q(self.v, self.v),
            ],
            [self.q(self.u, self.e), self.q(self.v, self.e)],
            self.q(self.e, self.e),
        ))
    }

    /// The horizon's condition ω′_z > 0 in scaled slopes, H = (α_x x, α_y y, 1), for the cone
    /// of `conic` across the horizon. ω′_z has the sign of 2(ω_i·H)H_z − ω_i,z|H|² = ω_i,z +
    /// 2(ω_i,x α_x x + ω_i,y α_y y) − ω_i,z(α_x² x² + α_y² y²), so the condition is {G < 0} for
    /// the form G below (an ellipse: ω_i,z > 0); within it ω_i·h > 0 holds too (ω_i + ω′ =
    /// 2(ω_i·h)h has a positive z). The boundaries cross at the normals that reflect ω_i to the
    /// two directions where the cone's rim meets the horizon: v = (cos φ, sin φ, 0) with
    /// cos(φ − φ_o) = cos γ/|ω_o,xy|.
    fn horizon(&self, conic: &SphericalConic) -> ellipse::Cut {
        let (alpha_x, alpha_y) = self.alpha;
        let form = (
            [
                self.wi.z * alpha_x * alpha_x,
                0.0,
                self.wi.z * alpha_y * alpha_y,
            ],
            [-self.wi.x * alpha_x, -self.wi.y * alpha_y],
            -self.wi.z,
        );
        let wo = conic.wo();
        let level = wo.x.hypot(wo.y);
        let crossings = if level > 0.0 {
            let turn = (conic.gamma().cos() / level).clamp(-1.0, 1.0).acos();
            let azimuth = wo.y.atan2(wo.x);
            [azimuth - turn, azimuth + turn]
                .into_iter()
                .filter_map(|phi| {
                    let h = self.wi + DVec3::new(phi.cos(), phi.sin(), 0.0);
                    (h.z > 0.0).then(|| [h.x / (h.z * alpha_x), h.y / (h.z * alpha_y)])
                })
                .collect()
        } else {
            Vec::new()
        };
        ellipse::Cut { form, crossings }
    }

    /// The angles ψ at which a ray grazes the conic's boundary: the zeros of the discriminant
    /// q(d, e)² − q(d, d)q(e, e) of q(e + ρd) in ρ, with d = u cos ψ + v sin ψ, a quadratic form
    /// a·c² + 2b·cs + c·s² in (cos ψ, sin ψ).
    fn grazing_angles(&self) -> Vec<f64> {
        let (qe, que, qve) = (
            self.q(self.e, self.e),
            self.q(self.u, self.e),
            self.q(self.v, self.e),
        );
        let (quu, quv, qvv) = (
            self.q(self.u, self.u),
            self.q(self.u, self.v),
            self.q(self.v, self.v),
        );
        let a = que * que - quu * qe;
        let b = que * qve - quv * qe;
        let c = qve * qve - qvv * qe;
        // a cos² + 2b cos sin + c sin² = 0. Its zero directions: with the eigen-decomposition
        // of [[a, b], [b, c]], eigenvalues λ± along angles θ, θ + π/2, the form is
        // λ+ cos²(ψ − θ) + λ− sin²(ψ − θ), zero where tan²(ψ − θ) = −λ+/λ−.
        let mean = 0.5 * (a + c);
        let radius = (0.25 * (a - c) * (a - c) + b * b).sqrt();
        let (plus, minus) = (mean + radius, mean - radius);
        if !(plus > 0.0 && minus < 0.0) {
            return Vec::new();
        }
        let theta = 0.5 * f64::atan2(2.0 * b, a - c);
        let offset = (plus / -minus).sqrt().atan();
        [
            offset,
            -offset,
            std::f64::consts::PI + offset,
            std::f64::consts::PI - offset,
        ]
        .into_iter()
        .map(|x| (theta + x).rem_euclid(std::f64::consts::TAU))
        .collect()
    }

    /// Whether the ray at angle ψ misses the conic: its start, the normal n (ρ = 0), lies
    /// outside it and q(e + ρd) has no real root. Both hold on a whole arc between grazing
    /// angles (the zeros of the discriminant), whose rays then carry no mass.
    fn misses_the_conic(&self, psi: f64) -> bool {
        let (sin, cos) = psi.sin_cos();
        let d = cos * self.u + sin * self.v;
        let (qee, qde, qdd) = (self.q(self.e, self.e), self.q(d, self.e), self.q(d, d));
        qee > 0.0 && qde * qde - qdd * qee < 0.0
    }

    /// The angles ψ at which the conic's boundary crosses the horizon's on the ray: where
    /// q(e + ρd) changes sign at ρ_h(ψ), the positive root of ω′_z ∝ ω_iz + 2ρ(ω_i·d) −
    /// ρ²ω_iz|d|² (there is exactly one: the product of the roots is −1/|d|²). There a ray's
    /// inside interval switches from ending at one boundary to ending at the other, and G(ψ)
    /// has a kink that the Gauss–Kronrod pair misjudges (errors of 1e-3 at 1e-4 estimated,
    /// for cones across the horizon). Found on the arc [`start`, `end`] (between the grazing
    /// angles, which bracket a narrow conic) by the sign of q at [`CROSSING_SCAN`] + 1 angles,
    /// then bisected; two crossings closer than the scan's step are left to the adaptive rule.
    fn horizon_crossings(&self, start: f64, end: f64) -> Vec<f64> {
        let sign_at = |psi: f64| {
            let (sin, cos) = psi.sin_cos();
            let d_frame = cos * self.u + sin * self.v;
            let d = DVec3::new(self.alpha.0 * cos, self.alpha.1 * sin, 0.0);
            let above = [
                self.wi.z,
                2.0 * self.wi.dot(d),
                -self.wi.z * d.length_squared(),
            ];
            let Some(rho) = positive_roots(above).into_iter().flatten().next() else {
                return 0.0;
            };
            let e = self.e + rho * d_frame;
            self.q(e, e).signum()
        };
        let step = (end - start) / CROSSING_SCAN as f64;
        let mut crossings = Vec::new();
        let mut previous = sign_at(start);
        for k in 1..=CROSSING_SCAN {
            let psi = start + step * k as f64;
            let sign = sign_at(psi);
            if sign * previous < 0.0 {
                let (mut lo, mut hi) = (psi - step, psi);
                for _ in 0..CROSSING_BISECTIONS {
                    let mid = 0.5 * (lo + hi);
                    if sign_at(mid) == previous {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                crossings.push((0.5 * (lo + hi)).clamp(start, end));
            }
            if sign != 0.0 {
                previous = sign;
            }
        }
        crossings
    }

    /// Σ (T(ρ_a) − T(ρ_b)) over the pieces of the ray at angle ψ inside Ω.
    fn mass(&self, psi: f64) -> f64 {
        let (sin, cos) = psi.sin_cos();
        let d_frame = cos * self.u + sin * self.v;
        let d = DVec3::new(self.alpha.0 * cos, self.alpha.1 * sin, 0.0);
        // q(e + ρd) = q_dd ρ² + 2 q_de ρ + q_ee.
        let cone = [
            self.q(self.e, self.e),
            2.0 * self.q(d_frame, self.e),
            self.q(d_frame, d_frame),
        ];
        // ω_i·H = ω_iz + ρ ω_i·d.
        let wi_d = self.wi.dot(d);
        // 2(ω_i·H)·1 − ω_iz|H|² = ω_iz + 2ρ(ω_i·d) − ρ² ω_iz |d|².
        let above = [self.wi.z, 2.0 * wi_d, -self.wi.z * d.length_squared()];
        let mut cuts = [0.0; 6];
        let mut n = 0;
        for root in positive_roots(cone)
            .into_iter()
            .chain(positive_roots(above))
            .chain(std::iter::once((wi_d < 0.0).then(|| -self.wi.z / wi_d)))
            .flatten()
        {
            cuts[n] = root;
            n += 1;
        }
        let cuts = &mut cuts[..n];
        cuts.sort_by(f64::total_cmp);
        let value = |[c0, c1, c2]: [f64; 3], rho: f64| c0 + rho * (c1 + rho * c2);
        let inside = |rho: f64| {
            value(cone, rho) < 0.0 && self.wi.z + rho * wi_d > 0.0 && value(above, rho) > 0.0
        };
        let mut sum = 0.0;
        let mut start = 0.0;
        for end in cuts.iter().copied().chain(std::iter::once(f64::INFINITY)) {
            if end > start {
                let middle = if end.is_finite() {
                    0.5 * (start + end)
                } else {
                    2.0 * start + 1.0
                };
                if inside(middle) {
                    sum += self.lobe.ray_mass((cos, sin), start, end);
                }
            }
            start = end;
        }
        sum
    }
}

/// The positive real roots of c0 + c1·ρ + c2·ρ², computed without cancellation.
fn positive_roots([c0, c1, c2]: [f64; 3]) -> [Option<f64>; 2] {
    let keep = |r: f64| (r > 0.0 && r.is_finite()).then_some(r);
    if c2 == 0.0 {
        return [(c1 != 0.0).then(|| -c0 / c1).and_then(keep), None];
    }
    let discriminant = c1 * c1 - 4.0 * c2 * c0;
    if discriminant < 0.0 {
        return [None, None];
    }
    let q = -0.5 * (c1 + discriminant.sqrt().copysign(c1));
    if q == 0.0 {
        return [None, None];
    }
    [keep(q / c2), keep(c0 / q)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cone::uniform_in_cone;
    use crate::distribution::DistributionKind;
    use crate::qmc::zero_two_point;

    /// The probability that ω′ (the sampler's first step, valid) lies within γ of ω_o, by
    /// drawing `n` normals from the lobe on a (0, 2)-sequence.
    fn brute_force(lobe: &Microfacet, wi: DVec3, wo: DVec3, gamma: f64, n: u32) -> f64 {
        let mut hits = 0u32;
        for i in 0..n {
            let [a, b] = zero_two_point(i);
            let h = lobe.sample_normal([a, b]);
            let wi_h = wi.dot(h);
            let reflected = 2.0 * wi_h * h - wi;
            if wi_h > 0.0 && reflected.z > 0.0 && reflected.dot(wo) >= gamma.cos() {
                hits += 1;
            }
        }
        f64::from(hits) / f64::from(n)
    }

    #[test]
    fn the_mass_is_the_probability_of_landing_in_the_cone() {
        let n = 1 << 20;
        let mut worst = 0.0_f64;
        for (kind, ax, ay, gamma_degrees) in [
            (DistributionKind::Beckmann, 0.02, 0.02, 20.0),
            (DistributionKind::Ggx, 0.02, 0.02, 60.0),
            (DistributionKind::Beckmann, 0.3, 0.3, 5.0),
            (DistributionKind::Ggx, 0.0002, 0.6, 3.0),
            (DistributionKind::Beckmann, 1.0, 0.01, 40.0),
        ] {
            let lobe = Microfacet::new(kind, ax, ay).unwrap();
            let gamma = f64::to_radians(gamma_degrees);
            for i in 0..12 {
                let [a, b] = zero_two_point(i + 5);
                let wi = uniform_in_cone(DVec3::Z, 1.5, a, b);
                // Directions near the lobe and away from it.
                let [c, e] = zero_two_point(i + 101);
                let wo = if i % 2 == 0 {
                    let mirror = DVec3::new(-wi.x, -wi.y, wi.z);
                    uniform_in_cone(mirror, 1.5 * gamma, c, e)
                } else {
                    uniform_in_cone(DVec3::Z, 1.5, c, e)
                };
                let conic = SphericalConic::new(wi, wo, gamma).unwrap();
                let exact = conic_mass(&lobe, &conic, wi);
                let sampled = brute_force(&lobe, wi, wo, gamma, n);
                // Binomial standard error of the sampled probability, and a floor for the
                // sequence's discrepancy.
                let error = (exact - sampled).abs();
                let allowed = 5.0 * (sampled * (1.0 - sampled) / f64::from(n)).sqrt() + 2e-5;
                worst = worst.max(error / allowed);
                assert!(
                    error <= allowed,
                    "{kind:?} α ({ax}, {ay}) γ {gamma_degrees}° wi {wi} wo {wo}: {exact} vs {sampled}"
                );
            }
        }
        println!("worst error / allowed: {worst}");
    }

    /// Cones across the horizon (ω_o within γ of it), where ω′_z > 0 cuts the conic: the rule
    /// stays within its tolerance of a 1e-9 reference, in few pieces (cut where the conic's
    /// boundary crosses the horizon's, G(ψ) is smooth on every arc). Measured: 5.3e-7 in at
    /// most 11 pieces.
    #[test]
    fn cones_across_the_horizon_converge_in_few_pieces() {
        let (mut worst, mut most) = (0.0_f64, 0);
        for (kind, alpha, gamma_degrees) in [
            (DistributionKind::Beckmann, 0.2, 0.5),
            (DistributionKind::Ggx, 0.2, 1.0),
            (DistributionKind::Beckmann, 0.05, 2.0),
        ] {
            let lobe = Microfacet::new(kind, alpha, alpha).unwrap();
            let gamma = f64::to_radians(gamma_degrees);
            for i in 0..100 {
                let [a, b] = zero_two_point(i + 3);
                let wi = uniform_in_cone(DVec3::Z, 1.4, a, b);
                let [c, e] = zero_two_point(i + 211);
                let phi = std::f64::consts::TAU * c;
                let height = gamma.sin() * (0.05 + 0.9 * e);
                let wo = DVec3::new(phi.cos(), phi.sin(), 0.0) * (1.0 - height * height).sqrt()
                    + DVec3::new(0.0, 0.0, height);
                let conic = SphericalConic::new(wi, wo, gamma).unwrap();
                let reference = conic_mass_to(&lobe, &conic, wi, 1e-9, 4096);
                if reference < 1e-9 {
                    continue;
                }
                let (mass, pieces) =
                    conic_mass_and_pieces(&lobe, &conic, wi, RELATIVE_TOLERANCE, MAX_PIECES);
                worst = worst.max((mass - reference).abs() / reference);
                most = most.max(pieces);
            }
        }
        // Without the cuts at the crossings: 1.1e-3 in up to 17 pieces.
        println!("worst relative error {worst:e}, most pieces {most}");
        assert!(worst < RELATIVE_TOLERANCE, "{worst}");
        assert!(most <= 16, "{most}");
    }

    /// The chord rule against the ray rule, which makes no use of the conic being an ellipse,
    /// for cones above the horizon and across it (cut by the horizon's ellipse): at a 1e-10
    /// tolerance they agree to the chords' erfc (1e-7); at the default one, within a few
    /// tolerances, in few pieces.
    #[test]
    fn chords_agree_with_rays() {
        for side in [ConeSide::AboveTheHorizon, ConeSide::AcrossTheHorizon] {
            let (mut exact_worst, mut default_worst, mut most, mut total, mut count) =
                (0.0_f64, 0.0_f64, 0, 0, 0);
            for (kind, ax, ay, gamma_degrees) in [
                (DistributionKind::Beckmann, 0.02, 0.02, 1.0),
                (DistributionKind::Beckmann, 0.02, 0.02, 20.0),
                (DistributionKind::Ggx, 0.02, 0.02, 1.0),
                (DistributionKind::Ggx, 0.02, 0.02, 60.0),
                (DistributionKind::Beckmann, 0.3, 0.3, 5.0),
                (DistributionKind::Ggx, 0.0002, 0.6, 3.0),
                (DistributionKind::Beckmann, 1.0, 0.01, 40.0),
                (DistributionKind::Beckmann, 0.0002, 0.0002, 10.0),
                (DistributionKind::Ggx, 0.0002, 0.0002, 10.0),
                (DistributionKind::Beckmann, 0.2, 0.2, 0.5),
            ] {
                let lobe = Microfacet::new(kind, ax, ay).unwrap();
                let gamma = f64::to_radians(gamma_degrees);
                for i in 0..96 {
                    let [a, b] = zero_two_point(i + 5);
                    let wi = uniform_in_cone(DVec3::Z, 1.55, a, b);
                    let [c, e] = zero_two_point(i + 101);
                    let wo = match (side, i % 2) {
                        (ConeSide::AboveTheHorizon, 0) => {
                            let mirror = DVec3::new(-wi.x, -wi.y, wi.z);
                            uniform_in_cone(mirror, 2.0 * gamma, c, e)
                        }
                        (ConeSide::AboveTheHorizon, _) => uniform_in_cone(DVec3::Z, 1.5, c, e),
                        // Within γ of the horizon, toward the mirror direction or anywhere.
                        (ConeSide::AcrossTheHorizon, k) => {
                            let phi = if k == 0 {
                                f64::atan2(-wi.y, -wi.x) + (c - 0.5)
                            } else {
                                std::f64::consts::TAU * c
                            };
                            let height = gamma.sin() * (0.02 + 0.96 * e);
                            DVec3::new(phi.cos(), phi.sin(), 0.0) * (1.0 - height * height).sqrt()
                                + DVec3::new(0.0, 0.0, height)
                        }
                    };
                    let conic = SphericalConic::new(wi, wo, gamma).unwrap();
                    if cone_side(&conic) != side {
                        continue;
                    }
                    let rays = Rays::new(lobe, &conic, wi);
                    let law = kind.radial_law().unwrap();
                    let Some(ellipse) = rays.ellipse() else {
                        assert_eq!(side, ConeSide::AcrossTheHorizon, "{wi} {wo}");
                        continue;
                    };
                    let reference = ray_mass_and_pieces(&rays, 1e-10, 1 << 14).0;
                    if reference < 1e-12 {
                        continue;
                    }
                    let cut = (side == ConeSide::AcrossTheHorizon).then(|| rays.horizon(&conic));
                    let exact = ellipse.mass(law, cut.as_ref(), 1e-10, 1 << 14).0;
                    let (mass, pieces) =
                        ellipse.mass(law, cut.as_ref(), RELATIVE_TOLERANCE, MAX_PIECES);
                    let error = (exact - reference).abs() / reference;
                    assert!(
                        error < 1e-6,
                        "{side:?} {kind:?} ({ax}, {ay}) {gamma_degrees}° {wi} {wo}: {exact} against {reference}"
                    );
                    exact_worst = exact_worst.max(error);
                    default_worst = default_worst.max((mass - reference).abs() / reference);
                    most = most.max(pieces);
                    total += pieces;
                    count += 1;
                }
            }
            println!(
                "{side:?}, {count} cones: worst relative error {exact_worst:e} (1e-10), \
                 {default_worst:e} (default); pieces: mean {:.2}, most {most}",
                total as f64 / f64::from(count)
            );
            assert!(count > 100, "{count}");
            assert!(default_worst < 5.0 * RELATIVE_TOLERANCE, "{default_worst}");
        }
    }

    /// Cones across the horizon whose cut set is a thin sliver near the ends of a long ellipse:
    /// its boundaries cross within a few degrees of each other on the ellipse, where a search
    /// at 24 angles missed both crossings and the whole set (pdf 0 for directions the sampler
    /// drew). The crossings now come from the cone's rim on the horizon.
    #[test]
    fn thin_cut_sets_keep_their_mass() {
        for (kind, alpha, gamma_degrees, wi, wo) in [
            (
                DistributionKind::Ggx,
                0.04,
                10.0,
                DVec3::new(
                    -0.490_268_749_097_647_45,
                    0.860_773_047_244_750_5,
                    0.136_771_030_540_881_4,
                ),
                DVec3::new(
                    0.492_529_137_664_126_9,
                    -0.869_462_748_272_384_3,
                    0.038_073_322_923_858_16,
                ),
            ),
            (
                DistributionKind::Beckmann,
                0.4,
                5.0,
                DVec3::new(
                    -0.966_783_691_255_9,
                    -0.242_380_384_560_265_03,
                    0.081_123_630_971_710_95,
                ),
                DVec3::new(
                    0.965_168_455_292_325,
                    0.261_551_651_669_123_8,
                    0.006_370_747_034_754_799,
                ),
            ),
        ] {
            let lobe = Microfacet::new(kind, alpha, alpha).unwrap();
            let conic = SphericalConic::new(wi, wo, f64::to_radians(gamma_degrees)).unwrap();
            let wi = wi.normalize();
            let rays = Rays::new(lobe, &conic, wi);
            let reference = ray_mass_and_pieces(&rays, 1e-10, 1 << 14).0;
            let mass = conic_mass(&lobe, &conic, wi);
            assert!(reference > 0.01, "{reference}");
            assert!(
                (mass - reference).abs() < 5.0 * RELATIVE_TOLERANCE * reference,
                "{mass} against {reference}"
            );
        }
    }

    #[test]
    fn refining_the_arcs_changes_little() {
        let mut worst = 0.0_f64;
        for (kind, ax, ay, gamma_degrees) in [
            (DistributionKind::Beckmann, 0.02, 0.02, 20.0),
            (DistributionKind::Ggx, 0.0002, 0.0002, 10.0),
            (DistributionKind::Beckmann, 0.0002, 2e-4 * 50.0, 1.0),
            (DistributionKind::Ggx, 0.5, 0.5, 60.0),
        ] {
            let lobe = Microfacet::new(kind, ax, ay).unwrap();
            let gamma = f64::to_radians(gamma_degrees);
            for i in 0..200 {
                let [a, b] = zero_two_point(i + 7);
                let wi = uniform_in_cone(DVec3::Z, 1.55, a, b);
                let [c, e] = zero_two_point(i + 301);
                let mirror = DVec3::new(-wi.x, -wi.y, wi.z);
                let wo = uniform_in_cone(mirror, 1.2 * gamma, c, e);
                if wo.z <= 0.0 {
                    continue;
                }
                let conic = SphericalConic::new(wi, wo, gamma).unwrap();
                let reference = conic_mass_to(&lobe, &conic, wi, 1e-9, 4096);
                if reference < 1e-6 {
                    continue;
                }
                let error = (conic_mass(&lobe, &conic, wi) - reference).abs() / reference;
                worst = worst.max(error);
            }
        }
        println!("worst relative change: {worst:e}");
        assert!(worst < 1e-3, "{worst}");
    }
}
