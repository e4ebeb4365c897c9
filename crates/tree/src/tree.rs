//! The procedural count tree of a material (Jakob et al. 2014, Sec. 3.3–3.4, Alg. 1 and 2,
//! Eq. 10 and 11): [`CountTree`], built once from a [`CountTreeConfig`] and the normal density,
//! with Alg. 2's tables and the top levels of its tree computed up front. Its parts:
//!
//! - `particles`: what particles the material has: the nodes' streams, Eq. 11's choice of
//!   split, the splits' counts, the leaves' explicit particles and their normals' descent. The
//!   part whose every draw must stay the same (see its header).
//! - `query`: Alg. 1's breadth-first count with Eq. 10's early stop ([`CountTree::query`]).
//! - `scratch`: the reusable working memory and memo of queries ([`QueryScratch`]).
//! - `spine`: the single spatial path from the root that queries share, remembered across
//!   queries so that a query starts below it.
//! - `lattice`: the lattice regime, a Poisson process drawn at the query's own scale for
//!   queries that expect many particles (`DenseCounts::Lattice`).
//! - `law`: the expected count and the directional law's excess over p
//!   ([`CountTree::expected_count`], [`CountTree::directional_law_excess`]).

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use glint_sphere::OverlapMethod;

use crate::density_map::DensityMap;
use crate::error::TreeError;
use crate::footprint::Footprint;
use crate::ndf::{DirectionalSplits, NdfQuadrature, NormalDensity, QuadratureTolerance};
use crate::sampling::MultinomialMode;
use crate::tea::DEFAULT_ROUNDS;

mod dense;
mod lattice;
mod law;
mod particles;
mod query;
mod scratch;
mod spine;

pub use dense::{DENSE_MIN_PARTICLES, DenseCounts, VIRTUAL_PARTICLES};
pub use lattice::{LATTICE_FROM, LATTICE_ONLY, LATTICE_POINTS, MAX_GRID_CELLS};
use law::LeafShare;
pub use law::{DirectionalLawExcess, TurnSymmetry};
use particles::{DescentStep, Node};
pub use particles::{LEAF_CELL_ARC, LEAF_PARTICLES};
pub use query::QueryResult;
pub use scratch::QueryScratch;

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
    /// ε of Eq. 10 (0 = exact evaluation; the paper uses 0.1): a partial node whose binomial
    /// spread is below ε × the count adds its expected share.
    pub epsilon: f64,
    /// How queries expecting many particles are answered: from the lattice regime, from the
    /// rescaled virtual samples of partial nodes at the query's scale, or resolved (the dense
    /// regime, `dense`).
    pub dense: DenseCounts,
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
    /// whole tile) would otherwise resolve every particle near the conic's boundary. A
    /// footprint whose bounding box spans T > 4 texture tiles tests each node at about T/4
    /// nodes' cost, so its queries get node_budget·4/T (at least 64): the budget bounds work.
    pub node_budget: u32,
    /// Particle areas per colour channel (Sec. 3.4, Fig. 8): 0 for none (each particle counts
    /// 1/N), 1 for gray areas, 3 for RGB.
    pub colour_channels: usize,
    /// When a footprint covers so many tiles that its count is taken as a periodic average
    /// (an approximation; [`ManyTiles::EXACT`] turns it off).
    pub many_tiles: ManyTiles,
}

/// Footprints over many texture tiles: beyond these limits a query answers with the periodic
/// average A·C, the footprint's area A (in tiles) times the exact count C of one whole tile,
/// instead of resolving every particle's multiplicity m(x), the number of its translates inside
/// the footprint.
///
/// Why: a particle at x counts m(x) times, and m is constant only between the footprint's
/// edges wrapped into the unit square. A footprint L tiles across wraps its edges about L times
/// over the square, so the traversal must resolve boxes down to about 1/L, at a cost that grows
/// with the tiles covered (a 3000 × 3000-tile footprint took 20 s at ε = 0); a long thin
/// footprint at an irrational slope wraps into a dense set of strips the same way.
///
/// The error: the mean of m over the square is exactly A, so A·C − Σ m(x) = Σ (A − m(x)) over
/// the C particles found, a sum of terms bounded by the footprint's perimeter in tiles whose
/// mean over positions is zero. It is measured in `tests` against exact queries: see
/// `docs/performance.md` ("Speed against accuracy").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ManyTiles {
    /// Footprints of a larger area (in tiles) are averaged.
    pub max_area: f64,
    /// Footprints whose bounding box spans more tiles than this are averaged (long thin ones).
    pub max_tiles_spanned: f64,
}

impl ManyTiles {
    /// Every footprint resolved exactly, whatever it costs.
    pub const EXACT: Self = Self {
        max_area: f64::INFINITY,
        max_tiles_spanned: f64::INFINITY,
    };

    /// Whether a query of `footprint` is answered by its periodic average.
    #[must_use]
    pub fn averages(&self, footprint: &Footprint) -> bool {
        footprint.area() > self.max_area || footprint.tiles_spanned() > self.max_tiles_spanned
    }
}

impl Default for ManyTiles {
    /// Averages above 256 tiles of area or 4096 tiles spanned: an exact query then costs at
    /// most about what a 16 × 16-tile footprint costs.
    fn default() -> Self {
        Self {
            max_area: 256.0,
            max_tiles_spanned: 4096.0,
        }
    }
}

impl Default for CountTreeConfig {
    /// N = 10⁶, seed 0, ε = 0.1, the lattice regime for queries expecting many particles
    /// (elsewhere dense nodes answered from their samples up to the query's scale), exact
    /// multinomials, planar overlaps, a footprint of 10⁻⁶
    /// (a pixel of ~1000² over the texture) and the conic of γ = 1° at normal incidence,
    /// δ = 1e-5, 8 TEA cycles, depth guard 64, 6 cached levels, node budget 10⁶, no colour,
    /// footprints over more than 256 tiles (or spanning 4096) averaged.
    fn default() -> Self {
        let gamma = 1f64.to_radians();
        Self {
            particles: 1_000_000,
            seed: 0,
            epsilon: 0.1,
            dense: DenseCounts::DEFAULT,
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
            many_tiles: ManyTiles::default(),
        }
    }
}

/// The solid angle of the conic for cone radius γ at ω_i = ω_o = n: the half-vector map has
/// Jacobian 1/(4 ω_i·m), so it is 2π(1 − cos γ)/4 = π sin²(γ/2). A default for Eq. 11.
#[must_use]
pub fn expected_conic_solid_angle(gamma: f64) -> f64 {
    std::f64::consts::PI * (0.5 * gamma).sin().powi(2)
}

/// The root's particles: N, or round(N·∫d) under a density map (N exactly for a map of ones).
fn root_particles(particles: u64, density_map: Option<&DensityMap>) -> u64 {
    density_map.map_or(particles, |map| {
        ((particles as f64 * map.mean()).round() as u64).min(particles)
    })
}

/// A tree identity no other tree has had (clones share theirs): the key of its memo entries.
fn fresh_id() -> u64 {
    static NEXT_ID: AtomicU64 = AtomicU64::new(1);
    NEXT_ID.fetch_add(1, Ordering::Relaxed)
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
    /// `directional_splits` as single leaf particles' descents walk them.
    descent_steps: Vec<DescentStep>,
    top_levels: TopLevels,
    /// The particle density over the square, N·d(x) (`None`: uniform, d = 1).
    density_map: Option<Arc<DensityMap>>,
    /// The root's particles: N, or round(N·∫d) under a density map.
    root_particles: u64,
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

impl CountTree {
    /// Builds the tree of a material: validates `config` and runs Alg. 2 on `density`,
    /// the particle normal density p(m) = D(m)(m·n), which must integrate to 1 over the upper
    /// hemisphere.
    ///
    /// # Errors
    /// A [`TreeError`] naming the invalid parameter.
    pub fn new(config: CountTreeConfig, density: Arc<NormalDensity>) -> Result<Self, TreeError> {
        Self::with_density_map(config, density, None)
    }

    /// [`CountTree::new`] with particles placed by a density map: the particle density at
    /// texture position x is N·d(x), the root holds round(N·∫d) particles, and a spatial split
    /// gives each quarter of a box the share of the box's mass it holds (see
    /// [`crate::density_map`]). Where the map is constant over a box the tree splits as it
    /// does without one, so a map of ones gives [`CountTree::new`]'s particles bit for bit.
    ///
    /// # Errors
    /// As [`CountTree::new`].
    pub fn with_density_map(
        config: CountTreeConfig,
        density: Arc<NormalDensity>,
        density_map: Option<Arc<DensityMap>>,
    ) -> Result<Self, TreeError> {
        if !(1..=MAX_PARTICLES).contains(&config.particles) {
            return Err(TreeError::ParticleCountOutOfRange {
                particles: config.particles,
            });
        }
        if !(0.0..=1.0).contains(&config.epsilon) {
            return Err(TreeError::InvalidEpsilon {
                epsilon: config.epsilon,
            });
        }
        if let DenseCounts::Sampled { node_scale } | DenseCounts::Lattice { node_scale } =
            config.dense
            && !config.dense.is_valid()
        {
            return Err(TreeError::InvalidDenseNodeScale { node_scale });
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
        let quadrature =
            NdfQuadrature::build(density.as_ref(), config.quadrature, config.particles)?;
        let directional_splits =
            DirectionalSplits::build(&quadrature, density.as_ref(), CACHED_DIRECTIONAL_LEVELS);
        let mut tree = Self {
            id: fresh_id(),
            config,
            quadrature,
            density,
            directional_splits,
            descent_steps: Vec::new(),
            top_levels: TopLevels::default(),
            root_particles: root_particles(config.particles, density_map.as_deref()),
            density_map,
        };
        tree.descent_steps = tree.descent_steps();
        tree.top_levels = tree.build_top_levels();
        Ok(tree)
    }

    /// The tree of the same material with another particle set of the same law: the material
    /// `seed` and Eq. 11's expected footprint area E[A(query)] replaced, what
    /// [`CountTree::new`] builds with them. Alg. 2's table and the directional splits depend on
    /// neither and are shared; only the top levels are built again.
    ///
    /// # Errors
    /// [`TreeError::InvalidExpectedQuery`] unless `expected_query_area` is positive and finite.
    pub fn with_realization(&self, seed: u64, expected_query_area: f64) -> Result<Self, TreeError> {
        if !(expected_query_area > 0.0 && expected_query_area.is_finite()) {
            return Err(TreeError::InvalidExpectedQuery);
        }
        let mut tree = Self {
            id: fresh_id(),
            config: CountTreeConfig {
                seed,
                expected_query_area,
                ..self.config
            },
            quadrature: self.quadrature.clone(),
            density: Arc::clone(&self.density),
            directional_splits: self.directional_splits.clone(),
            descent_steps: self.descent_steps.clone(),
            top_levels: TopLevels::default(),
            density_map: self.density_map.clone(),
            root_particles: self.root_particles,
        };
        tree.top_levels = tree.build_top_levels();
        Ok(tree)
    }

    /// Breadth first, so that entries land in label order within each depth.
    fn build_top_levels(&self) -> TopLevels {
        let levels = self.config.cached_levels;
        // (4^levels − 1)/3 entries, allocated once (growing by doubling copied them about
        // twice over and touched twice the fresh pages).
        let mut entries = Vec::with_capacity(((1usize << (2 * levels)) - 1) / 3);
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

    /// The density map particles are placed by, if any.
    #[must_use]
    pub fn density_map(&self) -> Option<&DensityMap> {
        self.density_map.as_deref()
    }

    /// The memo table of Alg. 2.
    #[must_use]
    pub fn quadrature(&self) -> &NdfQuadrature {
        &self.quadrature
    }
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
