//! Materials: diffuse, smooth microfacet conductor, plastic, the glint material, the perfect
//! mirror and linear combinations. Directions are in the local shading frame (n = +z), both pointing away from
//! the surface: `wi` toward the viewer (the direction a path arrives from), `wo` toward the
//! light. Every BRDF here is reciprocal, so the order only matters for sampling, which draws
//! `wo` given `wi`.

use std::sync::Arc;

use glam::{DVec2, DVec3};
use glint_brdf::{Bxdf, DiscreteBrdf, Footprint, Fresnel, MicrofacetBrdf, QueryScratch};
use std::f64::consts::PI;

use crate::image::RgbImage;
use crate::particle_histogram::ParticleHistogram;

/// A colour that may vary over the surface.
#[derive(Clone, Debug, PartialEq)]
pub enum Texture {
    /// One colour.
    Constant(DVec3),
    /// An image, repeated `scale` times over the surface's (u, v) square and multiplied by
    /// `tint`.
    Image {
        /// The texels.
        image: Arc<RgbImage>,
        /// Repetitions per unit of (u, v).
        scale: DVec2,
        /// A factor on every texel.
        tint: DVec3,
    },
}

impl Texture {
    /// The colour at `uv`.
    #[must_use]
    pub fn at(&self, uv: DVec2) -> DVec3 {
        match self {
            Self::Constant(c) => *c,
            Self::Image { image, scale, tint } => image.lookup(uv * *scale) * *tint,
        }
    }

    /// The mean colour (for the power of textured lights).
    #[must_use]
    pub fn mean(&self) -> DVec3 {
        match self {
            Self::Constant(c) => *c,
            Self::Image { image, tint, .. } => image.mean() * *tint,
        }
    }
}

/// Diffuse under a rough dielectric coating, in the simplest energy-aware form: the coat's
/// microfacet reflection plus the Lambertian base seen through the coat twice,
/// f = f_coat + (1 − F(cos θ_i))(1 − F(cos θ_o))·ρ/π. Internal reflections between coat and base
/// are ignored, so the model is slightly darker than a layered simulation; it never creates
/// energy (F ∈ [0, 1], and f_coat alone is a microfacet BRDF).
#[derive(Clone, Debug, PartialEq)]
pub struct Plastic {
    /// The base's albedo ρ.
    pub base: Texture,
    /// The coating (a dielectric Fresnel).
    pub coat: MicrofacetBrdf,
    /// The coating's index of refraction.
    pub eta: f64,
}

/// The glint material: a discrete BRDF, its texture scale and whether glints are off.
#[derive(Clone, Debug)]
pub struct GlintMaterial {
    /// The multiscale BRDF (shared: building it costs the NDF quadrature).
    pub brdf: Arc<DiscreteBrdf>,
    /// Texture repetitions per unit of the surface's (u, v): the particles' unit square is
    /// 1/scale of the surface parameter square.
    pub uv_scale: f64,
    /// Whether the scene's prior run chooses the tree's `expected_footprint_area` (see
    /// [`crate::plan`]); false when the scene file sets it.
    pub plan_footprint_area: bool,
}

impl GlintMaterial {
    /// The same material with the particle set of `seed` ([`Self::with_realization`]).
    ///
    /// # Errors
    /// None in practice: the parameters were valid when the material was built.
    pub fn reseeded(&self, seed: u64) -> Result<Self, glint_brdf::BrdfError> {
        let area = self.brdf.parameters().expected_footprint_area;
        self.with_realization(seed, area)
    }

    /// The same material with another particle set of the same law, for `seed` and the
    /// expected footprint area `area` of Eq. 11
    /// ([`glint_brdf::DiscreteBrdf::with_realization`]: only the tree's top levels are built
    /// again).
    ///
    /// # Errors
    /// A [`glint_brdf::BrdfError`] unless `area` is positive and finite.
    pub fn with_realization(&self, seed: u64, area: f64) -> Result<Self, glint_brdf::BrdfError> {
        Ok(Self {
            brdf: Arc::new(self.brdf.with_realization(seed, area)?),
            uv_scale: self.uv_scale,
            plan_footprint_area: self.plan_footprint_area,
        })
    }

    /// The same material with its parameters changed by `change` (rebuilds the tree: ~2 ms).
    ///
    /// # Errors
    /// A [`glint_brdf::BrdfError`] if the changed parameters are invalid.
    pub fn rebuilt(
        &self,
        change: impl FnOnce(&mut glint_brdf::GlintParameters),
    ) -> Result<Self, glint_brdf::BrdfError> {
        let mut parameters = self.brdf.parameters().clone();
        change(&mut parameters);
        Ok(Self {
            brdf: Arc::new(DiscreteBrdf::new(parameters)?),
            uv_scale: self.uv_scale,
            plan_footprint_area: self.plan_footprint_area,
        })
    }
}

/// A perfect mirror: delta reflection about the shading normal, f = R δ(ω_o − reflect(ω_i)) /
/// cos θ_o with reflectance R = `colour`·F(cos θ_i). It has no density: the integrator reflects
/// paths at it itself (no light sample, no MIS), and carries the pixel footprint on
/// (`crate::differentials`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mirror {
    /// A factor on the reflectance per channel, in [0, 1].
    pub colour: DVec3,
    /// The Fresnel term ([`Fresnel::None`]: R = `colour` at every angle).
    pub fresnel: Fresnel,
}

impl Mirror {
    /// The reflectance R at `cos_theta` = cos θ_i.
    #[must_use]
    pub fn reflectance(&self, cos_theta: f64) -> DVec3 {
        self.colour * self.fresnel.evaluate(cos_theta)
    }
}

/// A material.
#[derive(Clone, Debug)]
pub enum Material {
    /// Lambertian reflection with albedo ρ: f = ρ/π.
    Diffuse(Texture),
    /// A smooth microfacet BRDF (a rough conductor, or any Fresnel).
    Microfacet(MicrofacetBrdf),
    /// Diffuse under a rough dielectric coating.
    Plastic(Plastic),
    /// The discrete multiscale BRDF: f̂ with a footprint, its smooth limit at the shading
    /// point without ([`GlintMaterial::smooth_at`]).
    Glint(GlintMaterial),
    /// The smooth limit of a glint material with maps, everywhere (what
    /// [`Material::smooth_limit`] makes of one): f = Σ_k d_k(x)·f_k·t(x) at the shading point's
    /// texture position x ([`glint_brdf::DiscreteBrdf::smooth_at`]), sampled by the glint
    /// sampler at x. A glint material without maps becomes [`Material::Microfacet`] instead.
    SmoothGlint(GlintMaterial),
    /// Σ w_k f_k with weights w_k ≥ 0 (a component is sampled with probability w_k / Σ w).
    /// Mirror components contribute nothing (scene files reject them).
    Mix(Vec<(f64, Material)>),
    /// A perfect mirror: `eval` and `pdf` are 0 and `sample_direction` is `None` for it, as
    /// for any delta distribution; the integrator handles it (see [`Mirror`]).
    Mirror(Mirror),
}

/// Glint queries made while shading, for the paper's Table 1 statistics.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GlintCounters {
    /// Tree queries.
    pub queries: u64,
    /// Tree nodes visited (tested against the query), summed over queries.
    pub nodes_visited: u64,
    /// The visited nodes that meet the query, summed over queries.
    pub nodes_overlapping: u64,
    /// Particles found, summed over queries.
    pub particles_found: f64,
    /// Queries skipped as negligible (answered 0 without a traversal; counted in `queries`).
    pub negligible_queries: u64,
    /// The skipped queries' bounds on their expected counts, summed: an upper bound on the
    /// expected number of particles the skipping missed, and on the probability that the image
    /// differs from a render that traverses every query.
    pub negligible_bound: f64,
    /// The particles each query found (skipped ones found 0), binned.
    pub particles: ParticleHistogram,
}

impl GlintCounters {
    /// Adds another set of counters.
    pub fn add(&mut self, other: &Self) {
        self.queries += other.queries;
        self.nodes_visited += other.nodes_visited;
        self.nodes_overlapping += other.nodes_overlapping;
        self.particles_found += other.particles_found;
        self.negligible_queries += other.negligible_queries;
        self.negligible_bound += other.negligible_bound;
        self.particles.add(&other.particles);
    }

    /// Counts one query and what it found.
    fn record(&mut self, result: &glint_brdf::GlintEvaluation) {
        self.queries += 1;
        self.nodes_visited += u64::from(result.nodes_visited);
        self.nodes_overlapping += u64::from(result.nodes_overlapping);
        self.particles_found += result.count;
        self.particles.record(result.count);
        if let Some(bound) = result.negligible {
            self.negligible_queries += 1;
            self.negligible_bound += bound;
        }
    }

    /// Queries that traversed the tree (not skipped as negligible).
    #[must_use]
    pub fn traversed_queries(&self) -> u64 {
        self.queries - self.negligible_queries
    }

    /// Mean tree nodes visited per traversed query (skipped queries visit none; leaving them
    /// out keeps the figure comparable with the paper's Table 1, which skips nothing).
    #[must_use]
    pub fn nodes_per_query(&self) -> f64 {
        self.nodes_visited as f64 / self.traversed_queries().max(1) as f64
    }

    /// Mean nodes meeting the query per traversed query.
    #[must_use]
    pub fn overlapping_nodes_per_query(&self) -> f64 {
        self.nodes_overlapping as f64 / self.traversed_queries().max(1) as f64
    }

    /// Mean particles found per query.
    #[must_use]
    pub fn particles_per_query(&self) -> f64 {
        self.particles_found / self.queries.max(1) as f64
    }

    /// The particles 99% of the queries found at most, to within a factor 2^¼ above
    /// ([`ParticleHistogram::quantile_bound`]).
    #[must_use]
    pub fn particles_per_query_p99(&self) -> f64 {
        self.particles.quantile_bound(0.99)
    }
}

/// What shading a point needs besides the directions.
#[derive(Debug)]
pub struct ShadingContext<'a> {
    /// Texture coordinates of the point.
    pub uv: DVec2,
    /// The pixel's texture-space derivatives (∂(u,v)/∂x, ∂(u,v)/∂y) when glints should use the
    /// footprint; `None` evaluates glint materials by their smooth limit.
    pub footprint: Option<(DVec2, DVec2)>,
    /// The tree's working memory.
    pub scratch: &'a mut QueryScratch,
    /// Where glint queries are counted (the counters of the material being shaded).
    pub counters: &'a mut GlintCounters,
}

/// A sampled direction: `wo` with the material's total f and pdf there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaterialSample {
    /// The direction toward the light (local frame).
    pub wo: DVec3,
    /// f(wi, wo).
    pub f: DVec3,
    /// The density of `wo` in solid angle.
    pub pdf: f64,
}

/// `f` where it is 0, or where `visible()` (asked only for a nonzero `f`) holds; `None` when
/// it said no.
fn nonzero_where_visible(f: DVec3, visible: impl FnOnce() -> bool) -> Option<DVec3> {
    if f == DVec3::ZERO {
        Some(f)
    } else {
        visible().then_some(f)
    }
}

fn above(w: DVec3) -> bool {
    w.is_finite() && w.z > 0.0
}

/// A cosine-distributed direction (Malley's method, concentric disk mapping).
#[must_use]
pub fn sample_cosine_hemisphere(u: [f64; 2]) -> DVec3 {
    let (a, b) = (2.0 * u[0] - 1.0, 2.0 * u[1] - 1.0);
    let (r, phi) = if a == 0.0 && b == 0.0 {
        (0.0, 0.0)
    } else if a.abs() > b.abs() {
        (a, 0.25 * PI * (b / a))
    } else {
        (b, 0.5 * PI - 0.25 * PI * (a / b))
    };
    let (x, y) = (r * phi.cos(), r * phi.sin());
    DVec3::new(x, y, (1.0 - x * x - y * y).max(0.0).sqrt())
}

impl GlintMaterial {
    /// The context's footprint in this material's particle squares (scaled by `uv_scale`):
    /// `None` without one, or when it exceeds what a footprint may span
    /// ([`Footprint::MAX_EDGE`]); the material then shades its smooth limit.
    pub(crate) fn footprint(&self, ctx: &ShadingContext<'_>) -> Option<Footprint> {
        let (dx, dy) = ctx.footprint?;
        let s = self.uv_scale;
        Footprint::new(ctx.uv * s, dx * s, dy * s).ok()
    }

    /// The shading point's position `uv` (the shape's) in this material's particle square,
    /// where its maps are read: `uv` scaled by `uv_scale`, as the footprint's centre is.
    fn texture_position(&self, uv: DVec2) -> DVec2 {
        uv * self.uv_scale
    }

    /// The smooth limit at the shading point `uv` (the shape's (u, v)): the map-weighted
    /// smooth BRDF ([`glint_brdf::DiscreteBrdf::smooth_at`]); without maps, the smooth
    /// microfacet BRDF's value, bit for bit.
    #[must_use]
    pub fn smooth_at(&self, wi: DVec3, wo: DVec3, uv: DVec2) -> DVec3 {
        self.brdf.smooth_at(wi, wo, self.texture_position(uv))
    }

    /// The glint sampler's direction at the shading point `uv` (the shape's (u, v)): under a
    /// roughness map, the level is chosen by the densities there.
    fn sample_direction(&self, wi: DVec3, u: [f64; 4], uv: DVec2) -> Option<DVec3> {
        self.brdf
            .sample_direction_at(wi, u, self.texture_position(uv))
    }

    /// The density of [`GlintMaterial::sample_direction`] in solid angle.
    fn sampling_pdf(&self, wi: DVec3, wo: DVec3, uv: DVec2) -> f64 {
        self.brdf.sampling_pdf_at(wi, wo, self.texture_position(uv))
    }

    /// The smooth limit where no glint query is made: at the shading point without a
    /// footprint; averaged over the particle square ([`glint_brdf::DiscreteBrdf::smooth_mean`])
    /// for a footprint too large (or not finite) to query, which covers more tiles than a
    /// query may span and so sees the whole square's flakes, not the texel under `uv`.
    fn smooth_unqueried(&self, wi: DVec3, wo: DVec3, ctx: &ShadingContext<'_>) -> DVec3 {
        if ctx.footprint.is_some() {
            self.brdf.smooth_mean(wi, wo)
        } else {
            self.smooth_at(wi, wo, ctx.uv)
        }
    }

    /// f̂ for the context's footprint (counting the query), or the smooth limit
    /// ([`Self::smooth_unqueried`]) without one it can query.
    fn eval(&self, wi: DVec3, wo: DVec3, ctx: &mut ShadingContext<'_>) -> DVec3 {
        let Some(footprint) = self.footprint(ctx) else {
            return self.smooth_unqueried(wi, wo, ctx);
        };
        let result = self.brdf.at(&footprint, ctx.scratch).evaluate(wi, wo);
        ctx.counters.record(&result);
        result.f_hat
    }

    /// [`Self::eval`] where `visible()` holds, calling it only if f needs it: with a footprint,
    /// after the negligible-query test and before the tree traversal (a skipped query answers
    /// 0 without it); without one, where the smooth f is not 0. `None` when `visible()` said
    /// no (nothing counted).
    fn eval_if_visible(
        &self,
        wi: DVec3,
        wo: DVec3,
        ctx: &mut ShadingContext<'_>,
        visible: impl FnOnce() -> bool,
    ) -> Option<DVec3> {
        let Some(footprint) = self.footprint(ctx) else {
            return nonzero_where_visible(self.smooth_unqueried(wi, wo, ctx), visible);
        };
        let result = self
            .brdf
            .at(&footprint, ctx.scratch)
            .evaluate_if(wi, wo, visible)?;
        ctx.counters.record(&result);
        Some(result.f_hat)
    }

    /// f̂ for the cone of half-angle `half_angle` around `axis` (local) with the context's
    /// footprint (counting the query): [`glint_brdf::GlintBxdf::evaluate_in_cone`]. Zero
    /// without a valid footprint (light cones apply only where there is one).
    pub fn evaluate_in_cone(
        &self,
        wi: DVec3,
        axis: DVec3,
        half_angle: f64,
        ctx: &mut ShadingContext<'_>,
    ) -> DVec3 {
        let Some(footprint) = self.footprint(ctx) else {
            return DVec3::ZERO;
        };
        let result = self
            .brdf
            .at(&footprint, ctx.scratch)
            .evaluate_in_cone(wi, axis, half_angle);
        ctx.counters.record(&result);
        result.f_hat
    }
}

impl Plastic {
    fn fresnel(&self, cos: f64) -> f64 {
        Fresnel::Dielectric { eta: self.eta }.evaluate(cos).x
    }

    fn eval(&self, wi: DVec3, wo: DVec3, uv: DVec2) -> DVec3 {
        if !(above(wi) && above(wo)) {
            return DVec3::ZERO;
        }
        let transmitted = (1.0 - self.fresnel(wi.z)) * (1.0 - self.fresnel(wo.z));
        self.coat.eval(wi, wo) + self.base.at(uv) * (transmitted / PI)
    }

    /// The probability of sampling the coat rather than the base.
    fn coat_probability(&self, wi: DVec3, uv: DVec2) -> f64 {
        let f = self.fresnel(wi.z);
        let base = (1.0 - f) * self.base.at(uv).max_element();
        (f / (f + base).max(1e-12)).clamp(0.1, 0.9)
    }

    fn pdf(&self, wi: DVec3, wo: DVec3, uv: DVec2) -> f64 {
        if !(above(wi) && above(wo)) {
            return 0.0;
        }
        let p = self.coat_probability(wi, uv);
        p * self.coat.pdf(wi, wo) + (1.0 - p) * wo.z / PI
    }
}

impl Material {
    /// The glint material replaced by its smooth limit (for `--smooth`), recursively: the
    /// smooth microfacet BRDF without maps, [`Material::SmoothGlint`] with them.
    #[must_use]
    pub fn smooth_limit(&self) -> Self {
        match self {
            Self::Glint(g) if g.brdf.has_maps() => Self::SmoothGlint(g.clone()),
            Self::Glint(g) => Self::Microfacet(*g.brdf.smooth()),
            Self::Mix(parts) => {
                Self::Mix(parts.iter().map(|(w, m)| (*w, m.smooth_limit())).collect())
            }
            other => other.clone(),
        }
    }

    /// Every glint part reseeded with its seed mixed with `salt` (a new particle set).
    ///
    /// # Errors
    /// As [`GlintMaterial::reseeded`].
    pub fn reseeded(&self, salt: u64) -> Result<Self, glint_brdf::BrdfError> {
        self.map_glints(&|g| {
            let seed = g.brdf.parameters().seed;
            g.reseeded(seed ^ salt.wrapping_mul(0x9e37_79b9_7f4a_7c15))
        })
    }

    /// The same material with every glint part's `negligible_count` set to `count` (0
    /// traverses every query; see glint-brdf's "Negligible queries").
    ///
    /// # Errors
    /// [`glint_brdf::BrdfError::InvalidNegligibleCount`] unless `count` is finite and ≥ 0.
    pub fn with_negligible_count(&self, count: f64) -> Result<Self, glint_brdf::BrdfError> {
        self.map_glints(&|g| g.rebuilt(|parameters| parameters.negligible_count = count))
    }

    /// The material with every glint part replaced by `rebuild` of it (other parts cloned).
    pub(crate) fn map_glints(
        &self,
        rebuild: &dyn Fn(&GlintMaterial) -> Result<GlintMaterial, glint_brdf::BrdfError>,
    ) -> Result<Self, glint_brdf::BrdfError> {
        Ok(match self {
            Self::Glint(g) => Self::Glint(rebuild(g)?),
            Self::Mix(parts) => Self::Mix(
                parts
                    .iter()
                    .map(|(w, m)| Ok((*w, m.map_glints(rebuild)?)))
                    .collect::<Result<_, glint_brdf::BrdfError>>()?,
            ),
            other => other.clone(),
        })
    }

    /// The glint parts of the material, in order (itself, or a mix's, recursively).
    fn glint_parts(&self) -> Vec<&GlintMaterial> {
        match self {
            Self::Glint(g) => vec![g],
            Self::Mix(parts) => parts.iter().flat_map(|(_, m)| m.glint_parts()).collect(),
            _ => Vec::new(),
        }
    }

    /// The `expected_footprint_area` of each glint part, in order (Eq. 11's plan, see
    /// [`crate::plan`]); empty for materials without glints.
    #[must_use]
    pub fn expected_footprint_areas(&self) -> Vec<f64> {
        self.glint_parts()
            .iter()
            .map(|g| g.brdf.parameters().expected_footprint_area)
            .collect()
    }

    /// N, the particles per texture square, of each glint part, in order; empty for materials
    /// without glints.
    #[must_use]
    pub fn glint_particles(&self) -> Vec<u64> {
        self.glint_parts()
            .iter()
            .map(|g| g.brdf.parameters().particles)
            .collect()
    }

    /// Whether any part of the material is a glint material.
    #[must_use]
    pub fn has_glints(&self) -> bool {
        match self {
            Self::Glint(_) => true,
            Self::Mix(parts) => parts.iter().any(|(_, m)| m.has_glints()),
            _ => false,
        }
    }

    /// f(wi, wo) per RGB channel.
    pub fn eval(&self, wi: DVec3, wo: DVec3, ctx: &mut ShadingContext<'_>) -> DVec3 {
        if !(above(wi) && above(wo)) {
            return DVec3::ZERO;
        }
        match self {
            Self::Diffuse(albedo) => albedo.at(ctx.uv) / PI,
            Self::Microfacet(brdf) => brdf.eval(wi, wo),
            Self::Plastic(plastic) => plastic.eval(wi, wo, ctx.uv),
            Self::Glint(glint) => glint.eval(wi, wo, ctx),
            Self::SmoothGlint(glint) => glint.smooth_at(wi, wo, ctx.uv),
            Self::Mix(parts) => parts.iter().map(|(w, m)| *w * m.eval(wi, wo, ctx)).sum(),
            Self::Mirror(_) => DVec3::ZERO,
        }
    }

    /// f(wi, wo) toward a light where `visible()` (a shadow ray) holds, calling it only if f
    /// needs it; `None` when it said no. A glint material with a footprint asks after its
    /// negligible-query test and before its tree traversal (microseconds, against a fraction
    /// of one for the ray), so a query skipped as negligible costs no ray; a mix with glints
    /// asks first; other materials ask where f is not 0.
    pub fn eval_if_visible(
        &self,
        wi: DVec3,
        wo: DVec3,
        ctx: &mut ShadingContext<'_>,
        visible: impl FnOnce() -> bool,
    ) -> Option<DVec3> {
        if !(above(wi) && above(wo)) {
            return Some(DVec3::ZERO);
        }
        match self {
            Self::Glint(glint) => glint.eval_if_visible(wi, wo, ctx, visible),
            Self::Mix(_) if ctx.footprint.is_some() && self.has_glints() => {
                visible().then(|| self.eval(wi, wo, ctx))
            }
            _ => nonzero_where_visible(self.eval(wi, wo, ctx), visible),
        }
    }

    /// The density of [`Material::sample`] choosing `wo`, in solid angle.
    #[must_use]
    pub fn pdf(&self, wi: DVec3, wo: DVec3, uv: DVec2) -> f64 {
        if !(above(wi) && above(wo)) {
            return 0.0;
        }
        match self {
            Self::Diffuse(_) => wo.z / PI,
            Self::Microfacet(brdf) => brdf.pdf(wi, wo),
            Self::Plastic(plastic) => plastic.pdf(wi, wo, uv),
            Self::Glint(glint) | Self::SmoothGlint(glint) => glint.sampling_pdf(wi, wo, uv),
            Self::Mix(parts) => {
                let total: f64 = parts.iter().map(|(w, _)| *w).sum();
                if !(total > 0.0) {
                    return 0.0;
                }
                parts
                    .iter()
                    .map(|(w, m)| w / total * m.pdf(wi, wo, uv))
                    .sum()
            }
            Self::Mirror(_) => 0.0,
        }
    }

    /// A direction `wo` for `wi` from the uniforms `u_lobe` (chooses a lobe) and `u` (`u[0..2]`
    /// the lobe's direction, `u[2..4]` the glint sampler's point in its cone), with the
    /// material's total f and pdf there; `None` when the sample is invalid.
    pub fn sample(
        &self,
        wi: DVec3,
        u_lobe: f64,
        u: [f64; 4],
        ctx: &mut ShadingContext<'_>,
    ) -> Option<MaterialSample> {
        if !above(wi) {
            return None;
        }
        let (wo, pdf) = self.sample_direction_pdf(wi, u_lobe, u, ctx.uv)?;
        Some(MaterialSample {
            wo,
            f: self.eval(wi, wo, ctx),
            pdf,
        })
    }

    /// The direction of [`Material::sample`] with its density, without evaluating f (which
    /// costs a tree query for glint materials with a footprint).
    #[must_use]
    pub fn sample_direction_pdf(
        &self,
        wi: DVec3,
        u_lobe: f64,
        u: [f64; 4],
        uv: DVec2,
    ) -> Option<(DVec3, f64)> {
        if !above(wi) {
            return None;
        }
        let wo = self.sample_direction(wi, u_lobe, u, uv)?;
        let pdf = self.pdf(wi, wo, uv);
        (pdf > 0.0 && pdf.is_finite()).then_some((wo, pdf))
    }

    /// Only the direction of [`Material::sample`] (no pdf, no f): a renderer that may not need
    /// them for this direction computes them itself.
    #[must_use]
    pub fn sample_direction(
        &self,
        wi: DVec3,
        u_lobe: f64,
        u: [f64; 4],
        uv: DVec2,
    ) -> Option<DVec3> {
        self.sample_lobe(wi, u_lobe, u, uv).map(|(wo, _)| wo)
    }

    /// The direction of [`Material::sample_direction`] (the same bits) with the lobe that
    /// drew it: for a mix, the sampled component's; for plastic, the coat's or the base's.
    /// The integrator carries pixel footprints on through [`Lobe::Glossy`] bounces
    /// ([`crate::differentials`]).
    #[must_use]
    pub fn sample_lobe(
        &self,
        wi: DVec3,
        u_lobe: f64,
        u: [f64; 4],
        uv: DVec2,
    ) -> Option<(DVec3, Lobe)> {
        let (wo, lobe) = match self {
            Self::Diffuse(_) => (sample_cosine_hemisphere([u[0], u[1]]), Lobe::Diffuse),
            Self::Microfacet(brdf) => (
                brdf.sample_direction(wi, [u[0], u[1]])?,
                Lobe::glossy(brdf.distribution()),
            ),
            Self::Plastic(plastic) => {
                let p = plastic.coat_probability(wi, uv);
                if u_lobe < p {
                    (
                        plastic.coat.sample_direction(wi, [u[0], u[1]])?,
                        Lobe::glossy(plastic.coat.distribution()),
                    )
                } else {
                    (sample_cosine_hemisphere([u[0], u[1]]), Lobe::Diffuse)
                }
            }
            Self::Glint(glint) | Self::SmoothGlint(glint) => {
                (glint.sample_direction(wi, u, uv)?, Lobe::Glint)
            }
            Self::Mix(parts) => {
                let total: f64 = parts.iter().map(|(w, _)| *w).sum();
                if !(total > 0.0) {
                    return None;
                }
                // Only components with positive weight can be chosen (rounding in the running
                // sum must not select a zero-weight component the pdf leaves out).
                let last = parts.iter().rposition(|(w, _)| *w > 0.0)?;
                let mut start = 0.0;
                let mut chosen = None;
                for (k, (w, m)) in parts.iter().enumerate() {
                    if !(*w > 0.0) {
                        continue;
                    }
                    let p = w / total;
                    if u_lobe < start + p || k == last {
                        let remapped = ((u_lobe - start) / p).clamp(0.0, 1.0 - f64::EPSILON);
                        chosen = Some(m.sample_lobe(wi, remapped, u, uv)?);
                        break;
                    }
                    start += p;
                }
                chosen?
            }
            Self::Mirror(_) => return None,
        };
        above(wo).then_some((wo, lobe))
    }
}

/// The lobe a sampled direction came from (see [`Material::sample_lobe`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Lobe {
    /// Lambertian reflection (diffuse, or plastic's base).
    Diffuse,
    /// Reflection about a facet normal of a smooth microfacet distribution (a conductor, or
    /// plastic's coat): the direction is the mirror reflection of ω_i about the half vector.
    Glossy {
        /// The distribution's larger roughness, max(α_x, α_y).
        alpha: f64,
    },
    /// The glint material's sampler (a particle's normal within the cone γ).
    Glint,
}

impl Lobe {
    fn glossy(distribution: &glint_brdf::Microfacet) -> Self {
        let (alpha_x, alpha_y) = distribution.alpha();
        Self::Glossy {
            alpha: alpha_x.max(alpha_y),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glint_brdf::{
        DensityMap, DistributionKind, GlintParameters, Microfacet, NormalSampling, TintMap,
    };

    fn materials() -> Vec<Material> {
        let ggx = Microfacet::new(DistributionKind::Ggx, 0.2, 0.2).unwrap();
        let conductor = MicrofacetBrdf::new(
            ggx,
            Fresnel::Conductor {
                eta: DVec3::new(0.2, 0.9, 1.1),
                k: DVec3::new(3.9, 2.4, 2.2),
            },
            NormalSampling::Distribution,
        )
        .unwrap();
        let coat = MicrofacetBrdf::new(
            ggx,
            Fresnel::Dielectric { eta: 1.5 },
            NormalSampling::Distribution,
        )
        .unwrap();
        let mut parameters =
            GlintParameters::new(Microfacet::new(DistributionKind::Beckmann, 0.1, 0.1).unwrap());
        parameters.gamma_radians = 5f64.to_radians();
        let glint = Material::Glint(GlintMaterial {
            brdf: Arc::new(DiscreteBrdf::new(parameters).unwrap()),
            uv_scale: 1.0,
            plan_footprint_area: false,
        });
        vec![
            Material::Diffuse(Texture::Constant(DVec3::new(0.8, 0.5, 0.2))),
            Material::Microfacet(conductor),
            Material::Plastic(Plastic {
                base: Texture::Constant(DVec3::splat(0.6)),
                coat,
                eta: 1.5,
            }),
            glint.clone(),
            Material::Mix(vec![
                (
                    0.7,
                    Material::Diffuse(Texture::Constant(DVec3::new(0.6, 0.05, 0.05))),
                ),
                (0.3, glint),
            ]),
        ]
    }

    /// Each material's sampler, checked through its estimator: the mean of f·cos/pdf over
    /// sampled directions equals the albedo ∫ f cos dω computed by a fine quadrature, and the
    /// pdf integrates to at most 1 (to 1 where no sample falls below the horizon).
    #[test]
    fn sampling_estimators_match_quadrature() {
        let mut scratch = QueryScratch::new();
        let mut counters = GlintCounters::default();
        for (k, material) in materials().iter().enumerate() {
            for theta in [0.1f64, 0.8, 1.3] {
                let wi = DVec3::new(theta.sin(), 0.0, theta.cos());
                let mut ctx = ShadingContext {
                    uv: DVec2::new(0.3, 0.6),
                    footprint: None,
                    scratch: &mut scratch,
                    counters: &mut counters,
                };
                // Quadrature in (cos θ, φ) with 400 × 400 midpoints.
                let n = 400;
                let (mut albedo, mut pdf_integral) = (DVec3::ZERO, 0.0);
                for i in 0..n {
                    let cos_t = (f64::from(i) + 0.5) / f64::from(n);
                    let sin_t = (1.0 - cos_t * cos_t).sqrt();
                    for j in 0..n {
                        let phi = 2.0 * PI * (f64::from(j) + 0.5) / f64::from(n);
                        let wo = DVec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t);
                        let weight = 2.0 * PI / f64::from(n * n);
                        albedo += material.eval(wi, wo, &mut ctx) * cos_t * weight;
                        pdf_integral += material.pdf(wi, wo, ctx.uv) * weight;
                    }
                }
                assert!(
                    pdf_integral <= 1.0 + 2e-3,
                    "{k}: pdf integrates to {pdf_integral}"
                );
                let samples = 40_000;
                let mut estimate = DVec3::ZERO;
                let mut rng = glint_tests::SplitMix64::new(99u64 + k as u64);
                let mut next = move || rng.uniform();
                for _ in 0..samples {
                    let (a, u) = (next(), [next(), next(), next(), next()]);
                    if let Some(s) = material.sample(wi, a, u, &mut ctx) {
                        estimate += s.f * s.wo.z / s.pdf;
                        let again = material.pdf(wi, s.wo, ctx.uv);
                        assert!((again - s.pdf).abs() <= 1e-12 * s.pdf);
                    }
                }
                estimate /= f64::from(samples);
                let error = (estimate - albedo).abs().max_element();
                assert!(
                    error < 0.02 * albedo.max_element().max(0.05),
                    "{k} θ={theta}: sampled {estimate} vs quadrature {albedo}"
                );
                assert!(albedo.max_element() <= 1.0 + 1e-3, "{k}: albedo {albedo}");
            }
        }
    }

    /// `sample_lobe` draws `sample_direction`'s direction, bit for bit, and names the lobe
    /// that drew it: the conductor's and the plastic coat's are glossy with their α (the coat's
    /// direction the mirror reflection about the half vector), the plastic's base and the
    /// mix's diffuse component diffuse, the glint material's its own.
    #[test]
    fn sampled_lobes_are_the_components_that_drew_the_direction() {
        let mut rng = glint_tests::SplitMix64::new(34);
        let wi = DVec3::new(0.4, 0.1, 0.9).normalize();
        let uv = DVec2::new(0.3, 0.6);
        let mut seen = vec![Vec::new(); materials().len()];
        for (k, material) in materials().iter().enumerate() {
            for _ in 0..2000 {
                let (a, u) = (
                    rng.uniform(),
                    [rng.uniform(), rng.uniform(), rng.uniform(), rng.uniform()],
                );
                let direction = material.sample_direction(wi, a, u, uv);
                let lobe = material.sample_lobe(wi, a, u, uv);
                assert_eq!(direction, lobe.map(|(wo, _)| wo));
                let Some((wo, lobe)) = lobe else { continue };
                if let Lobe::Glossy { alpha } = lobe {
                    assert_eq!(alpha, 0.2);
                    let m = (wi + wo).normalize();
                    let mirrored = 2.0 * wi.dot(m) * m - wi;
                    assert!((mirrored - wo).length() < 1e-12);
                }
                if !seen[k].contains(&lobe) {
                    seen[k].push(lobe);
                }
            }
        }
        let glossy = Lobe::Glossy { alpha: 0.2 };
        assert_eq!(seen[0], [Lobe::Diffuse]);
        assert_eq!(seen[1], [glossy]);
        assert!(seen[2].len() == 2 && seen[2].contains(&glossy));
        assert_eq!(seen[3], [Lobe::Glint]);
        assert!(seen[4].len() == 2 && seen[4].contains(&Lobe::Glint));
    }

    #[test]
    fn smooth_limit_removes_every_glint() {
        for m in materials() {
            assert!(!m.smooth_limit().has_glints());
        }
        assert!(materials()[4].has_glints());
    }

    #[test]
    fn glint_queries_are_counted_only_with_a_footprint() {
        let glint = &materials()[3];
        let mut scratch = QueryScratch::new();
        let mut counters = GlintCounters::default();
        let wi = DVec3::new(0.3, 0.0, 0.954).normalize();
        let wo = DVec3::new(-0.3, 0.05, 0.954).normalize();
        let mut ctx = ShadingContext {
            uv: DVec2::new(0.2, 0.7),
            footprint: Some((DVec2::new(1e-3, 0.0), DVec2::new(0.0, 1e-3))),
            scratch: &mut scratch,
            counters: &mut counters,
        };
        let value = glint.eval(wi, wo, &mut ctx);
        assert!(value.is_finite() && value.min_element() >= 0.0);
        ctx.footprint = None;
        let _ = glint.eval(wi, wo, &mut ctx);
        assert_eq!(counters.queries, 1);
        assert!(counters.nodes_visited > 0);
    }

    /// A mapped material under a footprint too large to query shades the smooth limit averaged
    /// over its square, as f̂ over a footprint of many tiles does: half a density map at 0
    /// gives half the light of the unmapped material (it shaded the texel under uv, 1.00×),
    /// and a tint its mean.
    #[test]
    fn footprints_beyond_the_limit_under_maps_shade_the_squares_mean() {
        let mut parameters =
            GlintParameters::new(Microfacet::new(DistributionKind::Beckmann, 0.1, 0.1).unwrap());
        parameters.gamma_radians = 5f64.to_radians();
        let plain = DiscreteBrdf::new(parameters.clone()).unwrap();
        parameters.density_map = Some(Arc::new(DensityMap::new(2, 1, &[1.0, 0.0]).unwrap()));
        parameters.tint_map = Some(Arc::new(
            TintMap::new(2, 1, &[[1.0, 0.5, 0.25], [0.0, 0.0, 1.0]]).unwrap(),
        ));
        let glint = GlintMaterial {
            brdf: Arc::new(DiscreteBrdf::new(parameters).unwrap()),
            uv_scale: 1.0,
            plan_footprint_area: false,
        };
        let mut scratch = QueryScratch::new();
        let mut counters = GlintCounters::default();
        let wi = DVec3::new(0.3, 0.0, 0.954).normalize();
        let wo = DVec3::new(-0.3, 0.05, 0.954).normalize();
        let smooth = plain.smooth().eval(wi, wo);
        // The flakes' tint: the density is 0 where the tint is blue.
        let expected = smooth * 0.5 * DVec3::new(1.0, 0.5, 0.25);
        for uv in [DVec2::new(0.25, 0.5), DVec2::new(0.75, 0.5)] {
            let mut ctx = ShadingContext {
                uv,
                footprint: Some((DVec2::new(1e17, 0.0), DVec2::new(0.0, 1e-3))),
                scratch: &mut scratch,
                counters: &mut counters,
            };
            let f = glint.eval(wi, wo, &mut ctx);
            assert!(
                (f - expected).abs().max_element() <= 1e-12 * smooth.x,
                "{f} {expected}"
            );
        }
        assert_eq!(counters.queries, 0);
    }

    /// A footprint beyond what a footprint may span (edges past ±10¹⁵ particle squares, as a
    /// huge `uv_scale` gives) shades the smooth limit, bit for bit, and queries nothing; at
    /// the limit itself the glint query answers a finite f̂.
    #[test]
    fn footprints_beyond_the_limit_shade_the_smooth_limit() {
        let Material::Glint(glint) = &materials()[3] else {
            panic!("material 3 is the glint material");
        };
        let mut scratch = QueryScratch::new();
        let mut counters = GlintCounters::default();
        let wi = DVec3::new(0.3, 0.0, 0.954).normalize();
        let wo = DVec3::new(-0.3, 0.05, 0.954).normalize();
        let smooth = glint.brdf.smooth().eval(wi, wo);
        for side in [1e15 * 1.0001, 1e154, 1e300, f64::MAX] {
            let mut ctx = ShadingContext {
                uv: DVec2::new(0.2, 0.7),
                footprint: Some((DVec2::new(side, 0.0), DVec2::new(0.0, 1e-3))),
                scratch: &mut scratch,
                counters: &mut counters,
            };
            assert!(glint.footprint(&ctx).is_none());
            assert_eq!(glint.eval(wi, wo, &mut ctx), smooth, "{side}");
            assert_eq!(
                glint.eval_if_visible(wi, wo, &mut ctx, || true),
                Some(smooth)
            );
        }
        assert_eq!(counters.queries, 0);
        let mut ctx = ShadingContext {
            uv: DVec2::new(0.2, 0.7),
            footprint: Some((DVec2::new(1e15, 0.0), DVec2::new(0.0, 1e15))),
            scratch: &mut scratch,
            counters: &mut counters,
        };
        let f = glint.eval(wi, wo, &mut ctx);
        assert!(
            f.is_finite() && f.min_element() >= 0.0 && f != smooth,
            "{f}"
        );
    }
}
