//! The spine: the single spatial path a query descends before it branches, remembered across
//! queries.
//!
//! Below a footprint much smaller than the texture, Alg. 1 first follows a chain of spatial
//! splits from the root (Eq. 11 splits in space while a node's box is large against the
//! expected footprint): at each level one quarter holds the footprint and the other three are
//! tested and found disjoint. On stained_glass_closeup this chain is ten levels deep and costs
//! 40 of a query's 45 node visits. Neighbouring footprints follow the same chain, so a scratch
//! remembers it per tree and a query whose footprint lies in a remembered node's box starts
//! its breadth-first traversal there.
//!
//! **Why starting there gives the same answer.** A node joins the spine only if it was the
//! only node of its level, split in space, and its one queued child's box held the recording
//! query's footprint strictly inside; nothing had been counted and Eq. 10's scale floor was not
//! set, so the threshold ε·max(count, floor) was 0 and no early stop could happen at that
//! level. A later query may skip the levels above a spine node whose box holds its footprint's
//! bounding box strictly inside, when the footprint is neither within 2⁻⁵⁴ of the texture's
//! edges u = 0 or v = 0 nor narrower than about 2⁻⁴⁰ (below). Then, at every skipped level:
//! - the three other quarters are disjoint by the bounding-box test that
//!   [`crate::Footprint::overlap_box`] makes first: the footprint's bounding box lies strictly
//!   inside the unit square and strictly on one side of each of them, so no integer translate
//!   reaches them. The subtractions round monotonically and a difference of distinct doubles
//!   is not rounded to 0, so min − (a quarter's max) stays above −1 unless that max is 1 and
//!   min is below 2⁻⁵⁴, where min − 1 rounds to −1: such footprints start at the root;
//! - the node on the path meets the footprint only partly, as it did for the recording query,
//!   and splits the same way (the split depends on the node alone). Its box holds the
//!   footprint, so in the footprint's parameters (s, t) its ranges cover [−½, ½] and reach
//!   beyond by an amount of order 1 (a skipped node is at least twice as wide as the box
//!   holding the footprint); with the parameter map's entries at most 2⁴⁰, the rounding of
//!   the separating-axis test stays below 2⁻¹⁰, so it finds neither "disjoint" nor "inside";
//! - its children tested are those the recording query tested: the children with particles of
//!   the pair holding the path, and the other pair's undivided visits (it is disjoint for both
//!   footprints);
//! - the threshold is again 0 (nothing counted, the same number of nodes visited before it,
//!   a footprint below one tile), and so is every decision the level's node takes.
//!
//! So the query visits, counts and returns exactly what the full traversal does (the
//! integration test of remembered answers compares them), and `nodes_visited` includes the
//! skipped levels' visits.

use glam::DVec2;

use super::particles::{Node, quarter_min};
use crate::footprint::{BoxOverlap, Footprint};

/// Trees whose spines a scratch keeps (a scene's materials take turns at a slot).
const SPINE_SLOTS: usize = 4;

/// The largest entry of a footprint's parameter map for which a query may start on the spine:
/// 2⁴⁰, footprints wider than about 10⁻¹² (see the module docs).
const MAX_PARAMETER_MAP: f64 = (1u64 << 40) as f64;

/// One tree's remembered spine.
#[derive(Clone, Debug, Default)]
pub(super) struct Spine {
    tree: u64,
    /// The root, then each node's only queued child while the path held.
    nodes: Vec<Node>,
    /// `visits[j]`: the children tested when `nodes[j]` split (one fewer than `nodes`).
    visits: Vec<u32>,
}

/// The spines of the last trees queried through a scratch.
#[derive(Clone, Debug, Default)]
pub(super) struct Spines {
    slots: Vec<Spine>,
    /// The slot a tree without one takes next (round robin).
    next: usize,
}

impl Spines {
    /// The spine of tree `tree`: its own, or an emptied slot (the one filled longest ago).
    pub(super) fn of(&mut self, tree: u64) -> &mut Spine {
        if self.slots.is_empty() {
            self.slots = vec![Spine::default(); SPINE_SLOTS];
        }
        let slot = match self.slots.iter().position(|spine| spine.tree == tree) {
            Some(slot) => slot,
            None => {
                let slot = self.next;
                self.next = (self.next + 1) % SPINE_SLOTS;
                let spine = &mut self.slots[slot];
                spine.tree = tree;
                spine.nodes.clear();
                spine.visits.clear();
                slot
            }
        };
        &mut self.slots[slot]
    }
}

/// A spine node where a query starts: its level (the nodes above it were skipped) and the
/// nodes visited up to and including it.
#[derive(Clone, Copy, Debug)]
pub(super) struct SpineStart {
    pub(super) level: usize,
    pub(super) node: Node,
    pub(super) visited: u32,
}

impl Spine {
    /// The deepest remembered node below the root whose box holds the footprint's bounding box
    /// `[min, max]` strictly inside, with the nodes a full traversal visits down to it: the
    /// root and the children tested at each level above.
    pub(super) fn start(
        &self,
        (min, max): (DVec2, DVec2),
        parameter_map_bound: f64,
    ) -> Option<SpineStart> {
        // The conditions of the module docs: clear of the edges u = 0 and v = 0 by more than
        // rounding against 1, and not a sliver.
        let clear_of_edges = (min - DVec2::ONE).cmpgt(DVec2::NEG_ONE).all();
        if !(clear_of_edges && parameter_map_bound <= MAX_PARAMETER_MAP) {
            return None;
        }
        let inside = |node: &Node| strictly_inside(min, max, node);
        let level = self.nodes.iter().skip(1).take_while(|n| inside(n)).count();
        (level > 0).then(|| SpineStart {
            level,
            node: self.nodes[level],
            visited: 1 + self.visits[..level].iter().sum::<u32>(),
        })
    }

    /// Whether a full traversal answers the levels above `level` as the spine assumes for
    /// `footprint`: every node on the path meets it partly, and the other quarters of its box
    /// are disjoint from it. Debug builds check this at every start.
    pub(super) fn skipped_levels_hold(&self, level: usize, footprint: &Footprint) -> bool {
        let partly = BoxOverlap {
            inside: 0,
            partial: 1,
        };
        self.nodes.windows(2).take(level).all(|pair| {
            let (node, child) = (&pair[0], &pair[1]);
            footprint.overlap_box(node.box_min, node.box_size()) == partly
                && (0..4).map(|j| quarter_min(node, j)).all(|corner| {
                    corner == child.box_min
                        || footprint
                            .overlap_box(corner, child.box_size())
                            .is_disjoint()
                })
        })
    }

    /// Forgets the nodes below `level`: a query that started at `level` records its own
    /// path on from there. Level 0 starts afresh from `root`.
    pub(super) fn restart_at(&mut self, level: usize, root: &Node) {
        if level == 0 {
            self.nodes.clear();
            self.visits.clear();
            self.nodes.push(*root);
        } else {
            self.nodes.truncate(level + 1);
            self.visits.truncate(level);
        }
    }

    /// Adds `child`, the only child queued when the deepest node split in space with `visits`
    /// children tested, if the recording footprint's bounding box `[min, max]` lies strictly
    /// inside its box; returns whether it did (the path goes on).
    pub(super) fn extend(&mut self, visits: u32, child: &Node, (min, max): (DVec2, DVec2)) -> bool {
        if !strictly_inside(min, max, child) {
            return false;
        }
        self.visits.push(visits);
        self.nodes.push(*child);
        true
    }
}

/// Whether `[min, max]` lies strictly inside the node's box, [box_min, box_min + size]² (its
/// corner computed as [`crate::Footprint::overlap_box`] computes it).
fn strictly_inside(min: DVec2, max: DVec2, node: &Node) -> bool {
    let box_max = node.box_min + DVec2::splat(node.box_size());
    min.cmpgt(node.box_min).all() && max.cmplt(box_max).all()
}

#[cfg(test)]
mod tests {
    use glam::{DMat2, DVec2, DVec3};
    use glint_sphere::SphericalConic;

    use crate::footprint::Footprint;
    use crate::tree::test_support::beckmann;
    use crate::tree::{CountTree, CountTreeConfig, QueryScratch};

    /// Queries through one scratch, which start below the levels of the spine that hold their
    /// footprints, answer exactly as from the root with a fresh scratch: counts, areas, nodes
    /// visited and overlapping, truncation. The footprints are small (a deep spine: N = 10⁸,
    /// planned for 10⁻¹⁰), rotated and sheared; some have bounding boxes on the dyadic lines of
    /// the spine's boxes (where the strictness of the test decides), some lie within rounding
    /// of the texture's edges u = 0 or v = 0, some are slivers. Seven trees take turns at the
    /// scratch's four slots (exact, ε = 0.1, coloured, no cached levels, node budgets of 5, 9
    /// and 50, a depth guard of 12, and a clone, which shares its tree's spine).
    #[test]
    fn queries_started_on_the_spine_answer_as_from_the_root() {
        let config = |seed, epsilon, colour_channels| CountTreeConfig {
            particles: 100_000_000,
            seed,
            epsilon,
            expected_query_area: 1e-10,
            colour_channels,
            ..CountTreeConfig::default()
        };
        let tree = |config| CountTree::new(config, beckmann(0.01)).expect("valid");
        let exact = tree(config(1, 0.0, 0));
        let trees = [
            exact.clone(),
            tree(config(2, 0.1, 0)),
            tree(config(3, 0.1, 3)),
            tree(CountTreeConfig {
                cached_levels: 0,
                node_budget: 50,
                ..config(4, 0.1, 0)
            }),
            tree(CountTreeConfig {
                node_budget: 9,
                max_depth: 12,
                ..config(5, 0.0, 0)
            }),
            tree(CountTreeConfig {
                node_budget: 5,
                ..config(6, 0.1, 0)
            }),
            exact,
        ];
        let wi = DVec3::new(0.1, 0.05, 1.0).normalize();
        let wo = DVec3::new(-0.1, -0.05, 1.0).normalize();
        let conic = SphericalConic::new(wi, wo, 1f64.to_radians()).expect("valid");
        let mut shared = QueryScratch::new();
        let (mut started_deep, mut found) = (0, 0.0);
        let mut uniform = {
            let mut state = 0x9E37_79B9_7F4A_7C15u64;
            move || {
                state = crate::node::mix64(state.wrapping_add(0x9E37_79B9_7F4A_7C15));
                (state >> 11) as f64 / (1u64 << 53) as f64
            }
        };
        let tiny = |e: i32| 2f64.powi(e);
        for i in 0..1400u32 {
            // Edges of about 2e-5, rotated and sheared; every 7th a sliver 1e-13 wide.
            let angle = std::f64::consts::TAU * uniform();
            let (sin, cos) = angle.sin_cos();
            let width = if i % 7 == 6 {
                1e-13
            } else {
                2e-5 * (1.0 + uniform())
            };
            let shear = 0.5 * (uniform() - 0.5);
            let edges = DMat2::from_cols_array(&[cos, sin, -sin, cos])
                * DMat2::from_cols_array(&[2e-5, 0.0, shear * 2e-5, width]);
            let half = 0.5 * (edges.x_axis.abs() + edges.y_axis.abs());
            // Runs of ten queries per tree, around one point per run: most around it (a
            // pixel's samples), some with the bounding box's left edge on the dyadic line of
            // level 2 to 9 just left of it (a spine box's edge), some with its lower edge at
            // 2⁻⁶⁰, 2⁻⁵⁴ or 2⁻⁵³ when the run's point is at the texture's edge v = 0.
            let run = i / 10;
            let base = match run % 3 {
                0 => DVec2::new(0.3 + 0.01 * f64::from(run % 7), 0.6),
                1 => DVec2::new(0.7, 0.2 + 0.01 * f64::from(run % 5)),
                _ => DVec2::new(0.45, 0.0),
            };
            let level = 2 + (i / 3) % 8;
            let line = (base.x * f64::from(1u32 << level)).floor() / f64::from(1u32 << level);
            let edge = [tiny(-60), tiny(-54), tiny(-53)][(i / 3) as usize % 3];
            let near = base + DVec2::splat(half.max_element()) + 1e-4 * uniform();
            let uv = match i % 3 {
                0 => DVec2::new(line + half.x, near.y),
                1 if run % 3 == 2 => DVec2::new(near.x, edge + half.y),
                _ => near,
            };
            let footprint = Footprint::new(uv, edges.x_axis, edges.y_axis).expect("finite");
            let tree = &trees[run as usize % trees.len()];
            let bound = footprint.parameter_map_bound();
            if let Some(start) = shared.spines.of(tree.id).start(footprint.bounds(), bound) {
                started_deep += usize::from(start.level >= 6);
            }
            let warm = tree.query(&footprint, &conic, &mut shared);
            let fresh = tree.query(&footprint, &conic, &mut QueryScratch::new());
            assert_eq!(warm, fresh, "query {i}");
            found += warm.count;
        }
        assert!(started_deep > 100, "{started_deep} queries started deep");
        assert!(found > 0.0, "the queries find particles");
    }
}
