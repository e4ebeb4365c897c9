//! Unit tests of the lattice regime: its process against brute force and its distribution,
//! the threshold's and the blends' continuity, the estimate against λ.

use glam::DVec3;

use super::*;
use crate::tree::test_support::beckmann;
use crate::tree::{CountTreeConfig, DenseCounts};
use points::ThinnedQuery;

/// A tree of `particles` under Beckmann α = 0.1 in the lattice regime.
fn lattice_tree(particles: u64) -> CountTree {
    let config = CountTreeConfig {
        particles,
        dense: DenseCounts::Lattice { node_scale: 1.0 },
        ..CountTreeConfig::default()
    };
    CountTree::new(config, beckmann(0.1)).expect("valid")
}

/// The directions (ω_i, ω_o) reflected about the half-vector `h` at θ_d from it, turned
/// away from the normal.
fn directions_about(h: DVec3, theta_d: f64) -> (DVec3, DVec3) {
    let h = h.normalize();
    let t = h.cross(DVec3::Z).try_normalize().unwrap_or(DVec3::X);
    let wi = (theta_d.cos() * h + theta_d.sin() * t).normalize();
    (wi, 2.0 * wi.dot(h) * h - wi)
}

/// The slope cells' level the conic asks for (outside a blend, the nearest).
fn slope_level(tree: &CountTree, ellipse: &SlopeEllipse) -> i32 {
    tree.slope_scale(ellipse).0.round() as i32
}

/// The conic's probability Σ P_c·ν_c (cells by the 2 × 2 Gauss rule, cut ones by the rows of
/// the log-linear model) within 1% of a brute-force sum over slopes the conic itself tests
/// (0.005% to 0.4% for γ up to 0.1, under 1% for γ = 0.2 at 3 α), on conics from the lobe's
/// centre to 3 α on its flank.
#[test]
fn the_conic_probability_is_the_brute_force_sum() {
    let tree = lattice_tree(1 << 40);
    let mut scratch = LatticeScratch::default();
    for &(theta_h, theta_d, gamma) in &[
        (0.02f64, 0.3f64, 0.02),
        (0.1, 0.5, 0.0175),
        (0.15, 0.2, 0.05),
        (0.25, 0.9, 0.03),
        (0.08, 1.1, 0.1),
        (0.3, 0.6, 0.2),
    ] {
        let h = DVec3::new(theta_h * 0.8, theta_h * 0.6, 1.0);
        let (wi, wo) = directions_about(h, theta_d);
        let conic = SphericalConic::new(wi, wo, gamma).expect("valid");
        let ellipse = SlopeEllipse::of(&conic).expect("an ellipse");
        let level = slope_level(&tree, &ellipse);
        let in_conic = tree
            .slope_cells(
                &ellipse,
                level,
                &mut scratch.slopes[0],
                &mut scratch.squares,
            )
            .expect("cells");
        // P22 on a 1200 × 1200 grid of twice the ellipse's bounding box, each point tested
        // by the conic itself.
        let (lo, size) = (
            ellipse.center - 2.0 * ellipse.half_extent,
            4.0 * ellipse.half_extent,
        );
        let mut brute = 0.0;
        for j in 0..1200 {
            for i in 0..1200 {
                let s = lo + size * (DVec2::new(f64::from(i), f64::from(j)) + 0.5) / 1200.0;
                if conic.contains(s.extend(1.0)) {
                    brute += tree.slope_density(s);
                }
            }
        }
        brute *= size.x * size.y / 1_440_000.0;
        assert!(
            (in_conic / brute - 1.0).abs() < 1e-2,
            "θ_h {theta_h}, γ {gamma}: {in_conic} against {brute}"
        );
    }
}

/// A slope cell's points follow the law whose share in the conic the lattice expects: over
/// 100 000 points of each cell a wide conic cuts, the share inside is the cell's ν within
/// four standard errors plus the rows' 0.3%.
#[test]
fn a_slope_cells_points_follow_its_fraction() {
    let tree = lattice_tree(1 << 40);
    let mut scratch = LatticeScratch::default();
    let (wi, wo) = directions_about(DVec3::new(0.12, 0.05, 1.0), 0.4);
    let conic = SphericalConic::new(wi, wo, 6f64.to_radians()).expect("valid");
    let ellipse = SlopeEllipse::of(&conic).expect("an ellipse");
    let level = slope_level(&tree, &ellipse);
    tree.slope_cells(
        &ellipse,
        level,
        &mut scratch.slopes[0],
        &mut scratch.squares,
    )
    .expect("cells");
    let side = side_at(level);
    let mut stream = PointStream(99);
    let mut cut = 0;
    for cell in &scratch.slopes[0] {
        if cell.inside() {
            continue;
        }
        let fraction = fraction_in_conic(&ellipse, cell.lo, side, &cell.tilt);
        if fraction <= 0.0 || fraction >= 1.0 {
            continue;
        }
        cut += 1;
        let n = 100_000;
        let inside = (0..n)
            .filter(|_| cell.holds_point(&ellipse, side, [stream.uniform(), stream.uniform()]))
            .count() as f64;
        let share = inside / f64::from(n);
        let error = 4.0 * (fraction * (1.0 - fraction) / f64::from(n)).sqrt();
        assert!(
            (share - fraction).abs() < error + 0.003 * fraction,
            "{share} against ν {fraction}"
        );
    }
    assert!(cut >= 4, "{cut} cut cells");
}

/// λ̃ against the cells' λ across the lobe (Beckmann α = 0.1, half-vectors 0 to 3 α off
/// the normal, cones of 1° to 6°): 1.00–1.15 λ up to α off the peak, lower on the flank
/// where P22 is convex over a wide cone (0.65 λ at 2 α, 0.30 λ at 3 α for 6°). Never well
/// above λ, so no sparse query is sent to the lattice by the estimate.
#[test]
fn the_estimate_follows_the_cells_expected_count() {
    let tree = lattice_tree(1 << 40);
    let mut scratch = LatticeScratch::default();
    for theta_h in [0.0f64, 0.05, 0.1, 0.2, 0.3] {
        for gamma in [1f64, 3.0, 6.0].map(f64::to_radians) {
            let h = DVec3::new(theta_h.sin(), 0.0, theta_h.cos());
            let (wi, wo) = directions_about(h, 0.3);
            let conic = SphericalConic::new(wi, wo, gamma).expect("valid");
            let ellipse = SlopeEllipse::of(&conic).expect("an ellipse");
            let level = slope_level(&tree, &ellipse);
            let in_conic = tree
                .slope_cells(
                    &ellipse,
                    level,
                    &mut scratch.slopes[0],
                    &mut scratch.squares,
                )
                .expect("cells");
            let ratio = tree.slope_density(ellipse.center) * ellipse.area / in_conic;
            let lowest = if theta_h <= 0.1 { 0.99 } else { 0.25 };
            assert!(
                (lowest..1.16).contains(&ratio),
                "θ_h {theta_h}, γ {gamma}: λ̃/λ = {ratio}"
            );
        }
    }
}

/// The weight comes from λ̃, before any cell: a query below the band reads none (the tree
/// answers, and pays only for λ̃), λ̃ is within 25% of the cells' λ across the band, and
/// the weight moves without jumps as the cone widens across the slope levels.
#[test]
fn the_band_is_decided_before_the_cells() {
    let tree = lattice_tree(1 << 33);
    let mut scratch = LatticeScratch::default();
    let (wi, wo) = directions_about(DVec3::new(0.06, 0.04, 1.0), 0.4);
    let mut answer = |gamma: f64, side: f64| {
        let conic = SphericalConic::new(wi, wo, gamma).expect("valid");
        let footprint = Footprint::new(
            DVec2::new(0.4, 0.6),
            DVec2::new(side, 0.0),
            DVec2::new(0.0, side),
        )
        .expect("finite");
        for slopes in &mut scratch.slopes {
            slopes.clear();
        }
        let answer = tree.lattice_answer(&footprint, &conic, &mut scratch);
        (answer, scratch.slopes.iter().map(Vec::len).sum::<usize>())
    };
    let (below, cells) = answer(1f64.to_radians(), 1e-4);
    assert!(below.is_none() && cells == 0, "{below:?}, {cells} cells");
    // Over 700 steps from 1° to 8° at a footprint whose λ passes through the band.
    let mut last = 0.0;
    let mut crossed = false;
    for i in 0..=700 {
        let gamma = (1.0 + 7.0 * f64::from(i) / 700.0).to_radians();
        let weight = match answer(gamma, 2.2e-4).0.map(|a| a.blend) {
            None => 0.0,
            Some(None) => 1.0,
            Some(Some(blend)) => {
                let estimate = LATTICE_FROM
                    * (LATTICE_ONLY / LATTICE_FROM).powf(inverse_smoothstep(blend.weight));
                assert!(
                    (estimate / blend.expected - 1.0).abs() < 0.25,
                    "γ {gamma}: λ̃ {estimate}, λ {}",
                    blend.expected
                );
                blend.weight
            }
        };
        assert!((weight - last).abs() < 0.05, "γ {gamma}: {last} → {weight}");
        crossed |= weight > 0.0 && weight < 1.0;
        last = weight;
    }
    assert!(crossed && last == 1.0, "the sweep never crossed the band");
}

/// x ∈ [0, 1] from t = x²(3 − 2x), by bisection.
fn inverse_smoothstep(t: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if smoothstep(mid) < t {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// t rises from 0 at LATTICE_FROM to 1 at LATTICE_ONLY, monotone and without jumps.
#[test]
fn the_lattice_weight_rises_smoothly_across_the_band() {
    assert_eq!(lattice_weight(0.5 * LATTICE_FROM), 0.0);
    assert_eq!(lattice_weight(LATTICE_FROM), 0.0);
    assert_eq!(lattice_weight(LATTICE_ONLY), 1.0);
    assert_eq!(lattice_weight(1e9), 1.0);
    let steps = 1000;
    let mut last = 0.0;
    for i in 0..=steps {
        let expected = LATTICE_FROM * (LATTICE_ONLY / LATTICE_FROM).powf(i as f64 / steps as f64);
        let t = lattice_weight(expected);
        assert!(
            t >= last && t - last < 3.0 / steps as f64,
            "{expected}: {last} → {t}"
        );
        last = t;
    }
}

/// A ladder's weights sum to 1 and move continuously with x: each level's weight (0 where
/// the ladder does not name it) changes by little between close x, and a rung stands alone
/// except within the blend about a midpoint.
#[test]
fn the_ladder_blends_its_rungs_continuously() {
    let weight_of = |x: f64, level: i32| {
        ladder(x, 10, 5, 0.5)
            .iter()
            .filter(|&&(l, _)| l == level)
            .map(|&(_, w)| w)
            .sum::<f64>()
    };
    let mut alone = 0;
    for i in 0..=4000 {
        let x = -2.0 + 24.0 * f64::from(i) / 4000.0;
        let rungs = ladder(x, 10, 5, 0.5);
        assert!((rungs[0].1 + rungs[1].1 - 1.0).abs() < 1e-12, "{x}");
        assert!(rungs.iter().all(|&(level, _)| (level - 10) % 5 == 0), "{x}");
        alone += usize::from(rungs.iter().any(|&(_, w)| w == 1.0));
        for level in [0, 5, 10, 15, 20, 25] {
            let step = (weight_of(x + 0.006, level) - weight_of(x, level)).abs();
            assert!(step < 0.02, "x {x}, level {level}: {step}");
        }
    }
    // A blend of 0.5 levels in a rung of 5: 90% of x stand on one rung.
    assert!((3500..3700).contains(&alone), "{alone}");
}

/// τ is continuous and decreasing in the query's expected count, moves as ρ^(−0.15) between
/// its clamps, keeps at least POINTS_RANGE.0 (or takes MAX_THRESHOLD of the process) and at
/// most POINTS_RANGE.1 points below it, and is at most MAX_THRESHOLD.
#[test]
fn the_threshold_moves_slowly_with_the_expected_count() {
    let tree = lattice_tree(1 << 40);
    let (wi, wo) = directions_about(DVec3::Z, 0.3);
    let conic = SphericalConic::new(wi, wo, 1f64.to_radians()).expect("valid");
    let ellipse = SlopeEllipse::of(&conic).expect("an ellipse");
    let level = tree.grid_level();
    // A footprint's mass for each particle it expects, at the lobe's peak.
    let mass_per_count =
        1.0 / (tree.config.particles as f64 * tree.slope_density(DVec2::ZERO) * ellipse.area);
    let mut last = f64::INFINITY;
    let mut middle = 0;
    for i in 0..=2000 {
        let estimate = 10f64.powf(-2.0 + 12.0 * f64::from(i) / 2000.0);
        let tau = tree.threshold(estimate, estimate * mass_per_count, 1.0, level);
        assert!(
            tau <= MAX_THRESHOLD && tau <= last * (1.0 + 1e-12),
            "{estimate}: {tau}"
        );
        assert!(
            tau >= last * 0.985 || last.is_infinite(),
            "{estimate}: {last} → {tau}"
        );
        let points = tau * estimate;
        assert!(
            points <= POINTS_RANGE.1 * (1.0 + 1e-12)
                && (points >= POINTS_RANGE.0 * (1.0 - 1e-12) || tau >= MAX_THRESHOLD),
            "{estimate}: {points} points"
        );
        let next = tree.threshold(
            estimate * 1.01,
            estimate * 1.01 * mass_per_count,
            1.0,
            level,
        );
        let within = |points: f64| {
            points > POINTS_RANGE.0 * (1.0 + 1e-9) && points < POINTS_RANGE.1 * (1.0 - 1e-9)
        };
        if within(points) && within(next * estimate * 1.01) && next < MAX_THRESHOLD {
            let exponent = (next / tau).ln() / 1.01f64.ln();
            assert!(
                (exponent + 1.0 - POINTS_EXPONENT).abs() < 1e-9,
                "{exponent}"
            );
            middle += 1;
        }
        last = tau;
    }
    assert!(middle > 200, "{middle}");
}

/// One highlight conic's slope cells (level as the conic asks), its ellipse and Σ P_c·ν_c.
fn highlight(tree: &CountTree, scratch: &mut LatticeScratch) -> (SlopeEllipse, i32, f64) {
    let (wi, wo) = directions_about(DVec3::new(0.05, 0.02, 1.0), 0.3);
    let conic = SphericalConic::new(wi, wo, 1f64.to_radians()).expect("valid");
    let ellipse = SlopeEllipse::of(&conic).expect("an ellipse");
    let level = slope_level(tree, &ellipse);
    let in_conic = tree
        .slope_cells(
            &ellipse,
            level,
            &mut scratch.slopes[0],
            &mut scratch.squares,
        )
        .expect("cells");
    (ellipse, level, in_conic)
}

/// K, the points below `tau` in `footprint` × the highlight conic, on the material's grid.
fn points_below(
    tree: &CountTree,
    scratch: &mut LatticeScratch,
    footprint: &Footprint,
    (ellipse, level): (&SlopeEllipse, i32),
    tau: f64,
) -> f64 {
    assert!(scratch.grids[0].gather(footprint, tree.grid_level(), None, MAX_GRID_CELLS));
    let query = ThinnedQuery {
        footprint,
        ellipse,
        slope_level: level,
        threshold: tau,
        particles: tree.config.particles as f64,
        seed: 1234,
        density_map: None,
    };
    query.count(&scratch.grids[0], &scratch.slopes[0]).0
}

/// A random square footprint of side `side` (SplitMix64 positions from `state`).
fn square_at(state: &mut u64, side: f64) -> Footprint {
    *state = mix64(state.wrapping_add(1));
    let uv = DVec2::new((*state >> 40) as f64, (*state & 0xFF_FFFF) as f64) / 16_777_216.0;
    Footprint::new(uv, DVec2::new(side, 0.0), DVec2::new(0.0, side)).expect("finite")
}

/// The points below τ are the particles' Poisson process thinned to τ: over 20 000
/// footprint positions, K's mean and variance are both τ·λ (λ = N·A·Σ P_c·ν_c) within four
/// standard errors, at τ = 1 (the process itself: whole counts, Poisson(λ)) and at a τ of
/// about 8 points a query.
#[test]
fn the_points_below_a_threshold_are_the_thinned_process() {
    let tree = lattice_tree(1 << 36);
    let mut scratch = LatticeScratch::default();
    let (ellipse, level, in_conic) = highlight(&tree, &mut scratch);
    for (side, want_points) in [(2e-4, None), (1e-3, Some(8.0))] {
        let lambda = tree.config.particles as f64 * side * side * in_conic;
        let tau = want_points.map_or(1.0, |points: f64| points / lambda);
        let mut state = 17u64;
        let counts: Vec<f64> = (0..20_000)
            .map(|_| {
                let footprint = square_at(&mut state, side);
                points_below(&tree, &mut scratch, &footprint, (&ellipse, level), tau)
            })
            .collect();
        let n = counts.len() as f64;
        let mean = counts.iter().sum::<f64>() / n;
        let variance = counts.iter().map(|c| (c - mean).powi(2)).sum::<f64>() / (n - 1.0);
        let m = tau * lambda;
        assert!((2.0..20.0).contains(&m), "{m}");
        assert!(counts.iter().all(|c| c.fract() == 0.0));
        assert!(
            (mean - m).abs() < 4.0 * (m / n).sqrt(),
            "{mean} against {m}"
        );
        // Var of a sample variance of Poisson(m): (m + 2m²)/n.
        let error = 4.0 * ((m + 2.0 * m * m) / n).sqrt();
        assert!((variance - m).abs() < error, "{variance} against {m}");
    }
}

/// A query with a higher threshold sees every point a lower one sees: K is non-decreasing
/// in τ over 300 footprints of three sizes, from 1% of the process to all of it.
#[test]
fn points_below_a_threshold_nest() {
    let tree = lattice_tree(1 << 34);
    let mut scratch = LatticeScratch::default();
    let (ellipse, level, _) = highlight(&tree, &mut scratch);
    let mut state = 5u64;
    let mut grew = 0;
    for i in 0..300 {
        let footprint = square_at(&mut state, 4e-4 * f64::from(1 + i % 3));
        let mut last = 0.0;
        for k in 0..=20 {
            let tau = 0.01f64.powf(1.0 - f64::from(k) / 20.0);
            let found = points_below(&tree, &mut scratch, &footprint, (&ellipse, level), tau);
            assert!(found >= last, "footprint {i}, τ {tau}: {last} → {found}");
            grew += usize::from(found > last);
            last = found;
        }
    }
    assert!(grew > 1000, "{grew}");
}

/// The counts that intervals of priority hold are Poisson(BATCH): χ² over 400 000 intervals
/// (0 … 11 and 12 or more) below the 10⁻³ critical value of 11 degrees of freedom, 31.3.
#[test]
fn intervals_of_priority_hold_poisson_counts() {
    let mut stream = PointStream(3);
    let mut observed = [0u32; 13];
    let n = 400_000;
    for _ in 0..n {
        observed[(points::batch_count(stream.uniform()) as usize).min(12)] += 1;
    }
    let mut chi_square = 0.0;
    let (mut term, mut below) = ((-4f64).exp(), 0.0);
    for (k, &count) in observed.iter().enumerate() {
        let p = if k < 12 { term } else { 1.0 - below };
        below += term;
        term *= 4.0 / (k + 1) as f64;
        let expected = p * f64::from(n);
        chi_square += (f64::from(count) - expected).powi(2) / expected;
    }
    assert!(chi_square < 31.3, "χ² = {chi_square}");
}
