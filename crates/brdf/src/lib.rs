//! # glint-brdf: smooth and discrete multiscale microfacet BRDFs
//!
//! **Invariant: this crate knows nothing of scenes or rays; its inputs are local directions
//! (n = +z), a texture-space footprint and a material.** It implements the reflectance models of
//! Jakob et al. 2014: the smooth microfacet BRDF (Eq. 3) and the discrete multiscale BRDF
//! (Eq. 5, with the normalization derived in [`discrete`]), with importance sampling (Sec. 3.4).
//!
//! - [`Microfacet`]: Beckmann and GGX, isotropic and anisotropic: D, Smith Λ, G1, G, normal
//!   sampling (and visible-normal sampling for GGX), and the particle density p(m) = D(m)(m·n)
//!   the count tree integrates.
//! - [`Fresnel`]: none, conductor (complex index per RGB channel), dielectric.
//! - [`Bxdf`]: the pbrt-v4-style interface (`eval`, `sample` from uniform numbers, `pdf`).
//! - [`MicrofacetBrdf`]: Eq. 3.
//! - [`DiscreteBrdf`]: the glint material; [`DiscreteBrdf::evaluate`] for a footprint, the
//!   smooth model without one.
#![deny(missing_docs)]

pub mod discrete;
pub mod distribution;
mod error;
pub mod fresnel;
pub mod qmc;
pub mod smooth;

pub use discrete::{DiscreteBrdf, FootprintEvaluation, GlintEvaluation, GlintParameters};
pub use distribution::{DistributionKind, Microfacet, NormalSampling};
pub use error::BrdfError;
pub use fresnel::Fresnel;
pub use smooth::{Bxdf, BxdfSample, MicrofacetBrdf};
