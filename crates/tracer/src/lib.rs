//! # glint-tracer: a reference path tracer with pixel footprints
//!
//! **Invariant: this crate contains no glint mathematics; it computes texture-space footprints
//! from ray differentials and calls glint-brdf.** It renders what the paper's scenes need and
//! no more:
//!
//! - [`scene_file`]: TOML scene files, validated with errors that name the file, the field and
//!   the problem; [`Scene`] is the built, immutable scene.
//! - [`shape`], [`mesh`], [`accel`]: analytic spheres and rectangles, OBJ triangle meshes, and an
//!   `obvhs` BVH over all of them; every hit carries (u, v), ∂p/∂u and ∂p/∂v.
//! - [`camera`]: a perspective camera with ray differentials (Igehy 1999) and keyframed motion;
//!   [`camera::texture_footprint`] turns a hit's differentials into the footprint parallelogram
//!   of Sec. 3.1 ("Usage in a rendering system").
//! - [`differentials`]: ray differentials reflected at perfect mirrors, and at near-specular
//!   glossy bounces about the sampled facet and widened by the lobe's spread, so glints seen in
//!   mirrors, polished metal and glossy coats keep a footprint under `glint_footprints = "all"`.
//! - [`material`]: diffuse, smooth conductor, plastic, the glint material, the perfect mirror
//!   and linear combinations; [`light`]: sphere, rectangle (optionally textured), directional and
//!   environment lights.
//! - [`integrator`]: direct illumination and path tracing with next-event estimation, multiple
//!   importance sampling (power heuristic) and Russian roulette.
//! - [`settings`]: how an image is rendered ([`RenderSettings`]), as opposed to what is in it.
//! - [`job`]: a scene file, the command line's options and frames, as `cargo xtask render` and
//!   Python's `glint.render` run them (one path, so both give the same bits).
//! - [`film`]: pixel filters, tiles rendered in parallel with per-pixel seeded samplers (the
//!   image is bit-identical for any thread count and any pixel bounds), EXR and PNG output.
//! - [`limits`]: what the tracer accepts (magnitudes, sizes, counts), checked where values
//!   enter, so that hostile input gets an error rather than a panic, an abort or an image of
//!   infinities.
//!
//! A glittery floor under a small sphere light, rendered tiny (scene files are documented in
//! `scenes/README.md`):
//!
//! ```
//! use std::path::Path;
//! use glint_tracer::{render, scene_file::parse_scene};
//!
//! let scene = parse_scene(r#"
//!     [render]
//!     resolution = [48, 32]
//!     spp = 2
//!     integrator = "direct"
//!
//!     [camera]
//!     position = [0.0, 1.0, 4.0]
//!     look_at = [0.0, 0.0, 0.0]
//!     fov = 40
//!
//!     [materials.glitter]
//!     type = "glint"
//!     distribution = "beckmann"
//!     alpha = 0.1
//!     particles = 1e8
//!     gamma_degrees = 1.0
//!
//!     [[shapes]]
//!     type = "rectangle"
//!     center = [0.0, 0.0, 0.0]
//!     u = [10.0, 0.0, 0.0]
//!     v = [0.0, 0.0, -10.0]
//!     material = "glitter"
//!
//!     [[lights]]
//!     type = "sphere"
//!     center = [0.0, 1.0, -4.0]
//!     radius = 0.05
//!     power = 20.0
//! "#, Path::new("inline.toml"))?;
//! let output = render(&scene, &scene.settings, 0.0, &|_, _| {})?;
//! let statistics = &output.statistics;
//! assert!(statistics.glint.queries > 0, "the floor is shaded with glint queries");
//! assert!(output.image.pixels.iter().all(|p| p.is_finite() && p.min_element() >= 0.0));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]

pub mod accel;
mod bounce;
pub mod camera;
pub mod differentials;
pub mod distribution;
mod error;
pub mod film;
#[cfg(test)]
mod fuzz;
pub mod image;
pub mod integrator;
pub mod job;
pub mod light;
pub mod light_cone;
pub mod limits;
pub mod material;
pub mod mesh;
pub mod particle_histogram;
pub mod plan;
pub mod sampler;
pub mod scene;
pub mod scene_file;
pub mod settings;
pub mod shape;
#[cfg(test)]
mod test_scenes;
#[cfg(test)]
mod textured_glint_tests;

pub use error::TracerError;
pub use film::{RenderOutput, RenderStatistics, render};
pub use scene::Scene;
pub use settings::{
    Bloom, GlintFootprints, GlintRandomness, IntegratorKind, LightStrategy, PixelBounds,
    RenderSettings,
};
