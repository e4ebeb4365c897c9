//! The lattice's points: a Poisson process drawn cell by cell in order of priority, of which a
//! query reads the points below its threshold τ.
//!
//! Each cell (a square of space at a grid's level × a slope cell c) holds a Poisson process of
//! intensity N·d(x)·P_c per unit of area and of *priority*. Its points come in intervals of
//! priority of [`BATCH`] expected points each (a Poisson count per interval, the points'
//! priorities uniform over it: no logarithm a point), each point a position uniform over the
//! square and a slope in the slope cell by its log-linear law ([`super::SlopeCell`]). Where the
//! density map varies over the square the points come at the rate of its bound d⁺ there and a
//! point at x is kept with probability d(x)/d⁺: the thinning that turns a uniform process of
//! rate d⁺ into one of rate d(x). The points below τ are then a Poisson process of intensity
//! τ·N·d(x)·p(m), the particles' process thinned to a share τ, and the points below τ′ > τ
//! include them: a point's priority and position come from one draw of its cell's stream, in a
//! fixed order, its slope and its thinning from streams seeded by that draw, whatever the
//! query.

use glam::DVec2;

use super::slope_ellipse::SlopeEllipse;
use super::{PointStream, SlopeCell, side_at};
use crate::density_map::DensityMap;
use crate::footprint::Footprint;
use crate::node::mix64;

/// The expected points of one interval of priority: a cell's points come in intervals of
/// priority of width BATCH/μ, each holding Poisson(BATCH) points whose priorities are
/// uniform over it (a Poisson process of rate μ, drawn without a logarithm a point).
const BATCH: f64 = 4.0;

/// P(X ≤ k) for X ~ Poisson(BATCH), k = 0…29 (rounded from 60-digit values; X ≥ 30 has
/// probability below 2·10⁻¹⁷).
const BATCH_CDF: [f64; 30] = [
    0.01831563888873418,
    0.09157819444367091,
    0.23810330555354434,
    0.43347012036670896,
    0.6288369351798735,
    0.7851303870304052,
    0.8893260215974264,
    0.9488663842071526,
    0.9786365655120158,
    0.9918677572030662,
    0.9971602338794863,
    0.99908477085273,
    0.9997262831771445,
    0.9999236715846567,
    0.9999800682725173,
    0.9999951073892801,
    0.9999988671684709,
    0.9999997518223981,
    0.9999999484121597,
    0.9999999897994779,
    0.9999999980769415,
    0.9999999996536013,
    0.9999999999402667,
    0.9999999999901216,
    0.9999999999984307,
    0.9999999999997602,
    0.9999999999999647,
    0.999999999999995,
    0.9999999999999993,
    0.9999999999999999,
];

/// A Poisson(BATCH) count by inversion of the uniform `u`.
#[inline]
pub(super) fn batch_count(u: f64) -> u32 {
    BATCH_CDF.iter().position(|&below| u < below).unwrap_or(30) as u32
}

/// A cell reads at most this many intervals of priority (a guard on the work: a query's
/// cells hold about its points times the cells' excess over it, a few hundred points).
const MAX_CELL_INTERVALS: f64 = 4096.0;

/// 2⁻²⁰ and 2⁻²²: a point's priority within its interval and its position on each axis, as
/// uniform numbers in [0, 1) from 20 and 22 bits of its draw.
const PRIORITY_BITS: f64 = 1.0 / 1_048_576.0;
const POSITION_BITS: f64 = 1.0 / 4_194_304.0;

/// Told apart from the cells' streams: the streams of a point's slope and of its thinning draw,
/// seeded by its position's draw.
const SLOPE_STREAM: u64 = 0x534C_4F50_4553_0001;
const KEEP_STREAM: u64 = 0x4B45_4550_5354_0001;

/// A square of space of a grid that the footprint meets.
#[derive(Clone, Copy, Debug)]
pub(super) struct GridSquare {
    /// Its indices, wrapped into the texture square.
    index: [u64; 2],
    lo: DVec2,
    /// Its translate next to the footprint (`lo` plus whole tiles).
    near: DVec2,
    /// Translates of the footprint that hold the whole square (its points' multiplicity where
    /// none cuts it).
    inside: u64,
    /// Whether a translate of the footprint cuts it.
    cut: bool,
    /// An upper bound d⁺ on the density map over it (1 without a map): its points come at
    /// the rate of d⁺ and are kept where a uniform number falls below d(x)/d⁺.
    bound: f64,
    /// Whether the density map varies over it (its points are then thinned by d(x)/d⁺).
    varying: bool,
}

/// The squares of a grid that a footprint meets.
#[derive(Clone, Debug, Default)]
pub(super) struct GridSquares {
    pub(super) level: i32,
    squares: Vec<GridSquare>,
    /// Whether a point's multiplicity is whether the footprint holds its `near` translate.
    one_translate: bool,
}

impl GridSquares {
    /// The squares of the grid at `level` that `footprint` meets (each wrapped square once);
    /// `false` (and no squares) where its bounding box spans more than `most` of them.
    pub(super) fn gather(
        &mut self,
        footprint: &Footprint,
        level: i32,
        density_map: Option<&DensityMap>,
        most: usize,
    ) -> bool {
        self.level = level;
        self.squares.clear();
        let side = side_at(level);
        let (bounds_lo, bounds_hi) = footprint.bounds();
        let (lo, mut hi) = ((bounds_lo / side).floor(), (bounds_hi / side).floor());
        if !((hi - lo + DVec2::ONE).element_product() <= most as f64) {
            return false;
        }
        let wrap = 1i64 << level;
        // Each wrapped square once: its overlaps already count every translate of the
        // footprint, so a bounding box a tile wide or more must not visit it again.
        hi = hi.min(lo + DVec2::splat((wrap - 1) as f64));
        for iy in lo.y as i64..=hi.y as i64 {
            for ix in lo.x as i64..=hi.x as i64 {
                let index = [ix.rem_euclid(wrap) as u64, iy.rem_euclid(wrap) as u64];
                let square_lo = DVec2::new(index[0] as f64, index[1] as f64) * side;
                let overlap = footprint.overlap_box(square_lo, side);
                if overlap.is_disjoint() {
                    continue;
                }
                let (bound, varying) = match density_map {
                    None => (1.0, false),
                    Some(map) if map.is_constant_over(square_lo, side) => {
                        (map.value_at(square_lo + DVec2::splat(0.5 * side)), false)
                    }
                    Some(map) => {
                        let square = Footprint::new(
                            square_lo + DVec2::splat(0.5 * side),
                            DVec2::new(side, 0.0),
                            DVec2::new(0.0, side),
                        )
                        .expect("a square within the texture is a finite footprint");
                        (map.max_over(&square), true)
                    }
                };
                self.squares.push(GridSquare {
                    index,
                    lo: square_lo,
                    near: DVec2::new(ix as f64, iy as f64) * side,
                    inside: overlap.inside,
                    cut: overlap.partial > 0,
                    bound,
                    varying,
                });
            }
        }
        // One translate of the footprint holds all it can of these squares' points when its
        // bounding box and a square fit in a tile.
        self.one_translate = (bounds_hi - bounds_lo).max_element() + side < 1.0;
        true
    }
}

/// What a count over one grid and one level of slope cells needs besides the cells.
pub(super) struct ThinnedQuery<'a> {
    pub(super) footprint: &'a Footprint,
    pub(super) ellipse: &'a SlopeEllipse,
    /// The fine slope squares' level.
    pub(super) slope_level: i32,
    /// τ: the share of the particles' process the points below it stand for.
    pub(super) threshold: f64,
    /// N.
    pub(super) particles: f64,
    /// The material's lattice seed.
    pub(super) seed: u64,
    pub(super) density_map: Option<&'a DensityMap>,
}

impl ThinnedQuery<'_> {
    /// K: the points below τ in the footprint × conic (with their multiplicities), over every
    /// cell of `grid` × `slopes`, and the cells read.
    pub(super) fn count(&self, grid: &GridSquares, slopes: &[SlopeCell]) -> (f64, u32) {
        let side = side_at(grid.level);
        let slope_side = side_at(self.slope_level);
        let mut found = 0.0;
        let mut cells = 0u32;
        for slope in slopes {
            let slope_key = mix64(
                mix64(mix64(self.seed ^ self.slope_level as i64 as u64) ^ slope.index[0] as u64)
                    ^ slope.index[1] as u64,
            );
            for square in &grid.squares {
                // The cell's points come at the rate μ = N·d⁺·h²·P_c (d⁺ = d over a square
                // where the map is constant); where the map varies, a point at x is kept where
                // a uniform number falls below d(x)/d⁺, which thins them to the rate N·d(x)·P_c
                // at x: the particles' process.
                let mean = self.particles * square.bound * side * side * slope.probability;
                if !(mean > 0.0) {
                    continue;
                }
                cells += 1;
                let key = mix64(
                    mix64(slope_key ^ (grid.level as u64).rotate_left(40) ^ square.index[0])
                        ^ square.index[1].rotate_left(17),
                );
                let mut stream = PointStream(key);
                // The priorities in intervals of [`BATCH`] expected points each: a Poisson count
                // per interval, then its points' priorities uniform over it.
                let width = BATCH / mean;
                let intervals = (self.threshold / width).ceil().min(MAX_CELL_INTERVALS);
                let mut interval = 0.0;
                while interval < intervals {
                    let points = batch_count(stream.uniform());
                    for _ in 0..points {
                        // One draw a point: its priority within the interval (20 bits) and its
                        // position (22 bits an axis), from which its slope's seed and its
                        // thinning draw derive.
                        let bits = stream.next_bits();
                        let priority = (interval + (bits >> 44) as f64 * PRIORITY_BITS) * width;
                        if priority >= self.threshold {
                            continue;
                        }
                        let position = || {
                            let u = [
                                ((bits >> 22) & 0x3F_FFFF) as f64 * POSITION_BITS,
                                (bits & 0x3F_FFFF) as f64 * POSITION_BITS,
                            ];
                            square.lo + side * DVec2::new(u[0], u[1])
                        };
                        let multiplicity = if !square.cut {
                            square.inside as f64
                        } else if grid.one_translate {
                            let near = square.near + (position() - square.lo);
                            f64::from(u8::from(self.footprint.contains(near)))
                        } else {
                            self.footprint.multiplicity(position()) as f64
                        };
                        if multiplicity == 0.0 {
                            continue;
                        }
                        if square.varying
                            && let Some(map) = self.density_map
                        {
                            let keep = PointStream(bits ^ KEEP_STREAM).uniform();
                            if keep * square.bound >= map.value_at(position()) {
                                continue;
                            }
                        }
                        if slope.inside() || {
                            let mut slope_stream = PointStream(bits ^ SLOPE_STREAM);
                            let uniforms = [slope_stream.uniform(), slope_stream.uniform()];
                            slope.holds_point(self.ellipse, slope_side, uniforms)
                        } {
                            found += multiplicity;
                        }
                    }
                    interval += 1.0;
                }
            }
        }
        (found, cells)
    }
}
