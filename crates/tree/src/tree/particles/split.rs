//! A node's split (Sec. 3.3–3.4): Eq. 11 chooses between four equal boxes and four child
//! triangles from material constants only, and the children's counts are a multinomial draw
//! from the node's own streams: one stream, or for exact splits of many particles three (the
//! pairs' totals, then each pair's division), so that a query may leave a pair undivided.
//! Directional splits take the probabilities of Alg. 2's integrals of p over the children;
//! spatial splits take ¼ each, or under a density map that varies over the box, the quarters'
//! shares of its mass. Value-stable: see `super`.

use std::borrow::Cow;

use glam::DVec2;

use super::{DRAWN_AREAS_DEPTH, Node, PURPOSE_AREA, PURPOSE_PAIR, PURPOSE_SPLIT, UNDRAWN_AREAS};
use crate::ndf::{DirectionalCell, DirectionalSplit};
use crate::sampling::{
    dirichlet4, divide_pair, multinomial4, multinomial4_equal, pair_totals, splits_by_pairs,
};
use crate::tea::{TeaRng, draws_x4};
use crate::tree::CountTree;
use crate::tree::scratch::QueryMemo;

impl CountTree {
    /// Eq. 11: whether `node` splits in space (else in direction).
    pub(in crate::tree) fn splits_in_space(&self, node: &Node) -> bool {
        let box_area = node.box_size() * node.box_size();
        self.config.expected_query_area * node.solid_angle
            < self.config.expected_query_solid_angle * box_area
    }

    /// Hands the four children of `node` (counts drawn from its streams) to `emit`, in order,
    /// and returns whether the split is spatial. A pure function of the node: the same
    /// children in every query.
    pub(in crate::tree) fn emit_children(&self, node: &Node, emit: impl FnMut(Node)) -> bool {
        self.emit_children_drawing(node, true, None, emit)
    }

    /// [`Self::emit_children`], with the children's particle areas (coloured materials) drawn
    /// only if `draw_areas`; otherwise they are [`UNDRAWN_AREAS`], which
    /// [`Self::with_areas`] draws when a query needs them. The areas come from streams of
    /// their own, so the counts are the same either way. With a `memo`, the split counts may
    /// come from (and go to) its table of counts remembered across queries.
    pub(in crate::tree) fn emit_children_drawing(
        &self,
        node: &Node,
        draw_areas: bool,
        memo: Option<&mut QueryMemo>,
        mut emit: impl FnMut(Node),
    ) -> bool {
        let spatial = self.splits_in_space(node);
        let split = (!spatial).then(|| self.directional_split(&node.cell));
        let remembered = memo
            .as_ref()
            .and_then(|memo| memo.remembered_counts(self, node));
        let mut pairs = remembered.unwrap_or_else(|| self.split_counts(node, split.as_deref()));
        // Whether this split draws anything the memo does not hold yet.
        let drawn = remembered.is_none() || pairs.is_pending(0) || pairs.is_pending(1);
        let counts = [pairs.divide(0), pairs.divide(1)];
        if let (Some(memo), true) = (memo, drawn) {
            memo.remember_counts(self, node, pairs);
        }
        let counts = [counts[0][0], counts[0][1], counts[1][0], counts[1][1]];
        let mut areas = [[0.0; 3]; 4];
        if draw_areas {
            for channel in 0..self.config.colour_channels {
                let mut rng = self.stream(node.id, PURPOSE_AREA + channel as u32);
                let parts = dirichlet4(counts, &mut rng);
                for (child_areas, part) in areas.iter_mut().zip(parts) {
                    child_areas[channel] = node.areas[channel] * part;
                }
            }
        } else {
            areas = [UNDRAWN_AREAS; 4];
        }
        for j in 0..4 {
            emit(Node {
                areas: areas[j],
                ..self.child(node, split.as_deref(), j, counts[j])
            });
        }
        spatial
    }

    /// `node` with its particle areas drawn: as it is if they are, else as
    /// [`Self::emit_children`] draws them on the way down from the root. A node's label holds
    /// its path (child j of label i is 4i + j − 1), so the way down takes the cached top
    /// levels, then one split per level: the same nodes, with the same draws, as a query that
    /// drew every split's areas. Only the nodes a query counts need their areas (most queries
    /// count none); `memo` keeps the nodes drawn on the way for the query's other counted
    /// nodes, which share most of their ancestors.
    pub(in crate::tree) fn with_areas(&self, node: &Node, memo: &mut QueryMemo) -> Node {
        if !node.areas[0].is_nan() {
            return *node;
        }
        // The path's digits, deepest first (labels are exact at the depths areas are left
        // undrawn: see `DRAWN_AREAS_DEPTH`).
        let mut digits = [0u8; DRAWN_AREAS_DEPTH as usize];
        let mut label = node.id.0;
        for digit in digits.iter_mut().take(node.depth as usize) {
            *digit = ((label + 1) % 4) as u8;
            label = (label + 1) / 4;
        }
        let mut current = self.root();
        for &j in digits[..node.depth as usize].iter().rev() {
            let j = usize::from(j);
            current = match self.top_levels.get(&current) {
                Some((children, _)) => children[j],
                None => match memo.node_with_areas(self, current.id.child(j)) {
                    Some(child) => child,
                    None => {
                        // The split draws all four children's areas: remember them all, as
                        // the nodes a query counts are often siblings.
                        let mut children = [current; 4];
                        let mut k = 0;
                        self.emit_children_drawing(&current, true, Some(memo), |c| {
                            children[k] = c;
                            k += 1;
                        });
                        for sibling in children.iter().filter(|c| c.count > 0) {
                            memo.remember_with_areas(self, *sibling);
                        }
                        children[j]
                    }
                },
            };
        }
        debug_assert_eq!((current.id, current.count), (node.id, node.count));
        Node {
            areas: current.areas,
            ..*node
        }
    }

    /// The counts of `node`'s split (`split`: its directional split, `None` for a spatial
    /// one), pair by pair. Exact splits of more particles than a categorical or bit-by-bit
    /// draw takes are a binary tree of binomials (`sampling::pair_totals`, then
    /// `sampling::divide_pair`): the totals from the node's split stream, each pair's
    /// division from a stream of its own, so that a query may leave a pair undivided without
    /// changing the other. The first draws of the three streams are one 4-lane TEA call.
    pub(in crate::tree) fn split_counts(
        &self,
        node: &Node,
        split: Option<&DirectionalSplit>,
    ) -> PairCounts {
        let mode = self.config.multinomial;
        // Unequal children: a directional split's, or a spatial split's where the density map
        // varies over the box (`None` where it is constant: four equal quarters).
        let unequal = match split {
            Some(split) => Some(split.probabilities),
            None => self.spatial_split_probabilities(node),
        };
        let probabilities = unequal.unwrap_or([0.25; 4]);
        if !splits_by_pairs(node.count, unequal.is_none(), mode) {
            let mut rng = self.stream(node.id, PURPOSE_SPLIT);
            let counts = match unequal {
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

    /// The probabilities of a spatial split of `node`'s box: its quarters' shares of the
    /// density map's mass over it, or `None` (¼ each) where the map is constant over the box or
    /// there is no map.
    fn spatial_split_probabilities(&self, node: &Node) -> Option<[f64; 4]> {
        self.density_map
            .as_deref()
            .and_then(|map| map.quarter_probabilities(node.box_min, node.box_size()))
    }

    /// Child `j` of `node` under `split` (its directional split, `None` for a spatial one)
    /// holding `count` particles (areas zero): its box and cell.
    #[inline]
    pub(in crate::tree) fn child(
        &self,
        node: &Node,
        split: Option<&DirectionalSplit>,
        j: usize,
        count: u64,
    ) -> Node {
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

    /// The directional split of `cell`: borrowed from the material's table (coarse cells and
    /// cells with an Alg. 2 entry), else computed.
    pub(in crate::tree) fn directional_split(
        &self,
        cell: &DirectionalCell,
    ) -> Cow<'_, DirectionalSplit> {
        match self.directional_splits.get(cell) {
            Some(split) => Cow::Borrowed(split),
            None => Cow::Owned(DirectionalSplit::of(
                cell,
                &self.quadrature,
                self.density.as_ref(),
            )),
        }
    }
}

/// A split's counts as the totals of the pairs of children (0, 1) and (2, 3), each pair
/// divided between its children on demand (see `CountTree::split_counts`).
#[derive(Clone, Copy, Debug)]
pub(in crate::tree) struct PairCounts {
    pub(in crate::tree) totals: [u64; 2],
    pairs: [PairDivision; 2],
    probabilities: [f64; 4],
    /// The node's key and TEA rounds, for the pairs' streams.
    key: [u32; 4],
    rounds: u32,
}

/// A pair's division between its two children: drawn with the totals (small counts, all
/// four at once), pending with draw 0 of its stream, or divided on demand (by this query or,
/// remembered, by an earlier one).
#[derive(Clone, Copy, Debug)]
enum PairDivision {
    Drawn([u64; 2]),
    Pending { first_draw: u64 },
    Divided([u64; 2]),
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
    /// non-empty ones when the pair's counts are drawn with the totals; otherwise its total,
    /// at most the number of children with a positive probability (a query that leaves the
    /// pair undivided never learns whether one of those is empty, so a division remembered
    /// from an earlier query does not change the figure).
    pub(in crate::tree) fn undivided_visits(&self, pair: usize) -> u32 {
        match self.pairs[pair] {
            PairDivision::Drawn(counts) => counts.iter().map(|&c| u32::from(c > 0)).sum(),
            PairDivision::Pending { .. } | PairDivision::Divided(_) => {
                let possible = self.probabilities[2 * pair..2 * pair + 2]
                    .iter()
                    .map(|&p| u64::from(p > 0.0))
                    .sum();
                self.totals[pair].min(possible) as u32
            }
        }
    }

    /// Whether `pair`'s division is still to be drawn.
    pub(in crate::tree) fn is_pending(&self, pair: usize) -> bool {
        matches!(self.pairs[pair], PairDivision::Pending { .. })
    }

    /// The counts of the children of `pair` (0 or 1), drawn on the first call.
    pub(in crate::tree) fn divide(&mut self, pair: usize) -> [u64; 2] {
        match self.pairs[pair] {
            PairDivision::Drawn(counts) | PairDivision::Divided(counts) => counts,
            PairDivision::Pending { first_draw } => {
                let purpose = PURPOSE_PAIR + pair as u32;
                let mut rng = TeaRng::with_first_draw(self.key, purpose, self.rounds, first_draw);
                let counts = divide_pair(self.totals[pair], self.probabilities, pair, &mut rng);
                self.pairs[pair] = PairDivision::Divided(counts);
                counts
            }
        }
    }
}

/// The corner of quarter `j` of `node`'s box (j = column + 2·row), the box of its spatial
/// child j.
#[inline]
pub(in crate::tree) fn quarter_min(node: &Node, j: usize) -> DVec2 {
    node.box_min + DVec2::new((j & 1) as f64, (j >> 1) as f64) * (0.5 * node.box_size())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::node::NodeId;
    use crate::tree::CountTreeConfig;
    use crate::tree::test_support::beckmann;

    /// A query divides only the pairs of children it needs: dividing one pair alone, or the
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
}
