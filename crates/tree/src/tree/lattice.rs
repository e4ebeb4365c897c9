//! The lattice regime (`DenseCounts::Lattice`, the default): a query expecting many particles
//! is answered from a share of a Poisson process laid on cells, whatever N, instead of
//! descending the tree to its scale; and queries of different sizes read nested shares, so
//! that the count of a footprint follows it as it shrinks or grows (the camera moving closer).
//!
//! # The process and its points
//! The tree's N particles are independent points of the law d(x)·p(m) over the square and the
//! normals. Over any region much smaller than the square their counts are those of a Poisson
//! process of intensity N·d(x)·p(m) (binomial against Poisson: a variance n·p(1 − p) against
//! n·p, and a covariance −N·p·p′ against 0 between disjoint regions; p ≤ 10⁻⁴ for a pixel's
//! query). The lattice draws that process on cells: squares of space of a grid (side h, see
//! below) × slope cells, squares of slope space (s = m_xy/m_z, where Eq. 8's conic is an
//! ellipse, `slope_ellipse`; the law of slopes is P22(s) = p(m)·(1 + |s|²)^(−3/2)), each cell
//! c holding a Poisson process of rate μ_c = N·∫_square d·P_c per unit of *priority*
//! (`points`; P_c the cell's probability by a 2 × 2 Gauss rule, slopes within it by the
//! log-linear model of P22 there, `tilt`). A point's priority, position and slope come from
//! its cell's stream, so the points are a function of the material alone. The points of
//! priority below τ are the process thinned to a share τ, and those below τ′ > τ include them.
//!
//! # The count
//! A query R (footprint F × conic C) with threshold τ counts the points below τ in it, K_τ(R)
//! (with their multiplicities across tiles), and answers
//!
//! ```text
//!   Y(R) = λ(R) + (K_τ(R) − τ·λ(R))/√τ,     λ(R) = N·∫_F d · Σ_c P_c·ν_c
//! ```
//!
//! λ(R) the process's expected count (ν_c the cell's share in the conic, the log-linear
//! model's over 16 rows where the conic cuts it). K_τ(R) is Poisson with mean and variance
//! τ·λ(R), so E Y = λ and Var Y = λ: the exact counts' mean and dispersion. For two queries
//! with thresholds τ ≤ τ′, the points below τ are among those below τ′, so
//!
//! ```text
//!   Cov(Y, Y′) = Cov(K_τ(R), K_τ′(R′))/√(τ·τ′) = τ·λ(R ∩ R′)/√(τ·τ′) = √(τ/τ′)·λ(R ∩ R′)
//! ```
//!
//! the exact counts' covariance λ(R ∩ R′) times √(τ/τ′): equal thresholds keep it whatever
//! the two regions (the footprint moved by part of its width, its neighbour, the conic moved,
//! a footprint and the two halves it splits into: additive), and nested footprints of
//! different sizes keep it but for the factor. Y ≥ 0 (it is λ(1 − √τ) + K/√τ).
//!
//! # The threshold
//! τ sets a query's cost (it reads about τ·λ points in R, times the cells' excess over R: the
//! squares' area over the footprint's, the slope cells' over the ellipse's, about 16 on the
//! trade suite), its counts' lumpiness (skewness 1/√(τλ)) and, between queries, the factor
//! √(τ/τ′). A query expects P points below it:
//!
//! ```text
//!   P = P₀ · (∫_F d / (h²·d̄))^0.85 · (P22(c)/P22(0))^0.75,   within [½, 128],   τ = min(¼, P/λ̃)
//! ```
//!
//! P₀ = [`LATTICE_POINTS`] at a footprint of a grid square's area on the lobe's peak (d̄ the
//! map's mean, c the ellipse's centre, λ̃ the estimate below). So τ moves as the 0.15th power of
//! the footprint's area, and as the quarter power of the lobe's density at the conic: the
//! footprint of half the side keeps 4^(−0.075) = 0.90 of the exact counts' correlation (½),
//! consecutive frames of a dolly at 3% a frame 0.996 of theirs, and the conic turned by γ at
//! α from the lobe's peak (P22 falling by 19%) 0.97. Within the clamps; past them (footprints
//! far from the grid's scale, far on the lobe's flank) τ moves as 1/λ̃ and the factor
//! becomes √ of the ratio of counts. A query reads at most a quarter of the process
//! ([`MAX_THRESHOLD`]): below about 4P particles its τ is ¼ whatever its size, which keeps
//! its nesting and bounds the points it reads (at τ = 1 a query would read every point of its
//! cells, about 16 times the particles it expects).
//!
//! # The grids
//! A material's squares of space are those of grids at levels L_g + 5k (k an integer), L_g
//! the level of the material's expected footprint (`CountTreeConfig::expected_query_area`:
//! squares of about its side). A query uses the rung nearest its scale s (√area, or half its
//! bounding box's longer side if more), and within ¼ level of the midpoint between two rungs
//! both, blended (below): a grid serves footprints from about 5.7 times smaller to 5.7 times
//! larger than its squares, each meeting at most 2·[`MAX_GRID_CELLS`] of them. The slope cells are those of
//! the level nearest log₂(1/σ), σ the side of a square of the ellipse's area (or, if less,
//! 0.6/√|κ|, κ the curvature of ln P22, where the log-linear model holds), blended with the
//! next level within ⅛ of their midpoint. Points of different rungs or slope levels are
//! independent; a blend combines the answers' deviations from λ weighed by their weights w
//! and rescaled by 1/√Σw², which keeps the variance, and moves a count continuously from one
//! rung to the next.
//!
//! # Where it answers
//! By an estimate of the expected count that needs no cells, λ̃ = N·A·d̄·P22(c)·|E| (A the
//! footprint's area, d̄ a density map's mean over the square about its bounding box, and the
//! ellipse E's area times P22 at its centre c: the midpoint rule of ∫_C p in slope space),
//! continuous in the query: queries with λ̃ of at least [`LATTICE_ONLY`] are answered by the
//! lattice alone; below [`LATTICE_FROM`] by the tree (its particles, sampled dense nodes where
//! they are dense), before any cell is read, so that sparse queries pay nothing for the
//! lattice but the estimate. λ̃ is 1.00–1.15 λ up to α off the lobe's peak and lower on its
//! flank for wide cones (0.65 λ at 2 α, 0.30 λ at 3 α for γ = 6°; unit tests), where the tree
//! answers queries of up to a few tens of particles; in between by (1 − t)·tree + t·lattice,
//! t rising smoothly with ln λ̃, so that a query's count moves continuously across the band.
//! The blend is centred on λ; the two counts are independent draws, so their deviations from λ
//! are rescaled by 1/√((1 − t)² + t²) to keep the variance: λ + ((1 − t)(T − λ) +
//! t(L − λ))/√((1 − t)² + t²), at least 0. The tree answers also where the lattice cannot:
//! coloured materials, conics that are not ellipses in slope space (hyperbolic ones and those
//! reaching the horizon), footprints about half the texture square or wider, and lobes the
//! slope squares cannot resolve: where the ellipse's size forces squares more than 1.5 times
//! the side where the log-linear model holds (a lobe narrower than the cone, as polished
//! flakes under a wide cone; an ellipse stretched along the horizon at grazing angles), the
//! 2 × 2 Gauss rule misses the lobe (a count of 0 for Beckmann α = 10⁻⁴ under γ = 1°, where
//! every particle reflects into the cone; 2.5 times the exact mean at 88° for α = 0.03), and
//! the lattice's weight t falls to 0 by 1.8 times (`model_weight`), continuously.
//!
//! # What it does not keep
//! - **The tree's particles.** A lattice count is a draw of the same process, not a count of
//!   the tree's particles: across the band the count cross-fades, continuously, from one
//!   particle set to the other, and a footprint answered by the lattice and the nested one
//!   answered by the tree are uncorrelated (exact counts: ½).
//! - **Correlations across rungs and slope levels**, which have independent points: a query
//!   and one five levels of footprint size away, or whose ellipse's size crosses a slope
//!   level's midpoint, see independent points (continuously, through the blends).
//! - **The factor √(τ/τ′)** between queries of different sizes or lobe densities (above).
//! - **P22 within a slope cell** is log-linear, exp(g·(s − centre)) with g from the same
//!   four Gauss points, and the fractions ν_c of cells the conic cuts are integrals of that
//!   model over 16 rows; the conic's probability is within 0.4% of the true one for γ up to
//!   0.1 and 1% for γ = 0.2 on the lobe's flank (unit tests).
//! - **Higher moments**: the count's skewness is 1/√(τλ), that of about P points each worth
//!   1/√τ particles (0.44 on the trade suite's workload, where exact counts have 0.02–0.23).

mod points;
mod slope_ellipse;
mod square_memo;
mod tilt;

use glam::DVec2;
use glint_sphere::SphericalConic;
use points::{GridSquares, ThinnedQuery};
use slope_ellipse::SlopeEllipse;
use square_memo::{SquareLaw, SquareMemo};
use tilt::Tilt;

use super::CountTree;
use crate::density_map::DensityMap;
use crate::footprint::Footprint;
use crate::node::mix64;

/// P₀: the points below τ a query expects where its footprint has the area of its grid's
/// squares (see the module docs).
pub const LATTICE_POINTS: f64 = 16.0;

/// The fewest and most points below τ a query expects, whatever its footprint's area.
const POINTS_RANGE: (f64, f64) = (0.5, 128.0);

/// The highest threshold τ: a query reads at most this share of the process.
const MAX_THRESHOLD: f64 = 0.25;

/// The exponents 1 − β of the footprint's mass relative to its grid's squares' and 1 − β_d of
/// the lobe's density at the conic relative to its peak in the points a query expects below τ
/// (β = 0.15, β_d = ¼: see the module docs).
const POINTS_EXPONENT: f64 = 0.85;
const POINTS_LOBE_EXPONENT: f64 = 0.75;

/// Levels between the grids of space a material's queries use (a grid answers footprints of
/// up to half this many levels either side of its squares' side).
const GRID_STEP: i32 = 5;

/// Width, in levels, of the zone about the boundary between two grids (two slope levels) in
/// which a query blends them.
const GRID_BLEND: f64 = 0.5;
const SLOPE_BLEND: f64 = 0.25;

/// The slope squares' side, in units of the side where the log-linear model of P22 holds, up to
/// which the lattice answers alone and from which the tree answers ([`model_weight`]).
const MODEL_HOLDS: f64 = 1.5;
const MODEL_FAILS: f64 = 1.8;

/// Queries expecting fewer particles (by the estimate λ̃ the module docs define) are answered
/// by the tree.
pub const LATTICE_FROM: f64 = 4.0;

/// Queries expecting at least this many particles (by the same estimate) are answered by the
/// lattice alone.
pub const LATTICE_ONLY: f64 = 8.0;

/// The most slope cells a query's ellipse meets (its slope level keeps it to 49, or 64 at
/// the finer level of a blend), and the most squares of space its footprint's bounding box
/// spans is twice that (a grid's coarsest footprints, about 6.7 squares across, rotated); a
/// query meeting more is answered by the tree.
pub const MAX_GRID_CELLS: usize = 64;

/// A slope square against the conic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Place {
    Cut,
    Inside,
}

/// A slope cell the query's conic meets: a square of slope space at the query's slope level,
/// and where its points' slopes come from.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SlopeCell {
    index: [i64; 2],
    lo: DVec2,
    /// P_c: its probability under p (the 2 × 2 Gauss rule's; 0 where the rule's mean of P22
    /// is not positive).
    probability: f64,
    /// The log-linear model over it: a slope s has relative density exp(g·(s − centre)),
    /// g = ∇ln P22.
    tilt: Tilt,
    /// Where it lies against the conic.
    place: Place,
}

impl SlopeCell {
    /// Whether the cell lies inside the conic.
    #[inline]
    fn inside(&self) -> bool {
        self.place == Place::Inside
    }

    /// Whether the point of this cell's law drawn from `u` (the log-linear law on each axis)
    /// lies in the conic; cells of side `side`.
    #[inline]
    fn holds_point(&self, ellipse: &SlopeEllipse, side: f64, u: [f64; 2]) -> bool {
        match self.place {
            Place::Inside => true,
            Place::Cut => ellipse.contains(self.lo + side * self.tilt.quantile(u)),
        }
    }
}

/// The lattice's working memory, kept in the query scratch: the query's slope cells and
/// squares of space (of up to two slope levels and two grids), and the slope squares queries
/// have met.
#[derive(Clone, Debug, Default)]
pub(crate) struct LatticeScratch {
    slopes: [Vec<SlopeCell>; 2],
    grids: [GridSquares; 2],
    squares: SquareMemo,
}

/// What the lattice says of a query.
#[derive(Clone, Copy, Debug)]
pub(super) struct LatticeAnswer {
    /// The lattice's count.
    pub(super) count: f64,
    /// The cells (square, slope cell) read.
    pub(super) cells: u32,
    /// In the band, how the count blends with the tree's; `None` where the lattice answers
    /// alone (t = 1).
    pub(super) blend: Option<Blend>,
}

/// The band's blend of the lattice's count with the tree's (see the module docs).
#[derive(Clone, Copy, Debug)]
pub(super) struct Blend {
    /// The weight t of the lattice's count, in (0, 1).
    pub(super) weight: f64,
    /// λ, the expected count, on which the blend is centred.
    pub(super) expected: f64,
}

/// t: 0 below [`LATTICE_FROM`], 1 from [`LATTICE_ONLY`], smooth in ln λ̃ between.
fn lattice_weight(expected: f64) -> f64 {
    smoothstep((expected / LATTICE_FROM).ln() / (LATTICE_ONLY / LATTICE_FROM).ln())
}

/// The weight the slope squares' model of P22 leaves the lattice, for squares `ratio` times
/// the side where the log-linear model holds (0.6/√|κ|): 1 up to 1.5, where a square's
/// probability by the 2 × 2 Gauss rule and its fractions by the model keep the conic's
/// probability within about 1%, 0 from 1.8. Larger squares are those the ellipse's size
/// forces on a lobe narrower than it (a polished flake material under a wide cone, an ellipse
/// stretched along the horizon at grazing angles): there a lobe falls between the Gauss
/// points, and the tree answers. Smooth in ln ratio between (a narrow blend: in it a query
/// pays for both answers).
fn model_weight(ratio: f64) -> f64 {
    1.0 - smoothstep((ratio / MODEL_HOLDS).ln() / (MODEL_FAILS / MODEL_HOLDS).ln())
}

/// x²(3 − 2x) for x clamped to [0, 1].
fn smoothstep(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// The levels, with their weights, of a quantity at `x` on a ladder of levels `step` apart
/// from `origin`: the nearest rung alone, or the two rungs about a midpoint within `blend`/2
/// of it, weighed smoothly (continuous in x).
fn ladder(x: f64, origin: i32, step: i32, blend: f64) -> [(i32, f64); 2] {
    let rungs = (x - f64::from(origin)) / f64::from(step);
    let below = rungs.floor();
    let past_midpoint = (rungs - below - 0.5) * f64::from(step);
    let t = smoothstep(past_midpoint / blend + 0.5);
    let level = |k: f64| origin + step * k as i32;
    [(level(below), 1.0 - t), (level(below + 1.0), t)]
}

/// The side 2^−level.
fn side_at(level: i32) -> f64 {
    2f64.powi(-level)
}

impl CountTree {
    /// P22(s) = p(m)·(1 + |s|²)^(−3/2) / ∫p, the density of slopes.
    fn slope_density(&self, s: DVec2) -> f64 {
        let r2 = 1.0 + s.length_squared();
        let m = s.extend(1.0) / r2.sqrt();
        (self.density)(m) / (r2 * r2.sqrt() * self.quadrature.hemisphere_integral())
    }

    /// The level of the material's grid of space: squares of about its expected footprint's
    /// side.
    fn grid_level(&self) -> i32 {
        ((1.0 / self.config.expected_query_area.sqrt())
            .log2()
            .round() as i32)
            .clamp(1, 56)
    }

    /// τ of a query expecting λ̃ = `estimate` particles, whose footprint holds `mass` = ∫d
    /// (λ̃'s density times its area) and whose conic's lobe density P22(c) is `lobe` times its
    /// peak P22(0), answered on the grid at `level`: P₀·(mass/(h²·d̄))^(1−β)·lobe^(1−β_d)
    /// points below it (within [`POINTS_RANGE`]; h the grid's side, d̄ the density map's mean),
    /// at most [`MAX_THRESHOLD`]. So τ moves as the 0.15th power of the footprint's area and the map's density
    /// at it and as the quarter power of the lobe's density at the conic (module docs).
    fn threshold(&self, estimate: f64, mass: f64, lobe: f64, level: i32) -> f64 {
        let side = side_at(level);
        let map_mean = self.density_map.as_ref().map_or(1.0, |map| map.mean());
        let points = LATTICE_POINTS
            * (mass / (side * side * map_mean)).powf(POINTS_EXPONENT)
            * lobe.min(1.0).powf(POINTS_LOBE_EXPONENT);
        (points.clamp(POINTS_RANGE.0, POINTS_RANGE.1) / estimate).min(MAX_THRESHOLD)
    }

    /// log₂ of 1/(the fine slope squares' side) this conic's ellipse asks for (continuous):
    /// the side of a square of the ellipse's area, or, if less, the side where the log-linear
    /// model of P22 holds, but no finer than the side at which the ellipse's bounding box spans
    /// 25 squares (so that it meets at most [`MAX_GRID_CELLS`] at the finer level of a blend);
    /// and the weight the squares' model of P22 leaves the lattice ([`model_weight`]).
    fn slope_scale(&self, ellipse: &SlopeEllipse) -> (f64, f64) {
        // √(area): the side of a square of the ellipse's area (its diameter's 0.89 for a
        // circle), so that an elongated ellipse meets a few squares along its length instead
        // of many across it.
        let extent = ellipse.area.sqrt();
        // Squares about 0.6/√|κ| across at most, κ the curvature of ln P22 (−2/α² for
        // Beckmann: 0.42 α), where the log-linear model holds: the larger of κ at the
        // ellipse's centre and at its bounding box's point nearest the lobe's peak (the
        // origin), where a lobe narrower than the ellipse curves most.
        let delta = 0.25 * extent;
        let curvature_at = |at: DVec2| {
            let ln_at = |d: DVec2| self.slope_density(at + d).ln();
            let at_centre = 2.0 * ln_at(DVec2::ZERO);
            let along = |axis: DVec2| {
                (ln_at(delta * axis) + ln_at(-delta * axis) - at_centre).abs() / (delta * delta)
            };
            along(DVec2::X).max(along(DVec2::Y))
        };
        let nearest_peak = DVec2::ZERO.clamp(
            ellipse.center - ellipse.half_extent,
            ellipse.center + ellipse.half_extent,
        );
        let curvature = curvature_at(ellipse.center).max(curvature_at(nearest_peak));
        // A density that vanishes at a point of the stencil (a lobe many squares narrower than
        // the ellipse) has no finite curvature: no square resolves it.
        let widest = if curvature == 0.0 {
            extent
        } else if curvature.is_finite() {
            0.6 / curvature.sqrt()
        } else {
            0.0
        };
        // At least the side s at which the ellipse's bounding box, a × b, spans 25 squares:
        // (a/s + 1)(b/s + 1) = 25, continuous in the ellipse.
        let (a, b) = (2.0 * ellipse.half_extent.x, 2.0 * ellipse.half_extent.y);
        let z = (-(a + b) + ((a + b) * (a + b) + 96.0 * a * b).sqrt()) / (2.0 * a * b);
        let side = extent.min(widest).max(1.0 / z);
        ((1.0 / side).log2(), model_weight(side / widest))
    }

    /// The lattice's answer to the query, or `None` where the tree answers alone (see the
    /// module docs).
    pub(super) fn lattice_answer(
        &self,
        footprint: &Footprint,
        conic: &SphericalConic,
        scratch: &mut LatticeScratch,
    ) -> Option<LatticeAnswer> {
        if self.config.colour_channels > 0 {
            return None;
        }
        let ellipse = SlopeEllipse::of(conic)?;
        let particles = self.config.particles as f64;
        // λ̃: the weight's estimate of λ, before any cell (see the module docs).
        let density = self
            .density_map
            .as_ref()
            .map_or(1.0, |map| footprint_density(map, footprint));
        let estimate = particles
            * footprint.area()
            * density
            * self.slope_density(ellipse.center)
            * ellipse.area;
        let mut weight = lattice_weight(estimate);
        let footprint_mass = footprint.area() * density;
        let lobe = self.slope_density(ellipse.center) / self.slope_density(DVec2::ZERO);
        // Below the band, or λ̃ not a number (an infinite area times a vanishing density).
        if !(weight > 0.0) {
            return None;
        }
        let (slope_scale, model) = self.slope_scale(&ellipse);
        weight *= model;
        if !(weight > 0.0) {
            return None;
        }
        let LatticeScratch {
            slopes,
            grids,
            squares,
        } = scratch;
        // The grids of space, of squares about the footprint's scale s: √area, or half its
        // bounding box's longer side if more.
        let (bounds_lo, bounds_hi) = footprint.bounds();
        let scale = footprint
            .area()
            .sqrt()
            .max(0.5 * (bounds_hi - bounds_lo).max_element());
        let grid_rungs = ladder(
            (1.0 / scale).log2(),
            self.grid_level(),
            GRID_STEP,
            GRID_BLEND,
        );
        let slope_rungs = ladder(slope_scale, 0, 1, SLOPE_BLEND);
        let map = self.density_map.as_deref();
        let mass = map.map_or(footprint.area(), |map| map.mass_in(footprint));
        let mut in_conic = [0.0; 2];
        for (k, &(level, w)) in slope_rungs.iter().enumerate() {
            if w > 0.0 {
                in_conic[k] = self.slope_cells(&ellipse, level, &mut slopes[k], squares)?;
            }
        }
        let mut thresholds = [0.0; 2];
        for (k, &(level, w)) in grid_rungs.iter().enumerate() {
            if w > 0.0 {
                if !(1..=60).contains(&level)
                    || !grids[k].gather(footprint, level, map, 2 * MAX_GRID_CELLS)
                {
                    return None;
                }
                thresholds[k] = self.threshold(estimate, footprint_mass, lobe, level);
            }
        }
        // Each (slope level, grid) pair's count λ + (K − τλ)/√τ, their deviations from λ
        // weighed and rescaled to keep the variance: their points are independent.
        let seed = mix64(self.config.seed ^ 0x4C41_5454_4943_4500);
        let (mut expected, mut deviation, mut weights, mut cells) = (0.0, 0.0, 0.0, 0u32);
        for (i, &(slope_level, slope_weight)) in slope_rungs.iter().enumerate() {
            for (j, &(_, grid_weight)) in grid_rungs.iter().enumerate() {
                let w = slope_weight * grid_weight;
                if !(w > 0.0) {
                    continue;
                }
                let lambda = particles * mass * in_conic[i];
                let tau = thresholds[j];
                let query = ThinnedQuery {
                    footprint,
                    ellipse: &ellipse,
                    slope_level,
                    threshold: tau,
                    particles,
                    seed,
                    density_map: map,
                };
                let (found, read) = query.count(&grids[j], &slopes[i]);
                expected += w * lambda;
                deviation += w * (found - tau * lambda) / tau.sqrt();
                weights += w * w;
                cells += read;
            }
        }
        let count = (expected + deviation / weights.sqrt()).max(0.0);
        let blend = (weight < 1.0).then_some(Blend { weight, expected });
        Some(LatticeAnswer {
            count,
            cells,
            blend,
        })
    }

    /// The slope cells (squares of slope space at `level`) the conic meets, each with its
    /// fraction ν in the conic, and the conic's probability Σ P_c·ν_c; `None` where the
    /// ellipse's bounding box spans more than [`MAX_GRID_CELLS`] cells or a Gauss point's
    /// density vanishes in a cell the conic meets. Each cell's probability and log-linear law
    /// come from `memo` where an earlier query computed them (they depend on the cell only).
    fn slope_cells(
        &self,
        ellipse: &SlopeEllipse,
        level: i32,
        cells: &mut Vec<SlopeCell>,
        memo: &mut SquareMemo,
    ) -> Option<f64> {
        if !(-60..=60).contains(&level) {
            return None;
        }
        let side = side_at(level);
        let lo = ((ellipse.center - ellipse.half_extent) / side).floor();
        let hi = ((ellipse.center + ellipse.half_extent) / side).floor();
        if (hi - lo + DVec2::ONE).element_product() > MAX_GRID_CELLS as f64 {
            return None;
        }
        cells.clear();
        let mut in_conic = 0.0;
        // The 2 × 2 Gauss–Legendre points of a square, at ±1/(2√3) of its side from the centre.
        let gauss = 0.5 / 3f64.sqrt();
        let step = 2.0 * gauss * side;
        for jy in lo.y as i64..=hi.y as i64 {
            for jx in lo.x as i64..=hi.x as i64 {
                let cell_lo = DVec2::new(jx as f64, jy as f64) * side;
                if !ellipse.meets_square(cell_lo, side) {
                    continue;
                }
                let law = memo.law(self.id, level, [jx, jy], || {
                    let centre = cell_lo + DVec2::splat(0.5 * side);
                    let at = |dx: f64, dy: f64| {
                        self.slope_density(centre + side * gauss * DVec2::new(dx, dy))
                    };
                    let v = [at(-1.0, -1.0), at(1.0, -1.0), at(-1.0, 1.0), at(1.0, 1.0)];
                    let mean = 0.25 * v.iter().sum::<f64>();
                    // The log-linear model P22 ∝ exp(g·(s − centre)), g from the Gauss points.
                    let log = v.map(f64::ln);
                    let gradient = DVec2::new(
                        0.5 * ((log[1] + log[3]) - (log[0] + log[2])),
                        0.5 * ((log[2] + log[3]) - (log[0] + log[1])),
                    ) / step;
                    SquareLaw {
                        positive: mean > 0.0,
                        probability: mean * side * side,
                        tilt: gradient.is_finite().then(|| Tilt::new(gradient * side)),
                    }
                });
                if !law.positive {
                    continue;
                }
                // A Gauss point where p vanishes (a density of bounded support): the tree
                // answers rather than lose the cell.
                let tilt = law.tilt?;
                let place = if ellipse.holds_square(cell_lo, side) {
                    Place::Inside
                } else {
                    Place::Cut
                };
                let fraction = match place {
                    Place::Inside => 1.0,
                    _ => fraction_in_conic(ellipse, cell_lo, side, &tilt),
                };
                in_conic += law.probability * fraction;
                cells.push(SlopeCell {
                    index: [jx, jy],
                    lo: cell_lo,
                    probability: law.probability,
                    tilt,
                    place,
                });
            }
        }
        Some(in_conic)
    }
}

/// λ̃'s density: the map's mean over the square of the footprint's larger extent about its
/// bounding box, wrapped as the map repeats (the map's mean where it is a tile wide or more),
/// in O(1) and continuous in the footprint. A map's exact mass over the footprint would cost
/// as many look-ups as its edges cut texels.
fn footprint_density(map: &DensityMap, footprint: &Footprint) -> f64 {
    let (min, max) = footprint.bounds();
    map.mean_over_square(0.5 * (min + max), (max - min).max_element())
}

/// A cell's stream: SplitMix64 (Steele, Lea and Flood 2014) from the cell's key, for its
/// points' priorities, positions and slopes. The tree's TEA streams would be most of the
/// lattice's cost.
struct PointStream(u64);

impl PointStream {
    /// 64 random bits.
    #[inline]
    fn next_bits(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        mix64(self.0)
    }

    /// A uniform number in [0, 1) with 53 random bits.
    #[inline]
    fn uniform(&mut self) -> f64 {
        // Through i64: a single conversion instruction where u64's takes several.
        ((self.next_bits() >> 11) as i64) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// ν of a slope square the conic cuts: the log-linear law's mass inside the ellipse. Over the
/// rows where both the square and the ellipse lie (16 midpoints), the ellipse is an interval
/// of x (a quadratic's roots), clipped to the square, whose mass along x is a difference of
/// the x law's distribution function, weighed by the y law's density.
fn fraction_in_conic(ellipse: &SlopeEllipse, lo: DVec2, side: f64, tilt: &Tilt) -> f64 {
    let y0 = lo.y.max(ellipse.center.y - ellipse.half_extent.y);
    let y1 = (lo.y + side).min(ellipse.center.y + ellipse.half_extent.y);
    if y1 <= y0 {
        return 0.0;
    }
    let row_height = (y1 - y0) / FRACTION_ROWS as f64;
    let first = y0 + 0.5 * row_height;
    // The y law's density on the rows, from the first by its ratio over a row.
    let mut density = tilt.y.density((first - lo.y) / side);
    let ratio = tilt.y.density_ratio(row_height / side);
    let mut inside = 0.0;
    for row in 0..FRACTION_ROWS {
        let y = first + row as f64 * row_height;
        if let Some((x0, x1)) = ellipse.row(y) {
            let (t0, t1) = ((x0 - lo.x) / side, (x1 - lo.x) / side);
            if t0 <= 0.0 && t1 >= 1.0 {
                inside += density;
            } else if t1 > 0.0 && t0 < 1.0 {
                inside += density * (tilt.x.cdf(t1) - tilt.x.cdf(t0));
            }
        }
        density = match ratio {
            Some(ratio) => density * ratio,
            None => tilt.y.density((y + row_height - lo.y) / side),
        };
    }
    (inside * row_height / side).clamp(0.0, 1.0)
}

/// The rows of [`fraction_in_conic`].
const FRACTION_ROWS: usize = 16;

#[cfg(test)]
mod tests;
