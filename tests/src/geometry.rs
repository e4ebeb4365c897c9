//! Random configurations of glint-sphere and their brute-force audits.
//!
//! A [`ConicCase`] is a conic (ω_i, ω_o, γ) and a triangle, drawn to cover the numerical
//! extremes the tests must survive: γ log-uniform from 0.01° to 60°, directions 1e-6 from the horizon, ω_i = ω_o,
//! ω_i·ω_o at and around −cos γ, ω_i = −ω_o and within 1e-12 of it, triangles from an octant down to 1e-5 rad edges,
//! count-tree triangles (octants subdivided, vertices on the horizon), triangles dipping below
//! the horizon, and triangles placed near the conic so that classification is interesting.

use glam::DVec3;
use glint_sphere::{Classification, OverlapMethod, SphericalConic, SphericalTriangle};

/// How many uniform numbers [`ConicCase::from_uniforms`] consumes.
pub const CASE_UNIFORMS: usize = 16;

/// A conic and a triangle to test against each other.
#[derive(Clone, Copy, Debug)]
pub struct ConicCase {
    /// The conic (ω_i, ω_o, γ).
    pub conic: SphericalConic,
    /// The triangle.
    pub triangle: SphericalTriangle,
}

/// A unit direction from polar angle θ and azimuth φ (radians).
#[must_use]
pub fn direction(theta: f64, phi: f64) -> DVec3 {
    DVec3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    )
}

/// Any unit vector perpendicular to unit `v` (test helper; not the library's construction).
#[must_use]
pub(crate) fn perpendicular(v: DVec3) -> DVec3 {
    let helper = if v.x.abs() < 0.6 { DVec3::X } else { DVec3::Y };
    v.cross(helper).normalize()
}

/// Uniform direction in the cone of radius `gamma` around unit `axis`, from two uniforms.
#[must_use]
pub fn uniform_in_cone(axis: DVec3, gamma: f64, u0: f64, u1: f64) -> DVec3 {
    // cos θ uniform in [cos γ, 1], written with 1 − cos γ = 2 sin²(γ/2) for tiny γ.
    let one_minus_cos = u0 * 2.0 * (0.5 * gamma).sin().powi(2);
    let sin_theta = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
    let phi = 2.0 * std::f64::consts::PI * u1;
    let t = perpendicular(axis);
    let b = axis.cross(t);
    ((1.0 - one_minus_cos) * axis + sin_theta * (phi.cos() * t + phi.sin() * b)).normalize()
}

impl ConicCase {
    /// Builds a case from [`CASE_UNIFORMS`] uniform numbers in [0, 1).
    #[must_use]
    pub fn from_uniforms(u: &[f64; CASE_UNIFORMS]) -> Self {
        let gamma = (0.01_f64.ln() + u[0] * (60.0_f64.ln() - 0.01_f64.ln()))
            .exp()
            .to_radians();
        let conic = Self::random_conic(gamma, u);
        let triangle = Self::random_triangle(&conic, u);
        Self { conic, triangle }
    }

    fn random_conic(gamma: f64, u: &[f64; CASE_UNIFORMS]) -> SphericalConic {
        let tau = std::f64::consts::TAU;
        let upper = |a: f64, b: f64| direction(a * 0.5 * std::f64::consts::PI, b * tau);
        let near_horizon = |a: f64, b: f64| {
            let elevation = if a < 0.5 {
                1e-6
            } else {
                1e-6 + (a - 0.5) * 1e-3
            };
            direction(0.5 * std::f64::consts::PI - elevation, b * tau)
        };
        let (wi, wo) = match (u[1] * 8.0) as u32 {
            // Both anywhere in the upper hemisphere.
            0 | 1 => (upper(u[2], u[3]), upper(u[4], u[5])),
            // ω_i = ω_o: the circle.
            2 => {
                let w = upper(u[2], u[3]);
                (w, w)
            }
            // Grazing incidence and/or exitance.
            3 => (near_horizon(u[2], u[3]), upper(u[4], u[5])),
            4 => (near_horizon(u[2], u[3]), near_horizon(u[4], u[5])),
            // ω_i·ω_o at and around −cos γ: elevations e_i + e_o = γ + δ, opposite azimuths.
            5 => {
                let delta = match (u[4] * 5.0) as u32 {
                    0 => 0.0,
                    1 => 1e-9,
                    2 => -1e-9,
                    3 => 1e-3 * gamma,
                    _ => -1e-3 * gamma,
                };
                let total = (gamma + delta).max(2e-9);
                let ei = (0.05 + 0.9 * u[2]) * total;
                let half_pi = 0.5 * std::f64::consts::PI;
                let phi = u[3] * tau;
                (
                    direction(half_pi - ei, phi),
                    direction(half_pi - (total - ei), phi + std::f64::consts::PI),
                )
            }
            // ω_i = −ω_o, exactly or within 1e-12..1e-3 (ω_o below the horizon: the conic is
            // defined for any directions).
            6 => {
                let w = upper(u[2], u[3]);
                let offset = if u[4] < 0.3 {
                    0.0
                } else {
                    10f64.powf(-3.0 - 9.0 * u[5])
                };
                (w, (-w + offset * perpendicular(w)).normalize())
            }
            // Anywhere on the sphere.
            _ => (
                direction(u[2] * std::f64::consts::PI, u[3] * tau),
                direction(u[4] * std::f64::consts::PI, u[5] * tau),
            ),
        };
        SphericalConic::new(wi, wo, gamma).expect("generated conics are valid")
    }

    fn random_triangle(conic: &SphericalConic, u: &[f64; CASE_UNIFORMS]) -> SphericalTriangle {
        // Size log-uniform from 1e-5 rad to about an octant's edge.
        let size = (1e-5_f64.ln() + u[7] * (1.5_f64.ln() - 1e-5_f64.ln())).exp();
        match (u[6] * 6.0) as u32 {
            // A count-tree triangle: an octant subdivided towards a random point.
            0 => {
                let mut t = SphericalTriangle::upper_hemisphere_octants()[(u[8] * 4.0) as usize];
                let depth = (u[7] * 17.0) as u32;
                let mut choice = u[9];
                for _ in 0..depth {
                    let k = (choice * 4.0) as usize;
                    choice = choice * 4.0 - k as f64;
                    t = t.subdivide()[k.min(3)];
                }
                t
            }
            // Near the conic's valid set: around a point reflected into the cone's rim region.
            1..=3 => {
                let rim = uniform_in_cone(conic.wo(), 1.3 * conic.gamma(), u[8], u[9]);
                let centre = (conic.wi() + rim).normalize();
                let centre = if centre.is_finite() && centre.z > 0.0 {
                    centre
                } else {
                    DVec3::Z
                };
                Self::triangle_around(centre, size.min(4.0 * conic.gamma()), u)
            }
            // Anywhere in the upper hemisphere.
            4 => {
                let centre = direction(
                    u[8] * 0.5 * std::f64::consts::PI,
                    u[9] * std::f64::consts::TAU,
                );
                Self::triangle_around(centre, size, u)
            }
            // Anywhere, possibly below the horizon.
            _ => {
                let centre = direction(u[8] * std::f64::consts::PI, u[9] * std::f64::consts::TAU);
                Self::triangle_around(centre, size, u)
            }
        }
    }

    fn triangle_around(centre: DVec3, size: f64, u: &[f64; CASE_UNIFORMS]) -> SphericalTriangle {
        let t = perpendicular(centre);
        let b = centre.cross(t);
        let tau = std::f64::consts::TAU;
        let vertex = |angle: f64, radius: f64| {
            let offset = radius * size * (angle.cos() * t + angle.sin() * b);
            (centre + offset.clamp_length_max(1.2)).normalize()
        };
        let a0 = u[10] * tau;
        let a1 = a0 + (0.3 + 0.4 * u[11]) * tau;
        let a2 = a1 + (0.3 + 0.4 * u[12]) * 0.5 * (tau + a0 - a1);
        let (r0, r1, r2) = (0.3 + u[13], 0.3 + u[14], 0.3 + u[15]);
        SphericalTriangle::new(vertex(a0, r0), vertex(a1, r1), vertex(a2, r2))
            .or_else(|_| {
                SphericalTriangle::new(vertex(0.0, 1.0), vertex(2.1, 1.0), vertex(4.2, 1.0))
            })
            .expect("generated triangles are not degenerate")
    }
}

/// Draws `n` points in a triangle (planar-uniform then projected: every part of the triangle
/// has positive density), plus its vertices and points on its edges, and calls `visit`.
pub fn points_in_triangle(
    triangle: &SphericalTriangle,
    n: usize,
    rng: &mut crate::SplitMix64,
    mut visit: impl FnMut(DVec3),
) {
    let [a, b, c] = triangle.vertices();
    for v in [a, b, c] {
        visit(v);
    }
    for i in 0..n {
        let (mut s, mut t) = (rng.uniform(), rng.uniform());
        if i % 4 == 0 {
            // On an edge.
            t = 0.0;
        } else if s + t > 1.0 {
            s = 1.0 - s;
            t = 1.0 - t;
        }
        let p = match i % 3 {
            0 => a + s * (b - a) + t * (c - a),
            1 => b + s * (c - b) + t * (a - b),
            _ => c + s * (a - c) + t * (b - c),
        };
        visit(p.normalize());
    }
}

/// Tallies of a classification audit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ClassificationAudit {
    /// Cases classified.
    pub cases: u64,
    /// "Disjoint" answers for which a point of the triangle was in the conic (must be 0).
    pub wrong_disjoint: u64,
    /// "Triangle inside conic" answers with a point of the triangle outside it (must be 0).
    pub wrong_triangle_inside: u64,
    /// "Conic inside triangle" answers with a point of the conic outside the triangle (must be 0).
    pub wrong_conic_inside: u64,
    /// Answers per kind: disjoint, triangle inside, conic inside, partial.
    pub answers: [u64; 4],
    /// "Partial" answers where the samples saw no point of the conic in the triangle (an upper
    /// bound on needless splits: a sample can miss a small overlap).
    pub partial_but_looked_disjoint: u64,
}

impl ClassificationAudit {
    /// Whether no answer was wrong.
    #[must_use]
    pub fn is_clean(&self) -> bool {
        self.wrong_disjoint == 0 && self.wrong_triangle_inside == 0 && self.wrong_conic_inside == 0
    }

    /// Adds another audit's tallies.
    pub fn merge(&mut self, other: &Self) {
        self.cases += other.cases;
        self.wrong_disjoint += other.wrong_disjoint;
        self.wrong_triangle_inside += other.wrong_triangle_inside;
        self.wrong_conic_inside += other.wrong_conic_inside;
        for (a, b) in self.answers.iter_mut().zip(other.answers) {
            *a += b;
        }
        self.partial_but_looked_disjoint += other.partial_but_looked_disjoint;
    }
}

/// Classifies `case` and checks the answer by brute force with `samples` points of the triangle
/// and `samples` points of the conic (reflections of ω_i into the cone around ω_o).
pub fn audit_classification(
    case: &ConicCase,
    samples: usize,
    rng: &mut crate::SplitMix64,
    audit: &mut ClassificationAudit,
) {
    let answer = case.conic.classify(&case.triangle);
    audit_answer(case, answer, samples, rng, audit);
}

/// Checks `answer`, a classification of `case` from anywhere, by brute force as
/// [`audit_classification`] does.
pub fn audit_answer(
    case: &ConicCase,
    answer: Classification,
    samples: usize,
    rng: &mut crate::SplitMix64,
    audit: &mut ClassificationAudit,
) {
    let ConicCase { conic, triangle } = case;
    audit.cases += 1;
    audit.answers[match answer {
        Classification::Disjoint => 0,
        Classification::TriangleInsideConic => 1,
        Classification::ConicInsideTriangle => 2,
        Classification::Partial => 3,
    }] += 1;
    let mut triangle_points_in = 0usize;
    let mut triangle_points_out = 0usize;
    points_in_triangle(triangle, samples, rng, |p| {
        // Points on the horizon are outside by definition but only a boundary of the triangle.
        if p.z <= 0.0 && answer == Classification::TriangleInsideConic {
            return;
        }
        if conic.contains_by_reflection(p) {
            triangle_points_in += 1;
        } else {
            triangle_points_out += 1;
        }
    });
    let mut conic_points_in_triangle = 0usize;
    let mut conic_points_outside = 0usize;
    for _ in 0..samples {
        let reflected = uniform_in_cone(conic.wo(), conic.gamma(), rng.uniform(), rng.uniform());
        let m = (conic.wi() + reflected).normalize();
        if !(m.is_finite() && conic.contains_by_reflection(m)) {
            continue;
        }
        if triangle.contains(m) {
            conic_points_in_triangle += 1;
        } else {
            conic_points_outside += 1;
        }
    }
    match answer {
        Classification::Disjoint => {
            if triangle_points_in > 0 || conic_points_in_triangle > 0 {
                audit.wrong_disjoint += 1;
            }
        }
        Classification::TriangleInsideConic => {
            if triangle_points_out > 0 {
                audit.wrong_triangle_inside += 1;
            }
        }
        Classification::ConicInsideTriangle => {
            if conic_points_outside > 0 {
                audit.wrong_conic_inside += 1;
            }
        }
        Classification::Partial => {
            if triangle_points_in == 0 && conic_points_in_triangle == 0 {
                audit.partial_but_looked_disjoint += 1;
            }
        }
    }
}

/// A Monte Carlo estimate of the overlap solid angle and its standard error: points uniform
/// on the planar triangle, weighted by the gnomonic Jacobian h/|p|³ (self-normalized).
#[must_use]
pub fn overlap_by_sampling(
    conic: &SphericalConic,
    triangle: &SphericalTriangle,
    samples: usize,
    rng: &mut crate::SplitMix64,
) -> (f64, f64) {
    let [a, b, c] = triangle.vertices();
    let normal = (b - a).cross(c - a).normalize();
    let height = normal.dot(a);
    let (mut sum_w, mut sum_wi, mut sum_w2, mut sum_w2i) = (0.0, 0.0, 0.0, 0.0);
    for _ in 0..samples {
        let (mut s, mut t) = (rng.uniform(), rng.uniform());
        if s + t > 1.0 {
            s = 1.0 - s;
            t = 1.0 - t;
        }
        let p = a + s * (b - a) + t * (c - a);
        let weight = height / p.length().powi(3);
        let inside = f64::from(u8::from(conic.contains_by_reflection(p)));
        sum_w += weight;
        sum_wi += weight * inside;
        sum_w2 += weight * weight;
        sum_w2i += weight * weight * inside;
    }
    let ratio = sum_wi / sum_w;
    // Delta-method variance of a ratio estimator: Σ w²(1_K − r)² / (Σ w)².
    let variance = (sum_w2i * (1.0 - 2.0 * ratio) + sum_w2 * ratio * ratio) / (sum_w * sum_w);
    let omega = triangle.solid_angle();
    (ratio * omega, variance.max(0.0).sqrt() * omega)
}

/// The relative difference |planar − precise| / Ω(T) for one case: the planar approximation's
/// error as a fraction of the triangle.
#[must_use]
pub fn planar_error(case: &ConicCase) -> f64 {
    let planar =
        glint_sphere::overlap_solid_angle(&case.triangle, &case.conic, OverlapMethod::Planar);
    let precise =
        glint_sphere::overlap_solid_angle(&case.triangle, &case.conic, OverlapMethod::Precise);
    (planar - precise).abs() / case.triangle.solid_angle()
}

/// A rigorous bound on [`planar_error`] for `triangle`, whatever the conic.
///
/// The planar method takes the overlap fraction as area(P∩K)/area(P) where the truth is
/// ∫_{P∩K} J / ∫_P J with J = h/|p|³ the gnomonic Jacobian. If J varies over P by the ratio
/// ρ = J_max/J_min, the worst split (J_max on P∩K, J_min elsewhere, area fraction x) errs by
/// xρ/(xρ + 1 − x) − x, largest at x = 1/(1 + √ρ), where it is (√ρ − 1)/(√ρ + 1). The vertices
/// are unit vectors, so they are the farthest points of P from the origin (|p| = 1), and the
/// nearest point of P to the plane's foot point h·n̂, at distance d, is the nearest to the
/// origin: ρ = (h² + d²)^(−3/2).
#[must_use]
pub fn planar_error_bound(triangle: &SphericalTriangle) -> f64 {
    let [a, b, c] = triangle.vertices();
    let normal = (b - a).cross(c - a).normalize();
    let height = normal.dot(a);
    let foot = height * normal;
    let nearest_distance_squared =
        closest_point_in_triangle(foot, [a, b, c]).distance_squared(foot);
    let rho = (height * height + nearest_distance_squared).powf(-1.5);
    let root = rho.sqrt();
    (root - 1.0) / (root + 1.0)
}

/// The point of the planar triangle `v` closest to `p` (which lies in its plane).
fn closest_point_in_triangle(p: DVec3, v: [DVec3; 3]) -> DVec3 {
    let normal = (v[1] - v[0]).cross(v[2] - v[0]);
    let inside = (0..3).all(|i| (v[(i + 1) % 3] - v[i]).cross(p - v[i]).dot(normal) >= 0.0);
    if inside {
        return p;
    }
    (0..3)
        .map(|i| {
            let (s, e) = (v[i], v[(i + 1) % 3]);
            let t = ((p - s).dot(e - s) / (e - s).length_squared()).clamp(0.0, 1.0);
            s + t * (e - s)
        })
        .min_by(|x, y| x.distance_squared(p).total_cmp(&y.distance_squared(p)))
        .expect("three edges")
}

/// How many standard errors a claimed overlap `claimed` lies from a Monte Carlo estimate with
/// `samples` points (see [`overlap_by_sampling`]), after a slack of 1e-9·Ω(T) for rounding.
///
/// The standard error is the larger of the sample's own and the one the claim implies
/// (Ω·√(f(1−f)/n), f = claimed/Ω): when the overlap is tiny the sample may hold no hit at all,
/// and its own standard error is then zero.
#[must_use]
pub fn overlap_z_score(
    case: &ConicCase,
    claimed: f64,
    samples: usize,
    rng: &mut crate::SplitMix64,
) -> f64 {
    let omega = case.triangle.solid_angle();
    let (estimate, sample_error) = overlap_by_sampling(&case.conic, &case.triangle, samples, rng);
    let fraction = (claimed / omega).clamp(0.0, 1.0);
    let implied_error = omega * (fraction * (1.0 - fraction) / samples as f64).sqrt();
    let deviation = ((claimed - estimate).abs() - 1e-9 * omega).max(0.0);
    if deviation == 0.0 {
        0.0
    } else {
        deviation / sample_error.max(implied_error)
    }
}
