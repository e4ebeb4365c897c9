//! # glint-brdf: smooth and discrete multiscale microfacet BRDFs
//!
//! **Invariant: this crate knows nothing of scenes or rays; its inputs are local directions
//! (n = +z), a texture-space footprint and a material.** It implements the reflectance models of
//! Jakob et al. 2014: the smooth microfacet BRDF (Eq. 3) and the discrete multiscale BRDF
//! (Eq. 5, with the normalization derived in [`discrete`]), with importance sampling (Sec. 3.4).
//! A renderer depends on this crate alone: it re-exports the footprint, the scratch and the
//! vector types it needs.
//!
//! - [`DiscreteBrdf`]: the glint material. [`DiscreteBrdf::at`] binds it to a shading point's
//!   [`Footprint`] and a per-thread [`QueryScratch`], giving a [`GlintBxdf`] whose [`Bxdf`]
//!   methods are the glint model; [`GlintBxdf::evaluate`] adds the query's statistics, and
//!   [`GlintBxdf::evaluate_in_cone`] evaluates it with another cone (a sphere light's own).
//!   [`DiscreteBrdf::smooth`] is the smooth limit.
//! - [`Bxdf`]: `eval`, `sample` from uniform numbers, `pdf`; ω_i toward the viewer, ω_o toward
//!   the light (the paper's and Mitsuba's names, the reverse of pbrt-v4's).
//! - [`MicrofacetBrdf`]: the smooth model, Eq. 3.
//! - [`Microfacet`]: Beckmann and GGX, isotropic and anisotropic: D, Smith Λ, G1, G, normal
//!   sampling (and visible-normal sampling for GGX), and the particle density p(m) = D(m)(m·n)
//!   the count tree integrates.
//! - [`Fresnel`]: none, conductor (complex index per RGB channel), dielectric.
//! - [`frame`] and [`cone`]: shading frames, and cones of directions.
//!
//! ```
//! use glint_brdf::{
//!     Bxdf, DVec2, DVec3, DiscreteBrdf, DistributionKind, Footprint, GlintParameters,
//!     Microfacet, QueryScratch,
//! };
//!
//! // Beckmann α = 0.1 with 10⁶ flakes per unit texture square and γ = 1° (the defaults).
//! let distribution = Microfacet::new(DistributionKind::Beckmann, 0.1, 0.1)?;
//! let material = DiscreteBrdf::new(GlintParameters::new(distribution))?;
//! let mut scratch = QueryScratch::new();
//! // A pixel's footprint: (u, v) and its derivatives along the pixel's x and y.
//! let footprint = Footprint::new(DVec2::new(0.3, 0.4), DVec2::new(0.01, 0.0), DVec2::new(0.0, 0.01))?;
//! let bxdf = material.at(&footprint, &mut scratch);
//! let wi = DVec3::new(0.1, 0.0, 1.0).normalize();
//! let wo = DVec3::new(-0.1, 0.0, 1.0).normalize();
//! let e = bxdf.evaluate(wi, wo);
//! assert_eq!(e.f_hat, bxdf.eval(wi, wo));
//! assert!(e.count >= 0.0 && e.nodes_visited > 0);
//! if let Some(s) = bxdf.sample(wi, [0.3, 0.6, 0.2, 0.9]) {
//!     assert_eq!(s.pdf, bxdf.pdf(wi, s.wo));
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]

mod bxdf;
pub mod cone;
pub mod discrete;
pub mod distribution;
mod error;
pub mod frame;
pub mod fresnel;
mod glint;
mod glint_sampling;
pub mod map_budget;
mod negligible;
mod qmc;
mod quadrature;
mod slope_pdf;
pub mod smooth;
pub mod surface_maps;

pub use bxdf::{Bxdf, BxdfSample};
pub use discrete::{DiscreteBrdf, GlintParameters, NegligibleTestConstants};
pub use distribution::{
    ConeCheck, ConvergenceCheck, DistributionKind, KindChecks, Microfacet, NormalSampling,
};
pub use error::BrdfError;
pub use fresnel::Fresnel;
pub use glam::{DVec2, DVec3};
pub use glint::{GlintBxdf, GlintEvaluation};
pub use glint_sampling::{PdfQuadrature, PdfRule};
pub use glint_tree::{
    DenseCounts, DensityMap, DensityMapError, Footprint, MapFilter, MultinomialMode, QueryScratch,
    TreeError,
};
pub use map_budget::{MAX_MAP_BYTES, MapBytes};
pub use smooth::MicrofacetBrdf;
pub use surface_maps::{RoughnessMap, TintMap};

/// The README's example, compiled and run as a doctest so that it stays in step with the API.
#[doc = include_str!("../../../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;

/// `docs/integration.md`'s examples, compiled and run as doctests for the same reason.
#[doc = include_str!("../../../docs/integration.md")]
#[cfg(doctest)]
pub struct IntegrationDoctests;
