//! The types that cross the boundary: status codes, the enumerations of material settings, the
//! `#[repr(C)]` structs passed by pointer, and the two opaque handles.
//!
//! Enumerators carry their C names (C enumerators share one namespace, hence the `GLINT_`
//! prefix). Struct fields that hold an enumeration are `uint32_t`, not the enum type: a C
//! caller may store any integer there, and reading an out-of-range value into a Rust enum would
//! be undefined behaviour; the value is validated instead.

use std::ffi::c_int;

use glint_brdf::{DiscreteBrdf, QueryScratch};

/// What a call did: `GLINT_OK`, or why it failed (then `glint_last_error()` says more).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[allow(non_camel_case_types)] // the C names
pub enum GlintStatus {
    /// Success.
    GLINT_OK = 0,
    /// A required pointer argument was NULL.
    GLINT_NULL_POINTER = 1,
    /// A material parameter is invalid (`glint_material_new`).
    GLINT_INVALID_PARAMETER = 2,
    /// A query argument is invalid: a direction that is not finite or is zero, a footprint
    /// that is not finite or has an edge component beyond ±1e15, uniform numbers outside
    /// [0, 1).
    GLINT_INVALID_ARGUMENT = 3,
    /// An internal error: glint panicked. The panic was caught at the boundary; the message
    /// says where. Please report it.
    GLINT_PANIC = 4,
}

/// The microfacet distribution of the flake normals (`GlintMaterialParams::distribution`):
/// `GLINT_<NAME>` for each of glint-brdf's kinds, numbered in the order of its table
/// (`DistributionKind::ALL`; a test checks the header against it).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[allow(non_camel_case_types)] // the C names
pub enum GlintDistribution {
    /// Beckmann.
    GLINT_BECKMANN = 0,
    /// GGX (Trowbridge–Reitz).
    GLINT_GGX = 1,
    /// Ashikhmin and Shirley's anisotropic Phong, exponents e = 2/α² − 2.
    GLINT_ASHIKHMIN_SHIRLEY = 2,
}

/// The Fresnel term (`GlintMaterialParams::fresnel`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[allow(non_camel_case_types)] // the C names
pub enum GlintFresnel {
    /// F = 1.
    GLINT_FRESNEL_NONE = 0,
    /// A conductor with complex index `conductor_eta` + i `conductor_k` per RGB channel.
    GLINT_FRESNEL_CONDUCTOR = 1,
    /// A dielectric with relative index `dielectric_eta`.
    GLINT_FRESNEL_DIELECTRIC = 2,
}

/// How a tree node's particles are divided among its children
/// (`GlintMaterialParams::multinomial`); the two give different particle sets.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[allow(non_camel_case_types)] // the C names
pub enum GlintMultinomial {
    /// Exact multinomial draws.
    GLINT_MULTINOMIAL_EXACT = 0,
    /// The paper's normal approximation.
    GLINT_MULTINOMIAL_NORMAL = 1,
}

/// How queries expecting many particles are answered (`GlintMaterialParams::dense`).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[allow(non_camel_case_types)]
pub enum GlintDense {
    /// Nodes at the query's scale that hold many particles answer from a rescaled sample of
    /// 32 of them: the exact counts' mean and correlations at a cost bounded whatever N.
    GLINT_DENSE_SAMPLED = 0,
    /// Every particle resolved (exact counts; the cost grows with N).
    GLINT_DENSE_EXACT = 1,
    /// Queries expecting many particles are answered from the points below a threshold of a
    /// Poisson process laid on cells: the exact counts' mean and correlations, nested across
    /// footprint sizes (counts follow the camera moving closer), at a cost that does not grow
    /// with N; others as `GLINT_DENSE_SAMPLED`. The default.
    GLINT_DENSE_LATTICE = 2,
}

/// How the density and roughness maps are reconstructed between their texels
/// (`GlintMaterialParams::map_filter`); the tint map is nearest under either.
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[allow(non_camel_case_types)]
pub enum GlintMapFilter {
    /// Each texel constant over its square.
    GLINT_MAP_FILTER_NEAREST = 0,
    /// Bilinear between the texels' centres, wrapping as the map tiles: a mask's edge ramps
    /// over one texel (counts stay exact for the interpolated map).
    GLINT_MAP_FILTER_BILINEAR = 1,
}

/// How the sampler's pdf integrates over the cone of radius γ.
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[allow(non_camel_case_types)]
pub enum GlintPdfQuadrature {
    /// Cubature rules: 7 points exact to degree 5 for cones up to γ = 0.35 α_s, a 32-point
    /// polar Gauss rule for wider ones (quasi-Monte Carlo for cones across the horizon).
    GLINT_PDF_CUBATURE = 0,
    /// The paper's quasi-Monte Carlo rule over `pdf_points` points.
    GLINT_PDF_QMC = 1,
}

/// The parameters of a glint material. Fill it with `glint_material_params_default`, change
/// what you need, and pass it to `glint_material_new`, which validates every field.
///
/// | field | default | allowed |
/// |---|---|---|
/// | `distribution` | `GLINT_BECKMANN` | a `GlintDistribution` |
/// | `alpha_x`, `alpha_y` | 0.1 | [1e-4, 1] |
/// | `particles` | 1e6 | a whole number in [1, 2^53] |
/// | `gamma_degrees` | 1 | [5.73e-5, 60] (1e-6 rad to 60 degrees) |
/// | `epsilon` | 0.1 | [0, 1]: Eq. 10's early stop (0 = off; exact counts are 0 with `dense` = `GLINT_DENSE_EXACT`: the default dense mode still answers dense queries from the lattice) |
/// | `seed` | 0 | any |
/// | `fresnel` | `GLINT_FRESNEL_NONE` | a `GlintFresnel` |
/// | `conductor_eta`, `conductor_k` | {1, 1, 1}, {0, 0, 0} | eta in [1e-3, 1e3], k in [0, 1e3] |
/// | `dielectric_eta` | 1.5 | [1e-3, 1e3] |
/// | `multinomial` | `GLINT_MULTINOMIAL_EXACT` | a `GlintMultinomial` |
/// | `expected_footprint_area` | 1e-6 | finite, > 0 |
/// | `pdf_quadrature` | `GLINT_PDF_CUBATURE` | a `GlintPdfQuadrature` |
/// | `pdf_points` | 64 | 1 to 4096 |
/// | `negligible_count` | 1e-12 | finite, >= 0: queries provably below this expected count answer 0 untraversed (glint-tracer's and `eval`'s default; 0 = every query traversed) |
/// | `density_map`, `_width`, `_height` | NULL, 0, 0 | values in [0, 1], not all 0 |
/// | `alpha_map`, `_width`, `_height` | NULL, 0, 0 | values in [1e-4, 1] |
/// | `tint_map`, `_width`, `_height` | NULL, 0, 0 | 3 values per texel in [0, 1] |
/// | `roughness_levels` | 8 | 1 to 64 |
/// | `dense` | `GLINT_DENSE_LATTICE` | a `GlintDense` |
/// | `dense_node_scale` | 1 | (0, 16]: the largest node sampled, in widths of the query |
/// | `map_filter` | `GLINT_MAP_FILTER_NEAREST` | a `GlintMapFilter` (density and roughness maps) |
///
/// A map has width × height ≤ 2^28 texels, row 0 at the top of the texture; it is copied, so
/// the caller's array may be freed once `glint_material_new` returns. A bad texel is an error
/// naming the map and the texel (column, row).
///
/// Every range is glint-brdf's, the same in `cargo xtask eval`, Python and scene files.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GlintMaterialParams {
    /// The distribution D of the flake normals: a `GlintDistribution`.
    pub distribution: u32,
    /// Roughness along x (the texture's u direction).
    pub alpha_x: f64,
    /// Roughness along y (equal to `alpha_x` for an isotropic material).
    pub alpha_y: f64,
    /// N, flakes per unit texture square: a whole number in [1, 2^53].
    pub particles: f64,
    /// γ, the radius of the cone around the outgoing direction, in degrees.
    pub gamma_degrees: f64,
    /// ε of Eq. 10: a partly covered node whose expected error is below ε times the count so
    /// far adds its expected share instead of splitting (0 = off). 0 alone is not exact
    /// counting: exact counts are 0 with `dense` = `GLINT_DENSE_EXACT`.
    pub epsilon: f64,
    /// Which particle set.
    pub seed: u64,
    /// The Fresnel term: a `GlintFresnel`.
    pub fresnel: u32,
    /// The conductor's η per RGB channel (used with `GLINT_FRESNEL_CONDUCTOR`).
    pub conductor_eta: [f64; 3],
    /// The conductor's k per RGB channel (used with `GLINT_FRESNEL_CONDUCTOR`).
    pub conductor_k: [f64; 3],
    /// The dielectric's relative index η (used with `GLINT_FRESNEL_DIELECTRIC`).
    pub dielectric_eta: f64,
    /// Exact multinomial splits or the paper's normal approximation: a `GlintMultinomial`.
    pub multinomial: u32,
    /// The footprint area (texture units) the tree is shaped for (Eq. 11).
    pub expected_footprint_area: f64,
    /// The sampler pdf's rule over the cone: a `GlintPdfQuadrature`.
    pub pdf_quadrature: u32,
    /// Quasi-Monte Carlo points of the sampler's pdf (under `GLINT_PDF_QMC`, and for cones
    /// the cubature does not cover).
    pub pdf_points: u32,
    /// τ: a query whose expected count is provably below τ is answered 0 without a traversal.
    pub negligible_count: f64,
    /// The density map d(x) in [0, 1] (N·d(x) flakes per unit area; 0 masks): width × height
    /// doubles row by row, row 0 at the top of the texture (v near 1), column 0 at u = 0.
    /// NULL for none. Copied by `glint_material_new`.
    pub density_map: *const f64,
    /// The density map's width in texels (0 without a map).
    pub density_map_width: u32,
    /// The density map's height in texels (0 without a map).
    pub density_map_height: u32,
    /// The roughness map α(x) in [1e-4, 1] (isotropic, replacing `alpha_x`/`alpha_y`), laid
    /// out as `density_map`; NULL for none. With a density map it must have its size.
    pub alpha_map: *const f64,
    /// The roughness map's width in texels.
    pub alpha_map_width: u32,
    /// The roughness map's height in texels.
    pub alpha_map_height: u32,
    /// The tint map t(x) in [0, 1]^3 scaling the flakes' reflectance: width × height RGB
    /// triples (3 doubles each), laid out as `density_map`; NULL for none.
    pub tint_map: *const f64,
    /// The tint map's width in texels.
    pub tint_map_width: u32,
    /// The tint map's height in texels.
    pub tint_map_height: u32,
    /// K, the most roughness levels of a roughness map (exact up to K distinct values).
    pub roughness_levels: u32,
    /// How queries expecting many particles are answered: a `GlintDense`.
    pub dense: u32,
    /// The largest node `GLINT_DENSE_SAMPLED` (and `GLINT_DENSE_LATTICE` where it leaves a
    /// query to the tree) answers from its sample, in widths of the query.
    pub dense_node_scale: f64,
    /// How `density_map` and `alpha_map` are reconstructed between texels: a
    /// `GlintMapFilter` (the tint map is nearest under either).
    pub map_filter: u32,
}

/// A pixel's texture-space footprint: the parallelogram
/// {uv + s·duv_dx + t·duv_dy : s, t in [-1/2, 1/2]}. The texture repeats; a zero-area
/// footprint is valid and finds nothing. Every number must be finite, and each component of
/// `duv_dx` and `duv_dy` within ±1e15 (the area times N then stays finite); a footprint of
/// more than 256 tiles of area (or spanning 4096) is answered by its periodic average.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GlintFootprint {
    /// The centre (u, v).
    pub uv: [f64; 2],
    /// The change of (u, v) across the pixel in x.
    pub duv_dx: [f64; 2],
    /// The change of (u, v) across the pixel in y.
    pub duv_dy: [f64; 2],
}

/// One glint evaluation: f̂ with what its count-tree query found.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GlintEvaluation {
    /// f̂ per RGB channel, the discrete BRDF (Eq. 5, corrected normalization).
    pub f_hat: [f64; 3],
    /// D̂ of Eq. 6 per channel: the count over N.
    pub d_hat: [f64; 3],
    /// Particles found (fractional where Eq. 10 stopped early with ε > 0).
    pub count: f64,
    /// Tree nodes tested against the query.
    pub nodes_visited: u32,
    /// The visited nodes that meet the query.
    pub nodes_overlapping: u32,
    /// 1 when the query was skipped as negligible (then every other field but
    /// `negligible_bound` is 0), else 0.
    pub skipped_as_negligible: c_int,
    /// λ̄, the proven bound on the expected count of a skipped query; 0 otherwise.
    pub negligible_bound: f64,
}

impl GlintEvaluation {
    /// Every field 0 (the evaluation of a batch row that failed).
    pub(crate) const ZERO: Self = Self {
        f_hat: [0.0; 3],
        d_hat: [0.0; 3],
        count: 0.0,
        nodes_visited: 0,
        nodes_overlapping: 0,
        skipped_as_negligible: 0,
        negligible_bound: 0.0,
    };
}

/// A sampled outgoing direction.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GlintSample {
    /// The direction (unit, above the horizon).
    pub wo: [f64; 3],
    /// Its density in solid angle.
    pub pdf: f64,
    /// Deprecated (to be removed in the next version): `footprint_weight` when a footprint
    /// was given, else `smooth_weight`.
    pub weight: [f64; 3],
    /// 1 for a sample, 0 when none was drawn (then every other field is 0).
    pub valid: c_int,
    /// f_smooth·cos θ_o / pdf per RGB channel: the smooth BRDF's weight, for a path that
    /// carries no footprint (after the first bounce).
    pub smooth_weight: [f64; 3],
    /// f̂·cos θ_o / pdf per RGB channel with the footprint given (a glint query): the
    /// reflected radiance for unit radiance from `wo`, as Rust's `GlintBxdf::sample` and
    /// Python's `footprint_weight` give it; 0 without a footprint.
    pub footprint_weight: [f64; 3],
}

/// A glint material (opaque): its particle set, sampler and smooth limit. Immutable once
/// built: share one between any number of threads.
#[derive(Debug)]
pub struct GlintMaterial {
    pub(crate) brdf: DiscreteBrdf,
}

/// A query's working memory (opaque): one per thread, reused across queries and materials.
#[derive(Debug, Default)]
pub struct GlintScratch {
    pub(crate) scratch: QueryScratch,
    /// Set during a query; still set at the next call only if that query panicked, and then
    /// the scratch's memo tables are not trusted and are replaced.
    pub(crate) in_query: bool,
}

// The thread-safety contract stated in the crate documentation rests on these.
const _: () = {
    const fn shared_between_threads<T: Send + Sync>() {}
    const fn moved_between_threads<T: Send>() {}
    shared_between_threads::<DiscreteBrdf>();
    moved_between_threads::<QueryScratch>();
};
