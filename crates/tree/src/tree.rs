//! The procedural count tree and its breadth-first query (Alg. 1, Eq. 10, 11).
//!
//! # The particle set
//! A node is (texture box × directional cell, count, identity). The root is [0, 1]² × upper
//! hemisphere with N particles. A node splits in space (four equal boxes, probabilities ¼) or in
//! direction (four child triangles, probabilities ∫p over each, renormalized; octants at the
//! root), chosen by Eq. 11 from material constants only:
//!
//! ```text
//!   split in space  ⇔  E[A(query)] / A(node) < E[σ(query)] / σ(node).
//! ```
//!
//! The children's counts are a multinomial draw from the node's own TEA streams, keyed by the
//! material seed and the node's identity (one stream, or for exact splits of many particles
//! three: the pairs' totals, then each pair's division). A node with at most [`LEAF_PARTICLES`] particles, or
//! at the depth guard, is a *leaf*: its particles are placed explicitly, each from its own
//! stream, uniformly in the box and, in direction, by the same law the splits follow (one
//! particle descends the directional hierarchy with the split probabilities, then lands
//! uniformly in a small near-uniform triangle). Nothing here looks at a query, so every query sees the same
//! particles: overlapping queries agree on their overlap, and repeated queries are
//! bit-identical in any thread and order.
//!
//! # The query (Alg. 1)
//! Breadth first with the early stop of Eq. 10: see `query`.

use std::borrow::Cow;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use glam::{DVec2, DVec3};
use glint_sphere::{Classification, OverlapMethod, SphericalConic, SphericalTriangle};

use crate::error::TreeError;
use crate::footprint::Footprint;
use crate::ndf::{
    DirectionalCell, DirectionalSplit, DirectionalSplits, NdfQuadrature, NormalDensity,
    QuadratureTolerance,
};
use crate::node::NodeId;
use crate::sampling::{
    MultinomialMode, dirichlet4, divide_pair, exponential, multinomial4, multinomial4_equal,
    pair_totals, splits_by_pairs,
};
use crate::tea::{DEFAULT_ROUNDS, TeaRng, draw_at, draws_x4, unit_f64, unit_pair};

mod law;
mod query;
mod scratch;

pub use law::DirectionalLawExcess;
pub use query::QueryResult;
use query::QueuedNode;
use scratch::QueryMemo;
pub use scratch::QueryScratch;

/// Nodes with at most this many particles place them explicitly (leaves). A leaf costs one
/// visit and a few ns per particle (one 4-lane TEA call per four positions, the normal only
/// for particles in the footprint); splitting it instead costs a multinomial and four child
/// tests per level. Measured on the six Table 1 workloads (`profile_queries`): 8, 16, 32 and 64
/// visit 43–282, 42–239, 33–180 and 33–178 nodes per query, and 32 is the fastest on all six
/// (5–15% faster than 8; 64 is slower again on three). Rechecked after leaf positions took one
/// draw and spatial splits two bits per particle: in instructions per query 16 costs 6–12%
/// more than 32 on the dense and glass workloads, 64 within ±2%.
pub const LEAF_PARTICLES: u64 = 32;

/// A leaf's box is divided into this many sub-boxes per side for placing its particles (16:
/// four bits per particle).
const LEAF_SUB_BOXES_PER_SIDE: usize = 4;

/// The column and row of a leaf's sub-box from its four-bit code.
#[inline]
fn sub_box_column_and_row(code: usize) -> (usize, usize) {
    (
        code % LEAF_SUB_BOXES_PER_SIDE,
        code / LEAF_SUB_BOXES_PER_SIDE,
    )
}

/// Stream purposes: separate streams of one node.
const PURPOSE_SPLIT: u32 = 0;
const PURPOSE_AREA: u32 = 1; // + channel
const PURPOSE_LEAF_SUB_BOXES: u32 = 4; // after the area channels (at most 3)
const PURPOSE_PAIR: u32 = 5; // + pair (0 or 1): the division of an exact split's pair
const PURPOSE_LEAF: u32 = 16; // + particle index

/// The deepest top-level cache allowed (4⁸ entries of four nodes, ~70 MB).
pub const MAX_CACHED_LEVELS: u32 = 8;

/// Directional cells whose splits are computed once per material: depths 0 to 5, 1365
/// splits, about 600 KB.
const CACHED_DIRECTIONAL_LEVELS: u32 = 6;

/// The largest particle count (exact binomial sampling needs n ≤ 2⁵³).
pub const MAX_PARTICLES: u64 = 1 << 53;

/// The parameters that define a material's particle set and how it is queried.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CountTreeConfig {
    /// N, the number of particles in the unit texture square.
    pub particles: u64,
    /// The material seed.
    pub seed: u64,
    /// ε of Eq. 10 (0 = exact evaluation; the paper uses 0.1).
    pub epsilon: f64,
    /// Exact multinomial splits or the paper's normal approximation.
    pub multinomial: MultinomialMode,
    /// How partial nodes' directional overlap is measured when ε > 0.
    pub overlap: OverlapMethod,
    /// E[A(query)] of Eq. 11: the expected footprint area (texture units).
    pub expected_query_area: f64,
    /// E[σ(query)] of Eq. 11: the expected solid angle of the query's conic (steradians).
    pub expected_query_solid_angle: f64,
    /// The NDF quadrature tolerances (Alg. 2).
    pub quadrature: QuadratureTolerance,
    /// TEA cycles per random draw (the paper: 8).
    pub tea_rounds: u32,
    /// The depth guard: the deepest node a query visits.
    pub max_depth: u32,
    /// Depths whose splits are computed once when the tree is built (0 to 8; default 6, about
    /// 1 MB): every query passes through the top of the tree.
    pub cached_levels: u32,
    /// The work guard: a query never visits more nodes than this. A partial node whose split
    /// would queue nodes past the budget adds its expected share instead
    /// ([`QueryResult::truncated`] tells). Exact evaluation of huge counts (N = 10¹⁵ over a
    /// whole tile) would otherwise resolve every particle near the conic's boundary.
    pub node_budget: u32,
    /// Particle areas per colour channel (Sec. 3.4, Fig. 8): 0 for none (each particle counts
    /// 1/N), 1 for gray areas, 3 for RGB.
    pub colour_channels: usize,
}

impl Default for CountTreeConfig {
    /// N = 10⁶, seed 0, ε = 0.1, exact multinomials, planar overlaps, a footprint of 10⁻⁶
    /// (a pixel of ~1000² over the texture) and the conic of γ = 1° at normal incidence,
    /// δ = 1e-5, 8 TEA cycles, depth guard 64, 6 cached levels, node budget 10⁶, no colour.
    fn default() -> Self {
        let gamma = 1f64.to_radians();
        Self {
            particles: 1_000_000,
            seed: 0,
            epsilon: 0.1,
            multinomial: MultinomialMode::Exact,
            overlap: OverlapMethod::Planar,
            expected_query_area: 1e-6,
            expected_query_solid_angle: expected_conic_solid_angle(gamma),
            quadrature: QuadratureTolerance::default(),
            tea_rounds: DEFAULT_ROUNDS,
            max_depth: 64,
            cached_levels: 6,
            node_budget: 1_000_000,
            colour_channels: 0,
        }
    }
}

/// The solid angle of the conic for cone radius γ at ω_i = ω_o = n: the half-vector map has
/// Jacobian 1/(4 ω_i·m), so it is 2π(1 − cos γ)/4 = π sin²(γ/2). A default for Eq. 11.
#[must_use]
pub fn expected_conic_solid_angle(gamma: f64) -> f64 {
    std::f64::consts::PI * (0.5 * gamma).sin().powi(2)
}

/// The count tree of one material.
#[derive(Clone)]
pub struct CountTree {
    /// Unique to this tree (and its clones), for memos kept across queries.
    id: u64,
    config: CountTreeConfig,
    quadrature: NdfQuadrature,
    density: Arc<NormalDensity>,
    directional_splits: DirectionalSplits,
    top_levels: TopLevels,
}

/// The children of every node above depth [`CountTreeConfig::cached_levels`], computed once:
/// every query starts at the root and would otherwise redraw the same top splits (the large-n
/// multinomials and the coarse cells' geometry). Indexed by depth, then by the node's label
/// within its depth (labels of one depth are consecutive).
#[derive(Clone, Debug, Default)]
struct TopLevels {
    levels: u32,
    entries: Vec<([Node; 4], bool)>,
}

impl TopLevels {
    /// The first label of depth d: (2·4ᵈ + 1)/3; depths before d hold (4ᵈ − 1)/3 nodes.
    fn index(&self, node: &Node) -> Option<usize> {
        if node.depth >= self.levels {
            return None;
        }
        let power = 1u128 << (2 * node.depth);
        let first_label = (2 * power + 1) / 3;
        let before = (power - 1) / 3;
        Some((before + node.id.0 - first_label) as usize)
    }

    fn get(&self, node: &Node) -> Option<&([Node; 4], bool)> {
        self.index(node).and_then(|i| self.entries.get(i))
    }
}

impl std::fmt::Debug for CountTree {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CountTree")
            .field("config", &self.config)
            .field("quadrature_entries", &self.quadrature.len())
            .field("cached_directional_splits", &self.directional_splits.len())
            .finish_non_exhaustive()
    }
}

/// A node of the tree during a query.
#[derive(Clone, Copy, Debug)]
struct Node {
    id: NodeId,
    count: u64,
    box_min: DVec2,
    /// Spatial splits so far: the box's side is 2^−level.
    box_level: u32,
    cell: DirectionalCell,
    solid_angle: f64,
    depth: u32,
    /// The node's share of each channel's total particle area (1 at the root).
    areas: [f64; 3],
}

/// A split's counts as the totals of the pairs of children (0, 1) and (2, 3), each pair
/// divided between its children on demand (see `CountTree::split_counts`).
struct PairCounts {
    totals: [u64; 2],
    pairs: [PairDivision; 2],
    probabilities: [f64; 4],
    /// The node's key and TEA rounds, for the pairs' streams.
    key: [u32; 4],
    rounds: u32,
}

/// A pair's division between its two children: drawn, or pending with draw 0 of its stream.
#[derive(Clone, Copy)]
enum PairDivision {
    Drawn([u64; 2]),
    Pending { first_draw: u64 },
}

impl PairCounts {
    /// Counts drawn all at once.
    fn drawn(counts: [u64; 4]) -> Self {
        Self {
            totals: [counts[0] + counts[1], counts[2] + counts[3]],
            pairs: [
                PairDivision::Drawn([counts[0], counts[1]]),
                PairDivision::Drawn([counts[2], counts[3]]),
            ],
            probabilities: [0.25; 4],
            key: [0; 4],
            rounds: 0,
        }
    }

    /// How many children of `pair`, which both miss the query, count as visited: the
    /// non-empty ones when the pair's counts are drawn; otherwise its total, at most the
    /// number of children with a positive probability (whether one of those is empty is
    /// never drawn).
    fn undivided_visits(&self, pair: usize) -> u32 {
        match self.pairs[pair] {
            PairDivision::Drawn(counts) => counts.iter().map(|&c| u32::from(c > 0)).sum(),
            PairDivision::Pending { .. } => {
                let possible = self.probabilities[2 * pair..2 * pair + 2]
                    .iter()
                    .map(|&p| u64::from(p > 0.0))
                    .sum();
                self.totals[pair].min(possible) as u32
            }
        }
    }

    /// The counts of the children of `pair` (0 or 1), drawn on the first call.
    fn divide(&mut self, pair: usize) -> [u64; 2] {
        match self.pairs[pair] {
            PairDivision::Drawn(counts) => counts,
            PairDivision::Pending { first_draw } => {
                let purpose = PURPOSE_PAIR + pair as u32;
                let mut rng = TeaRng::with_first_draw(self.key, purpose, self.rounds, first_draw);
                let counts = divide_pair(self.totals[pair], self.probabilities, pair, &mut rng);
                self.pairs[pair] = PairDivision::Drawn(counts);
                counts
            }
        }
    }
}

impl Node {
    /// The box's side, 2^−level (exact: a power of two built from its exponent bits).
    #[inline]
    fn box_size(&self) -> f64 {
        box_size_at(self.box_level)
    }
}

/// The corner of quarter `j` of `node`'s box (j = column + 2·row), the box of its spatial
/// child j.
#[inline]
fn quarter_min(node: &Node, j: usize) -> DVec2 {
    node.box_min + DVec2::new((j & 1) as f64, (j >> 1) as f64) * (0.5 * node.box_size())
}

/// The side of a box at `level`, 2^−level (exact: a power of two built from its exponent bits).
#[inline]
fn box_size_at(level: u32) -> f64 {
    debug_assert!(level < 1000);
    f64::from_bits((1023 - u64::from(level)) << 52)
}

impl CountTree {
    /// Builds the tree of a material: validates `config` and runs Alg. 2 on `density`,
    /// the particle normal density p(m) = D(m)(m·n), which must integrate to 1 over the upper
    /// hemisphere.
    ///
    /// # Errors
    /// A [`TreeError`] naming the invalid parameter.
    pub fn new(config: CountTreeConfig, density: Arc<NormalDensity>) -> Result<Self, TreeError> {
        if !(1..=MAX_PARTICLES).contains(&config.particles) {
            return Err(TreeError::ParticleCountOutOfRange {
                particles: config.particles,
            });
        }
        if !(config.epsilon >= 0.0 && config.epsilon.is_finite()) {
            return Err(TreeError::InvalidEpsilon {
                epsilon: config.epsilon,
            });
        }
        let positive = |x: f64| x > 0.0 && x.is_finite();
        if !(positive(config.expected_query_area) && positive(config.expected_query_solid_angle)) {
            return Err(TreeError::InvalidExpectedQuery);
        }
        if config.colour_channels > 3 {
            return Err(TreeError::InvalidColourChannels {
                channels: config.colour_channels,
            });
        }
        if config.tea_rounds == 0 {
            return Err(TreeError::InvalidRounds);
        }
        if config.cached_levels > MAX_CACHED_LEVELS {
            return Err(TreeError::TooManyCachedLevels {
                levels: config.cached_levels,
            });
        }
        let quadrature = NdfQuadrature::build(density.as_ref(), config.quadrature)?;
        let directional_splits =
            DirectionalSplits::build(&quadrature, density.as_ref(), CACHED_DIRECTIONAL_LEVELS);
        static NEXT_ID: AtomicU64 = AtomicU64::new(1);
        let mut tree = Self {
            id: NEXT_ID.fetch_add(1, Ordering::Relaxed),
            config,
            quadrature,
            density,
            directional_splits,
            top_levels: TopLevels::default(),
        };
        tree.top_levels = tree.build_top_levels();
        Ok(tree)
    }

    /// Breadth first, so that entries land in label order within each depth.
    fn build_top_levels(&self) -> TopLevels {
        let levels = self.config.cached_levels;
        let mut entries = Vec::new();
        let mut level = vec![self.root()];
        for _ in 0..levels {
            let mut next = Vec::with_capacity(4 * level.len());
            for node in &level {
                let mut children = [*node; 4];
                let mut k = 0;
                let spatial = self.emit_children(node, |child| {
                    children[k] = child;
                    k += 1;
                });
                next.extend_from_slice(&children);
                entries.push((children, spatial));
            }
            level = next;
        }
        TopLevels { levels, entries }
    }

    /// The material parameters.
    #[must_use]
    pub fn config(&self) -> &CountTreeConfig {
        &self.config
    }

    /// The memo table of Alg. 2.
    #[must_use]
    pub fn quadrature(&self) -> &NdfQuadrature {
        &self.quadrature
    }

    fn stream(&self, id: NodeId, purpose: u32) -> TeaRng {
        TeaRng::new(id.key(self.config.seed), purpose, self.config.tea_rounds)
    }

    /// Eq. 11: whether `node` splits in space (else in direction).
    fn splits_in_space(&self, node: &Node) -> bool {
        let box_area = node.box_size() * node.box_size();
        self.config.expected_query_area * node.solid_angle
            < self.config.expected_query_solid_angle * box_area
    }

    /// Hands the four children of `node` (counts drawn from its streams) to `emit`, in order,
    /// and returns whether the split is spatial. A pure function of the node: the same
    /// children in every query.
    fn emit_children(&self, node: &Node, mut emit: impl FnMut(Node)) -> bool {
        let spatial = self.splits_in_space(node);
        let split = (!spatial).then(|| self.directional_split(&node.cell));
        let mut counts = self.split_counts(node, split.as_deref());
        let counts = [counts.divide(0), counts.divide(1)];
        let counts = [counts[0][0], counts[0][1], counts[1][0], counts[1][1]];
        let mut areas = [[0.0; 3]; 4];
        for channel in 0..self.config.colour_channels {
            let mut rng = self.stream(node.id, PURPOSE_AREA + channel as u32);
            let parts = dirichlet4(counts, &mut rng);
            for (child_areas, part) in areas.iter_mut().zip(parts) {
                child_areas[channel] = node.areas[channel] * part;
            }
        }
        for j in 0..4 {
            emit(Node {
                areas: areas[j],
                ..self.child(node, split.as_deref(), j, counts[j])
            });
        }
        spatial
    }

    /// Child `j` of `node` under `split` (its directional split, `None` for a spatial one)
    /// holding `count` particles (areas zero): its box and cell.
    #[inline]
    fn child(&self, node: &Node, split: Option<&DirectionalSplit>, j: usize, count: u64) -> Node {
        let (box_min, box_level, cell, solid_angle) = match split {
            None => (
                quarter_min(node, j),
                node.box_level + 1,
                node.cell,
                node.solid_angle,
            ),
            Some(split) => (
                node.box_min,
                node.box_level,
                split.children[j],
                split.solid_angles[j],
            ),
        };
        Node {
            id: node.id.child(j),
            count,
            box_min,
            box_level,
            cell,
            solid_angle,
            depth: node.depth + 1,
            areas: [0.0; 3],
        }
    }

    /// The counts of `node`'s split (`split`: its directional split, `None` for a spatial
    /// one), pair by pair. Exact splits of more particles than a categorical or bit-by-bit
    /// draw takes are a binary tree of binomials (`sampling::pair_totals`, then
    /// `sampling::divide_pair`): the totals from the node's split stream, each pair's
    /// division from a stream of its own, so that a query may leave a pair undivided without
    /// changing the other. The first draws of the three streams are one 4-lane TEA call.
    fn split_counts(&self, node: &Node, split: Option<&DirectionalSplit>) -> PairCounts {
        let mode = self.config.multinomial;
        let probabilities = split.map_or([0.25; 4], |split| split.probabilities);
        if !splits_by_pairs(node.count, split.is_none(), mode) {
            let mut rng = self.stream(node.id, PURPOSE_SPLIT);
            let counts = match split {
                None => multinomial4_equal(node.count, mode, &mut rng),
                Some(_) => multinomial4(node.count, probabilities, mode, &mut rng),
            };
            return PairCounts::drawn(counts);
        }
        let key = node.id.key(self.config.seed);
        let rounds = self.config.tea_rounds;
        // Lane 3 (a third pair's stream) is computed and unused.
        let purposes = [
            PURPOSE_SPLIT,
            PURPOSE_PAIR,
            PURPOSE_PAIR + 1,
            PURPOSE_PAIR + 2,
        ];
        let [first, left, right, _] = draws_x4(key, purposes, 0, rounds);
        let mut rng = TeaRng::with_first_draw(key, PURPOSE_SPLIT, rounds, first);
        PairCounts {
            totals: pair_totals(node.count, probabilities, &mut rng),
            pairs: [
                PairDivision::Pending { first_draw: left },
                PairDivision::Pending { first_draw: right },
            ],
            probabilities,
            key,
            rounds,
        }
    }

    /// The directional split of `cell`: borrowed from the material's table (coarse cells and
    /// cells with an Alg. 2 entry), else computed.
    fn directional_split(&self, cell: &DirectionalCell) -> Cow<'_, DirectionalSplit> {
        match self.directional_splits.get(cell) {
            Some(split) => Cow::Borrowed(split),
            None => Cow::Owned(DirectionalSplit::of(
                cell,
                &self.quadrature,
                self.density.as_ref(),
            )),
        }
    }

    /// The root node.
    fn root(&self) -> Node {
        Node {
            id: NodeId::ROOT,
            count: self.config.particles,
            box_min: DVec2::ZERO,
            box_level: 0,
            cell: DirectionalCell::HEMISPHERE,
            solid_angle: DirectionalCell::HEMISPHERE.solid_angle(),
            depth: 0,
            areas: [1.0; 3],
        }
    }

    /// Counts a leaf's particles (positions one by one, normals by [`Self::normals_in_conic`]);
    /// returns (count, area sums). `directional` is the
    /// conic's classification of the leaf's cell; `in_footprint` is reused working memory.
    fn count_leaf(
        &self,
        node: &Node,
        directional: Classification,
        footprint: &Footprint,
        conic: &SphericalConic,
        memo: &mut QueryMemo,
        in_footprint: &mut Vec<LeafParticle>,
    ) -> (f64, [f64; 3]) {
        let box_size = node.box_size();
        let channels = self.config.colour_channels;
        // Each particle's share of the node's area, per channel: Dirichlet(1, …, 1) as
        // normalized exponentials (all particles' draws are needed for the normalization).
        let key = node.id.key(self.config.seed);
        let rounds = self.config.tea_rounds;
        let mut exponential_sums = [0.0; 3];
        if channels > 0 {
            for k in 0..node.count {
                let mut rng = TeaRng::starting_at(key, PURPOSE_LEAF + k as u32, rounds, DRAW_AREAS);
                for sum in exponential_sums.iter_mut().take(channels) {
                    *sum += exponential(&mut rng);
                }
            }
        }
        // Particle k lies in one of the box's 4×4 sub-boxes, four random bits of the leaf's
        // own stream (sixteen particles per draw), and uniformly in it: its position is draw 0
        // of its stream (x from the high 32 bits, y from the low ones). That is uniform in the
        // box, and only the particles of sub-boxes whose translates may meet the footprint
        // need their positions (four per 4-lane TEA call). A particle's later draws (its
        // normal's, its areas': see `DRAW_DESCENT`) are drawn only if the footprint holds it.
        in_footprint.clear();
        let multiplicity_at = footprint.multiplicity_in_box(node.box_min, box_size);
        let sub_size = box_size / LEAF_SUB_BOXES_PER_SIDE as f64;
        let sub_box_min = |code: usize| {
            let (column, row) = sub_box_column_and_row(code);
            node.box_min + sub_size * DVec2::new(column as f64, row as f64)
        };
        let [columns, rows] = multiplicity_at
            .meeting_columns_and_rows::<LEAF_SUB_BOXES_PER_SIDE>(node.box_min, box_size);
        // Bit `code` set for the sub-boxes in a meeting column and a meeting row.
        let meeting =
            (0..LEAF_SUB_BOXES_PER_SIDE * LEAF_SUB_BOXES_PER_SIDE).fold(0u32, |mask, code| {
                let (column, row) = sub_box_column_and_row(code);
                mask | (columns >> column & rows >> row & 1) << code
            });
        let mut sub_boxes = self.stream(node.id, PURPOSE_LEAF_SUB_BOXES);
        for first in (0..node.count).step_by(16) {
            // The particles of these sixteen whose sub-boxes may meet the footprint.
            let codes = sub_boxes.next_bits();
            let mut candidates = [(0u32, 0usize); 16];
            let mut found = 0;
            for i in 0..(node.count - first).min(16) {
                // Written always, kept by advancing `found` (no branch to mispredict: whether
                // a particle's sub-box meets the footprint is a coin toss).
                let code = (codes >> (4 * i) & 15) as usize;
                candidates[found] = (PURPOSE_LEAF + (first + i) as u32, code);
                found += (meeting >> code & 1) as usize;
            }
            for four in candidates[..found].chunks(4) {
                let purposes: [u32; 4] = std::array::from_fn(|i| four.get(i).map_or(0, |c| c.0));
                let draws = draws_x4(key, purposes, 0, rounds);
                for (&(purpose, code), draw) in four.iter().zip(draws) {
                    let position = sub_box_min(code) + sub_size * DVec2::from(unit_pair(draw));
                    let multiplicity = multiplicity_at.at(position);
                    if multiplicity == 0 {
                        continue;
                    }
                    let mut shares = [0.0; 3];
                    if channels > 0 {
                        let mut rng = TeaRng::starting_at(key, purpose, rounds, DRAW_AREAS);
                        for share in shares.iter_mut().take(channels) {
                            *share = exponential(&mut rng);
                        }
                    }
                    in_footprint.push(LeafParticle {
                        normal: NormalDescent::new(purpose, DRAW_AREAS + channels as u32),
                        multiplicity,
                        shares,
                    });
                }
            }
        }
        // The first uniform number of each descent, four particles per 4-lane TEA call.
        for four in in_footprint.chunks_mut(4) {
            let purposes: [u32; 4] =
                std::array::from_fn(|i| four.get(i).map_or(0, |p| p.normal.purpose));
            let draws = draws_x4(key, purposes, DRAW_DESCENT, rounds);
            for (particle, draw) in four.iter_mut().zip(draws) {
                particle.normal.uniform = unit_f64(draw);
            }
        }
        // The normals of the particles in the footprint, 64 at a time (a bit each).
        let stream = LeafStream { key, rounds };
        let mut found = 0.0;
        let mut areas = [0.0; 3];
        for group in in_footprint.chunks_mut(64) {
            let everyone = u64::MAX >> (64 - group.len());
            let inside = self.normals_in_conic(
                &node.cell,
                directional,
                conic,
                memo,
                (&stream, group),
                everyone,
            );
            for particle in members(inside).map(|k| &group[k]) {
                let multiplicity = particle.multiplicity as f64;
                found += multiplicity;
                for c in 0..channels {
                    if exponential_sums[c] > 0.0 {
                        areas[c] +=
                            multiplicity * node.areas[c] * particle.shares[c] / exponential_sums[c];
                    }
                }
            }
        }
        (found, areas)
    }
}

/// Leaf particles' normals descend the directional hierarchy until the cell's longest edge is
/// below this arc (radians), then land uniformly in the cell: a particle's normal is within
/// this angle of every direction of the last cell it reached.
pub const LEAF_CELL_ARC: f64 = 0.01;

/// The chord of [`LEAF_CELL_ARC`], 2·sin(0.005).
const LEAF_CELL_CHORD: f64 = 0.009_999_958_333_385_416;

/// The directional law of the tree below a leaf, for one particle: descend the directional
/// hierarchy with the split probabilities of [`NdfQuadrature::split_probabilities`] (the law
/// of the multinomial splits, one particle at a time) until the cell has no table entry and
/// its longest edge is below 0.01 rad, then sample the flat triangle uniformly and project
/// (the projection's non-uniformity there is below 1e-4 relative).
impl CountTree {
    /// The triangle of `cell` if it is a *final cell* of the directional law: its longest edge
    /// is below [`LEAF_CELL_ARC`] and Alg. 2 has no entry for it, so a leaf particle's normal
    /// that reaches it lands uniformly in it.
    fn final_cell<'a>(&self, cell: &'a DirectionalCell) -> Option<&'a SphericalTriangle> {
        cell.triangle.as_ref().filter(|triangle| {
            triangle.longest_chord() <= LEAF_CELL_CHORD && !self.quadrature.has_entry(cell)
        })
    }

    /// Which of the leaf particles `members` (bits indexing `particles`, each descending the
    /// law above with its own stream, all now in `cell`, which the conic classifies as
    /// `classification`) have normals in the conic; the answer has their bits set.
    ///
    /// The particles descend together: a cell's split and its children's classifications are
    /// computed once for all the particles in it. Each particle still takes its own draws in
    /// its own order, so the answer is that of descending them one at a time. A descent stops
    /// as soon as its cell is inside the conic or disjoint from it: the classification is
    /// never wrong there, so the answer is that of the normals the full descent would reach.
    fn normals_in_conic(
        &self,
        cell: &DirectionalCell,
        classification: Classification,
        conic: &SphericalConic,
        memo: &mut QueryMemo,
        (stream, particles): (&LeafStream, &mut [LeafParticle]),
        members: u64,
    ) -> u64 {
        match classification {
            Classification::Disjoint => return 0,
            Classification::TriangleInsideConic => return members,
            Classification::ConicInsideTriangle | Classification::Partial => {}
        }
        if let Some(triangle) = self.final_cell(cell) {
            let mut inside = 0;
            for k in self::members(members) {
                let normal = particles[k].normal.point_in(triangle, stream);
                inside |= u64::from(conic.contains(normal)) << k;
            }
            return inside;
        }
        let computed;
        let (children, probabilities) = match self.directional_splits.get(cell) {
            Some(split) => (&split.children, split.probabilities),
            None => {
                computed = cell.children();
                (&computed, memo.split_probabilities(self, cell, &computed))
            }
        };
        let mut by_child = [0u64; 4];
        for k in self::members(members) {
            by_child[particles[k].normal.step(&probabilities, stream)] |= 1 << k;
        }
        let mut inside = 0;
        for (child, group) in children.iter().zip(by_child) {
            if group != 0 {
                let classification = memo.classify(child, conic);
                inside |= self.normals_in_conic(
                    child,
                    classification,
                    conic,
                    memo,
                    (stream, particles),
                    group,
                );
            }
        }
        inside
    }
}

/// A leaf particle in the footprint, between its position and its normal: its normal's
/// descent, how many footprint translates hold it, and its exponential area draws per channel.
#[derive(Clone, Debug)]
struct LeafParticle {
    normal: NormalDescent,
    multiplicity: u64,
    shares: [f64; 3],
}

/// A leaf particle's stream is (the leaf's key, its purpose): draw 0 is its position in the
/// box, draw 1 the first uniform number of its normal's descent, draws 2… its area shares
/// (one per colour channel), and the draws after those its descent's further numbers.
const DRAW_DESCENT: u32 = 1;
/// The first area-share draw of a leaf particle's stream (see [`DRAW_DESCENT`]).
const DRAW_AREAS: u32 = 2;

/// The key and TEA rounds of a leaf's particles' streams.
struct LeafStream {
    key: [u32; 4],
    rounds: u32,
}

/// A leaf particle's normal on its way down the directional hierarchy, by inversion: one
/// uniform number u picks the child whose interval [p₀ + … + p_{j−1}, p₀ + … + p_j) holds it,
/// and u rescaled to that interval, (u − p₀ − … − p_{j−1})/p_j, is again uniform and picks
/// the next level's child. The path then has the law of one categorical draw per level with
/// the split probabilities. Rescaling spends log₂(1/p_j) of u's 53 bits per level; once the
/// interval's width (the product of the p_j taken) is below 2⁻²¹, fewer than 32 bits would be
/// left (the resolution of the particle's position), and u is replaced by the stream's next
/// draw. Most descents thus take one draw until their final cell (a particle that reaches
/// one takes two more for its point in it), and a 4-lane TEA call computes the first draws of
/// four particles at once.
#[derive(Clone, Debug)]
struct NormalDescent {
    /// The particle's stream: (leaf key, purpose).
    purpose: u32,
    /// The stream's next unused draw.
    next_draw: u32,
    /// The current uniform number in [0, 1).
    uniform: f64,
    /// The width of the interval of the number drawn that `uniform` now spans.
    width: f64,
}

/// Below this interval width a descent takes a fresh draw (see [`NormalDescent`]).
const DESCENT_MIN_WIDTH: f64 = 1.0 / (1u64 << 21) as f64;

/// The largest double below 1.
const ONE_BELOW: f64 = 1.0 - f64::EPSILON / 2.0;

impl NormalDescent {
    /// The descent of the particle with stream `purpose`, whose draws from `next_draw` on are
    /// unused; `uniform` is set by the caller (draw [`DRAW_DESCENT`]).
    fn new(purpose: u32, next_draw: u32) -> Self {
        Self {
            purpose,
            next_draw,
            uniform: 0.0,
            width: 1.0,
        }
    }

    /// The stream's next draw as a uniform number in [0, 1).
    fn fresh_uniform(&mut self, stream: &LeafStream) -> f64 {
        let bits = draw_at(stream.key, self.purpose, self.next_draw, stream.rounds);
        self.next_draw += 1;
        unit_f64(bits)
    }

    /// The child (0–3) the descent takes under split `probabilities` (summing to 1 up to
    /// rounding; the last child takes any remainder), after which `self` is the descent in it.
    fn step(&mut self, probabilities: &[f64; 4], stream: &LeafStream) -> usize {
        let [p0, p1, p2, p3] = *probabilities;
        let u = self.uniform;
        let (r1, r2) = (u - p0, u - p0 - p1);
        let r3 = r2 - p2;
        // The first j with u − p₀ − … − p_{j−1} < p_j, without branches (the child is random,
        // so a branch per comparison would be mispredicted often).
        let child =
            usize::from(u >= p0) * (1 + usize::from(r1 >= p1) * (1 + usize::from(r2 >= p2)));
        let (remainder, p) = [(u, p0), (r1, p1), (r2, p2), (r3, p3)][child];
        self.width *= p;
        self.uniform = if self.width < DESCENT_MIN_WIDTH {
            self.width = 1.0;
            self.fresh_uniform(stream)
        } else {
            (remainder / p).clamp(0.0, ONE_BELOW)
        };
        child
    }

    /// The particle's normal, uniform in the flat `triangle` of its final cell (projected):
    /// two fresh draws.
    fn point_in(&mut self, triangle: &SphericalTriangle, stream: &LeafStream) -> DVec3 {
        let root = self.fresh_uniform(stream).sqrt();
        let v = self.fresh_uniform(stream);
        triangle.direction_at([1.0 - root, root * (1.0 - v), root * v])
    }
}

/// The indices of the set bits of `bits`, in increasing order.
fn members(mut bits: u64) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (bits != 0).then(|| {
            let k = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            k
        })
    })
}

/// Shared by the tests of this module's parts.
#[cfg(test)]
mod test_support {
    use std::sync::Arc;

    use glam::DVec3;
    use glint_sphere::{Classification, SphericalConic};

    use crate::ndf::{DirectionalCell, NormalDensity};

    /// How `conic` meets `cell` (the whole hemisphere always partially).
    pub(super) fn classify_cell(cell: &DirectionalCell, conic: &SphericalConic) -> Classification {
        cell.triangle
            .as_ref()
            .map_or(Classification::Partial, |t| conic.classify(t))
    }

    /// A lobe of width α, exp(−tan²θ/α²)/(π α² cos²θ): Beckmann's D(m)·cos²θ (the tree
    /// normalizes a density by its integral, so only the shape matters here).
    pub(super) fn beckmann(alpha: f64) -> Arc<NormalDensity> {
        Arc::new(move |m: DVec3| {
            let cos2 = m.z * m.z;
            let tan2 = (1.0 - cos2) / cos2;
            (-tan2 / (alpha * alpha)).exp() / (std::f64::consts::PI * alpha * alpha * cos2)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::test_support::{beckmann, classify_cell};
    use super::*;

    use glam::DVec3;

    /// The descent of one leaf particle at a time: the reference for the grouped descent.
    fn normal_in_conic_alone(
        tree: &CountTree,
        cell: &DirectionalCell,
        classification: Classification,
        conic: &SphericalConic,
        stream: &LeafStream,
        normal: &mut NormalDescent,
    ) -> bool {
        let (mut cell, mut classification) = (*cell, classification);
        loop {
            match classification {
                Classification::Disjoint => return false,
                Classification::TriangleInsideConic => return true,
                Classification::ConicInsideTriangle | Classification::Partial => {}
            }
            if let Some(triangle) = tree.final_cell(&cell) {
                return conic.contains(normal.point_in(triangle, stream));
            }
            let split = tree.directional_split(&cell);
            cell = split.children[normal.step(&split.probabilities, stream)];
            classification = classify_cell(&cell, conic);
        }
    }

    /// A descent by inversion has the law of independent categorical draws per level: the
    /// children taken at consecutive levels are independent, each with the split's
    /// probabilities, across the fresh draws that replace a spent number (chi-square, 15
    /// degrees of freedom, α = 1e-6 per level pair).
    #[test]
    fn descents_by_inversion_take_independent_categorical_steps() {
        let p = [0.05, 0.15, 0.3, 0.5];
        let (particles, levels) = (40_000u32, 30);
        let stream = LeafStream {
            key: [5, 6, 7, 8],
            rounds: 8,
        };
        let mut pairs = vec![[[0u32; 4]; 4]; levels - 1];
        let mut fresh_draws = 0;
        for purpose in 0..particles {
            let mut descent = NormalDescent::new(purpose, 1);
            descent.uniform = descent.fresh_uniform(&stream);
            let mut previous = descent.step(&p, &stream);
            for pair in &mut pairs {
                let child = descent.step(&p, &stream);
                pair[previous][child] += 1;
                previous = child;
            }
            fresh_draws += descent.next_draw - 2;
        }
        // About one fresh draw per 13 levels (−Σ p ln p = 1.14 nats per level, 2⁻²¹ = e^−14.6).
        assert!(
            fresh_draws > particles,
            "{fresh_draws} fresh draws for {particles} descents"
        );
        for (level, pair) in pairs.iter().enumerate() {
            let mut chi_square = 0.0;
            for (a, row) in pair.iter().enumerate() {
                for (b, &observed) in row.iter().enumerate() {
                    let expected = f64::from(particles) * p[a] * p[b];
                    chi_square += (f64::from(observed) - expected).powi(2) / expected;
                }
            }
            assert!(
                chi_square < 57.4,
                "levels {level}, {}: χ² = {chi_square}",
                level + 1
            );
        }
    }
    /// pairs in either order, gives the counts of the whole split (each pair has its own
    /// stream), over spatial and directional splits of 10 to 10⁹ particles.
    #[test]
    fn pairs_divided_alone_are_the_whole_splits_pairs() {
        let density = beckmann(0.1);
        let config = CountTreeConfig {
            particles: 1_000_000_000,
            cached_levels: 0,
            ..CountTreeConfig::default()
        };
        let tree = CountTree::new(config, density).expect("valid");
        let (mut level, mut binary_splits) = (vec![tree.root()], [0; 2]);
        for _ in 0..12 {
            let mut next = Vec::new();
            for node in &level {
                let mut whole = Vec::new();
                let spatial = tree.emit_children(node, |child| whole.push(child));
                let split = (!spatial).then(|| tree.directional_split(&node.cell));
                let counts = |k: usize| [whole[2 * k].count, whole[2 * k + 1].count];
                for order in [[0, 1], [1, 0]] {
                    let mut pairs = tree.split_counts(node, split.as_deref());
                    assert_eq!(
                        pairs.divide(order[0]),
                        counts(order[0]),
                        "node {:?}",
                        node.id
                    );
                    assert_eq!(
                        pairs.divide(order[1]),
                        counts(order[1]),
                        "node {:?}",
                        node.id
                    );
                }
                let pending = tree.split_counts(node, split.as_deref()).pairs[0];
                binary_splits[usize::from(spatial)] +=
                    u32::from(matches!(pending, PairDivision::Pending { .. }));
                // Follow the fullest child and one other (a few hundred nodes in all).
                whole.sort_by_key(|child| std::cmp::Reverse(child.count));
                next.extend(whole.into_iter().take(2).filter(|child| child.count > 10));
            }
            level = next;
        }
        assert!(
            binary_splits[0] > 20 && binary_splits[1] > 20,
            "directional and spatial splits drawn as pairs: {binary_splits:?}"
        );
    }

    /// An undivided pair counts its non-empty children as visited when its counts are known,
    /// and otherwise at most its total and its children of positive probability.
    #[test]
    fn undivided_pairs_count_the_children_that_may_hold_particles() {
        let drawn = PairCounts::drawn([0, 5, 3, 0]);
        assert_eq!(
            [drawn.undivided_visits(0), drawn.undivided_visits(1)],
            [1, 1]
        );
        let pending = |totals: [u64; 2], probabilities: [f64; 4]| PairCounts {
            totals,
            pairs: [PairDivision::Pending { first_draw: 0 }; 2],
            probabilities,
            key: [0; 4],
            rounds: 8,
        };
        let counts = pending([1, 7], [0.2, 0.3, 0.5, 0.0]);
        assert_eq!(
            [counts.undivided_visits(0), counts.undivided_visits(1)],
            [1, 1]
        );
        let counts = pending([9, 0], [0.2, 0.3, 0.25, 0.25]);
        assert_eq!(
            [counts.undivided_visits(0), counts.undivided_visits(1)],
            [2, 0]
        );
    }

    /// The splits a query draws pair by pair (three streams per node) have the multinomial
    /// law jointly: the outcomes of 40 000 nodes of 10 particles under one directional split,
    /// each node with its own identity, against the multinomial pmf (chi-square over the
    /// outcomes expected five times or more, the rest pooled; α = 1e-6). Dependent streams
    /// (the two pairs' divisions sharing their draws) would fail it.
    #[test]
    fn splits_drawn_pair_by_pair_are_multinomial() {
        let density = beckmann(0.5);
        let tree = CountTree::new(CountTreeConfig::default(), density).expect("valid");
        // A cell of depth 3 whose split is far from uniform and has no tiny child.
        let cells = (0..3).fold(vec![DirectionalCell::HEMISPHERE], |cells, _| {
            cells.iter().flat_map(DirectionalCell::children).collect()
        });
        let least = |cell: &DirectionalCell| {
            let p = tree.directional_split(cell).probabilities;
            p.into_iter().fold(1.0, f64::min)
        };
        let cell = *cells
            .iter()
            .filter(|cell| least(cell) < 0.2)
            .max_by(|a, b| least(a).total_cmp(&least(b)))
            .expect("cells");
        let split = tree.directional_split(&cell);
        let p = split.probabilities;
        let n = 10u64;
        let mut ids = vec![NodeId::ROOT];
        while ids.len() < 40_000 {
            ids = ids
                .iter()
                .flat_map(|id| (0..4).map(|j| id.child(j)))
                .collect();
        }
        let mut observed = std::collections::HashMap::new();
        for &id in ids.iter().take(40_000) {
            let node = Node {
                id,
                count: n,
                cell,
                ..tree.root()
            };
            let mut pairs = tree.split_counts(&node, Some(&split));
            let ([a, b], [c, d]) = (pairs.divide(0), pairs.divide(1));
            *observed.entry([a, b, c]).or_insert(0u32) += 1;
            assert_eq!(a + b + c + d, n);
        }
        // Every outcome (a, b, c, n − a − b − c) and its multinomial probability.
        let log_factorial = |k: u64| (1..=k).map(|i| (i as f64).ln()).sum::<f64>();
        let (mut chi_square, mut bins) = (0.0, 0);
        let (mut pooled_expected, mut pooled_observed) = (0.0, 0.0);
        for a in 0..=n {
            for b in 0..=n - a {
                for c in 0..=n - a - b {
                    let d = n - a - b - c;
                    let ln_pmf = log_factorial(n)
                        + [(a, p[0]), (b, p[1]), (c, p[2]), (d, p[3])]
                            .iter()
                            .map(|&(k, q)| k as f64 * q.ln() - log_factorial(k))
                            .sum::<f64>();
                    let expected = 40_000.0 * ln_pmf.exp();
                    let seen = f64::from(observed.get(&[a, b, c]).copied().unwrap_or(0));
                    if expected >= 5.0 {
                        chi_square += (seen - expected).powi(2) / expected;
                        bins += 1;
                    } else {
                        pooled_expected += expected;
                        pooled_observed += seen;
                    }
                }
            }
        }
        chi_square += (pooled_observed - pooled_expected).powi(2) / pooled_expected;
        // The chi-square quantile at 1 − 1e-6 by Wilson–Hilferty (z = 4.753).
        let df = f64::from(bins);
        let critical = df * (1.0 - 2.0 / (9.0 * df) + 4.753 * (2.0 / (9.0 * df)).sqrt()).powi(3);
        assert!(bins > 30, "{bins} bins, p = {p:?}");
        assert!(
            chi_square < critical,
            "χ² = {chi_square} over {bins} + 1 bins (critical {critical}), p = {p:?}"
        );
    }

    #[test]
    fn grouped_leaf_descent_is_the_descent_one_particle_at_a_time() {
        let alpha: f64 = 0.02;
        let density = Arc::new(move |m: DVec3| {
            let cos2 = m.z * m.z;
            let tan2 = (1.0 - cos2) / cos2;
            (-tan2 / (alpha * alpha)).exp() / (std::f64::consts::PI * alpha * alpha * cos2 * m.z)
        });
        let tree = CountTree::new(CountTreeConfig::default(), density).expect("valid");
        let centroid = |cell: &DirectionalCell| cell.triangle.map_or(DVec3::Z, |t| t.centroid());
        let mut draws = TeaRng::new([1, 2, 3, 4], 0, 8);
        let (mut partial_answers, mut found) = (0, 0);
        // One memo for all trials, as one scratch serves many queries.
        let mut memo = QueryMemo::default();
        for trial in 0..300 {
            // A cell 0–9 levels deep, towards the normal for most trials (where the table is).
            let mut cell = DirectionalCell::HEMISPHERE;
            for _ in 0..trial % 10 {
                let children = cell.children();
                let toward_normal = children
                    .iter()
                    .max_by(|a, b| centroid(a).z.total_cmp(&centroid(b).z))
                    .copied()
                    .expect("four children");
                cell = if draws.uniform() < 0.7 {
                    toward_normal
                } else {
                    children[(draws.uniform() * 4.0) as usize % 4]
                };
            }
            // A conic of half-vectors around a point near the cell's centroid.
            let h = (centroid(&cell)
                + 0.01 * DVec3::new(draws.uniform() - 0.5, draws.uniform() - 0.5, 0.0))
            .normalize();
            let wi = DVec3::new(0.3, -0.2, 1.0).normalize();
            let wo = 2.0 * wi.dot(h) * h - wi;
            let gamma = 0.002 + 0.1 * draws.uniform();
            let Ok(conic) = SphericalConic::new(wi, wo, gamma) else {
                continue;
            };
            let classification = classify_cell(&cell, &conic);
            let count = 1 + (trial % 64);
            let stream = LeafStream {
                key: [trial, 7, 8, 9],
                rounds: 8,
            };
            let mut particles: Vec<LeafParticle> = (0..count)
                .map(|k| {
                    let mut normal = NormalDescent::new(k, 2 + k % 3);
                    normal.uniform = draws.uniform();
                    LeafParticle {
                        normal,
                        multiplicity: 1,
                        shares: [0.0; 3],
                    }
                })
                .collect();
            let mut alone: Vec<NormalDescent> =
                particles.iter().map(|p| p.normal.clone()).collect();
            let everyone = u64::MAX >> (64 - count);
            memo.begin_query();
            let grouped = tree.normals_in_conic(
                &cell,
                classification,
                &conic,
                &mut memo,
                (&stream, &mut particles),
                everyone,
            );
            for (k, normal) in alone.iter_mut().enumerate() {
                let expected =
                    normal_in_conic_alone(&tree, &cell, classification, &conic, &stream, normal);
                assert_eq!(
                    grouped >> k & 1 == 1,
                    expected,
                    "trial {trial} particle {k}"
                );
                // Each particle took the same draws as alone.
                let grouped = &particles[k].normal;
                assert_eq!(
                    (grouped.uniform, grouped.next_draw),
                    (normal.uniform, normal.next_draw),
                    "trial {trial}"
                );
            }
            partial_answers += u32::from(grouped != 0 && grouped != everyone);
            found += grouped.count_ones();
        }
        // The trials exercise descents that split their particles.
        assert!(
            partial_answers > 30 && found > 300,
            "{partial_answers} {found}"
        );
    }
}
