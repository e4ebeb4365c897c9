//! # glint-eval: the eval contract of `docs/eval.md`, independent of its transport
//!
//! **Invariant: every way into the model from another language (the JSON Lines of
//! `cargo xtask eval`, the Python package) goes through this crate, so a material and a request
//! mean the same, give the same numbers bit for bit and fail with the same messages whichever
//! way they arrive.**
//!
//! - [`MaterialSpec`]: a material as `docs/eval.md` writes it (names, units, defaults), built
//!   into an [`EvalMaterial`] with errors that name the field.
//! - [`EvalMaterial`]: the answers to one `eval`, `sample` or `pdf` request from plain numbers,
//!   validating each input as the contract says.
//! - [`JsonLines`]: one JSON line in, one JSON answer out, with a cache of built materials.
//! - [`batch`]: many rows at once at a renderer's speed (per-thread scratches kept across
//!   calls, rows dispatched by footprint locality, answers in input order, bit for bit).
//!
//! ```
//! use glint_eval::{FresnelSpec, MaterialSpec};
//!
//! let material = MaterialSpec::new("beckmann", 0.1, 1e6, 1.0).build()?;
//! let mut scratch = glint_brdf::QueryScratch::new();
//! let answer = material.eval(
//!     &mut scratch,
//!     [0.0, 0.0, 1.0],
//!     [0.1, 0.0, 0.99],
//!     [0.3, 0.4],
//!     [1e-3, 0.0],
//!     [0.0, 1e-3],
//! )?;
//! assert!(answer.count >= 0.0 && answer.nodes_visited > 0);
//! let bad = MaterialSpec { fresnel: FresnelSpec::Dielectric { eta: -1.0 }, ..MaterialSpec::new("ggx", 0.2, 1e6, 1.0) };
//! assert!(bad.build().unwrap_err().contains("Fresnel"));
//! # Ok::<(), String>(())
//! ```
#![deny(missing_docs)]

pub mod batch;
mod json_lines;
mod maps;
mod material;
mod request;
mod strict_json;

pub use json_lines::{JsonLines, MATERIAL_CACHE_BYTES, MATERIAL_CACHE_SIZE};
pub use maps::{MapSpec, MapsSpec};
pub use material::{DEFAULT_NEGLIGIBLE_COUNT, FresnelSpec, MaterialSpec};
pub use request::{
    EvalAnswer, EvalColumns, EvalMaterial, EvalRow, SampleAnswer, split_uniform,
    uniforms_from_three,
};
