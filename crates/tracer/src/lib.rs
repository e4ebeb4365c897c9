//! # glint-tracer: a reference path tracer with pixel footprints
//!
//! **Invariant: this crate contains no glint mathematics; it computes texture-space footprints
//! from ray differentials and calls glint-brdf.** It renders what the paper's scenes need and
//! no more (DESIGN.md, "Model only what a scene requires"):
//!
//! - [`scene_file`]: TOML scene files, validated with errors that name the file, the field and
//!   the problem; [`Scene`] is the built, immutable scene.
//! - [`shape`], [`mesh`], [`accel`]: analytic spheres and rectangles, OBJ triangle meshes, and an
//!   `obvhs` BVH over all of them; every hit carries (u, v), ∂p/∂u and ∂p/∂v.
//! - [`camera`]: a perspective camera with ray differentials (Igehy 1999) and keyframed motion;
//!   [`camera::texture_footprint`] turns a hit's differentials into the footprint parallelogram
//!   of Sec. 3.1 ("Usage in a rendering system").
//! - [`material`]: diffuse, smooth conductor, plastic, the glint material and linear
//!   combinations; [`light`]: sphere, rectangle (optionally textured), directional and
//!   environment lights.
//! - [`integrator`]: direct illumination and path tracing with next-event estimation, multiple
//!   importance sampling (power heuristic) and Russian roulette.
//! - [`film`]: pixel filters, tiles rendered in parallel with per-pixel seeded samplers (the
//!   image is bit-identical for any thread count), EXR and PNG output.
#![deny(missing_docs)]

pub mod accel;
pub mod camera;
pub mod distribution;
mod error;
pub mod film;
pub mod image;
pub mod integrator;
pub mod light;
pub mod material;
pub mod mesh;
pub mod sampler;
pub mod scene;
pub mod scene_file;
pub mod shape;

pub use error::TracerError;
pub use film::{RenderOutput, RenderStatistics, render};
pub use integrator::{
    Bloom, GlintFootprints, GlintRandomness, IntegratorKind, LightStrategy, RenderSettings,
};
pub use scene::Scene;
