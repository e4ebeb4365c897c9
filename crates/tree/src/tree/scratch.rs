//! A query's reusable working memory: [`QueryScratch`], which holds Alg. 1's breadth-first
//! queues, the stack of the directional integrals, a leaf's particles in the footprint, and
//! [`QueryMemo`], the answers that recur within a query (conic classifications, box overlaps)
//! and the directional split probabilities that recur across queries.
//!
//! Nothing here changes an answer: a remembered answer is the one computed afresh, so a query
//! gives the same result with a new scratch or one reused across queries and materials.

use glam::DVec2;
use glint_sphere::{Classification, SphericalConic};

use super::CountTree;
use super::lattice::LatticeScratch;
use super::particles::{LeafDraws, LeafParticle, Node, PairCounts, box_size_at};
use super::query::QueuedNode;
use super::spine::Spines;
use crate::footprint::{BoxOverlap, Footprint};
use crate::ndf::DirectionalCell;
use crate::node::NodeId;

/// Reusable working memory of queries: keep one per thread, and queries do not allocate. Its
/// first query allocates 809 KB of memo tables (answers that recur within a query, and split
/// probabilities, split counts, coloured nodes' areas and leaves' particle positions and
/// normals that recur across queries, of any material: one scratch serves them all), its
/// first lattice query 45 KB more (the lattice's slope squares, `super::lattice`), and it
/// keeps the spines of the last four trees queried (`super::spine`: the spatial path from the
/// root their queries share).
#[derive(Debug, Default)]
pub struct QueryScratch {
    pub(super) queue: Vec<QueuedNode>,
    pub(super) next_queue: Vec<QueuedNode>,
    pub(super) cells: Vec<DirectionalCell>,
    pub(super) in_footprint: Vec<LeafParticle>,
    pub(super) memo: QueryMemo,
    pub(super) spines: Spines,
    pub(super) lattice: LatticeScratch,
}

impl QueryScratch {
    /// Empty scratch space (it grows to the largest query's needs, then stays).
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }
}

/// Answers that recur within one query, memoized. The leaves and directional splits of
/// different boxes share one directional hierarchy, and the spatial splits of different cells
/// one hierarchy of boxes, so a query meets the same cells and boxes again. Both tables are
/// direct-mapped; a generation count tells this query's entries from earlier ones', so a query
/// starts without clearing.
///
/// It also keeps, across queries, the split probabilities of the directional cells below the
/// material's table of splits that leaf particles descend through: a material's queries keep
/// meeting the same few of those cells, whose solid angles and density values cost more than
/// the rest of the descent step. And it keeps the split counts of the nodes below the tree's
/// cached top levels (with the pair divisions drawn): a pixel's samples and its neighbours'
/// descend through the same nodes, whose binomial draws cost more than the rest of a split.
/// And it keeps the leaves those queries meet, with their particles' sub-box codes, the
/// positions drawn so far (each costs a TEA draw, and most leaves a query meets hold no
/// particle of its footprint) and the normals descended so far; and coloured nodes' drawn
/// areas (gamma draws per split on the way down).
#[derive(Debug, Default)]
pub(super) struct QueryMemo {
    classifications: Vec<ClassificationEntry>,
    fractions: Vec<FractionEntry>,
    with_areas: Vec<NodeEntry>,
    boxes: Vec<BoxEntry>,
    generation: u32,
    splits: Vec<SplitEntry>,
    counts: Vec<CountsEntry>,
    leaves: Vec<LeafEntry>,
}

/// A leaf (its identity) of a tree (the tree's identity) with what queries have drawn of its
/// particles (sub-box codes, positions, normals).
#[derive(Clone, Copy, Debug)]
struct LeafEntry {
    tree: u64,
    id: NodeId,
    draws: Option<LeafDraws>,
}

/// A node's split counts (its identity) in a tree (the tree's identity), with the pair
/// divisions drawn so far.
#[derive(Clone, Copy, Debug)]
struct CountsEntry {
    tree: u64,
    id: NodeId,
    counts: Option<PairCounts>,
}

/// The split probabilities of a directional cell (its label) of a tree (its identity).
#[derive(Clone, Copy, Debug)]
struct SplitEntry {
    tree: u64,
    label: u64,
    probabilities: [f64; 4],
}

/// A cell's label and how the query's conic meets the cell.
#[derive(Clone, Copy, Debug)]
struct ClassificationEntry {
    label: u64,
    generation: u32,
    answer: Classification,
}

/// A cell's label and the share of the particles' normals in the cell that lie in the query's
/// conic (Eq. 10's directional fraction).
#[derive(Clone, Copy, Debug)]
struct FractionEntry {
    label: u64,
    generation: u32,
    fraction: f64,
}

/// A coloured node of a tree (the tree's identity) with its particle areas drawn (see
/// `CountTree::with_areas`).
#[derive(Clone, Copy, Debug)]
struct NodeEntry {
    tree: u64,
    node: Option<Node>,
}

/// A box (its corner's bits and its level) and how the query's footprint meets it.
#[derive(Clone, Copy, Debug)]
struct BoxEntry {
    corner: [u64; 2],
    level: u32,
    generation: u32,
    answer: BoxOverlap,
}

/// log₂ of the entries of the classification table (512, 8 KB), the fraction table (256,
/// 6 KB) and the box table (256, 10 KB).
const CLASSIFICATION_MEMO_BITS: u32 = 9;
const FRACTION_MEMO_BITS: u32 = 8;
/// log₂ of the entries of the table of coloured nodes with drawn areas (512, 98 KB).
const AREAS_MEMO_BITS: u32 = 9;
const BOX_MEMO_BITS: u32 = 8;

/// log₂ of the entries of the split table (1024, 48 KB).
const SPLIT_MEMO_BITS: u32 = 10;
/// log₂ of the entries of the table of split counts (2048, 295 KB).
const COUNTS_MEMO_BITS: u32 = 11;

/// log₂ of the entries of the table of leaves' particle positions and normals (256, 340 KB).
const LEAVES_MEMO_BITS: u32 = 8;

/// The slot of node `id` of tree `tree` in a table of 2^`bits` entries.
#[inline]
fn node_slot(tree: u64, id: NodeId, bits: u32) -> usize {
    memo_slot(
        id.0 as u64 ^ (id.0 >> 64) as u64 ^ tree.rotate_left(47),
        bits,
    )
}

/// The slot of a 64-bit key in a table of 2^`bits` entries (Fibonacci hashing).
#[inline]
pub(super) fn memo_slot(key: u64, bits: u32) -> usize {
    (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> (64 - bits)) as usize
}

impl QueryMemo {
    const NO_CLASSIFICATION: ClassificationEntry = ClassificationEntry {
        label: 0,
        generation: 0,
        answer: Classification::Partial,
    };
    const NO_FRACTION: FractionEntry = FractionEntry {
        label: 0,
        generation: 0,
        fraction: 0.0,
    };
    const NO_NODE: NodeEntry = NodeEntry {
        tree: 0,
        node: None,
    };
    const NO_BOX: BoxEntry = BoxEntry {
        corner: [0; 2],
        level: 0,
        generation: 0,
        answer: BoxOverlap {
            inside: 0,
            partial: 0,
        },
    };

    const NO_SPLIT: SplitEntry = SplitEntry {
        tree: 0,
        label: 0,
        probabilities: [0.0; 4],
    };

    const NO_COUNTS: CountsEntry = CountsEntry {
        tree: 0,
        id: NodeId(0),
        counts: None,
    };

    const NO_LEAF: LeafEntry = LeafEntry {
        tree: 0,
        id: NodeId(0),
        draws: None,
    };

    /// Forgets the previous query's answers (allocates the tables on first use).
    pub(super) fn begin_query(&mut self) {
        if self.classifications.is_empty() {
            self.classifications = vec![Self::NO_CLASSIFICATION; 1 << CLASSIFICATION_MEMO_BITS];
            self.fractions = vec![Self::NO_FRACTION; 1 << FRACTION_MEMO_BITS];
            self.with_areas = vec![Self::NO_NODE; 1 << AREAS_MEMO_BITS];
            self.boxes = vec![Self::NO_BOX; 1 << BOX_MEMO_BITS];
            self.splits = vec![Self::NO_SPLIT; 1 << SPLIT_MEMO_BITS];
            self.counts = vec![Self::NO_COUNTS; 1 << COUNTS_MEMO_BITS];
            self.leaves = vec![Self::NO_LEAF; 1 << LEAVES_MEMO_BITS];
        }
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            // After 2³² queries: entries of generation 0 are never current.
            self.classifications.fill(Self::NO_CLASSIFICATION);
            self.fractions.fill(Self::NO_FRACTION);
            self.boxes.fill(Self::NO_BOX);
            self.generation = 1;
        }
    }

    /// How the query's `conic` meets `cell` (the whole hemisphere always partially): the
    /// memoized answer if this query has classified the cell before.
    #[inline]
    pub(super) fn classify(
        &mut self,
        cell: &DirectionalCell,
        conic: &SphericalConic,
    ) -> Classification {
        let Some(triangle) = &cell.triangle else {
            return Classification::Partial;
        };
        // Labels name cells uniquely to this depth (deeper ones share a saturated label).
        if cell.depth >= DirectionalCell::MAX_LABELLED_DEPTH {
            return conic.classify(triangle);
        }
        let entry = &mut self.classifications[memo_slot(cell.label, CLASSIFICATION_MEMO_BITS)];
        if entry.generation == self.generation && entry.label == cell.label {
            return entry.answer;
        }
        let answer = conic.classify(triangle);
        *entry = ClassificationEntry {
            label: cell.label,
            generation: self.generation,
            answer,
        };
        answer
    }

    /// The share of the normals in `cell` that lie in the query's conic, from `compute`: the
    /// memoized answer if this query has computed it for the cell before (the children of a
    /// spatial split share their parent's cell, and so its fraction).
    #[inline]
    pub(super) fn directional_fraction(
        &mut self,
        cell: &DirectionalCell,
        compute: impl FnOnce(&mut Self) -> f64,
    ) -> f64 {
        self.fraction_by_key(cell, 0, compute)
    }

    /// [`QueryMemo::directional_fraction`] by the dense regime's rule (p linear across the
    /// table's leaf cells), memoized apart from it.
    #[inline]
    pub(super) fn dense_conic_share(
        &mut self,
        cell: &DirectionalCell,
        compute: impl FnOnce(&mut Self) -> f64,
    ) -> f64 {
        self.fraction_by_key(cell, 1 << 63, compute)
    }

    /// Memoized by the cell's label with `rule` in its top bit (labels stay below 2⁶³).
    #[inline]
    fn fraction_by_key(
        &mut self,
        cell: &DirectionalCell,
        rule: u64,
        compute: impl FnOnce(&mut Self) -> f64,
    ) -> f64 {
        // Labels name cells uniquely to this depth (deeper ones share a saturated label).
        if cell.depth >= DirectionalCell::MAX_LABELLED_DEPTH {
            return compute(self);
        }
        let key = cell.label | rule;
        let slot = memo_slot(key, FRACTION_MEMO_BITS);
        let entry = self.fractions[slot];
        if entry.generation == self.generation && entry.label == key {
            return entry.fraction;
        }
        let fraction = compute(self);
        self.fractions[slot] = FractionEntry {
            label: key,
            generation: self.generation,
            fraction,
        };
        fraction
    }

    /// Node `id` of `tree` with its areas drawn, if a query has drawn them (a query's counted
    /// nodes share most of their ancestors, and a pixel's samples count the same nodes).
    #[inline]
    pub(super) fn node_with_areas(&self, tree: &CountTree, id: NodeId) -> Option<Node> {
        let entry = self
            .with_areas
            .get(node_slot(tree.id, id, AREAS_MEMO_BITS))?;
        entry
            .node
            .filter(|node| entry.tree == tree.id && node.id == id)
    }

    /// Remembers `node` of `tree`, whose areas are drawn.
    #[inline]
    pub(super) fn remember_with_areas(&mut self, tree: &CountTree, node: Node) {
        let slot = node_slot(tree.id, node.id, AREAS_MEMO_BITS);
        if let Some(entry) = self.with_areas.get_mut(slot) {
            *entry = NodeEntry {
                tree: tree.id,
                node: Some(node),
            };
        }
    }

    /// How the query's `footprint` meets the box at `box_min` of side 2^−`box_level`: the
    /// memoized answer if this query has tested the box before.
    #[inline]
    pub(super) fn overlap_box(
        &mut self,
        box_min: DVec2,
        box_level: u32,
        footprint: &Footprint,
    ) -> BoxOverlap {
        let corner = [box_min.x.to_bits(), box_min.y.to_bits()];
        let key = corner[0] ^ corner[1].rotate_left(29) ^ u64::from(box_level);
        let entry = &mut self.boxes[memo_slot(key, BOX_MEMO_BITS)];
        if entry.generation == self.generation && entry.corner == corner && entry.level == box_level
        {
            return entry.answer;
        }
        let answer = footprint.overlap_box(box_min, box_size_at(box_level));
        *entry = BoxEntry {
            corner,
            level: box_level,
            generation: self.generation,
            answer,
        };
        answer
    }

    /// The split counts of `node` in `tree` as an earlier query left them (with the pair
    /// divisions it drew), if they are still remembered. Neighbouring pixels' queries, and a
    /// pixel's samples, descend through the same nodes.
    #[inline]
    pub(super) fn remembered_counts(&self, tree: &CountTree, node: &Node) -> Option<PairCounts> {
        let entry = self
            .counts
            .get(node_slot(tree.id, node.id, COUNTS_MEMO_BITS))?;
        entry
            .counts
            .filter(|_| entry.tree == tree.id && entry.id == node.id)
    }

    /// Remembers `counts`, the split counts of `node` in `tree`, for later queries.
    #[inline]
    pub(super) fn remember_counts(&mut self, tree: &CountTree, node: &Node, counts: PairCounts) {
        if let Some(entry) = self
            .counts
            .get_mut(node_slot(tree.id, node.id, COUNTS_MEMO_BITS))
        {
            *entry = CountsEntry {
                tree: tree.id,
                id: node.id,
                counts: Some(counts),
            };
        }
    }

    /// What queries have drawn of the particles of `leaf` in `tree` (sub-box codes, positions,
    /// normals), marked as met again, or, when it is not remembered, an entry that `start`
    /// begins afresh (it takes the codes only): a pixel's samples and its neighbours' meet the
    /// same leaves. The caller adds what it draws.
    #[inline]
    pub(super) fn leaf_draws(
        &mut self,
        tree: &CountTree,
        leaf: &Node,
        start: impl FnOnce(&mut LeafDraws),
    ) -> &mut LeafDraws {
        let entry = &mut self.leaves[node_slot(tree.id, leaf.id, LEAVES_MEMO_BITS)];
        let met_again = entry.tree == tree.id && entry.id == leaf.id && entry.draws.is_some();
        entry.tree = tree.id;
        entry.id = leaf.id;
        // The slot's earlier leaf is overwritten in place (its 1.3 KB are not cleared).
        let draws = entry.draws.get_or_insert(LeafDraws::EMPTY);
        if met_again {
            draws.met_again = true;
        } else {
            start(draws);
        }
        draws
    }

    /// What queries have drawn of the particles of `leaf` in `tree`, if it is remembered.
    #[inline]
    pub(super) fn remembered_leaf(
        &mut self,
        tree: &CountTree,
        leaf: &Node,
    ) -> Option<&mut LeafDraws> {
        let entry = &mut self.leaves[node_slot(tree.id, leaf.id, LEAVES_MEMO_BITS)];
        if entry.tree == tree.id && entry.id == leaf.id {
            entry.draws.as_mut()
        } else {
            None
        }
    }

    /// The split probabilities of `cell` (whose `children` the caller has) in `tree`, for a
    /// cell outside the tree's table of splits: remembered from an earlier query, or computed
    /// (and remembered) as [`DirectionalSplit::of`] computes them.
    ///
    /// [`DirectionalSplit::of`]: crate::ndf::DirectionalSplit::of
    pub(super) fn split_probabilities(
        &mut self,
        tree: &CountTree,
        cell: &DirectionalCell,
        children: &[DirectionalCell; 4],
    ) -> [f64; 4] {
        let compute = || {
            let solid_angles = children.map(|c| c.solid_angle());
            tree.quadrature
                .split_probabilities(children, &solid_angles, tree.density.as_ref())
        };
        // Labels name cells uniquely to this depth (deeper ones share a saturated label).
        if cell.depth >= DirectionalCell::MAX_LABELLED_DEPTH {
            return compute();
        }
        let key = cell.label ^ tree.id.rotate_left(47);
        // The table's size (a power of two: 2^SPLIT_MEMO_BITS, smaller in a test).
        let bits = self.splits.len().trailing_zeros();
        let entry = &mut self.splits[memo_slot(key, bits)];
        if entry.tree == tree.id && entry.label == cell.label {
            return entry.probabilities;
        }
        let probabilities = compute();
        *entry = SplitEntry {
            tree: tree.id,
            label: cell.label,
            probabilities,
        };
        probabilities
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::ndf::DirectionalSplit;
    use crate::node::NodeId;
    use crate::tree::CountTreeConfig;
    use crate::tree::particles::Node;
    use crate::tree::test_support::{beckmann, classify_cell};

    #[test]
    fn the_memo_answers_as_the_conic_does_across_queries() {
        // The 1365 cells above depth 6 share 512 slots; each query has its own conic; the
        // generation count wraps during the run.
        let mut cells = vec![DirectionalCell::HEMISPHERE];
        let mut level = cells.clone();
        for _ in 0..5 {
            level = level.iter().flat_map(DirectionalCell::children).collect();
            cells.extend_from_slice(&level);
        }
        let mut memo = QueryMemo::default();
        memo.begin_query();
        memo.generation = u32::MAX - 3;
        let mut answers = [0usize; 4];
        for query in 0..8 {
            memo.begin_query();
            let angle = 0.2 * f64::from(query);
            let wi = DVec3::new(angle.sin(), 0.1, angle.cos()).normalize();
            let wo = DVec3::new(-0.3, angle.cos(), 1.0).normalize();
            let conic =
                SphericalConic::new(wi, wo, 0.05 + 0.1 * f64::from(query)).expect("valid conic");
            for _ in 0..2 {
                for cell in &cells {
                    let answer = memo.classify(cell, &conic);
                    assert_eq!(answer, classify_cell(cell, &conic), "query {query}");
                    answers[answer as usize] += 1;
                }
            }
        }
        assert!(answers.iter().all(|&n| n > 0), "{answers:?}");
    }

    #[test]
    fn the_memo_answers_as_the_footprint_does_across_queries() {
        // The 1365 boxes of levels 0 to 5 share 256 slots; each query has its own footprint
        // (a pixel, one reaching across a texture edge, several tiles).
        let mut boxes = Vec::new();
        for level in 0..6u32 {
            let side = 1u32 << level;
            for iy in 0..side {
                for ix in 0..side {
                    let size = 1.0 / f64::from(side);
                    boxes.push(Node {
                        id: NodeId::ROOT,
                        count: 1,
                        box_min: DVec2::new(f64::from(ix), f64::from(iy)) * size,
                        box_level: level,
                        cell: DirectionalCell::HEMISPHERE,
                        solid_angle: 1.0,
                        depth: level,
                        areas: [0.0; 3],
                    });
                }
            }
        }
        let footprints = [
            ([0.3, 0.4], [0.01, 0.002], [-0.003, 0.02]),
            ([0.99, 0.02], [0.1, 0.03], [0.02, 0.2]),
            ([5.5, -3.2], [2.3, 0.7], [-0.5, 1.9]),
        ]
        .map(|(c, dx, dy)| {
            Footprint::new(DVec2::from(c), DVec2::from(dx), DVec2::from(dy)).expect("finite")
        });
        let mut memo = QueryMemo::default();
        memo.begin_query();
        memo.generation = u32::MAX - 2;
        let mut resolved = [0usize; 3];
        for query in 0..6 {
            memo.begin_query();
            let footprint = &footprints[query % 3];
            for _ in 0..2 {
                for node in &boxes {
                    let answer = memo.overlap_box(node.box_min, node.box_level, footprint);
                    assert_eq!(
                        answer,
                        footprint.overlap_box(node.box_min, node.box_size()),
                        "query {query}"
                    );
                    resolved[usize::from(answer.inside > 0) + usize::from(answer.partial > 0)] += 1;
                }
            }
        }
        assert!(resolved.iter().all(|&n| n > 0), "{resolved:?}");
    }

    #[test]
    fn remembered_split_probabilities_are_the_trees_own() {
        // Sixteen materials share one memo (as one scratch serves every material of a scene):
        // the 4096 cells of depth 6 of each, twice over, in the full table and in one of two
        // slots, where materials meet under one label all the time.
        let trees: Vec<CountTree> = (0..16)
            .map(|k| {
                let alpha = 0.05 + 0.05 * f64::from(k);
                CountTree::new(CountTreeConfig::default(), beckmann(alpha)).expect("valid")
            })
            .collect();
        let mut cells = vec![DirectionalCell::HEMISPHERE];
        for _ in 0..6 {
            cells = cells.iter().flat_map(DirectionalCell::children).collect();
        }
        let mut memo = QueryMemo::default();
        memo.begin_query();
        for slots in [1 << SPLIT_MEMO_BITS, 2] {
            memo.splits = vec![QueryMemo::NO_SPLIT; slots];
            for cell in cells.iter().chain(&cells) {
                for tree in &trees {
                    let expected =
                        DirectionalSplit::of(cell, &tree.quadrature, tree.density.as_ref());
                    let remembered = memo.split_probabilities(tree, cell, &cell.children());
                    assert_eq!(remembered, expected.probabilities, "cell {}", cell.label);
                }
            }
        }
    }
}
