//! The particle set: what particles a material has (Jakob et al. 2014, Sec. 3.3–3.4).
//!
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
//! three: the pairs' totals, then each pair's division). A node with at most
//! [`LEAF_PARTICLES`] particles, or at the depth guard, is a *leaf*: its particles are placed
//! explicitly, each from its own stream, uniformly in the box and, in direction, by the same
//! law the splits follow (one particle descends the directional hierarchy with the split
//! probabilities, then lands uniformly in a small near-uniform triangle). Nothing here depends
//! on a query, so every query sees the same particles: overlapping queries agree on their
//! overlap, and repeated queries are bit-identical in any thread and order.
//!
//! **Value stability.** This module and its parts define the particles: which stream (node
//! identity and purpose) and which draw of it every random choice takes, and in what order;
//! Eq. 11's choice; which splits are drawn pair by pair; the leaf size, the sub-boxes and the
//! final cells of the normals' descent. Change any of them and every material's particles
//! move, and with them every count and every image. Keep them value-stable: the query, the
//! memo and the law only read what is defined here.
//!
//! - `split`: Eq. 11's choice between a spatial and a directional split, and the children's
//!   counts (multinomial draws, exact splits pair by pair).
//! - `leaf`: a leaf's particles, placed one by one (sub-box, position, area shares).
//! - `descent`: a leaf particle's normal, by inversion down the directional hierarchy.

use glam::DVec2;

use crate::ndf::DirectionalCell;
use crate::node::NodeId;
use crate::tea::TeaRng;
use crate::tree::CountTree;

mod descent;
mod leaf;
mod split;

pub(super) use descent::DescentStep;
pub use descent::LEAF_CELL_ARC;
pub(super) use descent::LEAF_CELL_CHORD;
pub use leaf::LEAF_PARTICLES;
pub(super) use leaf::{LeafDraws, LeafParticle};
pub(super) use split::{PairCounts, quarter_min};

/// Stream purposes: separate streams of one node.
const PURPOSE_SPLIT: u32 = 0;
const PURPOSE_AREA: u32 = 1; // + channel
const PURPOSE_LEAF_SUB_BOXES: u32 = 4; // after the area channels (at most 3)
const PURPOSE_PAIR: u32 = 5; // + pair (0 or 1): the division of an exact split's pair
const PURPOSE_LEAF: u32 = 16; // + particle index

/// The areas of a coloured node whose split has not drawn them (see
/// `CountTree::with_areas`).
pub(super) const UNDRAWN_AREAS: [f64; 3] = [f64::NAN; 3];

/// Queries leave the areas of coloured children undrawn above this depth, where labels are
/// exact (to depth 62) and so hold the path that `CountTree::with_areas` retraces.
pub(super) const DRAWN_AREAS_DEPTH: u32 = 60;

/// A node of the tree during a query.
#[derive(Clone, Copy, Debug)]
pub(super) struct Node {
    pub(super) id: NodeId,
    pub(super) count: u64,
    pub(super) box_min: DVec2,
    /// Spatial splits so far: the box's side is 2^−level.
    pub(super) box_level: u32,
    pub(super) cell: DirectionalCell,
    pub(super) solid_angle: f64,
    pub(super) depth: u32,
    /// The node's share of each channel's total particle area (1 at the root).
    pub(super) areas: [f64; 3],
}

impl Node {
    /// The box's side, 2^−level (exact: a power of two built from its exponent bits).
    #[inline]
    pub(super) fn box_size(&self) -> f64 {
        box_size_at(self.box_level)
    }
}

/// The side of a box at `level`, 2^−level (exact: a power of two built from its exponent bits).
#[inline]
pub(super) fn box_size_at(level: u32) -> f64 {
    debug_assert!(level < 1000);
    f64::from_bits((1023 - u64::from(level)) << 52)
}

impl CountTree {
    /// The TEA stream of node `id` for `purpose` (one of the purposes above).
    fn stream(&self, id: NodeId, purpose: u32) -> TeaRng {
        TeaRng::new(id.key(self.config.seed), purpose, self.config.tea_rounds)
    }

    /// The root node.
    pub(super) fn root(&self) -> Node {
        Node {
            id: NodeId::ROOT,
            count: self.root_particles,
            box_min: DVec2::ZERO,
            box_level: 0,
            cell: DirectionalCell::HEMISPHERE,
            solid_angle: DirectionalCell::HEMISPHERE.solid_angle(),
            depth: 0,
            // The share of N's particle area the root holds (1 without a density map).
            areas: [self.root_particles as f64 / self.config.particles as f64; 3],
        }
    }
}
