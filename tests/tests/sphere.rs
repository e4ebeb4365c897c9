//! glint-sphere: every predicate against its definition.
//!
//! Sizes here fit `cargo test`; `cargo xtask validate` runs the same checkers on 10⁶+ cases.

use glam::DVec3;
use glint_sphere::{Classification, OverlapMethod, SphericalConic, SphericalTriangle};
use glint_tests::SplitMix64;
use glint_tests::geometry::{
    CASE_UNIFORMS, ClassificationAudit, ConicCase, audit_answer, audit_classification,
    overlap_z_score, planar_error, planar_error_bound, uniform_in_cone,
};
use proptest::prelude::*;

fn cases() -> impl Strategy<Value = ConicCase> {
    prop::array::uniform16(0.0..1.0f64)
        .prop_map(|u: [f64; CASE_UNIFORMS]| ConicCase::from_uniforms(&u))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// Membership agrees with the definition on uniform directions and on directions near the
    /// conic (reflections into a cone slightly wider than γ).
    #[test]
    fn membership_matches_reflection_definition(case in cases(), u in prop::array::uniform4(0.0..1.0f64)) {
        let conic = case.conic;
        let uniform = glint_tests::geometry::direction((2.0 * u[0] - 1.0).acos(), u[1] * std::f64::consts::TAU);
        let reflected = uniform_in_cone(conic.wo(), 1.2 * conic.gamma(), u[2], u[3]);
        let near = (conic.wi() + reflected).normalize();
        for m in [uniform, near] {
            if m.is_finite() {
                prop_assert_eq!(conic.contains(m), conic.contains_by_reflection(m), "m = {:?}, {:?}", m, conic);
            }
        }
    }

    /// Classification is never wrong about "disjoint" or "inside" (brute force per case).
    #[test]
    fn classification_is_never_wrong(case in cases(), seed in any::<u64>()) {
        let mut audit = ClassificationAudit::default();
        audit_classification(&case, 200, &mut SplitMix64::new(seed), &mut audit);
        prop_assert!(audit.is_clean(), "{:?} for {:?}", audit, case);
    }

    /// The four children of a subdivision tile the parent.
    #[test]
    fn subdivision_conserves_solid_angle(case in cases()) {
        let parent = case.triangle;
        let children: f64 = parent.subdivide().iter().map(SphericalTriangle::solid_angle).sum();
        let omega = parent.solid_angle();
        // Rounded unit vertices (and midpoints) move each edge by ~1e-16 rad: an absolute
        // error ~1e-16 × perimeter on top of the relative rounding.
        let tolerance = 1e-12 * omega + 1e-15 * parent.longest_edge();
        prop_assert!((children - omega).abs() <= tolerance, "{} vs {}", children, omega);
    }

    /// Overlap areas lie in [0, Ω(T)] and are consistent with the classification.
    #[test]
    fn overlap_is_bounded_and_consistent(case in cases()) {
        let omega = case.triangle.solid_angle();
        for method in [OverlapMethod::Planar, OverlapMethod::Precise] {
            let overlap = glint_sphere::overlap_solid_angle(&case.triangle, &case.conic, method);
            prop_assert!(overlap.is_finite() && (0.0..=omega).contains(&overlap));
            match case.conic.classify(&case.triangle) {
                Classification::Disjoint => prop_assert_eq!(overlap, 0.0),
                Classification::TriangleInsideConic => prop_assert_eq!(overlap, omega),
                _ => {}
            }
        }
    }
}

/// 50 000 random cases (10⁶ run in `cargo xtask validate`), 64 + 64 sample points each:
/// zero wrong "disjoint" / "inside" answers, and every kind of answer occurs.
#[test]
fn classification_audit_over_many_cases() {
    let mut rng = SplitMix64::new(2014);
    let mut audit = ClassificationAudit::default();
    for _ in 0..50_000 {
        let case = ConicCase::from_uniforms(&rng.uniforms());
        audit_classification(&case, 64, &mut rng, &mut audit);
    }
    assert!(audit.is_clean(), "{audit:?}");
    assert!(
        audit.answers.iter().all(|&n| n > 100),
        "answers not exercised: {audit:?}"
    );
}

/// The cell of `cells` that holds direction `half` (the first if none does).
fn holding(cells: [SphericalTriangle; 4], half: DVec3) -> SphericalTriangle {
    cells
        .into_iter()
        .find(|t| t.contains(half))
        .unwrap_or(cells[0])
}

/// A small conic (γ = 0.05° to 5.05°, directions within 1.2 rad of the normal) and a cell of
/// the tree's directional hierarchy 1 to 64 conic widths wide that holds its half vector
/// (returned last), from six uniform numbers.
fn small_conic_in_a_wider_cell(
    [a, b, c, d, e, f]: [f64; 6],
) -> (SphericalConic, SphericalTriangle, DVec3) {
    let gamma = (0.05 + 5.0 * a).to_radians();
    let upper =
        |s: f64, t: f64| glint_tests::geometry::direction(1.2 * s, std::f64::consts::TAU * t);
    let (wi, wo) = (upper(b, c), upper(d, e));
    let conic = SphericalConic::new(wi, wo, gamma).expect("valid conic");
    let half = (wi + wo).normalize();
    let mut cell = holding(SphericalTriangle::upper_hemisphere_octants(), half);
    let width = gamma * (1.0 + 63.0 * f);
    while cell.longest_edge() > 2.0 * width {
        cell = holding(cell.subdivide(), half);
    }
    (conic, cell, half)
}

/// Small conics in the tree's cells 1 to 64 times wider (the directional splits of the dense
/// Table 1 settings): the cell holding the half vector, or at the last step one of its
/// siblings. The quick answers from the conic's bounding cap against the edges' great circles
/// settle most of these; none is wrong, and both kinds occur by the thousand.
#[test]
fn small_conics_in_wider_cells_are_never_misclassified() {
    let mut rng = SplitMix64::new(77);
    let mut audit = ClassificationAudit::default();
    for _ in 0..20_000 {
        let (conic, cell, half) = small_conic_in_a_wider_cell(rng.uniforms());
        let [g, h] = rng.uniforms();
        let triangle = if g < 0.5 {
            holding(cell.subdivide(), half)
        } else {
            cell.subdivide()[((h * 4.0) as usize).min(3)]
        };
        audit_classification(&ConicCase { conic, triangle }, 64, &mut rng, &mut audit);
    }
    assert!(audit.is_clean(), "{audit:?}");
    assert!(
        audit.answers[0] > 2000 && audit.answers[2] > 2000,
        "disjoint and conic-inside answers not exercised: {audit:?}"
    );
}

/// The children of a cell that holds a small conic, classified at once from the conic's
/// bounding cap against the centre child's edges (`classify_children_of_holder`, used by the
/// tree's directional splits): every answer given is right by brute force, agrees with the
/// child's own classification wherever that one is decisive, and both the centre and the
/// corners are found holding the conic.
#[test]
fn children_of_a_cell_holding_the_conic_are_classified_at_once() {
    let mut rng = SplitMix64::new(1914);
    let mut audit = ClassificationAudit::default();
    let (mut settled, mut centre, mut corner) = (0, 0, 0);
    for _ in 0..20_000 {
        let (conic, parent, _) = small_conic_in_a_wider_cell(rng.uniforms());
        if conic.classify(&parent) != Classification::ConicInsideTriangle {
            continue;
        }
        let children = parent.subdivide();
        let Some(answers) = conic.classify_children_of_holder(&children) else {
            continue;
        };
        settled += 1;
        assert_eq!(
            answers
                .iter()
                .filter(|&&a| a == Classification::ConicInsideTriangle)
                .count(),
            1
        );
        centre += usize::from(answers[3] == Classification::ConicInsideTriangle);
        corner += usize::from(answers[3] == Classification::Disjoint);
        for (child, answer) in children.into_iter().zip(answers) {
            let own = conic.classify(&child);
            if own != Classification::Partial {
                assert_eq!(own, answer, "{child:?}");
            }
            let case = ConicCase {
                conic,
                triangle: child,
            };
            audit_answer(&case, answer, 64, &mut rng, &mut audit);
        }
    }
    assert!(audit.is_clean(), "{audit:?}");
    assert!(
        settled > 2000 && centre > 500 && corner > 500,
        "{settled} settled, the centre holding {centre}, a corner {corner}"
    );
}

/// The precise overlap agrees with an independent Monte Carlo estimate (points on the planar
/// triangle weighted by the gnomonic Jacobian, membership by the reflection definition):
/// within 5 standard errors over 1000 cases (family-wise false-alarm rate ≈ 1000 · 5.7e-7).
#[test]
fn precise_overlap_matches_monte_carlo() {
    let mut rng = SplitMix64::new(1);
    let mut checked = 0;
    while checked < 1000 {
        let case = ConicCase::from_uniforms(&rng.uniforms());
        if case.conic.classify(&case.triangle) != Classification::Partial {
            continue;
        }
        let precise =
            glint_sphere::overlap_solid_angle(&case.triangle, &case.conic, OverlapMethod::Precise);
        let z = overlap_z_score(&case, precise, 10_000, &mut rng);
        assert!(
            z <= 5.0,
            "precise {precise} is {z} standard errors off: {case:?}"
        );
        checked += 1;
    }
}

/// The planar approximation's error relative to the triangle's solid angle stays within the
/// rigorous bound set by the variation of the gnomonic Jacobian over the triangle
/// ([`planar_error_bound`]), plus 1e-9 for rounding in the planar frame of tiny triangles.
#[test]
fn planar_overlap_error_within_jacobian_bound() {
    let mut rng = SplitMix64::new(3);
    let mut checked = 0;
    while checked < 20_000 {
        let case = ConicCase::from_uniforms(&rng.uniforms());
        if case.conic.classify(&case.triangle) != Classification::Partial {
            continue;
        }
        let error = planar_error(&case);
        let bound = planar_error_bound(&case.triangle);
        assert!(
            error <= bound + 1e-9,
            "error {error} > bound {bound}: {case:?}"
        );
        checked += 1;
    }
}

#[test]
fn solid_angle_agrees_with_girard_and_lhuilier() {
    let mut rng = SplitMix64::new(5);
    for _ in 0..2000 {
        let case = ConicCase::from_uniforms(&rng.uniforms());
        let t = case.triangle;
        let [a, b, c] = t.vertices();
        let omega = t.solid_angle();
        // L'Huilier from side lengths (2·asin(chord/2) is accurate for short sides).
        let side = |p: DVec3, q: DVec3| 2.0 * (0.5 * (p - q).length()).asin();
        let (x, y, z) = (side(b, c), side(c, a), side(a, b));
        let s = 0.5 * (x + y + z);
        let product =
            (0.5 * s).tan() * (0.5 * (s - x)).tan() * (0.5 * (s - y)).tan() * (0.5 * (s - z)).tan();
        let lhuilier = 4.0 * product.max(0.0).sqrt().atan();
        let edge = t.longest_edge();
        // L'Huilier loses relative precision on needles; allow for its conditioning.
        assert!(
            (omega - lhuilier).abs() <= 1e-9 * omega + 1e-15,
            "{omega} vs L'Huilier {lhuilier}, edge {edge}"
        );
        if edge > 0.05 {
            // Girard: angle excess, well conditioned for large triangles only.
            let angle = |p: DVec3, q: DVec3, r: DVec3| {
                let u = (q - p.dot(q) * p).normalize();
                let v = (r - p.dot(r) * p).normalize();
                u.dot(v).clamp(-1.0, 1.0).acos()
            };
            let girard = angle(a, b, c) + angle(b, c, a) + angle(c, a, b) - std::f64::consts::PI;
            assert!(
                (omega - girard).abs() <= 1e-10,
                "{omega} vs Girard {girard}"
            );
        }
    }
}

#[test]
fn solid_angle_of_tiny_triangles_keeps_precision() {
    // Down to edges of 1e-6 rad, each level's four children sum to their parent to 1e-13
    // relative, plus the ~1e-16 rad the rounding of unit vertices moves each edge.
    let mut t = SphericalTriangle::upper_hemisphere_octants()[1];
    for level in 0..20 {
        let children = t.subdivide();
        let sum: f64 = children.iter().map(SphericalTriangle::solid_angle).sum();
        let tolerance = 1e-13 * t.solid_angle() + 1e-15 * t.longest_edge();
        assert!((sum - t.solid_angle()).abs() <= tolerance, "level {level}");
        t = children[3];
    }
    assert!(t.longest_edge() < 3e-6, "{}", t.longest_edge());
    assert!(t.solid_angle() > 0.0);
}

#[test]
fn octants_are_the_root_split() {
    let octants = SphericalTriangle::upper_hemisphere_octants();
    let mut rng = SplitMix64::new(9);
    for _ in 0..10_000 {
        let m = glint_tests::geometry::direction(
            (rng.uniform()).acos(),
            rng.uniform() * std::f64::consts::TAU,
        );
        let holders = octants.iter().filter(|t| t.contains(m)).count();
        assert!(holders >= 1, "{m}");
    }
}

/// At the elliptic–hyperbolic transition ω_i·ω_o = −cos γ the conic is exact on both sides.
#[test]
fn transition_between_ellipse_and_band() {
    let gamma = 0.3_f64;
    for delta in [-1e-6, 0.0, 1e-6] {
        let ei = 0.4 * (gamma + delta);
        let eo = gamma + delta - ei;
        let wi = glint_tests::geometry::direction(0.5 * std::f64::consts::PI - ei, 0.0);
        let wo =
            glint_tests::geometry::direction(0.5 * std::f64::consts::PI - eo, std::f64::consts::PI);
        let conic = SphericalConic::new(wi, wo, gamma).unwrap();
        let mut rng = SplitMix64::new(11);
        for _ in 0..20_000 {
            let m = glint_tests::geometry::direction(
                rng.uniform().acos(),
                rng.uniform() * std::f64::consts::TAU,
            );
            assert_eq!(conic.contains(m), conic.contains_by_reflection(m));
        }
    }
}
