//! Scene files: TOML, documented field by field in `scenes/README.md`. Loading validates every
//! value and reports the file, the field (e.g. `shapes[2].radius`) and the problem; asset paths
//! (meshes, textures, environment maps) are relative to the scene file.

use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DAffine3, DQuat, DVec2, DVec3};
use glint_brdf::{
    DiscreteBrdf, DistributionKind, Fresnel, GlintParameters, Microfacet, MicrofacetBrdf,
    MultinomialMode, NormalSampling,
};
use serde::Deserialize;

use crate::accel::{Accelerator, Geometry, Primitive};
use crate::camera::{Camera, CameraPose, Keyframe};
use crate::error::TracerError;
use crate::image::RgbImage;
use crate::integrator::{
    Bloom, GlintFootprints, GlintRandomness, IntegratorKind, LightStrategy, PixelFilter,
    RenderSettings,
};
use crate::light::{EnvironmentMap, Light};
use crate::material::{GlintMaterial, Material, Plastic, Texture};
use crate::mesh::Mesh;
use crate::scene::Scene;
use crate::shape::{Rectangle, Sphere};

/// A glint material's `negligible_count` when the scene file gives none: queries provably
/// expecting fewer particles are skipped (glint-brdf's "Negligible queries"). At ε = 0 a render
/// of Q queries then differs from the fully traversed one anywhere with probability below
/// Q·10⁻¹² (10⁻⁴ for 10⁸ queries); with ε > 0 the traversal's own early stops may also add
/// fractional expectations of order ε²E² there. The render statistics report the bound's sum
/// over skipped queries.
pub const SCENE_NEGLIGIBLE_COUNT: f64 = 1e-12;

/// A colour: one number (grey) or three (linear RGB).
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(untagged)]
enum Colour {
    Grey(f64),
    Rgb([f64; 3]),
}

impl Colour {
    fn rgb(self) -> DVec3 {
        match self {
            Self::Grey(g) => DVec3::splat(g),
            Self::Rgb(c) => DVec3::from_array(c),
        }
    }
}

/// Roughness: one number (isotropic) or [α_x, α_y].
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(untagged)]
enum Roughness {
    Isotropic(f64),
    Anisotropic([f64; 2]),
}

#[derive(Clone, Copy, Debug, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
enum DistributionName {
    #[default]
    Beckmann,
    Ggx,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    #[serde(default)]
    render: RenderSection,
    camera: CameraSection,
    #[serde(default)]
    materials: BTreeMap<String, MaterialSection>,
    #[serde(default)]
    shapes: Vec<ShapeSection>,
    #[serde(default)]
    lights: Vec<LightSection>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RenderSection {
    resolution: Option<[u32; 2]>,
    spp: Option<u32>,
    max_depth: Option<u32>,
    integrator: Option<IntegratorName>,
    light_strategy: Option<StrategyName>,
    glint_footprints: Option<FootprintName>,
    footprint_scale: Option<f64>,
    filter: Option<FilterName>,
    exposure: Option<f64>,
    seed: Option<u64>,
    roulette_depth: Option<u32>,
    glint_randomness: Option<RandomnessName>,
    bloom: Option<BloomSection>,
}

#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(rename_all = "snake_case")]
enum RandomnessName {
    Coherent,
    PerFrame,
}

#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BloomSection {
    #[serde(default = "default_bloom_threshold")]
    threshold: f64,
    #[serde(default = "default_bloom_radius")]
    radius: f64,
    #[serde(default = "default_bloom_strength")]
    strength: f64,
}

fn default_bloom_threshold() -> f64 {
    1.0
}

fn default_bloom_radius() -> f64 {
    4.0
}

fn default_bloom_strength() -> f64 {
    0.5
}

#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(rename_all = "snake_case")]
enum IntegratorName {
    Direct,
    Path,
}

#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(rename_all = "snake_case")]
enum StrategyName {
    Mis,
    LightOnly,
    BrdfOnly,
}

#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(rename_all = "snake_case")]
enum FootprintName {
    FirstHit,
    Never,
}

#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(rename_all = "snake_case")]
enum FilterName {
    Box,
    Gaussian,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraSection {
    position: [f64; 3],
    look_at: [f64; 3],
    #[serde(default = "default_up")]
    up: [f64; 3],
    #[serde(default = "default_fov")]
    fov: f64,
    #[serde(default)]
    keyframes: Vec<KeyframeSection>,
}

fn default_up() -> [f64; 3] {
    [0.0, 1.0, 0.0]
}

fn default_fov() -> f64 {
    40.0
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct KeyframeSection {
    frame: f64,
    position: Option<[f64; 3]>,
    look_at: Option<[f64; 3]>,
    up: Option<[f64; 3]>,
    fov: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
enum MaterialSection {
    Diffuse(DiffuseSection),
    Conductor(ConductorSection),
    Plastic(PlasticSection),
    Glint(GlintSection),
    Mix(MixSection),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DiffuseSection {
    colour: Option<Colour>,
    texture: Option<String>,
    texture_scale: Option<[f64; 2]>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ConductorSection {
    #[serde(default)]
    distribution: DistributionName,
    alpha: Roughness,
    eta: Colour,
    k: Colour,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PlasticSection {
    colour: Option<Colour>,
    texture: Option<String>,
    texture_scale: Option<[f64; 2]>,
    #[serde(default)]
    distribution: DistributionName,
    alpha: Roughness,
    #[serde(default = "default_eta")]
    eta: f64,
}

fn default_eta() -> f64 {
    1.5
}

#[derive(Debug, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
enum FresnelSection {
    None,
    Conductor { eta: Colour, k: Colour },
    Dielectric { eta: f64 },
}

#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(rename_all = "snake_case")]
enum MultinomialName {
    Exact,
    Normal,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct GlintSection {
    #[serde(default)]
    distribution: DistributionName,
    alpha: Roughness,
    particles: f64,
    /// Degrees.
    gamma: f64,
    epsilon: Option<f64>,
    seed: Option<u64>,
    fresnel: Option<FresnelSection>,
    multinomial: Option<MultinomialName>,
    #[serde(default)]
    coloured: bool,
    sampling_scale: Option<f64>,
    pdf_points: Option<usize>,
    expected_footprint_area: Option<f64>,
    negligible_count: Option<f64>,
    uv_scale: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MixSection {
    components: Vec<ComponentSection>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ComponentSection {
    material: String,
    weight: f64,
}

#[derive(Debug, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
enum ShapeSection {
    Sphere(SphereSection),
    Rectangle(RectangleSection),
    Mesh(MeshSection),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SphereSection {
    center: [f64; 3],
    radius: f64,
    material: String,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RectangleSection {
    center: [f64; 3],
    u: [f64; 3],
    v: [f64; 3],
    material: String,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshSection {
    file: String,
    material: String,
    #[serde(default)]
    transform: TransformSection,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct TransformSection {
    translate: Option<[f64; 3]>,
    scale: Option<Colour>,
    /// Axis (x, y, z) and angle in degrees.
    rotate: Option<[f64; 4]>,
}

#[derive(Debug, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
enum LightSection {
    Sphere(SphereLightSection),
    Rectangle(RectangleLightSection),
    Directional(DirectionalSection),
    Environment(EnvironmentSection),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SphereLightSection {
    center: [f64; 3],
    radius: f64,
    power: Option<Colour>,
    radiance: Option<Colour>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RectangleLightSection {
    center: [f64; 3],
    u: [f64; 3],
    v: [f64; 3],
    power: Option<Colour>,
    radiance: Option<Colour>,
    texture: Option<String>,
    #[serde(default)]
    two_sided: bool,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DirectionalSection {
    direction: [f64; 3],
    irradiance: Colour,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct EnvironmentSection {
    file: Option<String>,
    radiance: Option<Colour>,
    scale: Option<Colour>,
    /// Degrees about +y.
    rotation: Option<f64>,
}

/// Builds scenes from one file, naming it in every error.
struct Builder<'a> {
    file: &'a Path,
    directory: PathBuf,
}

type Checked<T> = Result<T, TracerError>;

impl Builder<'_> {
    fn fail<T>(&self, field: impl Into<String>, problem: impl Into<String>) -> Checked<T> {
        Err(TracerError::Scene {
            file: self.file.to_path_buf(),
            field: field.into(),
            problem: problem.into(),
        })
    }

    fn asset(&self, relative: &str) -> PathBuf {
        self.directory.join(relative)
    }

    fn finite_vector(&self, field: &str, v: [f64; 3]) -> Checked<DVec3> {
        let v = DVec3::from_array(v);
        if v.is_finite() {
            Ok(v)
        } else {
            self.fail(field, format!("{v} is not finite"))
        }
    }

    fn direction(&self, field: &str, v: [f64; 3]) -> Checked<DVec3> {
        let v = self.finite_vector(field, v)?;
        if v.length_squared() > 0.0 {
            Ok(v.normalize())
        } else {
            self.fail(field, "a direction cannot be the zero vector")
        }
    }

    fn positive(&self, field: &str, x: f64) -> Checked<f64> {
        if x > 0.0 && x.is_finite() {
            Ok(x)
        } else {
            self.fail(field, format!("must be positive and finite, got {x}"))
        }
    }

    fn colour(&self, field: &str, c: Colour) -> Checked<DVec3> {
        let c = c.rgb();
        if c.is_finite() && c.min_element() >= 0.0 {
            Ok(c)
        } else {
            self.fail(
                field,
                format!("colour components must be finite and ≥ 0, got {c}"),
            )
        }
    }

    fn image(&self, field: &str, relative: &str) -> Checked<RgbImage> {
        let path = self.asset(relative);
        RgbImage::load(&path).map_err(|e| TracerError::Scene {
            file: self.file.to_path_buf(),
            field: field.into(),
            problem: e.to_string(),
        })
    }

    fn texture(
        &self,
        field: &str,
        colour: Option<Colour>,
        texture: Option<&str>,
        scale: Option<[f64; 2]>,
    ) -> Checked<Texture> {
        match texture {
            None => Ok(Texture::Constant(match colour {
                Some(c) => self.colour(&format!("{field}.colour"), c)?,
                None => DVec3::splat(0.5),
            })),
            Some(file) => {
                let image = self.image(&format!("{field}.texture"), file)?;
                let scale = DVec2::from_array(scale.unwrap_or([1.0, 1.0]));
                if !(scale.is_finite() && scale.min_element() > 0.0) {
                    return self.fail(
                        format!("{field}.texture_scale"),
                        format!("must be positive, got {scale}"),
                    );
                }
                let tint = match colour {
                    Some(c) => self.colour(&format!("{field}.colour"), c)?,
                    None => DVec3::ONE,
                };
                Ok(Texture::Image {
                    image: Arc::new(image),
                    scale,
                    tint,
                })
            }
        }
    }

    fn microfacet(
        &self,
        field: &str,
        kind: DistributionName,
        alpha: Roughness,
    ) -> Checked<Microfacet> {
        let kind = match kind {
            DistributionName::Beckmann => DistributionKind::Beckmann,
            DistributionName::Ggx => DistributionKind::Ggx,
        };
        let (ax, ay) = match alpha {
            Roughness::Isotropic(a) => (a, a),
            Roughness::Anisotropic([ax, ay]) => (ax, ay),
        };
        Microfacet::new(kind, ax, ay).map_err(|e| TracerError::Scene {
            file: self.file.to_path_buf(),
            field: format!("{field}.alpha"),
            problem: e.to_string(),
        })
    }

    fn brdf_error(&self, field: &str, e: &glint_brdf::BrdfError) -> TracerError {
        TracerError::Scene {
            file: self.file.to_path_buf(),
            field: field.into(),
            problem: e.to_string(),
        }
    }

    fn material(
        &self,
        name: &str,
        sections: &BTreeMap<String, MaterialSection>,
        visiting: &mut Vec<String>,
    ) -> Checked<Material> {
        let field = format!("materials.{name}");
        let Some(section) = sections.get(name) else {
            return self.fail(field, "no material of this name is defined");
        };
        if visiting.iter().any(|v| v == name) {
            return self.fail(
                field,
                format!(
                    "mix components form a cycle: {} → {name}",
                    visiting.join(" → ")
                ),
            );
        }
        Ok(match section {
            MaterialSection::Diffuse(d) => Material::Diffuse(self.texture(
                &field,
                d.colour,
                d.texture.as_deref(),
                d.texture_scale,
            )?),
            MaterialSection::Conductor(c) => {
                let distribution = self.microfacet(&field, c.distribution, c.alpha)?;
                let fresnel = Fresnel::Conductor {
                    eta: self.colour(&format!("{field}.eta"), c.eta)?,
                    k: self.colour(&format!("{field}.k"), c.k)?,
                };
                Material::Microfacet(
                    MicrofacetBrdf::new(distribution, fresnel, NormalSampling::Distribution)
                        .map_err(|e| self.brdf_error(&format!("{field}.eta"), &e))?,
                )
            }
            MaterialSection::Plastic(p) => {
                let distribution = self.microfacet(&field, p.distribution, p.alpha)?;
                let eta = self.positive(&format!("{field}.eta"), p.eta)?;
                Material::Plastic(Plastic {
                    base: self.texture(&field, p.colour, p.texture.as_deref(), p.texture_scale)?,
                    coat: MicrofacetBrdf::new(
                        distribution,
                        Fresnel::Dielectric { eta },
                        NormalSampling::Distribution,
                    )
                    .map_err(|e| self.brdf_error(&format!("{field}.eta"), &e))?,
                    eta,
                })
            }
            MaterialSection::Glint(g) => self.glint(&field, g)?,
            MaterialSection::Mix(m) => {
                if m.components.is_empty() {
                    return self.fail(
                        format!("{field}.components"),
                        "a mix needs at least one component",
                    );
                }
                visiting.push(name.to_string());
                let mut parts = Vec::new();
                for (i, c) in m.components.iter().enumerate() {
                    let weight_field = format!("{field}.components[{i}].weight");
                    if !(c.weight >= 0.0 && c.weight.is_finite()) {
                        return self.fail(
                            weight_field,
                            format!("must be finite and ≥ 0, got {}", c.weight),
                        );
                    }
                    parts.push((c.weight, self.material(&c.material, sections, visiting)?));
                }
                visiting.pop();
                if !(parts.iter().map(|p| p.0).sum::<f64>() > 0.0) {
                    return self.fail(format!("{field}.components"), "the weights sum to zero");
                }
                Material::Mix(parts)
            }
        })
    }

    fn glint(&self, field: &str, g: &GlintSection) -> Checked<Material> {
        let distribution = self.microfacet(field, g.distribution, g.alpha)?;
        let mut parameters = GlintParameters::new(distribution);
        if !(g.particles >= 1.0 && g.particles <= 1e18 && g.particles.fract() == 0.0) {
            return self.fail(
                format!("{field}.particles"),
                format!("must be a whole number in [1, 10¹⁸], got {}", g.particles),
            );
        }
        parameters.particles = g.particles as u64;
        if !(g.gamma > 0.0 && g.gamma <= 60.0) {
            return self.fail(
                format!("{field}.gamma"),
                format!("the cone radius must be in (0°, 60°], got {}°", g.gamma),
            );
        }
        parameters.gamma = g.gamma.to_radians();
        if let Some(epsilon) = g.epsilon {
            parameters.epsilon = epsilon;
        }
        parameters.seed = g.seed.unwrap_or(0);
        parameters.fresnel = match &g.fresnel {
            None | Some(FresnelSection::None) => Fresnel::None,
            Some(FresnelSection::Conductor { eta, k }) => Fresnel::Conductor {
                eta: self.colour(&format!("{field}.fresnel.eta"), *eta)?,
                k: self.colour(&format!("{field}.fresnel.k"), *k)?,
            },
            Some(FresnelSection::Dielectric { eta }) => Fresnel::Dielectric {
                eta: self.positive(&format!("{field}.fresnel.eta"), *eta)?,
            },
        };
        parameters.multinomial = match g.multinomial {
            None | Some(MultinomialName::Exact) => MultinomialMode::Exact,
            Some(MultinomialName::Normal) => MultinomialMode::Normal,
        };
        parameters.colour_channels = if g.coloured { 3 } else { 0 };
        if let Some(s) = g.sampling_scale {
            parameters.sampling_scale = s;
        }
        if let Some(p) = g.pdf_points {
            parameters.pdf_points = p;
        }
        if let Some(a) = g.expected_footprint_area {
            parameters.expected_footprint_area = a;
        }
        let negligible_count = g.negligible_count.unwrap_or(SCENE_NEGLIGIBLE_COUNT);
        if !(negligible_count >= 0.0 && negligible_count.is_finite()) {
            return self.fail(
                format!("{field}.negligible_count"),
                format!("must be finite and ≥ 0 (0 traverses every query), got {negligible_count}"),
            );
        }
        parameters.negligible_count = negligible_count;
        let uv_scale = self.positive(&format!("{field}.uv_scale"), g.uv_scale.unwrap_or(1.0))?;
        let brdf = DiscreteBrdf::new(parameters).map_err(|e| self.brdf_error(field, &e))?;
        Ok(Material::Glint(GlintMaterial {
            brdf: Arc::new(brdf),
            uv_scale,
        }))
    }

    fn transform(&self, field: &str, t: &TransformSection) -> Checked<DAffine3> {
        let scale = match t.scale {
            None => DVec3::ONE,
            Some(s) => s.rgb(),
        };
        if !(scale.is_finite() && scale.abs().min_element() > 0.0) {
            return self.fail(
                format!("{field}.scale"),
                format!("must be finite and non-zero, got {scale}"),
            );
        }
        let rotation = match t.rotate {
            None => DQuat::IDENTITY,
            Some([x, y, z, degrees]) => {
                let axis = self.direction(&format!("{field}.rotate"), [x, y, z])?;
                if !degrees.is_finite() {
                    return self.fail(format!("{field}.rotate"), "the angle must be finite");
                }
                DQuat::from_axis_angle(axis, degrees.to_radians())
            }
        };
        let translation = self.finite_vector(
            &format!("{field}.translate"),
            t.translate.unwrap_or([0.0; 3]),
        )?;
        Ok(DAffine3::from_scale_rotation_translation(
            scale,
            rotation,
            translation,
        ))
    }

    fn rectangle(
        &self,
        field: &str,
        center: [f64; 3],
        u: [f64; 3],
        v: [f64; 3],
    ) -> Checked<Rectangle> {
        let center = self.finite_vector(&format!("{field}.center"), center)?;
        let u = self.finite_vector(&format!("{field}.u"), u)?;
        let v = self.finite_vector(&format!("{field}.v"), v)?;
        match Rectangle::new(center, u, v) {
            Some(r) => Ok(r),
            None => self.fail(
                format!("{field}.v"),
                "the edges u and v are parallel or zero: the rectangle has no area",
            ),
        }
    }

    fn sphere(&self, field: &str, center: [f64; 3], radius: f64) -> Checked<Sphere> {
        Ok(Sphere {
            center: self.finite_vector(&format!("{field}.center"), center)?,
            radius: self.positive(&format!("{field}.radius"), radius)?,
        })
    }

    /// Exactly one of `power` and `radiance`, converted to radiance by `radiance_per_watt`.
    fn emission(
        &self,
        field: &str,
        power: Option<Colour>,
        radiance: Option<Colour>,
        radiance_per_watt: f64,
    ) -> Checked<DVec3> {
        match (power, radiance) {
            (Some(p), None) => Ok(self.colour(&format!("{field}.power"), p)? * radiance_per_watt),
            (None, Some(l)) => self.colour(&format!("{field}.radiance"), l),
            (Some(_), Some(_)) => self.fail(field, "give either power or radiance, not both"),
            (None, None) => self.fail(field, "an emitter needs power (watts) or radiance"),
        }
    }

    fn camera(&self, c: &CameraSection) -> Checked<Camera> {
        let base = CameraPose {
            position: self.finite_vector("camera.position", c.position)?,
            look_at: self.finite_vector("camera.look_at", c.look_at)?,
            up: self.finite_vector("camera.up", c.up)?,
            fov_degrees: c.fov,
        };
        let mut keyframes = vec![];
        if c.keyframes.is_empty() {
            keyframes.push(Keyframe {
                frame: 0.0,
                pose: base,
            });
        }
        for (i, k) in c.keyframes.iter().enumerate() {
            let field = format!("camera.keyframes[{i}]");
            let pose = CameraPose {
                position: k.position.map_or(Ok(base.position), |p| {
                    self.finite_vector(&format!("{field}.position"), p)
                })?,
                look_at: k.look_at.map_or(Ok(base.look_at), |p| {
                    self.finite_vector(&format!("{field}.look_at"), p)
                })?,
                up: k.up.map_or(Ok(base.up), |p| {
                    self.finite_vector(&format!("{field}.up"), p)
                })?,
                fov_degrees: k.fov.unwrap_or(base.fov_degrees),
            };
            if !k.frame.is_finite() {
                return self.fail(format!("{field}.frame"), "must be finite");
            }
            if Camera::new(vec![Keyframe { frame: 0.0, pose }]).is_none() {
                return self.fail(field, "degenerate pose: the eye is at the target, up is along the view direction, or fov is outside (0°, 180°)");
            }
            keyframes.push(Keyframe {
                frame: k.frame,
                pose,
            });
        }
        match Camera::new(keyframes) {
            Some(camera) => Ok(camera),
            None => self.fail("camera", "degenerate pose: the eye is at the target, up is along the view direction, or fov is outside (0°, 180°)"),
        }
    }

    fn settings(&self, r: &RenderSection) -> Checked<RenderSettings> {
        let mut s = RenderSettings::default();
        if let Some([w, h]) = r.resolution {
            s.width = w;
            s.height = h;
        }
        if let Some(spp) = r.spp {
            s.samples_per_pixel = spp;
        }
        if let Some(d) = r.max_depth {
            s.max_depth = d;
        }
        if let Some(i) = r.integrator {
            s.integrator = match i {
                IntegratorName::Direct => IntegratorKind::Direct,
                IntegratorName::Path => IntegratorKind::Path,
            };
        }
        if let Some(l) = r.light_strategy {
            s.light_strategy = match l {
                StrategyName::Mis => LightStrategy::Mis,
                StrategyName::LightOnly => LightStrategy::LightOnly,
                StrategyName::BrdfOnly => LightStrategy::BrdfOnly,
            };
        }
        if let Some(g) = r.glint_footprints {
            s.glint_footprints = match g {
                FootprintName::FirstHit => GlintFootprints::FirstHit,
                FootprintName::Never => GlintFootprints::Never,
            };
        }
        if let Some(f) = r.footprint_scale {
            s.footprint_scale = f;
        }
        if let Some(f) = r.filter {
            s.filter = match f {
                FilterName::Box => PixelFilter::Box,
                FilterName::Gaussian => PixelFilter::Gaussian,
            };
        }
        if let Some(e) = r.exposure {
            s.exposure = e;
        }
        if let Some(seed) = r.seed {
            s.seed = seed;
        }
        if let Some(d) = r.roulette_depth {
            s.roulette_depth = d;
        }
        if let Some(g) = r.glint_randomness {
            s.glint_randomness = match g {
                RandomnessName::Coherent => GlintRandomness::Coherent,
                RandomnessName::PerFrame => GlintRandomness::PerFrame,
            };
        }
        if let Some(b) = r.bloom {
            if !(b.threshold >= 0.0 && b.threshold.is_finite()) {
                return self.fail(
                    "render.bloom.threshold",
                    format!("must be finite and ≥ 0, got {}", b.threshold),
                );
            }
            let radius = self.positive("render.bloom.radius", b.radius)?;
            if !(radius <= 256.0) {
                return self.fail(
                    "render.bloom.radius",
                    format!("at most 256 pixels, got {radius}"),
                );
            }
            if !(b.strength >= 0.0 && b.strength.is_finite()) {
                return self.fail(
                    "render.bloom.strength",
                    format!("must be finite and ≥ 0, got {}", b.strength),
                );
            }
            s.bloom = Some(Bloom {
                threshold: b.threshold,
                radius,
                strength: b.strength,
            });
        }
        crate::film::validate_settings(&s).map_err(|e| match e {
            TracerError::Settings { setting, problem } => TracerError::Scene {
                file: self.file.to_path_buf(),
                field: format!("render.{setting}"),
                problem,
            },
            other => other,
        })?;
        Ok(s)
    }

    fn build(&self, file: SceneFile) -> Checked<Scene> {
        let settings = self.settings(&file.render)?;
        let camera = self.camera(&file.camera)?;
        // Materials by name, in name order; only those used are built (a glint material builds
        // its NDF quadrature).
        let mut material_index: BTreeMap<String, u32> = BTreeMap::new();
        let mut materials = Vec::new();
        let mut material_names = Vec::new();
        let mut primitives = Vec::new();
        let mut meshes = Vec::new();
        let mut lights = Vec::new();
        let mut use_material =
            |name: &str, field: &str, materials: &mut Vec<Material>| -> Checked<u32> {
                if let Some(&i) = material_index.get(name) {
                    return Ok(i);
                }
                if !file.materials.contains_key(name) {
                    let known: Vec<&str> = file.materials.keys().map(String::as_str).collect();
                    return self.fail(
                        field,
                        format!("unknown material `{name}` (defined: {})", known.join(", ")),
                    );
                }
                let material = self.material(name, &file.materials, &mut Vec::new())?;
                materials.push(material);
                material_names.push(name.to_string());
                let i = (materials.len() - 1) as u32;
                material_index.insert(name.to_string(), i);
                Ok(i)
            };
        for (i, shape) in file.shapes.iter().enumerate() {
            let field = format!("shapes[{i}]");
            match shape {
                ShapeSection::Sphere(s) => {
                    let sphere = self.sphere(&field, s.center, s.radius)?;
                    let material =
                        use_material(&s.material, &format!("{field}.material"), &mut materials)?;
                    primitives.push(Primitive {
                        geometry: Geometry::Sphere(sphere),
                        material,
                        light: None,
                    });
                }
                ShapeSection::Rectangle(r) => {
                    let rectangle = self.rectangle(&field, r.center, r.u, r.v)?;
                    let material =
                        use_material(&r.material, &format!("{field}.material"), &mut materials)?;
                    primitives.push(Primitive {
                        geometry: Geometry::Rectangle(rectangle),
                        material,
                        light: None,
                    });
                }
                ShapeSection::Mesh(m) => {
                    let material =
                        use_material(&m.material, &format!("{field}.material"), &mut materials)?;
                    let transform = self.transform(&format!("{field}.transform"), &m.transform)?;
                    let mesh =
                        Mesh::load_obj(&self.asset(&m.file)).map_err(|e| TracerError::Scene {
                            file: self.file.to_path_buf(),
                            field: format!("{field}.file"),
                            problem: e.to_string(),
                        })?;
                    let mesh = mesh.transformed(&transform);
                    let mesh_index = meshes.len() as u32;
                    for t in 0..mesh.triangles.len() as u32 {
                        primitives.push(Primitive {
                            geometry: Geometry::Triangle {
                                mesh: mesh_index,
                                triangle: t,
                            },
                            material,
                            light: None,
                        });
                    }
                    meshes.push(mesh);
                }
            }
        }
        for (i, light) in file.lights.iter().enumerate() {
            let field = format!("lights[{i}]");
            let index = lights.len() as u32;
            match light {
                LightSection::Sphere(s) => {
                    let sphere = self.sphere(&field, s.center, s.radius)?;
                    // A Lambertian sphere of radiance L emits Φ = L·π·4πr².
                    let radiance = self.emission(
                        &field,
                        s.power,
                        s.radiance,
                        1.0 / (4.0 * PI * PI * sphere.radius * sphere.radius),
                    )?;
                    lights.push(Light::Sphere { sphere, radiance });
                    primitives.push(Primitive {
                        geometry: Geometry::Sphere(sphere),
                        material: 0,
                        light: Some(index),
                    });
                }
                LightSection::Rectangle(r) => {
                    let rectangle = self.rectangle(&field, r.center, r.u, r.v)?;
                    let sides = if r.two_sided { 2.0 } else { 1.0 };
                    // A Lambertian emitter of radiance L emits Φ = L·π·area per side.
                    let mut colour = self.emission(
                        &field,
                        r.power,
                        r.radiance,
                        1.0 / (sides * PI * rectangle.area()),
                    )?;
                    let radiance = match &r.texture {
                        None => Texture::Constant(colour),
                        Some(file) => {
                            let image = self.image(&format!("{field}.texture"), file)?;
                            // With power given, the texture's mean carries that power.
                            if r.power.is_some() {
                                let mean = crate::light::luminance(image.mean());
                                if !(mean > 0.0) {
                                    return self.fail(
                                        format!("{field}.texture"),
                                        "a black texture cannot carry power",
                                    );
                                }
                                colour /= mean;
                            }
                            Texture::Image {
                                image: Arc::new(image),
                                scale: DVec2::ONE,
                                tint: colour,
                            }
                        }
                    };
                    lights.push(Light::Rectangle {
                        rectangle,
                        radiance,
                        two_sided: r.two_sided,
                    });
                    primitives.push(Primitive {
                        geometry: Geometry::Rectangle(rectangle),
                        material: 0,
                        light: Some(index),
                    });
                }
                LightSection::Directional(d) => {
                    lights.push(Light::Directional {
                        direction: self.direction(&format!("{field}.direction"), d.direction)?,
                        irradiance: self.colour(&format!("{field}.irradiance"), d.irradiance)?,
                    });
                }
                LightSection::Environment(e) => {
                    let rotation = e.rotation.unwrap_or(0.0);
                    if !rotation.is_finite() {
                        return self.fail(format!("{field}.rotation"), "must be finite");
                    }
                    let scale = match e.scale {
                        Some(s) => self.colour(&format!("{field}.scale"), s)?,
                        None => DVec3::ONE,
                    };
                    let map = match (&e.file, e.radiance) {
                        (Some(file), None) => EnvironmentMap::new(
                            self.image(&format!("{field}.file"), file)?,
                            scale,
                            rotation.to_radians(),
                        ),
                        (None, Some(l)) => EnvironmentMap::constant(
                            self.colour(&format!("{field}.radiance"), l)? * scale,
                        ),
                        _ => {
                            return self.fail(
                                field,
                                "an environment needs exactly one of file and radiance",
                            );
                        }
                    };
                    if lights.iter().any(|l| matches!(l, Light::Environment(_))) {
                        return self.fail(field, "a scene has at most one environment");
                    }
                    lights.push(Light::Environment(map));
                }
            }
        }
        if lights.is_empty() {
            return self.fail("lights", "the scene has no lights: it would render black");
        }
        if materials.is_empty() {
            // Emitter-only scenes still index material 0.
            materials.push(Material::Diffuse(Texture::Constant(DVec3::ZERO)));
            material_names.push(String::from("(none)"));
        }
        Ok(Scene {
            accelerator: Accelerator::new(primitives, meshes),
            materials,
            material_names,
            lights,
            camera,
            settings,
        })
    }
}

/// Reads and builds the scene in `path`.
///
/// # Errors
/// [`TracerError::Scene`] naming the file, the field and the problem.
pub fn load_scene(path: &Path) -> Result<Scene, TracerError> {
    let text = std::fs::read_to_string(path).map_err(|e| TracerError::Scene {
        file: path.to_path_buf(),
        field: String::new(),
        problem: format!("cannot read the scene file: {e}"),
    })?;
    parse_scene(&text, path)
}

/// Builds a scene from TOML `text`, as if read from `path` (assets resolve beside it).
///
/// # Errors
/// [`TracerError::Scene`] naming the file, the field and the problem.
pub fn parse_scene(text: &str, path: &Path) -> Result<Scene, TracerError> {
    let builder = Builder {
        file: path,
        directory: path.parent().map(Path::to_path_buf).unwrap_or_default(),
    };
    let file: SceneFile = toml::from_str(text).map_err(|e| TracerError::Scene {
        file: path.to_path_buf(),
        field: String::new(),
        problem: e.to_string().trim_end().to_string(),
    })?;
    builder.build(file)
}

#[cfg(test)]
mod tests {
    use super::*;

    const VALID: &str = r#"
[render]
resolution = [8, 6]
spp = 2

[camera]
position = [0, 1, 3]
look_at = [0, 0, 0]

[materials.red]
type = "diffuse"
colour = [0.8, 0.1, 0.1]

[materials.sparkle]
type = "glint"
alpha = 0.2
particles = 1e6
gamma = 2

[materials.both]
type = "mix"
components = [{ material = "red", weight = 0.7 }, { material = "sparkle", weight = 0.3 }]

[[shapes]]
type = "sphere"
center = [0, 0, 0]
radius = 0.5
material = "both"

[[lights]]
type = "sphere"
center = [1, 2, 1]
radius = 0.1
power = 10
"#;

    fn error_of(text: &str) -> (String, String) {
        match parse_scene(text, Path::new("scenes/test.toml")) {
            Err(TracerError::Scene {
                file,
                field,
                problem,
            }) => {
                assert_eq!(file, Path::new("scenes/test.toml"));
                (field, problem)
            }
            Err(other) => panic!("expected a scene error, got {other}"),
            Ok(_) => panic!("expected an error for:\n{text}"),
        }
    }

    #[test]
    fn a_valid_scene_builds() {
        let scene = parse_scene(VALID, Path::new("scenes/test.toml")).unwrap();
        assert_eq!(scene.lights.len(), 1);
        assert_eq!(scene.accelerator.primitives().len(), 2);
        assert!(scene.has_glints());
        assert_eq!((scene.settings.width, scene.settings.height), (8, 6));
    }

    /// Each mistake gets an error naming the field and the problem, never a panic.
    #[test]
    fn scene_errors_name_the_field_and_the_problem() {
        let cases: &[(&str, &str, &str, &str)] = &[
            // (replace, with, expected field, expected words in the problem)
            ("radius = 0.5", "radus = 0.5", "", "unknown field `radus`"),
            (
                "radius = 0.5",
                "radius = -0.5",
                "shapes[0].radius",
                "must be positive",
            ),
            (
                "radius = 0.5",
                "radius = nan",
                "shapes[0].radius",
                "must be positive",
            ),
            (
                "material = \"both\"",
                "material = \"gold\"",
                "shapes[0].material",
                "unknown material `gold`",
            ),
            (
                "alpha = 0.2",
                "alpha = -0.2",
                "materials.sparkle.alpha",
                "roughness",
            ),
            (
                "gamma = 2",
                "gamma = 90",
                "materials.sparkle.gamma",
                "(0°, 60°]",
            ),
            (
                "particles = 1e6",
                "particles = 0.5",
                "materials.sparkle.particles",
                "whole number",
            ),
            ("power = 10", "power = -10", "lights[0].power", "≥ 0"),
            ("power = 10", "", "lights[0]", "power (watts) or radiance"),
            ("spp = 2", "spp = 0", "render.spp", "outside"),
            (
                "type = \"sphere\"\ncenter = [0, 0, 0]",
                "type = \"cube\"\ncenter = [0, 0, 0]",
                "",
                "unknown variant `cube`",
            ),
            (
                "look_at = [0, 0, 0]",
                "look_at = [0, 1, 3]",
                "camera",
                "degenerate",
            ),
            (
                "weight = 0.7",
                "weight = -1",
                "materials.both.components[0].weight",
                "≥ 0",
            ),
            (
                "gamma = 2",
                "gamma = 2\nnegligible_count = -1e-9",
                "materials.sparkle.negligible_count",
                "≥ 0",
            ),
            ("[render]", "[render", "", "TOML parse error"),
            ("spp = 2", "spp = \"many\"", "", "invalid type"),
        ];
        for (from, to, field, words) in cases {
            assert!(VALID.contains(from), "{from}");
            let text = VALID.replacen(from, to, 1);
            let (f, problem) = error_of(&text);
            assert_eq!(&f, field, "{from} → {to}: {problem}");
            assert!(
                problem.contains(words),
                "{from} → {to}: `{problem}` lacks `{words}`"
            );
        }
    }

    #[test]
    fn missing_assets_and_cycles_are_reported() {
        let mesh = VALID.replace(
            "type = \"sphere\"\ncenter = [0, 0, 0]\nradius = 0.5",
            "type = \"mesh\"\nfile = \"meshes/missing.obj\"",
        );
        let (field, problem) = error_of(&mesh);
        assert_eq!(field, "shapes[0].file");
        assert!(problem.contains("missing.obj"), "{problem}");
        let texture = VALID.replace("colour = [0.8, 0.1, 0.1]", "texture = \"nowhere.png\"");
        let (field, problem) = error_of(&texture);
        assert_eq!(field, "materials.red.texture");
        assert!(problem.contains("nowhere.png"), "{problem}");
        let cycle = VALID.replace(
            "{ material = \"red\", weight = 0.7 }",
            "{ material = \"both\", weight = 0.7 }",
        );
        let (field, problem) = error_of(&cycle);
        assert_eq!(field, "materials.both");
        assert!(problem.contains("cycle"), "{problem}");
        let dark = VALID.replace(
            "[[lights]]\ntype = \"sphere\"\ncenter = [1, 2, 1]\nradius = 0.1\npower = 10",
            "",
        );
        let (field, problem) = error_of(&dark);
        assert_eq!(field, "lights");
        assert!(problem.contains("render black"), "{problem}");
        let missing_file = load_scene(Path::new("/nonexistent/scene.toml"));
        assert!(
            missing_file
                .unwrap_err()
                .to_string()
                .contains("cannot read the scene file")
        );
    }
}

#[cfg(test)]
mod mesh_tests {
    use super::*;

    /// An OBJ mesh beside the scene file, moved by a transform, is found by rays.
    #[test]
    fn obj_meshes_load_relative_to_the_scene_with_their_transform() {
        let dir = std::env::temp_dir().join(format!("glint-scene-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("meshes")).unwrap();
        std::fs::write(
            dir.join("meshes/quad.obj"),
            "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 4/4 3/3 2/2\n",
        )
        .unwrap();
        let text = r#"
[camera]
position = [0, 3, 0.01]
look_at = [0, 0, 0]
[materials.grey]
type = "diffuse"
[[shapes]]
type = "mesh"
file = "meshes/quad.obj"
material = "grey"
transform = { scale = 2, translate = [0, 0.5, 0], rotate = [0, 1, 0, 30] }
[[lights]]
type = "directional"
direction = [0, 1, 0]
irradiance = 1
"#;
        let path = dir.join("scene.toml");
        std::fs::write(&path, text).unwrap();
        let scene = load_scene(&path).unwrap();
        assert_eq!(scene.accelerator.primitives().len(), 2);
        let ray = crate::shape::Ray {
            origin: DVec3::new(1.5, 3.0, 0.0),
            direction: -DVec3::Y,
        };
        let hit = scene
            .intersect(&ray, f64::INFINITY)
            .expect("the scaled quad spans ±2");
        assert!((hit.surface.point.y - 0.5).abs() < 1e-12);
        let miss = crate::shape::Ray {
            origin: DVec3::new(2.9, 3.0, 0.0),
            direction: -DVec3::Y,
        };
        // Rotated by 30°, the square's corner region at (2.9, 0) lies outside it.
        assert!(scene.intersect(&miss, f64::INFINITY).is_none());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
