//! The lattice regime (`DenseCounts::Lattice`): a query expecting many particles is answered
//! from a Poisson process laid on a lattice at the query's own scale, whatever N, instead of
//! descending the tree to that scale.
//!
//! # The process
//! The tree's N particles are independent points of the law d(x)·p(m) over the square and the
//! normals. Over any region much smaller than the square their counts are those of a Poisson
//! process of intensity N·d(x)·p(m) (binomial against Poisson: a variance n·p(1 − p) against
//! n·p, and a covariance −N·p·p′ against 0 between disjoint regions; p ≤ 10⁻⁴ for a pixel's
//! query). The lattice draws that process cell by cell:
//!
//! - Space is cut into squares of side h_s = 2^−a, normals into squares of side h_d = 2^−b in
//!   slope space (s = m_xy/m_z, where Eq. 8's conic is an ellipse, `slope_ellipse`; the law of
//!   slopes is P22(s) = p(m)·(1 + |s|²)^(−3/2)). a and b come from the query's size: a square
//!   whose side is the power of two nearest √(the footprint's area), a slope square's the
//!   power of two nearest the lesser of √(the ellipse's area) and 0.6/√|κ| (κ: the curvature
//!   of ln P22 there; 0.6/√|κ| is 0.42 α for Beckmann). Nearest in ln: within √2 of either.
//! - A cell c = (square, slope cell) pairs a square with a slope cell of 2 × 2 slope squares.
//!   It holds X_c ~ Poisson(μ_c) particles, μ_c = N·d·h_s²·P_c (P_c the slope cell's
//!   probability, the sum of its squares' by a 2 × 2 Gauss rule each), drawn from the cell's
//!   own stream: cells are independent, and the same for every query at these levels.
//! - A cell inside the query adds X_c. A cell the query cuts places min(X_c, M) points of its
//!   law (M = [`LATTICE_POINTS`]; positions uniform over the square, slopes in a slope square
//!   drawn by its probability, by the log-linear model of P22 over it) and counts the k inside
//!   the query. With X_c ≤ M they are its particles, and the count is the process's own. With
//!   X_c > M it adds the rescaled sample of `super::dense`:
//!
//! ```text
//!   Y_c = √(X_c/M)·k + (X_c − √(X_c·M))·ν_c
//! ```
//!
//!   ν_c the fraction of the cell's law in the query. Given X_c, Y_c has the mean X_c·ν_c and
//!   the variance X_c·ν_c(1 − ν_c) of the cell's exact count, and for two queries R, R′ the
//!   covariance X_c·(ν_c(R ∩ R′) − ν_c(R)ν_c(R′)); over X_c ~ Poisson(μ_c) that is
//!   μ_c·ν_c(R ∩ R′): the Poisson process's covariance, for every pair of queries at the same
//!   levels (the footprint moved by part of its width, its neighbour, the conic moved).
//!
//! So the count keeps the exact counts' mean, dispersion and correlations at a cost set by the
//! lattice's cells (about 4–9 squares × 2–6 slope cells, at most [`MAX_GRID_CELLS`] squares
//! of either grid), not by N. Slope cells of four squares instead of one draw about half the
//! cells (trade suite, N = 10¹²: 11 against 20, 42.8 k instructions per query against 51.9 k;
//! 47.5 cells per `glitter_object` query at N = 10¹⁰ against 85) for coarser higher moments: a cut
//! cell's sample is coarser by √(X_c/M), and X_c is four times larger (skewness 0.38 against
//! 0.19 at N = 10¹², exact 0.02; mean, dispersion and correlations as before).
//!
//! # Where it answers
//! By an estimate of the expected count that needs no cells, λ̃ = N·A·d̄·P22(c)·|E| (A the
//! footprint's area, d̄ a density map's mean over the square about its bounding box, and the
//! ellipse E's area times P22 at its centre c: the midpoint rule of ∫_C p in slope space),
//! continuous in the query: queries with λ̃ of at least [`LATTICE_ONLY`] are answered by the
//! lattice alone; below [`LATTICE_FROM`] by the tree (its particles, sampled dense nodes where
//! they are dense), before any cell is built, so that sparse queries pay nothing for the
//! lattice but the estimate. λ̃ is 1.00–1.15 λ up to α off the lobe's peak and lower on its
//! flank for wide cones (0.65 λ at 2 α, 0.30 λ at 3 α for γ = 6°; unit tests), where the tree
//! answers queries of up to a few tens of particles; in between by (1 − t)·tree + t·lattice, t rising smoothly with
//! ln λ̃, so that a query's count moves continuously across the band. The blend is centred
//! on the cells' own λ = N·∫_F d·Σ P_c·ν_c; the two counts are
//! independent draws, so their deviations from λ are rescaled by 1/√((1 − t)² + t²) to keep
//! the variance: λ + ((1 − t)(T − λ) + t(L − λ))/√((1 − t)² + t²), at least 0. The tree answers
//! also where the lattice cannot: coloured materials, density maps that vary over a square of
//! the query's lattice, and conics that are not ellipses in slope space (hyperbolic ones and
//! those reaching the horizon).
//!
//! # What it does not keep
//! - **The tree's particles.** A lattice count is a draw of the same process, not a count of
//!   the tree's particles: a query answered by the lattice and one answered by the tree (two
//!   sizes, or λ on both sides of the band) see different particles.
//! - **Correlations across levels.** The levels follow the query's size, so a footprint and
//!   one twice as wide, or a footprint whose width crosses a power of two as the camera
//!   moves, see independent draws.
//! - **P22 within a slope square** is log-linear, exp(g·(s − centre)) with g from the same
//!   four Gauss points, and the fractions ν_c of slope squares the conic cuts are integrals of
//!   that model over 16 rows. Its error (P22's curvature in ln) grows with the square's side
//!   against α: the conic's probability is within 0.23% of the true one for γ up to 0.1 and
//!   0.83% for γ = 0.2 on the lobe's flank, where [`MAX_GRID_CELLS`] coarsens the squares
//!   (unit tests).
//! - **Higher moments** of cells with X_c > M are the sample's, coarser by √(X_c/M).

mod slope_ellipse;
mod square_memo;
mod tilt;

use glam::DVec2;
use glint_sphere::SphericalConic;
use slope_ellipse::SlopeEllipse;
use square_memo::{SquareLaw, SquareMemo};
use tilt::Tilt;

use super::CountTree;
use crate::density_map::DensityMap;
use crate::footprint::{BoxOverlap, Footprint};
use crate::node::mix64;

/// M: the points a cut cell places at most.
pub const LATTICE_POINTS: u64 = 8;

/// Queries expecting fewer particles (by the estimate λ̃ the module docs define) are answered
/// by the tree.
pub const LATTICE_FROM: f64 = 4.0;

/// Queries expecting at least this many particles (by the same estimate) are answered by the
/// lattice alone.
pub const LATTICE_ONLY: f64 = 8.0;

/// The most squares of either grid (space, slopes) a query meets; a query meeting more at its
/// own scale takes coarser squares.
pub const MAX_GRID_CELLS: usize = 64;

/// A fine slope square of a [`SlopeCell`]: where its points' slopes come from.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SlopeSquare {
    lo: DVec2,
    /// The square's probability under p (0 where the Gauss rule's mean of P22 is not
    /// positive).
    probability: f64,
    /// The cell's probability up to and with this square, over the cell's (the point's
    /// square is the first whose share exceeds a uniform draw).
    share_up_to: f64,
    /// The log-linear model over the square: a slope s has relative density
    /// exp(g·(s − centre)), g = ∇ln P22.
    tilt: Tilt,
    /// Where the square lies against the conic.
    place: Place,
}

/// A square against the conic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Place {
    Outside,
    Cut,
    Inside,
}

/// A slope cell the query's conic meets: a square of 2 × 2 fine slope squares, so that a
/// cell holds the particles of four of the model's squares.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SlopeCell {
    index: [i64; 2],
    /// P_c: the probability of the cell under p, the sum of its squares'.
    probability: f64,
    /// Whether the cell lies inside the conic.
    inside: bool,
    /// ν: the cell's share of its law inside the conic, once computed ([`SlopeCell::fraction`]).
    fraction: Option<f64>,
    squares: [SlopeSquare; 4],
}

/// Which slope cells' fractions ν [`CountTree::slope_cells`] computes. A cut square's fraction
/// integrates the log-linear model over 16 rows; a query the lattice answers alone needs it
/// only for the cells of more than M particles that the query cuts (in slope or in space),
/// which the lattice's count asks for ([`SlopeCell::fraction`]), and the same arithmetic
/// gives the same ν either way.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Fractions {
    /// Every cell's, and the conic's probability Σ P_c·ν_c: the band's blend is centred on λ.
    Now,
    /// Only those the count asks for.
    WhenAsked,
}

impl SlopeCell {
    /// ν, computed on first use: the cell's mass in the conic over its probability. The
    /// first call's `ellipse` and `side` (fine squares') must be those the cell was built
    /// with, as every later call's: the value is cached.
    fn fraction(&mut self, ellipse: &SlopeEllipse, side: f64) -> f64 {
        if let Some(fraction) = self.fraction {
            return fraction;
        }
        let fraction = self.mass_in_conic(ellipse, side) / self.probability;
        self.fraction = Some(fraction);
        fraction
    }

    /// Σ P_k·ν_k over the cell's squares, in their order: P_k for a square inside the conic,
    /// P_k times the log-linear model's mass in the ellipse for one it cuts ([`fraction_in_conic`];
    /// fine squares of side `side`).
    fn mass_in_conic(&self, ellipse: &SlopeEllipse, side: f64) -> f64 {
        let mut mass = 0.0;
        for square in &self.squares {
            mass += match square.place {
                Place::Outside => continue,
                Place::Inside => square.probability,
                Place::Cut => {
                    square.probability * fraction_in_conic(ellipse, square.lo, side, &square.tilt)
                }
            };
        }
        mass
    }

    /// The fine square a point's uniform draw `u` falls in.
    #[inline]
    fn square(&self, u: f64) -> &SlopeSquare {
        self.squares
            .iter()
            .find(|square| u < square.share_up_to)
            .unwrap_or(&self.squares[3])
    }

    /// Whether the point of this cell's law drawn from `u` (its square, then the square's
    /// log-linear law on each axis) lies in the conic; fine squares of side `side`.
    #[inline]
    fn holds_point(&self, ellipse: &SlopeEllipse, side: f64, u: [f64; 3]) -> bool {
        let square = self.square(u[0]);
        match square.place {
            Place::Inside => true,
            Place::Outside => false,
            Place::Cut => {
                let t = square.tilt.quantile([u[1], u[2]]);
                ellipse.contains(square.lo + side * t)
            }
        }
    }
}

/// A square of space the query's footprint meets.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SpaceCell {
    /// Its indices, wrapped to the square.
    index: [u64; 2],
    lo: DVec2,
    /// Its translate next to the footprint (`lo` plus whole tiles), where a footprint smaller
    /// than a tile less a square can hold its points (no other translate can).
    near: DVec2,
    overlap: BoxOverlap,
    /// ∫ m(x) dx / h_s² over the square: the mean multiplicity of its points.
    multiplicity: f64,
    /// d over the square (1 without a density map).
    density: f64,
}

/// The lattice's working memory, kept in the query scratch: the query's cells, and the slope
/// squares queries have met.
#[derive(Clone, Debug, Default)]
pub(crate) struct LatticeScratch {
    slopes: Vec<SlopeCell>,
    spaces: Vec<SpaceCell>,
    squares: SquareMemo,
}

/// What the lattice says of a query.
#[derive(Clone, Copy, Debug)]
pub(super) struct LatticeAnswer {
    /// The lattice's count.
    pub(super) count: f64,
    /// The cells (square, slope cell) drawn.
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
    let x = ((expected / LATTICE_FROM).ln() / (LATTICE_ONLY / LATTICE_FROM).ln()).clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
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
        let weight = lattice_weight(estimate);
        // Below the band, or λ̃ not a number (an infinite area times a vanishing density).
        if !(weight > 0.0) {
            return None;
        }
        // Space first: a density map that varies over a square turns the query to the tree
        // before the slope squares' fractions are paid for. Alone, the lattice needs no λ.
        let spatial = self.space_cells(footprint, &mut scratch.spaces)?;
        let fractions = if weight < 1.0 {
            Fractions::Now
        } else {
            Fractions::WhenAsked
        };
        let directional = self.slope_cells(
            &ellipse,
            &mut scratch.slopes,
            &mut scratch.squares,
            fractions,
        )?;
        let (count, cells) =
            self.lattice_count(footprint, &ellipse, scratch, &spatial, directional.level);
        let blend = directional.in_conic.map(|in_conic| Blend {
            weight,
            expected: particles * spatial.mass * in_conic,
        });
        Some(LatticeAnswer {
            count,
            cells,
            blend,
        })
    }

    /// The slope cells the conic meets: pairs of pairs of fine squares, whose level is the
    /// one with the side nearest √(the ellipse's area) or, if less, the side where the
    /// log-linear model of P22 holds (coarser if that gives more than [`MAX_GRID_CELLS`]).
    /// The level returned is the fine squares'. Each square's probability and log-linear law
    /// come from `memo` where an earlier query computed them (they depend on the square only).
    /// The cells' fractions ν and the conic's probability are computed now or when asked,
    /// as `fractions` says.
    fn slope_cells(
        &self,
        ellipse: &SlopeEllipse,
        cells: &mut Vec<SlopeCell>,
        memo: &mut SquareMemo,
        fractions: Fractions,
    ) -> Option<DirectionalGrid> {
        // √(area): the side of a square of the ellipse's area (its diameter's 0.89 for a
        // circle), so that an elongated ellipse meets a few squares along its length instead
        // of many across it.
        let extent = ellipse.area.sqrt();
        // Squares about 0.6/√|κ| across at most, κ the curvature of ln P22 at the ellipse's
        // centre (−2/α² for Beckmann: 0.42 α), where the log-linear model holds.
        let curvature = {
            let delta = 0.25 * extent;
            let ln_at = |d: DVec2| self.slope_density(ellipse.center + d).ln();
            let at_centre = 2.0 * ln_at(DVec2::ZERO);
            let along = |axis: DVec2| {
                (ln_at(delta * axis) + ln_at(-delta * axis) - at_centre).abs() / (delta * delta)
            };
            along(DVec2::X).max(along(DVec2::Y))
        };
        let widest = if curvature.is_finite() && curvature > 0.0 {
            0.6 / curvature.sqrt()
        } else {
            extent
        };
        let mut level = (1.0 / extent.min(widest)).log2().round() as i32;
        let grid = |level: i32| {
            let side = side_at(level);
            let lo = ((ellipse.center - ellipse.half_extent) / side).floor();
            let hi = ((ellipse.center + ellipse.half_extent) / side).floor();
            (lo, hi, (hi - lo + DVec2::ONE).element_product())
        };
        // Beyond 2⁻⁶⁰ (a conic of γ below about 10⁻¹⁸) or 2⁶⁰ the tree answers; the loop
        // below then runs at most 120 times.
        if !(-60..=60).contains(&level) {
            return None;
        }
        while grid(level).2 > MAX_GRID_CELLS as f64 && level > -60 {
            level -= 1;
        }
        let side = side_at(level);
        let (lo, hi, _) = grid(level);
        cells.clear();
        let mut in_conic = (fractions == Fractions::Now).then_some(0.0);
        // The 2 × 2 Gauss–Legendre points of a square, at ±1/(2√3) of its side from the centre.
        let gauss = 0.5 / 3f64.sqrt();
        let step = 2.0 * gauss * side;
        // The cells pair the fine squares two by two on each axis.
        let (cells_lo, cells_hi) = (lo / 2.0, hi / 2.0);
        for cy in cells_lo.y.floor() as i64..=cells_hi.y.floor() as i64 {
            for cx in cells_lo.x.floor() as i64..=cells_hi.x.floor() as i64 {
                // Fine square k of the cell: its indices, and its lower corner.
                let square_index = |k: usize| [2 * cx + (k & 1) as i64, 2 * cy + (k >> 1) as i64];
                let square_lo = |k: usize| {
                    let [jx, jy] = square_index(k);
                    DVec2::new(jx as f64, jy as f64) * side
                };
                let meets = [0, 1, 2, 3].map(|k| ellipse.meets_square(square_lo(k), side));
                if !meets.contains(&true) {
                    continue;
                }
                let mut squares = [SlopeSquare {
                    lo: DVec2::ZERO,
                    probability: 0.0,
                    share_up_to: 0.0,
                    tilt: Tilt::new(DVec2::ZERO),
                    place: Place::Outside,
                }; 4];
                let mut probability = 0.0;
                for (k, square) in squares.iter_mut().enumerate() {
                    let square_lo = square_lo(k);
                    square.lo = square_lo;
                    let law = memo.law(self.id, level, square_index(k), || {
                        let centre = square_lo + DVec2::splat(0.5 * side);
                        let at = |dx: f64, dy: f64| {
                            self.slope_density(centre + side * gauss * DVec2::new(dx, dy))
                        };
                        let v = [at(-1.0, -1.0), at(1.0, -1.0), at(-1.0, 1.0), at(1.0, 1.0)];
                        let mean = 0.25 * v.iter().sum::<f64>();
                        // The log-linear model P22 ∝ exp(g·(s − centre)), g from the Gauss
                        // points.
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
                    square.probability = law.probability;
                    probability += square.probability;
                    if !meets[k] {
                        continue;
                    }
                    // A Gauss point where p vanishes (a density of bounded support): the tree
                    // answers rather than lose the square.
                    square.tilt = law.tilt?;
                    square.place = if ellipse.holds_square(square_lo, side) {
                        Place::Inside
                    } else {
                        Place::Cut
                    };
                }
                if !(probability > 0.0) {
                    continue;
                }
                // Each square's share, cumulated; the last square with a share takes every
                // draw past the others', whatever the rounding.
                let mut cumulated = 0.0;
                for square in &mut squares {
                    cumulated += square.probability;
                    square.share_up_to = cumulated / probability;
                }
                if let Some(last) = squares.iter().rposition(|square| square.probability > 0.0) {
                    squares[last].share_up_to = f64::INFINITY;
                }
                let mut cell = SlopeCell {
                    index: [cx, cy],
                    probability,
                    inside: squares.iter().all(|square| square.place == Place::Inside),
                    fraction: None,
                    squares,
                };
                if let Some(in_conic) = &mut in_conic {
                    let mass = cell.mass_in_conic(ellipse, side);
                    *in_conic += mass;
                    cell.fraction = Some(mass / probability);
                }
                cells.push(cell);
            }
        }
        Some(DirectionalGrid { level, in_conic })
    }

    /// The squares of space the footprint meets, at the level whose side is nearest
    /// √(the footprint's area) (coarser if that gives more than [`MAX_GRID_CELLS`]);
    /// `None` if the density map varies over one of them or the footprint is wider than the
    /// texture square.
    fn space_cells(
        &self,
        footprint: &Footprint,
        cells: &mut Vec<SpaceCell>,
    ) -> Option<SpatialGrid> {
        let (dx, dy) = footprint.edges();
        let reach = 0.5 * (dx.abs() + dy.abs());
        let (bounds_lo, bounds_hi) = (footprint.center() - reach, footprint.center() + reach);
        // Squares of about the footprint's area (its side for a square footprint), so that
        // an elongated footprint meets a few along its length instead of many across it; the
        // nearest power of two in ln (within √2), which meets fewer squares than the next
        // smaller one (a square footprint: about 4 instead of 6).
        let mut level = (1.0 / footprint.area().sqrt()).log2().round() as i32;
        let grid = |level: i32| {
            let side = side_at(level);
            let (lo, hi) = ((bounds_lo / side).floor(), (bounds_hi / side).floor());
            (lo, hi, (hi - lo + DVec2::ONE).element_product())
        };
        while level > 0 && grid(level).2 > MAX_GRID_CELLS as f64 {
            level -= 1;
        }
        if level <= 0 || level > 60 {
            return None;
        }
        let side = side_at(level);
        let (lo, mut hi, _) = grid(level);
        let wrap = 1i64 << level;
        // Each wrapped square once: its overlaps already count every translate of the
        // footprint, so a bounding box a tile wide or more must not visit it again.
        hi = hi.min(lo + DVec2::splat((wrap - 1) as f64));
        cells.clear();
        let mut mass = 0.0;
        for iy in lo.y as i64..=hi.y as i64 {
            for ix in lo.x as i64..=hi.x as i64 {
                let index = [ix.rem_euclid(wrap), iy.rem_euclid(wrap)];
                let cell_lo = DVec2::new(index[0] as f64, index[1] as f64) * side;
                // The wrapped square's overlap: the footprint's translates meet it.
                let overlap = footprint.overlap_box(cell_lo, side);
                if overlap.is_disjoint() {
                    continue;
                }
                let density = match &self.density_map {
                    None => 1.0,
                    Some(map) if map.is_constant_over(cell_lo, side) => {
                        map.value_at(cell_lo + DVec2::splat(0.5 * side))
                    }
                    Some(_) => return None,
                };
                let multiplicity = if overlap.partial == 0 {
                    overlap.inside as f64
                } else {
                    footprint.overlap_area(cell_lo, side) / (side * side)
                };
                mass += multiplicity * density * side * side;
                cells.push(SpaceCell {
                    index: index.map(|i| i as u64),
                    lo: cell_lo,
                    near: DVec2::new(ix as f64, iy as f64) * side,
                    overlap,
                    multiplicity,
                    density,
                });
            }
        }
        // One translate of the footprint holds all it can of these squares' points when its
        // bounding box and a square fit in a tile.
        let one_translate = (bounds_hi - bounds_lo).max_element() + side < 1.0;
        Some(SpatialGrid {
            level,
            mass,
            one_translate,
        })
    }

    /// The lattice's count over the cells `scratch` holds, of the `spatial` grid and the
    /// slope squares at `directional_level`, and the cells drawn.
    fn lattice_count(
        &self,
        footprint: &Footprint,
        ellipse: &SlopeEllipse,
        scratch: &mut LatticeScratch,
        spatial: &SpatialGrid,
        directional_level: i32,
    ) -> (f64, u32) {
        let spatial_level = spatial.level;
        let particles_per_area = self.config.particles as f64;
        let side = side_at(spatial_level);
        let slope_side = side_at(directional_level);
        let cell_level = directional_level - 1;
        let m = LATTICE_POINTS as f64;
        let seed = mix64(self.config.seed ^ 0x4C41_5454_4943_4500);
        let mut count = 0.0;
        let mut drawn = 0u32;
        for space in &scratch.spaces {
            let space_key =
                mix64(mix64(mix64(seed ^ spatial_level as u64) ^ space.index[0]) ^ space.index[1]);
            let space_inside = space.overlap.partial == 0;
            for slope in &mut scratch.slopes {
                // The cell's key: the square's, then the slope cell's level and indices.
                let cell_key = mix64(
                    mix64(mix64(space_key ^ cell_level as i64 as u64) ^ slope.index[0] as u64)
                        ^ slope.index[1] as u64,
                );
                let mut rng = PointStream(cell_key);
                drawn += 1;
                let mean = particles_per_area * space.density * side * side * slope.probability;
                let particles = poisson(mean, &mut rng);
                if particles == 0 {
                    continue;
                }
                if space_inside && slope.inside {
                    count += space.multiplicity * particles as f64;
                    continue;
                }
                // The cut cell's points: positions uniform over the square, slopes in a fine
                // square drawn by its probability, by the log-linear model of P22 there
                // (inverting its distribution on each axis).
                let mut found = 0.0;
                for _ in 0..particles.min(LATTICE_POINTS) {
                    // Five draws per point, whatever the query tests: the point is the same for
                    // every query that meets the cell.
                    let u = [
                        rng.uniform(),
                        rng.uniform(),
                        rng.uniform(),
                        rng.uniform(),
                        rng.uniform(),
                    ];
                    let offset = side * DVec2::new(u[0], u[1]);
                    let multiplicity = if space_inside {
                        space.multiplicity
                    } else if spatial.one_translate {
                        f64::from(u8::from(footprint.contains(space.near + offset)))
                    } else {
                        footprint.multiplicity(space.lo + offset) as f64
                    };
                    if multiplicity == 0.0 {
                        continue;
                    }
                    if slope.holds_point(ellipse, slope_side, [u[2], u[3], u[4]]) {
                        found += multiplicity;
                    }
                }
                if particles <= LATTICE_POINTS {
                    count += found;
                } else {
                    let n = particles as f64;
                    let share = space.multiplicity * slope.fraction(ellipse, slope_side);
                    count += (n / m).sqrt() * found + (n - (n * m).sqrt()) * share;
                }
            }
        }
        // Each cell adds at least 0: √(n/M)·k ≥ 0 and n ≥ √(n·M) when n > M.
        debug_assert!(count >= 0.0, "{count}");
        (count, drawn)
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

/// A cell's stream: SplitMix64 (Steele, Lea and Flood 2014) from the cell's key, for its count
/// and then its points (five draws each). The tree's TEA streams would be most of the
/// lattice's cost.
struct PointStream(u64);

impl PointStream {
    /// A uniform number in [0, 1) with 53 random bits.
    #[inline]
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        (mix64(self.0) >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// Below this mean a cell's count is drawn by inversion; from it, by the normal law.
const POISSON_NORMAL_FROM: f64 = 64.0;

/// X ~ Poisson(μ): exact by sequential inversion below [`POISSON_NORMAL_FROM`]; above, the
/// normal law N(μ, μ) rounded (Box–Muller; it drops the skewness 1/√μ ≤ 1/8 of one cell's
/// count, which cells cut by the query replace by their sample's anyway).
fn poisson(mean: f64, rng: &mut PointStream) -> u64 {
    if !(mean > 0.0) {
        return 0;
    }
    if mean < POISSON_NORMAL_FROM {
        let u = rng.uniform();
        let mut term = (-mean).exp();
        let mut below = term;
        let mut k = 0u64;
        // The tail past μ + 40√μ + 40 holds less than 10⁻¹⁶.
        while u >= below && k < 400 {
            k += 1;
            term *= mean / k as f64;
            below += term;
        }
        return k;
    }
    let (u1, u2) = (rng.uniform(), rng.uniform());
    let normal = (-2.0 * (1.0 - u1).ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
    (mean + mean.sqrt() * normal + 0.5).floor().max(0.0) as u64
}

/// The level and the conic's probability Σ P_c·ν_c of the slope squares (where computed:
/// [`Fractions::Now`]).
struct DirectionalGrid {
    level: i32,
    in_conic: Option<f64>,
}

/// The level and the footprint's mass ∫ m(x)·d(x) dx over the squares.
struct SpatialGrid {
    level: i32,
    mass: f64,
    /// Whether a point's multiplicity is whether the footprint holds its `near` translate.
    one_translate: bool,
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
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::tree::test_support::beckmann;
    use crate::tree::{CountTreeConfig, DenseCounts, QueryScratch};

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

    /// The lattice's expected count N·∫_F d·Σ P_c·ν_c (slope squares by the 2 × 2 Gauss rule,
    /// cut ones by the rows of the log-linear model): the footprint's area, and the conic's
    /// probability within 1% of a brute-force sum over slopes the conic itself tests (0.005%
    /// to 0.23% for γ up to 0.1, 0.83% for γ = 0.2 at 3 α, where the grid's cap coarsens the
    /// squares), on conics from the lobe's centre to 3 α on its flank. (The tree's `expected_count`, which takes p uniform over Alg. 2's near-uniform
    /// cells, is 5% low at 2.5 α.)
    #[test]
    fn the_lattice_expects_the_process_count() {
        let tree = lattice_tree(1 << 40);
        let mut scratch = QueryScratch::new();
        let mut checked = 0;
        for &(theta_h, theta_d, gamma) in &[
            (0.02f64, 0.3f64, 0.02),
            (0.1, 0.5, 0.0175),
            (0.15, 0.2, 0.05),
            (0.25, 0.9, 0.03),
            (0.08, 1.1, 0.1),
            (0.3, 0.6, 0.2),
        ] {
            let h = DVec3::new(theta_h * 0.8, theta_h * 0.6, 1.0).normalize();
            let t = h.cross(DVec3::Z).try_normalize().unwrap_or(DVec3::X);
            let wi = (theta_d.cos() * h + theta_d.sin() * t).normalize();
            let wo = 2.0 * wi.dot(h) * h - wi;
            let conic = SphericalConic::new(wi, wo, gamma).expect("valid");
            for side in [1e-3, 1e-2] {
                let footprint = Footprint::new(
                    DVec2::new(0.3, 0.7),
                    DVec2::new(side, 0.2 * side),
                    DVec2::new(-0.1 * side, side),
                )
                .expect("finite");
                let ellipse = SlopeEllipse::of(&conic).expect("an ellipse");
                let grid = tree
                    .slope_cells(
                        &ellipse,
                        &mut scratch.lattice.slopes,
                        &mut scratch.lattice.squares,
                        Fractions::Now,
                    )
                    .expect("cells");
                let space = tree
                    .space_cells(&footprint, &mut scratch.lattice.spaces)
                    .expect("cells");
                assert!((space.mass / footprint.area() - 1.0).abs() < 1e-9);
                // The conic's probability by brute force: P22 on a 1200 × 1200 grid of twice the
                // ellipse's bounding box, each point tested by the conic itself.
                let (lo, size) = (
                    ellipse.center - 2.0 * ellipse.half_extent,
                    4.0 * ellipse.half_extent,
                );
                let mut brute = 0.0;
                for j in 0..1200 {
                    for i in 0..1200 {
                        let t = (DVec2::new(f64::from(i), f64::from(j)) + 0.5) / 1200.0;
                        let s = lo + size * t;
                        if conic.contains(s.extend(1.0)) {
                            brute += tree.slope_density(s);
                        }
                    }
                }
                brute *= size.x * size.y / 1_440_000.0;
                let in_conic = grid.in_conic.expect("computed now");
                assert!(
                    (in_conic / brute - 1.0).abs() < 1e-2,
                    "θ_h {theta_h}, γ {gamma}, side {side}: {in_conic} against {brute}"
                );
                checked += 1;
            }
        }
        assert_eq!(checked, 12);
    }

    /// Where its cells hold at most M particles, the lattice places each: a footprint's count
    /// is then the Poisson process's, Poisson(λ) with λ = N·A·Σ P_c·ν_c. Over 40 000 positions
    /// of a pixel footprint (λ ≈ 0.075, cells of up to about 2 expected particles), the counts
    /// are whole where no cell held more than M, and their mean, variance and share of zeros
    /// are Poisson(λ)'s within four standard errors.
    #[test]
    fn the_lattice_places_a_poisson_process() {
        let tree = lattice_tree(22_000_000);
        let h = DVec3::new(0.08, 0.06, 1.0).normalize();
        let t = h.cross(DVec3::Z).normalize();
        let wi = (0.5f64.cos() * h + 0.5f64.sin() * t).normalize();
        let conic = SphericalConic::new(wi, 2.0 * wi.dot(h) * h - wi, 0.0175).expect("valid");
        let ellipse = SlopeEllipse::of(&conic).expect("an ellipse");
        let mut scratch = LatticeScratch::default();
        let mut state = 3u64;
        let (mut counts, mut expected) = (Vec::new(), 0.0);
        for _ in 0..40_000 {
            state = crate::node::mix64(state.wrapping_add(1));
            let uv = DVec2::new((state >> 40) as f64, (state & 0xFF_FFFF) as f64) / 16_777_216.0;
            let footprint =
                Footprint::new(uv, DVec2::new(1e-3, 0.0), DVec2::new(0.0, 1e-3)).expect("finite");
            let directional = tree
                .slope_cells(
                    &ellipse,
                    &mut scratch.slopes,
                    &mut scratch.squares,
                    Fractions::Now,
                )
                .expect("cells");
            let spatial = tree
                .space_cells(&footprint, &mut scratch.spaces)
                .expect("cells");
            let in_conic = directional.in_conic.expect("computed now");
            expected = tree.config.particles as f64 * spatial.mass * in_conic;
            let level = directional.level;
            counts.push(
                tree.lattice_count(&footprint, &ellipse, &mut scratch, &spatial, level)
                    .0,
            );
        }
        assert!((0.05..0.12).contains(&expected), "λ = {expected}");
        let n = counts.len() as f64;
        let whole = counts.iter().filter(|c| c.fract() == 0.0).count() as f64;
        assert!(whole >= 0.995 * n, "{whole} whole counts of {n}");
        let mean = counts.iter().sum::<f64>() / n;
        let variance = counts.iter().map(|c| (c - mean).powi(2)).sum::<f64>() / (n - 1.0);
        let zeros = counts.iter().filter(|&&c| c == 0.0).count() as f64 / n;
        let error = |standard: f64| 4.0 * standard;
        assert!(
            (mean - expected).abs() < error((expected / n).sqrt()),
            "{mean} against {expected}"
        );
        // Var of a sample variance of Poisson(λ): (λ + 2λ²)/n.
        let variance_error = error(((expected + 2.0 * expected * expected) / n).sqrt());
        assert!(
            (variance - expected).abs() < variance_error,
            "{variance} against {expected}"
        );
        let p0 = (-expected).exp();
        assert!(
            (zeros - p0).abs() < error((p0 * (1.0 - p0) / n).sqrt()),
            "{zeros} against {p0}"
        );
    }

    /// A query the lattice answers alone computes a cell's fraction ν only where its count
    /// asks for it (a cut cell of more than M particles): its counts are those of the cells
    /// with every ν computed first, bit for bit, and ν is the same either way. Queries from
    /// sparse (cells of a few particles) to dense (thousands), on and off the lobe's peak.
    #[test]
    fn fractions_computed_when_asked_give_the_same_counts() {
        let mut asked = 0;
        for particles in [1u64 << 24, 1 << 30, 1 << 36] {
            let tree = lattice_tree(particles);
            let (mut now, mut when_asked) = (LatticeScratch::default(), LatticeScratch::default());
            let mut state = 11u64;
            for i in 0..400 {
                state = crate::node::mix64(state.wrapping_add(1));
                let uv =
                    DVec2::new((state >> 40) as f64, (state & 0xFF_FFFF) as f64) / 16_777_216.0;
                let theta_h = 0.25 * f64::from(i % 5) / 4.0;
                let (wi, wo) = directions_about(
                    DVec3::new(theta_h, 0.3 * theta_h, 1.0),
                    0.2 + 0.002 * f64::from(i),
                );
                let gamma = (1.0 + f64::from(i % 7)).to_radians();
                let conic = SphericalConic::new(wi, wo, gamma).expect("valid");
                let Some(ellipse) = SlopeEllipse::of(&conic) else {
                    continue;
                };
                let side = 1e-3 * (1.0 + f64::from(i % 3));
                let footprint = Footprint::new(
                    uv,
                    DVec2::new(side, 0.3 * side),
                    DVec2::new(-0.2 * side, side),
                )
                .expect("finite");
                let count = |scratch: &mut LatticeScratch, fractions: Fractions| {
                    let directional = tree
                        .slope_cells(
                            &ellipse,
                            &mut scratch.slopes,
                            &mut scratch.squares,
                            fractions,
                        )
                        .expect("cells");
                    let spatial = tree
                        .space_cells(&footprint, &mut scratch.spaces)
                        .expect("cells");
                    tree.lattice_count(&footprint, &ellipse, scratch, &spatial, directional.level)
                };
                let (a, b) = (
                    count(&mut now, Fractions::Now),
                    count(&mut when_asked, Fractions::WhenAsked),
                );
                assert_eq!(
                    (a.0.to_bits(), a.1),
                    (b.0.to_bits(), b.1),
                    "query {i}, N = {particles}"
                );
                for (cell, lazy) in now.slopes.iter().zip(&when_asked.slopes) {
                    if let Some(fraction) = lazy.fraction {
                        assert_eq!(Some(fraction.to_bits()), cell.fraction.map(f64::to_bits));
                        asked += 1;
                    }
                }
            }
        }
        // Dense queries ask for some fractions (cut cells of more than M particles).
        assert!(asked > 100, "{asked} fractions asked for");
    }

    /// A footprint whose bounding box spans more than a tile meets each wrapped square once:
    /// the squares' mass is the footprint's area (its overlaps count every translate).
    #[test]
    fn footprints_wider_than_a_tile_meet_each_square_once() {
        let tree = lattice_tree(1 << 40);
        let mut scratch = LatticeScratch::default();
        for (dx, dy) in [
            (DVec2::new(1.2, 0.0), DVec2::new(0.0, 0.01)),
            (DVec2::new(0.7, 0.7), DVec2::new(-0.003, 0.003)),
            (DVec2::new(0.02, 2.5), DVec2::new(0.05, 0.0)),
        ] {
            let footprint = Footprint::new(DVec2::new(0.5, 0.5), dx, dy).expect("finite");
            if let Some(grid) = tree.space_cells(&footprint, &mut scratch.spaces) {
                let area = footprint.area();
                assert!(
                    (grid.mass / area - 1.0).abs() < 1e-9,
                    "{} against {area}",
                    grid.mass
                );
                let mut seen = std::collections::HashSet::new();
                assert!(scratch.spaces.iter().all(|cell| seen.insert(cell.index)));
            }
        }
    }

    /// A slope cell's points follow the law whose fraction in the conic the cell reports: over
    /// 100 000 points of each cell a wide conic cuts, the share inside is the cell's ν within
    /// four standard errors plus the rows' 0.3%, and each square is drawn by its probability;
    /// squares of probability 0 (first, between, last) are never drawn.
    #[test]
    fn a_slope_cell_draws_the_law_of_its_fraction() {
        let tree = lattice_tree(1 << 40);
        let mut scratch = LatticeScratch::default();
        let (wi, wo) = directions_about(DVec3::new(0.12, 0.05, 1.0), 0.4);
        let conic = SphericalConic::new(wi, wo, 6f64.to_radians()).expect("valid");
        let ellipse = SlopeEllipse::of(&conic).expect("an ellipse");
        let grid = tree
            .slope_cells(
                &ellipse,
                &mut scratch.slopes,
                &mut scratch.squares,
                Fractions::Now,
            )
            .expect("cells");
        let side = side_at(grid.level);
        let mut rng = PointStream(99);
        let mut cut = 0;
        for cell in &scratch.slopes {
            let fraction = cell.fraction.expect("computed now");
            if fraction <= 0.0 || fraction >= 1.0 {
                continue;
            }
            cut += 1;
            let n = 100_000;
            let (mut inside, mut drawn) = (0u32, [0u32; 4]);
            for _ in 0..n {
                let u = [rng.uniform(), rng.uniform(), rng.uniform()];
                inside += u32::from(cell.holds_point(&ellipse, side, u));
                let k = cell
                    .squares
                    .iter()
                    .position(|square| std::ptr::eq(square, cell.square(u[0])))
                    .expect("a square");
                drawn[k] += 1;
            }
            let share = f64::from(inside) / f64::from(n);
            let error = 4.0 * (fraction * (1.0 - fraction) / f64::from(n)).sqrt();
            assert!(
                (share - fraction).abs() < error + 0.003 * fraction,
                "{share} against ν {fraction}"
            );
            let mut below = 0.0;
            for (k, square) in cell.squares.iter().enumerate() {
                let up_to = square.share_up_to.min(1.0).max(below);
                let p = up_to - below;
                let got = f64::from(drawn[k]) / f64::from(n);
                assert!(
                    (got - p).abs() < 4.0 * (p * (1.0 - p) / f64::from(n)).sqrt() + 1e-9,
                    "square {k}: {got} against {p}"
                );
                below = up_to;
            }
        }
        assert!(cut >= 4, "{cut} cut cells");
        // Shares with squares of probability 0 first, between and last.
        let mut cell = scratch.slopes[0];
        for (k, share) in [0.0, 0.5, 0.5, f64::INFINITY].into_iter().enumerate() {
            cell.squares[k].share_up_to = share;
        }
        for u in [0.0, 0.25, 0.499_999, 0.5, 0.75, 1.0 - 1e-16] {
            let k = cell
                .squares
                .iter()
                .position(|square| std::ptr::eq(square, cell.square(u)))
                .expect("a square");
            assert_eq!(k, if u < 0.5 { 1 } else { 3 }, "u = {u}");
        }
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
                let grid = tree
                    .slope_cells(
                        &ellipse,
                        &mut scratch.slopes,
                        &mut scratch.squares,
                        Fractions::Now,
                    )
                    .expect("cells");
                let in_conic = grid.in_conic.expect("computed now");
                let ratio = tree.slope_density(ellipse.center) * ellipse.area / in_conic;
                let lowest = if theta_h <= 0.1 { 0.99 } else { 0.25 };
                assert!(
                    (lowest..1.16).contains(&ratio),
                    "θ_h {theta_h}, γ {gamma}: λ̃/λ = {ratio}"
                );
            }
        }
    }

    /// The weight comes from λ̃, before any cell: a query below the band builds none (the
    /// tree answers, and pays only for λ̃), λ̃ is within 25% of the cells' λ across the
    /// band, and the weight moves without jumps as the cone widens across the grids' levels.
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
            scratch.slopes.clear();
            scratch.spaces.clear();
            let answer = tree.lattice_answer(&footprint, &conic, &mut scratch);
            (answer, scratch.slopes.len() + scratch.spaces.len())
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
                        * (LATTICE_ONLY / LATTICE_FROM).powf(inverse_weight(blend.weight));
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
    fn inverse_weight(t: f64) -> f64 {
        let (mut lo, mut hi) = (0.0, 1.0);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if mid * mid * (3.0 - 2.0 * mid) < t {
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
            let expected =
                LATTICE_FROM * (LATTICE_ONLY / LATTICE_FROM).powf(i as f64 / steps as f64);
            let t = lattice_weight(expected);
            assert!(
                t >= last && t - last < 3.0 / steps as f64,
                "{expected}: {last} → {t}"
            );
            last = t;
        }
    }
}
