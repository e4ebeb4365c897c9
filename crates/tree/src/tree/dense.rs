//! The dense regime: a node that the query meets in part, holds many particles and is not much
//! larger than the query is answered from a small sample of its law, rescaled so that the
//! count keeps the exact counts' mean and covariances, instead of being split down to its
//! particles.
//!
//! # The rescaled sample
//! The tree is a hierarchical sampler of independent particles: given a node's count n, its
//! particles are n independent points of the node's law ν (positions over the box by the
//! density map, normals over the cell by p). For any query region R, the exact count
//! X(R) = Σᵢ 1[xᵢ ∈ R] (with multiplicity across tiles) then has, given n,
//!
//! ```text
//!   E X(R) = n·ν(R),    Cov(X(R), X(R′)) = n·(ν(R ∩ R′) − ν(R)·ν(R′)).
//! ```
//!
//! The node's *virtual sample* is M = [`VIRTUAL_PARTICLES`] points of the same law, placed
//! exactly as a leaf places its particles (the node's own leaf streams, which a node of more
//! than [`super::LEAF_PARTICLES`] particles uses for nothing else above the depth guard), and
//! so the same for every query. With k(R)
//! the sample's points in R and w = n/M, the node contributes
//!
//! ```text
//!   Y(R) = √w·k(R) + (n − √(n·M))·ν(R)          (= n·ν(R) + √w·(k(R) − M·ν(R)))
//! ```
//!
//! whose mean is n·ν(R) and whose covariance is w·M·(ν(R ∩ R′) − ν(R)ν(R′)), the exact one,
//! for every pair of regions that both answer the node from its sample: the same footprint
//! moved by part of its width, a neighbouring footprint (disjoint parts of one node are
//! negatively correlated, as exact counts are), the conic moved with the light or the view. A
//! footprint moving inside a node larger than itself still changes its count: the sample's
//! points are spread over the box. Y steps by √w where a sample point crosses the query's edge
//! (an exact count steps by 1 per particle) and moves continuously with ν(R) between steps; it
//! lies in [0, n·m] for multiplicities up to m, and is deterministic (the sample depends on the
//! node alone).
//!
//! # What it does not keep
//! - **Higher moments.** The count's skewness and lattice are the sample's, coarser by √w.
//!   They grow with the nodes sampled: at node scale 1 (the default) the counts' skewness is
//!   0.2–0.3 where exact counts have 0.02–0.2; at 2 it is 1.3 and at 4 it is 5.3 (few sample
//!   points fall in the query, each worth √w particles: lumpy counts). Measured in `cargo xtask
//!   validate`'s trade suite.
//! - **Correlations across levels.** Whether a node is sampled depends on the query's size (its
//!   footprint's width, γ), so two queries of different sizes may answer one node at different
//!   levels (one from its sample, the other from its children), and their counts are then
//!   uncorrelated there where exact counts are not: a footprint nested in one twice as wide,
//!   or a footprint whose width crosses a threshold while the camera moves (the sampled part
//!   of the count is redrawn once per factor two of width).
//! - **Exact means.** ν(R) comes from the directional share with p linear across Alg. 2's leaf
//!   cells ([`super::LeafShare::LinearDensity`]; by solid angle, shares were 4% low on a lobe's
//!   flank), whose error Δν biases the count by about n·Δν: +0.3% of the mean count on the
//!   trade suite's workload.
//! - **Particle areas.** Coloured materials (per-channel particle areas) are not sampled: a
//!   sample draws no area shares, and the areas' Dirichlet variance would be lost.
//!
//! Eq. 10 (ε > 0) waits, under the dense regime, until a query is long (the scale floor of
//! `super::query`): ordinary queries are resolved or sampled, so they keep the exact counts'
//! statistics, and long ones still stop early.
//!
//! # Which nodes
//! A partial node is answered this way when it holds at least [`DENSE_MIN_PARTICLES`] and its
//! cell is at most `node_scale`·γ across (√Ω; γ/2 is the conic's minor half-axis) and its box
//! at most 4·`node_scale` footprint widths, each unless the query holds the node in that
//! dimension; never the hemisphere's nodes (the spine's levels, which a query may skip), nodes
//! at the depth guard (real leaves there may hold more than 32 particles, the first 32 of them
//! the sample's) or coloured materials' nodes. Larger nodes split as before. So the cost is
//! bounded by the query's shape, not by N: the nodes answered are those of the query's
//! boundary at its own scale.

use glint_sphere::{Classification, SphericalConic};

use super::particles::{LEAF_PARTICLES, LeafParticle, Node};
use super::scratch::QueryMemo;
use super::{CountTree, LeafShare};
use crate::density_map::DensityMap;
use crate::error::TreeError;
use crate::footprint::{BoxOverlap, Footprint};
use crate::ndf::DirectionalCell;

/// The virtual sample's size M: a leaf's capacity, so that the leaf machinery places and
/// remembers it.
pub const VIRTUAL_PARTICLES: u64 = LEAF_PARTICLES;

/// Nodes with fewer particles are resolved exactly: a sample of M = 32 stands for at least
/// four times as many (w ≥ 4), or it saves little over the node's own leaves.
pub const DENSE_MIN_PARTICLES: u64 = 4 * VIRTUAL_PARTICLES;

/// How a query answers the nodes it meets in part (see the module `dense`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DenseCounts {
    /// Every partly covered node is split down to its particles: exact counts, at a cost that
    /// grows with the particles along the query's boundary.
    Exact,
    /// A partly covered node of at least [`DENSE_MIN_PARTICLES`] particles, with its cell at
    /// most `node_scale`·γ across and its box at most 4·`node_scale` footprint widths, adds
    /// its rescaled virtual sample's count: the exact counts' mean and covariances at a cost
    /// bounded whatever N. Larger `node_scale`: fewer nodes, coarser counts.
    Sampled {
        /// The largest node answered from its sample, in widths of the query (0 < s ≤ 16).
        node_scale: f64,
    },
    /// A query expecting at least [`super::LATTICE_FROM`] particles (by an estimate made
    /// before any cell) is answered, in part or (from [`super::LATTICE_ONLY`]) whole, from
    /// the points below a threshold of a Poisson process laid on cells (`super::lattice`):
    /// the exact counts' mean and dispersion, their correlations between queries of one size
    /// and, to a factor of 0.9 or more, between nested footprints of sizes up to four times
    /// apart in area (the camera moving closer), at a cost bounded by the points a query reads,
    /// not by N. Elsewhere (fewer particles, coloured materials, conics reaching the horizon)
    /// the tree answers as with `Sampled { node_scale }`. The default.
    Lattice {
        /// The largest node the tree answers from its sample where the lattice leaves a
        /// query to it, in widths of the query (0 < s ≤ 16), as in `Sampled`.
        node_scale: f64,
    },
}

impl DenseCounts {
    /// The default: the lattice for queries expecting many particles, the tree with samples of
    /// nodes up to the query's width for the others.
    pub const DEFAULT: Self = Self::Lattice {
        node_scale: Self::DEFAULT_NODE_SCALE,
    };

    /// The default `node_scale` of [`DenseCounts::Sampled`]: larger scales cost less but make
    /// the counts lumpy (skewness 1.3 at 2, 5.3 at 4, against 0.2–0.3 at 1; `cargo xtask
    /// validate`, trade suite).
    pub const DEFAULT_NODE_SCALE: f64 = 1.0;

    /// The names every interface spells the modes with: "sampled", "exact" and "lattice".
    pub const NAMES: [&'static str; 3] = ["sampled", "exact", "lattice"];

    /// The mode named `name` (one of [`DenseCounts::NAMES`]) with `node_scale` (used by
    /// "sampled" and by "lattice" where it leaves a query to the tree; `None` for the default).
    ///
    /// # Errors
    /// [`TreeError::UnknownDenseMode`] for another name, [`TreeError::InvalidDenseNodeScale`]
    /// for a node scale outside (0, 16].
    pub fn from_name(name: &str, node_scale: Option<f64>) -> Result<Self, TreeError> {
        let node_scale = node_scale.unwrap_or(Self::DEFAULT_NODE_SCALE);
        let mode = match name {
            "sampled" => Self::Sampled { node_scale },
            "exact" => Self::Exact,
            "lattice" => Self::Lattice { node_scale },
            _ => return Err(TreeError::UnknownDenseMode),
        };
        if mode.is_valid() {
            Ok(mode)
        } else {
            Err(TreeError::InvalidDenseNodeScale { node_scale })
        }
    }

    /// Whether the setting is valid (node_scale in (0, 16]).
    #[must_use]
    pub fn is_valid(&self) -> bool {
        match *self {
            Self::Exact => true,
            Self::Sampled { node_scale } | Self::Lattice { node_scale } => {
                node_scale > 0.0 && node_scale <= 16.0
            }
        }
    }
}

impl Default for DenseCounts {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// The largest nodes a query answers from their samples.
#[derive(Clone, Copy, Debug)]
pub(super) struct DenseScales {
    max_box_side: f64,
    max_cell_solid_angle: f64,
}

/// What a sampled answer needs from the query loop about one node.
pub(super) struct PartialNode<'a> {
    pub(super) node: &'a Node,
    pub(super) spatial: BoxOverlap,
    pub(super) directional: Classification,
    /// The density map where it varies over the node's box (the box's share is then weighed).
    pub(super) varying_map: Option<&'a DensityMap>,
}

/// The query's working memory that a sampled answer uses.
pub(super) struct DenseWork<'a> {
    pub(super) memo: &'a mut QueryMemo,
    pub(super) cells: &'a mut Vec<DirectionalCell>,
    pub(super) in_footprint: &'a mut Vec<LeafParticle>,
}

impl CountTree {
    /// The largest nodes this query answers from their samples, if the material samples them.
    pub(super) fn dense_scales(
        &self,
        footprint: &Footprint,
        conic: &SphericalConic,
    ) -> Option<DenseScales> {
        let node_scale = match self.config.dense {
            DenseCounts::Exact => return None,
            DenseCounts::Sampled { node_scale } | DenseCounts::Lattice { node_scale } => node_scale,
        };
        let cell_across = node_scale * conic.gamma();
        Some(DenseScales {
            max_box_side: 4.0 * node_scale * footprint.narrowest_width(),
            // A cell of the tree's near-equilateral triangles with solid angle Ω is about √Ω
            // across.
            max_cell_solid_angle: cell_across * cell_across,
        })
    }

    /// Y(R) of the module docs for `partial`, if the node is dense and small enough against the
    /// query; `None` to split it.
    pub(super) fn sampled_count(
        &self,
        scales: Option<DenseScales>,
        partial: &PartialNode,
        footprint: &Footprint,
        conic: &SphericalConic,
        work: DenseWork,
    ) -> Option<f64> {
        let scales = scales?;
        let PartialNode {
            node,
            spatial,
            directional,
            varying_map,
        } = *partial;
        let directions_inside = directional == Classification::TriangleInsideConic;
        let size = node.box_size();
        // Not sampled: coloured materials (a sample draws no area shares, whose Dirichlet
        // variance D̂ would lose), the hemisphere's nodes (the spine's levels, which a query
        // may skip), and nodes at the depth guard (real leaves there may hold more than 32
        // particles, the first 32 of them the sample's).
        if self.config.colour_channels > 0
            || node.cell.triangle.is_none()
            || node.depth >= self.config.max_depth
            || node.count < DENSE_MIN_PARTICLES
            || (spatial.partial > 0 && size > scales.max_box_side)
            || (!directions_inside
                && (directional == Classification::ConicInsideTriangle
                    || node.solid_angle > scales.max_cell_solid_angle))
        {
            return None;
        }
        // ν(R): the particles' mean multiplicity in the footprint times the cell's share of p
        // in the conic.
        let multiplicity = match varying_map {
            _ if spatial.partial == 0 => spatial.inside as f64,
            Some(map) => map.mean_multiplicity(footprint, node.box_min, size)?,
            None => footprint.overlap_area(node.box_min, size) / (size * size),
        };
        let DenseWork {
            memo,
            cells,
            in_footprint,
        } = work;
        let in_conic = if directions_inside {
            1.0
        } else {
            memo.dense_conic_share(&node.cell, |memo| {
                self.directional_fraction(node, conic, LeafShare::LinearDensity, cells, memo)
            })
        };
        let share = multiplicity * in_conic;
        let sample = Node {
            count: VIRTUAL_PARTICLES,
            ..*node
        };
        let (found, _) = self.count_leaf(
            &sample,
            directional,
            footprint,
            conic,
            memo,
            in_footprint,
            0,
        );
        let n = node.count as f64;
        let m = VIRTUAL_PARTICLES as f64;
        Some((n / m).sqrt() * found + (n - (n * m).sqrt()) * share)
    }
}
