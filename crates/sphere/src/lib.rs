//! # glint-sphere: geometry on the unit sphere for the discrete stochastic microfacet model
//!
//! **Invariant: this crate knows nothing of particles, BRDFs or rendering; it is pure geometry
//! on S².** It answers three questions that the count tree (glint-tree) asks millions of times
//! per frame, following Jakob et al. 2014, "Discrete Stochastic Microfacet Models" (Sec. 3.2
//! and the "Intersection and overlap computations" part of Sec. 3.3):
//!
//! 1. Which microfacet normals reflect ω_i into the cone of radius γ around ω_o? That set is a
//!    [`SphericalConic`] (Eq. 7, 8), held in its standard form (Eq. 9).
//! 2. How does a [`SphericalTriangle`] (a directional node of the tree) relate to that set?
//!    [`SphericalConic::classify`] answers [`Classification::Disjoint`],
//!    [`Classification::TriangleInsideConic`], [`Classification::ConicInsideTriangle`] or
//!    [`Classification::Partial`]. "Disjoint" and the two "inside" answers are never wrong; when
//!    floating point leaves any doubt the answer is "partial", which only costs the tree a split.
//! 3. How large is their overlap? [`overlap_solid_angle`] computes the solid angle of
//!    triangle ∩ conic with the paper's planar approximation ([`OverlapMethod::Planar`]) or with
//!    a precise reference ([`OverlapMethod::Precise`]).
//!
//! ## Example
//! ```
//! use glint_sphere::{Classification, DVec3, OverlapMethod, SphericalConic, SphericalTriangle};
//!
//! // Light from ω_i, viewed from ω_o (local frame, z = normal; any length), cone radius 1°.
//! let conic = SphericalConic::new(DVec3::new(0.3, 0.0, 1.0), DVec3::new(-0.2, 0.1, 1.0), 1f64.to_radians())?;
//! let mut total = 0.0;
//! for octant in SphericalTriangle::upper_hemisphere_octants() {
//!     total += match conic.classify(&octant) {
//!         Classification::Disjoint => 0.0,
//!         Classification::TriangleInsideConic => octant.solid_angle(),
//!         _ => glint_sphere::overlap_solid_angle(&octant, &conic, OverlapMethod::Precise),
//!     };
//! }
//! // The half-vector map ω_r ↦ m has Jacobian 1/(4 ω_i·m), so for small γ the conic covers
//! // the cone's solid angle 2π(1 − cos γ) divided by 4 ω_i·h, h the half vector.
//! let (wi, wo) = (conic.wi(), conic.wo());
//! let h = (wi + wo).normalize();
//! let expected = 2.0 * std::f64::consts::PI * (1.0 - conic.gamma().cos()) / (4.0 * wi.dot(h));
//! assert!((total / expected - 1.0).abs() < 1e-3, "{total} vs {expected}");
//! # Ok::<(), glint_sphere::SphereError>(())
//! ```
//!
//! ## Conventions
//! - Directions are `glam::DVec3` in the local shading frame; the surface normal n is +z.
//!   Constructors normalize their inputs and reject non-finite or zero vectors with a
//!   [`SphereError`].
//! - A facet normal m belongs to the conic when m·n > 0, m·ω_i > 0 and the mirror reflection of
//!   ω_i about m lies within γ of ω_o. The quadric of Eq. 8 is a double cone; the conditions
//!   m·ω_i > 0 and m·n > 0 select the physically valid part of it.
//! - The per-call paths ([`SphericalConic::contains`], [`SphericalConic::classify`],
//!   [`SphericalTriangle::contains`]) use no trigonometry and never allocate.
//!
//! ## Modules
//! - [`triangle`]: spherical triangles, solid angle, containment, subdivision.
//! - [`conic`]: the spherical conic of reflection geometry and its standard form.
//! - [`classify`]: triangle–conic classification (Sec. 3.3).
//! - [`overlap`]: the solid angle of triangle ∩ conic, planar and precise.
#![deny(missing_docs)]

pub mod classify;
pub mod conic;
mod error;
pub mod overlap;
mod quadrature;
pub mod triangle;

pub use classify::Classification;
pub use conic::{ConeRadius, ConicKind, SphericalConic};
pub use error::SphereError;
pub use overlap::{OverlapMethod, overlap_share_with_linear_density, overlap_solid_angle};
pub use triangle::SphericalTriangle;

/// Re-export of the vector type used throughout the public API.
pub use glam::DVec3;
