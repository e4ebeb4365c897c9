//! The query: Alg. 1's breadth-first count of the particles in a footprint × conic, with the
//! error criterion of Eq. 10.
//!
//! Breadth first, from the root: a node disjoint from the query in space or direction, or
//! empty, is dropped; a node inside it (multiplicity constant over the box, triangle inside the
//! conic) adds its count; a partial node on which p is near-uniform stops early when
//! √(n·q(1−q)) < ε·count (Eq. 10), adding n·q with q its overlap fraction (under a density
//! map that varies over the box, the map-weighted fraction); a leaf counts its particles one by
//! one; in the dense regime (`super::dense`, on by default) a partial node at the query's scale
//! that holds many particles answers from its rescaled sample, before Eq. 10 is asked; any
//! other node splits. ε = 0 with `DenseCounts::Exact` is exact: the count is then a sum of
//! whole particles, the count in a fixed region is Binomial(N, ·), and counts are additive over
//! disjoint footprints.
//!
//! Footprints wrap around the texture: a particle is counted once per integer translate inside
//! the footprint (see [`crate::footprint`]).
//!
//! The query chooses which nodes to visit, split or estimate, never what they hold: the
//! children and their counts come from the particle set's definition (`super::particles`).

use glam::DVec2;
use glint_sphere::{Classification, SphericalConic};

use super::DenseCounts;
use super::dense::{DenseWork, PartialNode};
use super::particles::{DRAWN_AREAS_DEPTH, LEAF_PARTICLES, Node, quarter_min};
use super::scratch::QueryMemo;
use super::{CountTree, LeafShare, QueryScratch};
use crate::footprint::{BoxOverlap, Footprint};
use crate::ndf::DirectionalCell;

/// At the depth guard, nodes with more particles than this add their expected share instead of
/// being placed one by one (only degenerate queries get there).
const MAX_EXPLICIT_PARTICLES: u64 = 256;

/// Queries that have visited (tested against the query) this many nodes take the expected
/// count as Eq. 10's scale.
const SCALE_AFTER_NODES: u32 = 512;

/// The node budget of a query of `footprint` under the material's `node_budget`: the budget
/// bounds the query's work, not only its nodes. A node test of a footprint spanning T > 4
/// tiles costs about T/4 tests of a small one ([`Footprint::node_test_cost`]), so such a query
/// may visit node_budget·4/T nodes (at least 64). Footprints within four tiles keep the whole
/// budget. (A sliver 10³ tiles long with N = 10¹⁵ and ε = 0 spent 58 s on 10⁶ nodes.)
pub(crate) fn node_budget_for(footprint: &Footprint, node_budget: u32) -> u32 {
    let cost = footprint.node_test_cost();
    if cost <= 1.0 {
        return node_budget;
    }
    let scaled = f64::from(node_budget) / cost;
    (scaled as u32).clamp(node_budget.min(64), node_budget)
}

/// The answer to a query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QueryResult {
    /// Particles found (counted with multiplicity across texture tiles); fractional where ε > 0
    /// let nodes stop early or dense nodes answered from their samples.
    pub count: f64,
    /// D̂ of Eq. 6 per colour channel: count/N without particle areas, else the summed areas of
    /// the particles found (all three channels equal for gray materials).
    pub d_hat: [f64; 3],
    /// Tree nodes visited: every non-empty node tested against the query, as Alg. 1 pops
    /// and tests every child it pushed (disjoint ones included); under the lattice regime,
    /// the lattice's cells drawn (added to the tree's nodes in the band between the two).
    pub nodes_visited: u32,
    /// The visited nodes that meet the query (not proven disjoint from it: the conservative
    /// "partial" answers count): those Alg. 1 counts, splits or estimates rather than
    /// discards. At least 1 unless the footprint is degenerate (then both counts are 0).
    pub nodes_overlapping: u32,
    /// Whether the node budget cut the traversal short (the count is then partly an
    /// expectation, even with ε = 0).
    pub truncated: bool,
    /// Whether the footprint covered more tiles than [`super::CountTreeConfig::many_tiles`] allows
    /// and the count is its periodic average: the area times one whole tile's count.
    pub periodic_average: bool,
}

/// A node waiting in a query's queue, with the query's answers for it: how its box meets the
/// footprint and how its cell meets the conic. Both are computed when the node is created
/// (children of a spatial split share the parent's directional answer, children of a
/// directional split its spatial one), so nodes disjoint from the query never enter the queue.
#[derive(Clone, Copy, Debug)]
pub(super) struct QueuedNode {
    node: Node,
    spatial: BoxOverlap,
    directional: Classification,
}

/// A node's expected contribution per particle to a query, and its variance (Eq. 10).
#[derive(Clone, Copy, Debug)]
struct OverlapShare {
    mean: f64,
    variance: f64,
}

impl OverlapShare {
    /// √(n·Var): the spread of the node's contribution, Eq. 10's √(np(1 − p)).
    fn deviation(&self, particles: u64) -> f64 {
        (particles as f64 * self.variance.max(0.0)).sqrt()
    }
}

impl CountTree {
    /// Counts the particles in `footprint` × `conic` (Alg. 1). The result is finite, ≥ 0 and
    /// deterministic; `scratch` is reused working memory (no allocation once it has grown).
    pub fn query(
        &self,
        footprint: &Footprint,
        conic: &SphericalConic,
        scratch: &mut QueryScratch,
    ) -> QueryResult {
        if footprint.is_degenerate() {
            return self.result(0.0, [0.0; 3], [0, 0], false);
        }
        if self.config.many_tiles.averages(footprint) {
            return self.periodic_average(footprint, conic, scratch);
        }
        if matches!(self.config.dense, DenseCounts::Lattice { .. })
            && let Some(lattice) = self.lattice_answer(footprint, conic, &mut scratch.lattice)
        {
            let cells = [lattice.cells; 2];
            let Some(blend) = lattice.blend else {
                return self.result(lattice.count, [0.0; 3], cells, false);
            };
            // The band between the regimes: the two independent counts' deviations from λ,
            // weighed by 1 − t and t and rescaled to keep the variance (`super::lattice`).
            let tree = self.traverse(footprint, conic, scratch);
            let (t, mean) = (blend.weight, blend.expected);
            let deviation = (1.0 - t) * (tree.count - mean) + t * (lattice.count - mean);
            let count = (mean + deviation / ((1.0 - t).powi(2) + t * t).sqrt()).max(0.0);
            let nodes = [tree.nodes_visited, tree.nodes_overlapping].map(|n| n + lattice.cells);
            return self.result(count, [0.0; 3], nodes, tree.truncated);
        }
        self.traverse(footprint, conic, scratch)
    }

    /// Alg. 1 over the tree, for a footprint that is not degenerate and not averaged.
    fn traverse(
        &self,
        footprint: &Footprint,
        conic: &SphericalConic,
        scratch: &mut QueryScratch,
    ) -> QueryResult {
        let mut count = 0.0;
        let mut area_sums = [0.0; 3];
        let mut visited;
        let mut overlapping = 0u32;
        let mut truncated = false;
        let node_budget = node_budget_for(footprint, self.config.node_budget);
        let QueryScratch {
            queue,
            next_queue,
            cells,
            in_footprint,
            memo,
            spines,
            ..
        } = scratch;
        queue.clear();
        next_queue.clear();
        memo.begin_query();
        // The traversal starts at the root, or below the levels of this tree's spine that
        // hold the footprint (see `super::spine`: the same visits and answers).
        let bounds = footprint.bounds();
        let spine = spines.of(self.id);
        let root = self.root();
        let (first, level) = match spine.start(bounds, footprint.parameter_map_bound()) {
            Some(start) => {
                debug_assert!(spine.skipped_levels_hold(start.level, footprint));
                visited = start.visited;
                overlapping = start.level as u32;
                (start.node, start.level)
            }
            None => {
                visited = 1;
                (root, 0)
            }
        };
        spine.restart_at(level, &root);
        let first = QueuedNode {
            spatial: memo.overlap_box(first.box_min, first.box_level, footprint),
            directional: memo.classify(&first.cell, conic),
            node: first,
        };
        if !first.spatial.is_disjoint() {
            queue.push(first);
        }
        // Whether the levels so far are a single spatial path (the spine goes on).
        let mut on_spine = true;
        // Eq. 10 compares a node's spread with ε times the running count. A footprint of a
        // tile or more finds nothing fully inside for many levels (its wrapped edges cut every
        // coarse box), and a dense query may also run long on a zero count; there the expected
        // total N·A·∫p (what the count converges to) is the scale: from the start for
        // footprints of a tile or more, after SCALE_AFTER_NODES nodes for the others.
        let mut scale_floor = None;
        let dense_scales = self.dense_scales(footprint, conic);
        // Every node in the queue meets the query (disjoint children are dropped when created)
        // and has been counted in `visited`.
        // Breadth first, a level at a time: the queue holds one level while its children
        // gather in the next (the order of a FIFO queue, without copying nodes out of it).
        while !queue.is_empty() {
            let visited_before = visited;
            for queued in queue.iter() {
                overlapping += 1;
                if scale_floor.is_none()
                    && self.config.epsilon > 0.0
                    && (footprint.area() >= 1.0 || visited > SCALE_AFTER_NODES)
                {
                    // Eq. 10's scale: the material's overlap method suffices.
                    let expected =
                        self.expected_count_by(footprint, conic, self.config.overlap, cells);
                    scale_floor = Some(expected);
                }
                let (node, spatial, directional) =
                    (&queued.node, queued.spatial, queued.directional);
                let directions_inside = directional == Classification::TriangleInsideConic;
                if spatial.partial == 0 && directions_inside {
                    let multiplicity = spatial.inside as f64;
                    count += multiplicity * node.count as f64;
                    accumulate(&mut area_sums, self.areas_of(node, memo), multiplicity);
                    continue;
                }
                // The dense regime: a node at the query's scale holding many particles answers
                // from its rescaled sample.
                let varying_map = (spatial.partial > 0)
                    .then_some(self.density_map.as_deref())
                    .flatten()
                    .filter(|map| !map.is_constant_over(node.box_min, node.box_size()));
                let partial = PartialNode {
                    node,
                    spatial,
                    directional,
                    varying_map,
                };
                let work = DenseWork {
                    memo,
                    cells,
                    in_footprint,
                };
                if let Some(sampled) =
                    self.sampled_count(dense_scales, &partial, footprint, conic, work)
                {
                    count += sampled;
                    let share = sampled / node.count as f64;
                    accumulate(&mut area_sums, self.areas_of(node, memo), share);
                    continue;
                }
                // Eq. 10. Its binomial spread needs the fraction of the node's particles in the
                // query: in space they are uniform; in direction the fraction is the overlap's
                // share of the triangle where p is near-uniform (no table entry, the paper's
                // condition), and elsewhere ∫p over the overlap by the table, divided by ∫p over
                // the triangle.
                // Under the dense regime, Eq. 10 waits for the scale floor: a query is long
                // (past SCALE_AFTER_NODES nodes) or its footprint a tile or more. Before that a
                // partial node is resolved or sampled, so that ordinary queries keep the exact
                // counts' statistics (Eq. 10's expectations lowered the dispersion of
                // N = 10¹⁰ pixel queries by a fifth), while long ones still stop early.
                let threshold = match (scale_floor, dense_scales) {
                    (None, Some(_)) => 0.0,
                    (floor, _) => self.config.epsilon * count.max(floor.unwrap_or(0.0)),
                };
                // Off the paper's condition the directional fraction costs a descent of the
                // table: only try when a bound on the spread (Popoviciu: a contribution in
                // [0, hi] has variance ≤ hi²/4) already passes. The descent is only worth it
                // once a query has proved long (the scale floor is active); before that the
                // paper's condition decides, as in Alg. 1.
                // Under a density map that varies over a box the footprint cuts, the node's
                // particles are not uniform over the box: their mean multiplicity is the
                // map-weighted one (`None` where the box spans too many texels to weigh: the
                // node is then split rather than estimated, but at the guards).
                let expected_share = |memo: &mut QueryMemo, cells: &mut Vec<DirectionalCell>| {
                    let directional = if directions_inside {
                        1.0
                    } else {
                        memo.directional_fraction(&node.cell, |memo| {
                            let leaf = LeafShare::SolidAngle(self.config.overlap);
                            self.directional_fraction(node, conic, leaf, cells, memo)
                        })
                    };
                    let multiplicity = varying_map.and_then(|map| {
                        map.mean_multiplicity(footprint, node.box_min, node.box_size())
                    });
                    self.overlap_share(node, footprint, spatial, directional, multiplicity)
                };
                // (A table look-up, so only asked when the threshold is positive.)
                let cheap = || directions_inside || !self.quadrature.has_entry(&node.cell);
                let descend =
                    scale_floor.is_some() && spread_bound(node.count, spatial) < threshold;
                let weighable =
                    varying_map.is_none_or(|map| map.can_weigh(node.box_min, node.box_size()));
                if threshold > 0.0 && weighable && (descend || cheap()) {
                    let share = expected_share(memo, cells);
                    if share.deviation(node.count) < threshold {
                        count += node.count as f64 * share.mean;
                        accumulate(&mut area_sums, self.areas_of(node, memo), share.mean);
                        continue;
                    }
                }
                // Split only if the children's tests keep the visits within budget.
                let over_budget = visited as usize + 4 > node_budget as usize;
                truncated |= over_budget;
                if over_budget
                    || (node.depth >= self.config.max_depth && node.count > MAX_EXPLICIT_PARTICLES)
                {
                    // The work guard, or the depth guard on a crowded node: the expected share.
                    let share = expected_share(memo, cells);
                    count += node.count as f64 * share.mean;
                    accumulate(&mut area_sums, self.areas_of(node, memo), share.mean);
                    continue;
                }
                if node.count <= LEAF_PARTICLES || node.depth >= self.config.max_depth {
                    let (found, areas) = self.count_leaf(
                        node,
                        directional,
                        footprint,
                        conic,
                        memo,
                        in_footprint,
                        self.config.colour_channels,
                    );
                    count += found;
                    accumulate(&mut area_sums, areas, 1.0);
                    continue;
                }
                visited += self.split_into(queued, footprint, conic, memo, next_queue);
            }
            // The level was one node that split in space and queued one child, with nothing
            // counted and the threshold 0: the spine goes on if the child holds the footprint.
            on_spine = on_spine
                && queue.len() == 1
                && next_queue.len() == 1
                && count == 0.0
                && scale_floor.is_none()
                && self.splits_in_space(&queue[0].node)
                && spine.extend(visited - visited_before, &next_queue[0].node, bounds);
            std::mem::swap(queue, next_queue);
            next_queue.clear();
        }
        self.result(count, area_sums, [visited, overlapping], truncated)
    }

    /// Tests the children of `parent` (from the top-level cache when it is in it) against the
    /// query and queues those that meet it, with the answers; returns how many were tested.
    /// Those are the nodes Alg. 1 visits: it would pop the disjoint ones and discard them.
    /// Empty children hold nothing for any query, so they are neither tested nor counted.
    /// A pair of children (0, 1) or (2, 3) that both miss the query is not divided between
    /// them when its division is still to be drawn: then min(total, 2) of them count as
    /// tested (fewer if a child has probability 0; whether one was empty is not drawn).
    fn split_into(
        &self,
        parent: &QueuedNode,
        footprint: &Footprint,
        conic: &SphericalConic,
        memo: &mut QueryMemo,
        queue: &mut Vec<QueuedNode>,
    ) -> u32 {
        let mut tested = 0;
        let node = &parent.node;
        // A cell that holds the conic: its children's answers from the inner edges
        // (`children_of_holder`), instead of four classifications.
        let holds_conic = parent.directional == Classification::ConicInsideTriangle;
        // The query's answers for a child (the box at `box_min` of `box_level`, the cell),
        // the parent's in the dimension the split keeps.
        let answer = |memo: &mut QueryMemo,
                      spatial: bool,
                      box_min: DVec2,
                      box_level: u32,
                      cell: &DirectionalCell| {
            if spatial {
                let overlap = memo.overlap_box(box_min, box_level, footprint);
                (overlap, parent.directional)
            } else {
                (parent.spatial, memo.classify(cell, conic))
            }
        };
        let meets = |(spatial, directional): (BoxOverlap, Classification)| {
            !(spatial.is_disjoint() || directional == Classification::Disjoint)
        };
        let queued =
            |child: Node, (spatial, directional): (BoxOverlap, Classification)| QueuedNode {
                node: child,
                spatial,
                directional,
            };
        // Cached or coloured splits: all four counts are drawn (particle areas need them all,
        // a Dirichlet draw over them).
        let mut all_drawn = |memo: &mut QueryMemo, children: &[Node; 4], spatial: bool| {
            let held = (!spatial && holds_conic)
                .then(|| children_of_holder(conic, &children.map(|child| child.cell)))
                .flatten();
            for (j, child) in children.iter().enumerate().filter(|(_, c)| c.count > 0) {
                tested += 1;
                let answers = match held {
                    Some(held) => (parent.spatial, held[j]),
                    None => answer(memo, spatial, child.box_min, child.box_level, &child.cell),
                };
                if meets(answers) {
                    queue.push(queued(*child, answers));
                }
            }
        };
        if let Some((children, spatial)) = self.top_levels.get(node) {
            all_drawn(memo, children, *spatial);
            return tested;
        }
        let spatial = self.splits_in_space(node);
        if self.config.colour_channels > 0 {
            let mut children = [*node; 4];
            let mut k = 0;
            // The children's areas are drawn when a query counts them (`with_areas`).
            let draw_areas = node.depth + 1 >= DRAWN_AREAS_DEPTH;
            self.emit_children_drawing(node, draw_areas, Some(memo), |child| {
                children[k] = child;
                k += 1;
            });
            all_drawn(memo, &children, spatial);
            return tested;
        }
        let split = (!spatial).then(|| self.directional_split(&node.cell));
        let split = split.as_deref();
        let held = split
            .filter(|_| holds_conic)
            .and_then(|split| children_of_holder(conic, &split.children));
        let remembered = memo.remembered_counts(self, node);
        // Whether this split draws anything the memo does not hold yet.
        let mut drawn = remembered.is_none();
        let mut counts = remembered.unwrap_or_else(|| self.split_counts(node, split));
        for pair in 0..2 {
            if counts.totals[pair] == 0 {
                continue;
            }
            let children = [2 * pair, 2 * pair + 1];
            let pair_answers = children.map(|j| match split {
                None => answer(
                    memo,
                    true,
                    quarter_min(node, j),
                    node.box_level + 1,
                    &node.cell,
                ),
                Some(split) => match held {
                    Some(held) => (parent.spatial, held[j]),
                    None => answer(
                        memo,
                        false,
                        node.box_min,
                        node.box_level,
                        &split.children[j],
                    ),
                },
            });
            if !(meets(pair_answers[0]) || meets(pair_answers[1])) {
                tested += counts.undivided_visits(pair);
                continue;
            }
            drawn |= counts.is_pending(pair);
            let divided = counts.divide(pair);
            for i in 0..2 {
                if divided[i] > 0 {
                    tested += 1;
                    if meets(pair_answers[i]) {
                        let child = self.child(node, split, children[i], divided[i]);
                        queue.push(queued(child, pair_answers[i]));
                    }
                }
            }
        }
        if drawn {
            memo.remember_counts(self, node, counts);
        }
        tested
    }

    /// The node's particle areas (drawn now if its split left them undrawn); unused without
    /// colour channels.
    fn areas_of(&self, node: &Node, memo: &mut QueryMemo) -> [f64; 3] {
        if self.config.colour_channels > 0 {
            self.with_areas(node, memo).areas
        } else {
            node.areas
        }
    }

    fn result(
        &self,
        count: f64,
        area_sums: [f64; 3],
        [nodes_visited, nodes_overlapping]: [u32; 2],
        truncated: bool,
    ) -> QueryResult {
        let d_hat = match self.config.colour_channels {
            0 => [count / self.config.particles as f64; 3],
            1 => [area_sums[0]; 3],
            _ => area_sums,
        };
        QueryResult {
            count,
            d_hat,
            nodes_visited,
            nodes_overlapping,
            truncated,
            periodic_average: false,
        }
    }

    /// The count of a footprint over many tiles by its periodic average (see [`super::ManyTiles`]):
    /// its area times the count of one whole tile, where every particle has multiplicity 1.
    fn periodic_average(
        &self,
        footprint: &Footprint,
        conic: &SphericalConic,
        scratch: &mut QueryScratch,
    ) -> QueryResult {
        let tile = Footprint::new(DVec2::splat(0.5), DVec2::X, DVec2::Y)
            .expect("the unit square is a finite footprint");
        let one = self.query(&tile, conic, scratch);
        let area = footprint.area();
        QueryResult {
            count: one.count * area,
            d_hat: one.d_hat.map(|d| d * area),
            periodic_average: true,
            ..one
        }
    }

    /// The share of `node`'s particles whose normals lie in the conic: the overlap's share of
    /// the triangle by `leaf` where Alg. 2's table has no entry, else ∫p over the overlap by
    /// the table divided by ∫p over the triangle.
    pub(super) fn directional_fraction(
        &self,
        node: &Node,
        conic: &SphericalConic,
        leaf: LeafShare,
        cells: &mut Vec<DirectionalCell>,
        memo: &mut QueryMemo,
    ) -> f64 {
        if let (Some(t), false) = (&node.cell.triangle, self.quadrature.has_entry(&node.cell)) {
            return self.leaf_share(t, node.solid_angle, conic, leaf);
        }
        let inside = self.integral_over_conic_within(&node.cell, conic, leaf, cells, Some(memo));
        let total = self.quadrature.integral_with_solid_angle(
            &node.cell,
            node.solid_angle,
            self.density.as_ref(),
        );
        if total > 0.0 {
            (inside / total).clamp(0.0, 1.0)
        } else {
            0.0
        }
    }

    /// The expected contribution per particle of `node` and the bound on its variance, given
    /// the share `directional` of its normals in the conic and, under a density map that
    /// varies over the box, the particles' `weighted` mean multiplicity (else the box's mean,
    /// its overlap area over its area).
    fn overlap_share(
        &self,
        node: &Node,
        footprint: &Footprint,
        spatial: BoxOverlap,
        directional: f64,
        weighted: Option<f64>,
    ) -> OverlapShare {
        let box_size = node.box_size();
        let multiplicity = match weighted {
            _ if spatial.partial == 0 => spatial.inside as f64,
            Some(multiplicity) => multiplicity,
            None => footprint.overlap_area(node.box_min, box_size) / (box_size * box_size),
        };
        // A particle contributes m(x)·[normal in the conic]: m ∈ [inside, inside + partial] has
        // mean m̄ and (Bhatia–Davis) variance ≤ (m̄ − inside)(inside + partial − m̄); with the
        // independent Bernoulli(d) of its normal, Var = d·Var(m) + m̄²·d(1 − d). For one tile
        // (inside 0, partial 1) this is q(1 − q) with q = m̄·d, Eq. 10's binomial variance.
        let (low, high) = (
            spatial.inside as f64,
            (spatial.inside + spatial.partial) as f64,
        );
        let multiplicity = multiplicity.clamp(low, high);
        let spread = (multiplicity - low) * (high - multiplicity);
        OverlapShare {
            mean: multiplicity * directional,
            variance: directional * spread
                + multiplicity * multiplicity * directional * (1.0 - directional),
        }
    }
}

/// How `conic` meets the four children `cells` of a cell that holds it
/// ([`SphericalConic::classify_children_of_holder`]), if the inner edges settle it.
fn children_of_holder(
    conic: &SphericalConic,
    cells: &[DirectionalCell; 4],
) -> Option<[Classification; 4]> {
    let [a, b, c, d] = cells.each_ref().map(|cell| cell.triangle);
    conic.classify_children_of_holder(&[a?, b?, c?, d?])
}

/// An upper bound on Eq. 10's spread √(n·Var) that needs no overlap computation: a particle
/// contributes m(x)·[normal in the conic] ∈ [0, hi], so Var ≤ hi²/4 (Popoviciu).
fn spread_bound(particles: u64, spatial: BoxOverlap) -> f64 {
    let high = (spatial.inside + spatial.partial) as f64;
    0.5 * high * (particles as f64).sqrt()
}

/// sums += factor · areas, per channel.
fn accumulate(sums: &mut [f64; 3], areas: [f64; 3], factor: f64) {
    for (sum, area) in sums.iter_mut().zip(areas) {
        *sum += factor * area;
    }
}
