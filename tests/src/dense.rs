//! What a viewer sees of dense counts, measured the same way for every setting of the dense
//! regime (`glint_tree::DenseCounts`) and for exact counts: one highlight conic (Beckmann
//! α = 0.1, γ = 1°) over square footprints of side 10⁻³ at random positions. The mean and the
//! dispersion (variance/mean: 1 − A·q ≈ 1 for exact counts), the skewness (about 1/√mean for
//! exact counts: how lumpy the counts are beyond their variance), and the correlation of a
//! footprint's count with the same footprint moved by half its width (exact counts: their
//! overlap, ½), with its right-hand neighbour (disjoint: about 0) and with the same footprint
//! under the conic of ω_o turned by γ (the light or the view moving; exact counts: about 0.41).

use glam::{DQuat, DVec2, DVec3};
use glint_sphere::SphericalConic;
use glint_tree::{CountTree, Footprint, QueryScratch};

use crate::SplitMix64;
use crate::counts::{correlation, highlight_query, mean_and_variance};

/// The footprints' side (texture units): a pixel of a 1000-pixel-wide view of the square.
pub const SIDE: f64 = 1e-3;

/// The statistics of [`dense_statistics`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DenseStatistics {
    /// Mean count.
    pub mean: f64,
    /// Variance over mean.
    pub dispersion: f64,
    /// The third standardized moment (exact counts: about 1/√mean).
    pub skewness: f64,
    /// Correlation with the footprint moved by half its width.
    pub shifted: f64,
    /// Correlation with the neighbouring footprint (moved by its width).
    pub neighbour: f64,
    /// Correlation with the same footprint under the conic moved by about half its width.
    pub conic_moved: f64,
}

/// The conic of the statistics and the same conic with ω_o turned by γ (the half vector, and
/// with it the conic, moves by about γ/2: half the conic's minor axis γ).
#[must_use]
pub fn conic_and_moved() -> (SphericalConic, SphericalConic) {
    let gamma = 1f64.to_radians();
    let (_, conic) = highlight_query(0.1, gamma, SIDE, &mut SplitMix64::new(99));
    let axis = conic.wo().cross(DVec3::Z).normalize();
    let wo = DQuat::from_axis_angle(axis, gamma) * conic.wo();
    let moved = SphericalConic::new(conic.wi(), wo, gamma).expect("a valid conic");
    (conic, moved)
}

/// The statistics of `tree`'s counts over `positions` random footprint positions (`seed`).
#[must_use]
pub fn dense_statistics(tree: &CountTree, positions: usize, seed: u64) -> DenseStatistics {
    let (conic, moved) = conic_and_moved();
    let square = |uv: DVec2| {
        Footprint::new(uv, DVec2::new(SIDE, 0.0), DVec2::new(0.0, SIDE)).expect("finite")
    };
    let mut scratch = QueryScratch::new();
    let mut rng = SplitMix64::new(seed);
    let mut count =
        |uv: DVec2, conic: &SphericalConic| tree.query(&square(uv), conic, &mut scratch).count;
    let (mut base, mut shifted, mut neighbour, mut conic_moved) = (vec![], vec![], vec![], vec![]);
    for _ in 0..positions {
        let uv = DVec2::new(rng.uniform(), rng.uniform());
        base.push(count(uv, &conic));
        shifted.push(count(uv + DVec2::new(0.5 * SIDE, 0.0), &conic));
        neighbour.push(count(uv + DVec2::new(SIDE, 0.0), &conic));
        conic_moved.push(count(uv, &moved));
    }
    let (mean, variance) = mean_and_variance(&base);
    let third = base.iter().map(|c| (c - mean).powi(3)).sum::<f64>() / base.len() as f64;
    DenseStatistics {
        mean,
        dispersion: variance / mean,
        skewness: third / variance.powf(1.5),
        shifted: correlation(&base, &shifted),
        neighbour: correlation(&base, &neighbour),
        conic_moved: correlation(&base, &conic_moved),
    }
}

/// Asserts that `tree`'s counts on the statistics' conic are deterministic (the same query
/// gives the same bits after other queries, with a reused or a fresh scratch) and continuous
/// (a footprint moved by 10⁻⁶ of its width changes its count by at most 5%, and all 200
/// counts by less than 10⁻³ of their sum: only a point crossing an edge steps a count).
///
/// # Panics
/// If either property fails.
pub fn assert_deterministic_and_continuous(tree: &CountTree) {
    let square = |uv: DVec2| {
        Footprint::new(uv, DVec2::new(SIDE, 0.0), DVec2::new(0.0, SIDE)).expect("finite")
    };
    let (conic, moved) = conic_and_moved();
    let mut rng = SplitMix64::new(11);
    let positions: Vec<DVec2> = (0..200)
        .map(|_| DVec2::new(rng.uniform(), rng.uniform()))
        .collect();
    let mut scratch = QueryScratch::new();
    let first: Vec<f64> = positions
        .iter()
        .map(|&uv| tree.query(&square(uv), &conic, &mut scratch).count)
        .collect();
    // Other queries in between, then the same ones in reverse with a fresh scratch.
    for &uv in &positions {
        let _ = tree.query(&square(uv + DVec2::splat(0.3)), &moved, &mut scratch);
    }
    let mut fresh = QueryScratch::new();
    for (uv, count) in positions.iter().zip(&first).rev() {
        let again = tree.query(&square(*uv), &conic, &mut fresh).count;
        assert_eq!(again.to_bits(), count.to_bits());
    }
    // The mean term moves continuously with the footprint's share of each sampled node; the
    // sampled points (√w each, w = n/32) and the exact particles only where one crosses an edge.
    let (mut moved_total, mut total) = (0.0, 0.0);
    for (uv, count) in positions.iter().zip(&first) {
        let nudged = tree
            .query(
                &square(*uv + DVec2::new(1e-6 * SIDE, 0.0)),
                &conic,
                &mut scratch,
            )
            .count;
        assert!((nudged - count).abs() <= 0.05 * count, "{count} → {nudged}");
        moved_total += (nudged - count).abs();
        total += count;
    }
    assert!(
        moved_total < 1e-3 * total,
        "a move of 10⁻⁶ width changed the counts by {moved_total} of {total}"
    );
}

/// The camera move of the coherence measures: a square footprint whose side shrinks by 3% a
/// frame from 4·10⁻³ to 2.5·10⁻⁴ (92 frames, a dolly moving 16 times closer), over the
/// statistics' conic.
pub const DOLLY_FRAMES: usize = 92;

/// The dolly's first side and its ratio from frame to frame.
pub const DOLLY_START: f64 = 4e-3;
/// See [`DOLLY_START`].
pub const DOLLY_RATIO: f64 = 0.97;

/// What a viewer sees of counts as the camera moves closer ([`dolly_coherence`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Coherence {
    /// The correlation over positions of each frame's count with the next frame's.
    pub frame_to_frame: Vec<f64>,
    /// The correlation of a footprint's count with the count of the nested footprint of half
    /// its side (23 frames later, 0.97²³ ≈ ½), for the frames that have one.
    pub half_side: Vec<f64>,
}

impl Coherence {
    /// The lowest frame-to-frame correlation.
    #[must_use]
    pub fn lowest_frame_to_frame(&self) -> f64 {
        self.frame_to_frame
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min)
    }
}

/// The side of dolly frame `frame`.
#[must_use]
pub fn dolly_side(frame: usize) -> f64 {
    DOLLY_START * DOLLY_RATIO.powi(frame as i32)
}

/// The frames between a dolly footprint and the nested one of (about) half its side.
pub const HALF_SIDE_FRAMES: usize = 23;

/// `tree`'s counts along the dolly (footprints centred on `positions` random points, `seed`):
/// each frame's correlation with the next, and with the frame of half its side.
#[must_use]
pub fn dolly_coherence(tree: &CountTree, positions: usize, seed: u64) -> Coherence {
    let (conic, _) = conic_and_moved();
    let mut rng = SplitMix64::new(seed);
    let centres: Vec<DVec2> = (0..positions)
        .map(|_| DVec2::new(rng.uniform(), rng.uniform()))
        .collect();
    let mut scratch = QueryScratch::new();
    let counts: Vec<Vec<f64>> = (0..DOLLY_FRAMES)
        .map(|frame| {
            let side = dolly_side(frame);
            centres
                .iter()
                .map(|&uv| {
                    let footprint =
                        Footprint::new(uv, DVec2::new(side, 0.0), DVec2::new(0.0, side))
                            .expect("finite");
                    tree.query(&footprint, &conic, &mut scratch).count
                })
                .collect()
        })
        .collect();
    Coherence {
        frame_to_frame: counts
            .windows(2)
            .map(|w| correlation(&w[0], &w[1]))
            .collect(),
        half_side: (0..DOLLY_FRAMES - HALF_SIDE_FRAMES)
            .map(|frame| correlation(&counts[frame], &counts[frame + HALF_SIDE_FRAMES]))
            .collect(),
    }
}

/// The correlation over `positions` random positions (`seed`) of a square footprint's count
/// (side `side`, the statistics' conic) with the nested footprint of half its side about the
/// same centre (exact counts: √(¼) = ½), and with the sum of the counts of its two halves
/// (left and right; exact counts: 1, the same particles).
#[must_use]
pub fn nested_correlations(tree: &CountTree, side: f64, positions: usize, seed: u64) -> (f64, f64) {
    let (conic, _) = conic_and_moved();
    let mut rng = SplitMix64::new(seed);
    let mut scratch = QueryScratch::new();
    let mut count = |uv: DVec2, dx: f64, dy: f64| {
        let footprint =
            Footprint::new(uv, DVec2::new(dx, 0.0), DVec2::new(0.0, dy)).expect("finite");
        tree.query(&footprint, &conic, &mut scratch).count
    };
    let (mut whole, mut half, mut halves) = (vec![], vec![], vec![]);
    for _ in 0..positions {
        let uv = DVec2::new(rng.uniform(), rng.uniform());
        whole.push(count(uv, side, side));
        half.push(count(uv, 0.5 * side, 0.5 * side));
        let quarter = DVec2::new(0.25 * side, 0.0);
        halves.push(count(uv - quarter, 0.5 * side, side) + count(uv + quarter, 0.5 * side, side));
    }
    (correlation(&whole, &half), correlation(&whole, &halves))
}
