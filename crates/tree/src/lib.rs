//! # glint-tree: the procedural count tree of the discrete stochastic microfacet model
//!
//! **Invariant: this crate knows nothing of Fresnel, shading frames or light; it counts points in
//! (texture box × spherical triangle) regions against (parallelogram × conic) queries. The
//! particle set is a function of the material alone** — N, the normal density, the seed and
//! the expected query statistics of Eq. 11 — never of the query being answered (Jakob et al.
//! 2014, Sec. 3.3–3.4, Alg. 1 and 2).
//!
//! - [`CountTree`]: a material's implicit 4D position–normal hierarchy and its breadth-first
//!   query ([`CountTree::query`]) with the error criterion of Eq. 10.
//! - [`DensityMap`]: a piecewise-constant density d(x) over the square: N·d(x) particles per
//!   unit area, masks where d = 0, exact counts ([`CountTree::with_density_map`]).
//! - [`Footprint`]: the texture-space parallelogram of a pixel, wrapping across tiles.
//! - [`NdfQuadrature`]: Alg. 2's memoized integrals of the normal density.
//! - [`sampling`]: exact binomial and multinomial splits, the paper's normal approximation,
//!   Dirichlet particle areas.
//! - [`tea`]: the Tiny Encryption Algorithm as the source of randomness, scalar and 4-lane.
//! - [`NodeId`]: node identities that stay unique at any depth.
//!
//! ```
//! use std::sync::Arc;
//! use glint_sphere::{DVec3, SphericalConic};
//! use glint_tree::{CountTree, CountTreeConfig, Footprint, QueryScratch};
//! use glam::DVec2;
//!
//! // Beckmann, α = 0.2: p(m) = D(m)·cos θ.
//! let alpha: f64 = 0.2;
//! let density = Arc::new(move |m: DVec3| {
//!     let cos2 = m.z * m.z;
//!     let tan2 = (1.0 - cos2) / cos2;
//!     (-tan2 / (alpha * alpha)).exp() / (std::f64::consts::PI * alpha * alpha * cos2 * m.z)
//! });
//! let tree = CountTree::new(CountTreeConfig { particles: 100_000, ..Default::default() }, density)?;
//! let footprint = Footprint::new(DVec2::new(0.3, 0.6), DVec2::new(0.01, 0.0), DVec2::new(0.0, 0.01))?;
//! let conic = SphericalConic::new(DVec3::new(0.2, 0.0, 1.0), DVec3::new(-0.1, 0.1, 1.0), 0.05)?;
//! let mut scratch = QueryScratch::new();
//! let result = tree.query(&footprint, &conic, &mut scratch);
//! assert!(result.count >= 0.0 && result.count.is_finite());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]

pub mod density_map;
mod error;
pub mod footprint;
pub mod ndf;
pub mod node;
pub mod sampling;
pub mod tea;
mod tree;

pub use density_map::{DensityMap, DensityMapError, LevelTexels, MapFilter, MapOccupancy};
pub use error::TreeError;
pub use footprint::{BoxOverlap, Footprint};
pub use ndf::{DirectionalCell, NdfQuadrature, NormalDensity, QuadratureTolerance};
pub use node::NodeId;
pub use sampling::MultinomialMode;
pub use tree::{
    CountTree, CountTreeConfig, DENSE_MIN_PARTICLES, DenseCounts, DirectionalLawExcess,
    LATTICE_FROM, LATTICE_ONLY, LATTICE_POINTS, LEAF_CELL_ARC, LEAF_PARTICLES, MAX_CACHED_LEVELS,
    MAX_GRID_CELLS, MAX_PARTICLES, ManyTiles, QueryResult, QueryScratch, TurnSymmetry,
    VIRTUAL_PARTICLES, expected_conic_solid_angle,
};
