//! Scene files: TOML, documented field by field in `scenes/README.md`. Loading validates every
//! value and reports the file, the field (e.g. `shapes[2].radius`) and the problem; asset paths
//! (meshes, textures, environment maps) are relative to the scene file. Values are bounded
//! where they enter ([`crate::limits`]): magnitudes, sizes, counts, so that an accepted scene
//! builds and renders in bounded memory without overflowing.
//!
//! The TOML is read in two steps: into a table (syntax errors, with line and column), then each
//! section into its typed form with the path to it, so that a mistake deep inside
//! (`shapes[2].center` with two numbers) is named by its field.

use std::cell::Cell;
use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DAffine3, DQuat, DVec2, DVec3};
use glint_brdf::{
    DiscreteBrdf, DistributionKind, Fresnel, GlintParameters, Microfacet, MicrofacetBrdf,
    MultinomialMode, NormalSampling, PdfQuadrature,
};
use serde::Deserialize;
use serde::de::DeserializeOwned;

use crate::accel::{Accelerator, Geometry, Primitive};
use crate::camera::{Camera, CameraPose, Keyframe, pose_problem};
use crate::error::TracerError;
use crate::image::RgbImage;
use crate::light::{EnvironmentMap, Light};
use crate::limits::{self, echo};
use crate::material::{GlintMaterial, Material, Mirror, Plastic, Texture};
use crate::mesh::Mesh;
use crate::scene::Scene;
use crate::settings::{
    Bloom, GlintFootprints, GlintRandomness, IntegratorKind, LightStrategy, PixelBounds,
    PixelFilter, RenderSettings,
};
use crate::shape::{Rectangle, Sphere};

/// A glint material's `negligible_count` when the scene file gives none: queries provably
/// expecting fewer particles are skipped (glint-brdf's "Negligible queries"). At ε = 0 a render
/// of Q queries then differs from the fully traversed one anywhere with probability below
/// Q·10⁻¹² (10⁻⁴ for 10⁸ queries); with ε > 0 the traversal's own early stops may also add
/// fractional expectations of order ε²E² there. The render statistics report the bound's sum
/// over skipped queries.
pub const SCENE_NEGLIGIBLE_COUNT: f64 = 1e-12;

/// A colour: one number (grey) or three (linear RGB).
#[derive(Clone, Copy, Debug)]
struct Colour(DVec3);

impl Colour {
    fn rgb(self) -> DVec3 {
        self.0
    }
}

/// Roughness: one number (isotropic) or [α_x, α_y].
#[derive(Clone, Copy, Debug)]
struct Roughness(f64, f64);

/// Reads one number or an array of `N` numbers, for [`Colour`] and [`Roughness`], with an error
/// that says which forms are accepted.
struct NumbersVisitor<const N: usize>(&'static str);

impl<'de, const N: usize> serde::de::Visitor<'de> for NumbersVisitor<N> {
    type Value = [f64; N];

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "a number or an array of {N} numbers {}", self.0)
    }

    fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<Self::Value, E> {
        Ok([v; N])
    }

    fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<Self::Value, E> {
        Ok([v as f64; N])
    }

    fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<Self::Value, E> {
        Ok([v as f64; N])
    }

    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
        let mut values = [0.0; N];
        for (i, value) in values.iter_mut().enumerate() {
            *value = seq
                .next_element()?
                .ok_or_else(|| serde::de::Error::invalid_length(i, &self))?;
        }
        if seq.next_element::<serde::de::IgnoredAny>()?.is_some() {
            return Err(serde::de::Error::invalid_length(N + 1, &self));
        }
        Ok(values)
    }
}

impl<'de> Deserialize<'de> for Colour {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let [r, g, b] = d.deserialize_any(NumbersVisitor::<3>("[r, g, b]"))?;
        Ok(Self(DVec3::new(r, g, b)))
    }
}

impl<'de> Deserialize<'de> for Roughness {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let [x, y] = d.deserialize_any(NumbersVisitor::<2>("[α_x, α_y]"))?;
        Ok(Self(x, y))
    }
}

#[derive(Clone, Copy, Debug, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
enum DistributionName {
    #[default]
    Beckmann,
    Ggx,
}

/// The file's top level; each section is read on its own, with its path.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    render: Option<toml::Value>,
    camera: toml::Value,
    #[serde(default)]
    materials: BTreeMap<String, toml::Value>,
    #[serde(default)]
    shapes: Vec<toml::Value>,
    #[serde(default)]
    lights: Vec<toml::Value>,
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
    glint_light_cones: Option<bool>,
    pixel_bounds: Option<[u32; 4]>,
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
    All,
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
    keyframes: Vec<toml::Value>,
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

/// The material types, by their `type`.
const MATERIAL_TYPES: &[&str] = &["diffuse", "conductor", "plastic", "glint", "mirror", "mix"];

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
struct MirrorSection {
    colour: Option<Colour>,
    fresnel: Option<FresnelSection>,
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

#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(rename_all = "snake_case")]
enum PdfQuadratureName {
    Cubature,
    Qmc,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct GlintSection {
    #[serde(default)]
    distribution: DistributionName,
    alpha: Roughness,
    particles: f64,
    /// The cone radius γ in degrees; `gamma`, its older name, is still read (deprecated).
    #[serde(alias = "gamma")]
    gamma_degrees: f64,
    epsilon: Option<f64>,
    seed: Option<u64>,
    fresnel: Option<FresnelSection>,
    multinomial: Option<MultinomialName>,
    #[serde(default)]
    coloured: bool,
    sampling_scale: Option<f64>,
    pdf_quadrature: Option<PdfQuadratureName>,
    pdf_points: Option<usize>,
    expected_footprint_area: Option<f64>,
    negligible_count: Option<f64>,
    uv_scale: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MixSection {
    components: Vec<toml::Value>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ComponentSection {
    material: String,
    weight: f64,
}

/// The shape types, by their `type`.
const SHAPE_TYPES: &[&str] = &["sphere", "rectangle", "mesh"];

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

/// The light types, by their `type`.
const LIGHT_TYPES: &[&str] = &["sphere", "rectangle", "directional", "environment"];

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

/// A number for an error message (see [`limits::number`]).
fn shown(x: f64) -> String {
    limits::number(x)
}

/// `name` and up to nine more of `names`, quoted and bounded, for an error message.
fn name_list<'a>(names: impl ExactSizeIterator<Item = &'a str>) -> String {
    const SHOWN: usize = 10;
    let total = names.len();
    let mut out: Vec<String> = names.take(SHOWN).map(echo).collect();
    if total > SHOWN {
        out.push(format!("… {total} in all"));
    }
    out.join(", ")
}

/// What a scene has used of its budgets ([`crate::limits`]): asset bytes, image pixels,
/// material parts.
#[derive(Debug, Default)]
struct Budget {
    asset_bytes: Cell<u64>,
    /// Every asset file read, in order.
    assets: std::cell::RefCell<Vec<PathBuf>>,
    pixels: Cell<usize>,
    material_parts: Cell<usize>,
}

/// Builds scenes from one file, naming it in every error.
struct Builder<'a> {
    file: &'a Path,
    directory: PathBuf,
    budget: Budget,
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

    /// `value` read as a `T`, errors naming the field by `field` and the path inside it.
    fn section<T: DeserializeOwned>(&self, field: &str, value: toml::Value) -> Checked<T> {
        value.try_into().map_err(|e: toml::de::Error| {
            // The path inside the value is only in the error's display: "message\nin `a.b`".
            let shown = e.to_string();
            let inner = shown
                .lines()
                .rev()
                .find_map(|line| line.strip_prefix("in `")?.strip_suffix('`'))
                .filter(|keys| !keys.is_empty());
            let field = match (field.is_empty(), inner) {
                (_, None) => field.to_string(),
                (true, Some(keys)) => keys.to_string(),
                (false, Some(keys)) => format!("{field}.{keys}"),
            };
            TracerError::Scene {
                file: self.file.to_path_buf(),
                field,
                problem: echo(e.message()),
            }
        })
    }

    /// The `type` of a tagged table (a material, shape or light) among `types`, and the table
    /// without it.
    fn tagged(
        &self,
        field: &str,
        value: toml::Value,
        types: &[&str],
    ) -> Checked<(String, toml::Value)> {
        let expected = types
            .iter()
            .map(|t| format!("`{t}`"))
            .collect::<Vec<_>>()
            .join(", ");
        let toml::Value::Table(mut table) = value else {
            return self.fail(
                field,
                format!("expected a table with a `type` (one of {expected})"),
            );
        };
        let kind = match table.remove("type") {
            None => return self.fail(field, format!("missing `type` (one of {expected})")),
            Some(toml::Value::String(kind)) if types.contains(&kind.as_str()) => kind,
            Some(toml::Value::String(kind)) => {
                return self.fail(
                    format!("{field}.type"),
                    format!("unknown type `{}`, expected one of {expected}", echo(&kind)),
                );
            }
            Some(other) => {
                return self.fail(
                    format!("{field}.type"),
                    format!(
                        "expected a string, one of {expected}, got {}",
                        echo(&other.to_string())
                    ),
                );
            }
        };
        Ok((kind, toml::Value::Table(table)))
    }

    /// A position or vector: finite and within [`limits::MAX_COORDINATE`] per component.
    fn point(&self, field: &str, v: [f64; 3]) -> Checked<DVec3> {
        let v = DVec3::from_array(v);
        // `max_element` skips NaN: finiteness is checked on its own.
        if v.is_finite() && v.abs().max_element() <= limits::MAX_COORDINATE {
            Ok(v)
        } else {
            self.fail(
                field,
                format!(
                    "{}: coordinates must be finite and within ±{:e}",
                    limits::vector(v),
                    limits::MAX_COORDINATE
                ),
            )
        }
    }

    /// A unit direction from any finite, non-zero vector (scaled first, so that neither tiny
    /// nor huge components underflow or overflow).
    fn direction(&self, field: &str, v: [f64; 3]) -> Checked<DVec3> {
        let v = DVec3::from_array(v);
        if !v.is_finite() {
            return self.fail(field, format!("{} is not finite", limits::vector(v)));
        }
        let largest = v.abs().max_element();
        if largest > 0.0 {
            Ok((v / largest).normalize())
        } else {
            self.fail(field, "a direction cannot be the zero vector")
        }
    }

    fn positive(&self, field: &str, x: f64) -> Checked<f64> {
        if x > 0.0 && x.is_finite() {
            Ok(x)
        } else {
            self.fail(
                field,
                format!("must be positive and finite, got {}", shown(x)),
            )
        }
    }

    /// A number in [lowest, highest] (NaN is not).
    fn within(&self, field: &str, x: f64, lowest: f64, highest: f64) -> Checked<f64> {
        if x >= lowest && x <= highest {
            Ok(x)
        } else {
            self.fail(
                field,
                format!(
                    "must be in [{}, {}], got {}",
                    shown(lowest),
                    shown(highest),
                    shown(x)
                ),
            )
        }
    }

    /// A colour with every component in [0, `highest`]; `what` names the quantity.
    fn colour_at_most(&self, field: &str, c: Colour, highest: f64, what: &str) -> Checked<DVec3> {
        let c = c.rgb();
        if c.is_finite() && c.min_element() >= 0.0 && c.max_element() <= highest {
            Ok(c)
        } else {
            self.fail(
                field,
                format!(
                    "{what} components must be in [0, {}], got {}",
                    shown(highest),
                    limits::vector(c)
                ),
            )
        }
    }

    /// An albedo: components in [0, [`limits::MAX_ALBEDO`]].
    fn albedo(&self, field: &str, c: Colour) -> Checked<DVec3> {
        self.colour_at_most(field, c, limits::MAX_ALBEDO, "albedo")
    }

    /// A Fresnel term within glint-brdf's range (η in [10⁻³, 10³], k in [0, 10³]: the range
    /// of every interface), its error naming `{field}.eta` or `{field}.k`.
    fn checked_fresnel(&self, field: &str, fresnel: Fresnel) -> Checked<Fresnel> {
        fresnel.validated().map_err(|e| match e {
            glint_brdf::BrdfError::InvalidFresnel { parameter, .. } => {
                self.brdf_error(&format!("{field}.{parameter}"), &e)
            }
            other => self.brdf_error(field, &other),
        })
    }

    /// An emitted radiance or irradiance: components in [0, [`limits::MAX_EMISSION`]].
    fn emitted(&self, field: &str, c: DVec3, what: &str) -> Checked<DVec3> {
        if c.is_finite() && c.min_element() >= 0.0 && c.max_element() <= limits::MAX_EMISSION {
            Ok(c)
        } else {
            self.fail(
                field,
                format!(
                    "{what} must be in [0, {:e}] per channel, got {}",
                    limits::MAX_EMISSION,
                    limits::vector(c)
                ),
            )
        }
    }

    /// Checks that `bytes` more asset bytes fit the scene's budget, and counts them.
    fn spend_asset_bytes(&self, field: &str, path: &Path) -> Checked<()> {
        // A file that cannot be inspected is reported by its reader.
        let bytes = std::fs::metadata(path).map_or(0, |m| m.len());
        let total = self.budget.asset_bytes.get().saturating_add(bytes);
        if total > limits::MAX_SCENE_ASSET_BYTES {
            return self.fail(
                field,
                format!(
                    "the scene's assets exceed {} bytes together",
                    limits::MAX_SCENE_ASSET_BYTES
                ),
            );
        }
        self.budget.asset_bytes.set(total);
        self.budget.assets.borrow_mut().push(path.to_path_buf());
        Ok(())
    }

    fn image(&self, field: &str, relative: &str) -> Checked<RgbImage> {
        let path = self.asset(relative);
        self.spend_asset_bytes(field, &path)?;
        let image = RgbImage::load(&path).map_err(|e| TracerError::Scene {
            file: self.file.to_path_buf(),
            field: field.into(),
            problem: e.to_string(),
        })?;
        let pixels = self.budget.pixels.get() + image.pixels.len();
        if pixels > limits::MAX_SCENE_PIXELS {
            return self.fail(
                field,
                format!(
                    "the scene's images exceed {} pixels together",
                    limits::MAX_SCENE_PIXELS
                ),
            );
        }
        self.budget.pixels.set(pixels);
        Ok(image)
    }

    /// An albedo: a colour, or an image tinted by it; every texel times the tint at most
    /// [`limits::MAX_ALBEDO`].
    fn texture(
        &self,
        field: &str,
        colour: Option<Colour>,
        texture: Option<&str>,
        scale: Option<[f64; 2]>,
    ) -> Checked<Texture> {
        match texture {
            None => Ok(Texture::Constant(match colour {
                Some(c) => self.albedo(&format!("{field}.colour"), c)?,
                None => DVec3::splat(0.5),
            })),
            Some(file) => {
                let image = self.image(&format!("{field}.texture"), file)?;
                let scale = DVec2::from_array(scale.unwrap_or([1.0, 1.0]));
                if !(scale.is_finite() && scale.min_element() > 0.0) {
                    return self.fail(
                        format!("{field}.texture_scale"),
                        format!(
                            "must be positive, got [{}, {}]",
                            shown(scale.x),
                            shown(scale.y)
                        ),
                    );
                }
                let tint = match colour {
                    Some(c) => self.albedo(&format!("{field}.colour"), c)?,
                    None => DVec3::ONE,
                };
                let brightest = image.max_value() * tint.max_element();
                if !(brightest <= limits::MAX_ALBEDO) {
                    return self.fail(
                        format!("{field}.texture"),
                        format!(
                            "an albedo of {} (texel times colour): albedos must be at most {}",
                            shown(brightest),
                            limits::MAX_ALBEDO
                        ),
                    );
                }
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
        let Roughness(ax, ay) = alpha;
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

    /// Builds material `name`, used at `used_at` (the field that names it). `visiting` holds
    /// the mixes being built around it (for cycles and the nesting limit).
    fn material(
        &self,
        name: &str,
        used_at: &str,
        sections: &BTreeMap<String, toml::Value>,
        visiting: &mut Vec<String>,
    ) -> Checked<Material> {
        let Some(section) = sections.get(name) else {
            return self.fail(
                used_at,
                format!(
                    "unknown material `{}` (defined: {})",
                    echo(name),
                    name_list(sections.keys().map(String::as_str))
                ),
            );
        };
        let field = format!("materials.{}", echo(name));
        if visiting.iter().any(|v| v == name) {
            return self.fail(
                field,
                format!(
                    "mix components form a cycle: {} → {}",
                    visiting
                        .iter()
                        .map(|v| echo(v))
                        .collect::<Vec<_>>()
                        .join(" → "),
                    echo(name)
                ),
            );
        }
        if visiting.len() >= limits::MAX_MIX_DEPTH {
            return self.fail(
                field,
                format!("mixes nest deeper than {} levels", limits::MAX_MIX_DEPTH),
            );
        }
        let parts = self.budget.material_parts.get() + 1;
        if parts > limits::MAX_MATERIAL_PARTS {
            return self.fail(
                field,
                format!(
                    "the scene builds more than {} material parts (each use inside a mix counts)",
                    limits::MAX_MATERIAL_PARTS
                ),
            );
        }
        self.budget.material_parts.set(parts);
        let (kind, section) = self.tagged(&field, section.clone(), MATERIAL_TYPES)?;
        Ok(match kind.as_str() {
            "diffuse" => {
                let d: DiffuseSection = self.section(&field, section)?;
                Material::Diffuse(self.texture(
                    &field,
                    d.colour,
                    d.texture.as_deref(),
                    d.texture_scale,
                )?)
            }
            "conductor" => {
                let c: ConductorSection = self.section(&field, section)?;
                let distribution = self.microfacet(&field, c.distribution, c.alpha)?;
                let fresnel = self.checked_fresnel(
                    &field,
                    Fresnel::Conductor {
                        eta: c.eta.rgb(),
                        k: c.k.rgb(),
                    },
                )?;
                Material::Microfacet(
                    MicrofacetBrdf::new(distribution, fresnel, NormalSampling::Distribution)
                        .map_err(|e| self.brdf_error(&format!("{field}.eta"), &e))?,
                )
            }
            "plastic" => {
                let p: PlasticSection = self.section(&field, section)?;
                let distribution = self.microfacet(&field, p.distribution, p.alpha)?;
                let eta = p.eta;
                self.checked_fresnel(&field, Fresnel::Dielectric { eta })?;
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
            "glint" => {
                let g: GlintSection = self.section(&field, section)?;
                self.glint(&field, &g)?
            }
            "mirror" => {
                let m: MirrorSection = self.section(&field, section)?;
                let colour = match m.colour {
                    None => DVec3::ONE,
                    Some(c) => self.colour_at_most(
                        &format!("{field}.colour"),
                        c,
                        1.0,
                        "reflectance factor",
                    )?,
                };
                Material::Mirror(Mirror {
                    colour,
                    fresnel: self.fresnel(&format!("{field}.fresnel"), m.fresnel.as_ref())?,
                })
            }
            _ => {
                let m: MixSection = self.section(&field, section)?;
                if m.components.is_empty() {
                    return self.fail(
                        format!("{field}.components"),
                        "a mix needs at least one component",
                    );
                }
                visiting.push(name.to_string());
                let mut parts = Vec::new();
                for (i, c) in m.components.into_iter().enumerate() {
                    let component = format!("{field}.components[{i}]");
                    let c: ComponentSection = self.section(&component, c)?;
                    let weight = c.weight;
                    if !(0.0..=limits::MAX_MIX_WEIGHT).contains(&weight) {
                        return self.fail(
                            format!("{component}.weight"),
                            format!(
                                "must be in [0, {}], got {}",
                                limits::MAX_MIX_WEIGHT,
                                shown(weight)
                            ),
                        );
                    }
                    let used_at = format!("{component}.material");
                    let part = self.material(&c.material, &used_at, sections, visiting)?;
                    if matches!(part, Material::Mirror(_)) {
                        return self.fail(
                            used_at,
                            format!(
                                "`{}` is a mirror, which cannot be a mix component (a delta \
                                 reflection has no density to mix)",
                                echo(&c.material)
                            ),
                        );
                    }
                    parts.push((weight, part));
                }
                visiting.pop();
                if !(parts.iter().map(|p| p.0).sum::<f64>() > 0.0) {
                    return self.fail(format!("{field}.components"), "the weights sum to zero");
                }
                Material::Mix(parts)
            }
        })
    }

    /// The Fresnel term of section `field` (absent: none).
    fn fresnel(&self, field: &str, section: Option<&FresnelSection>) -> Checked<Fresnel> {
        let fresnel = match section {
            None | Some(FresnelSection::None) => Fresnel::None,
            Some(FresnelSection::Conductor { eta, k }) => Fresnel::Conductor {
                eta: eta.rgb(),
                k: k.rgb(),
            },
            Some(FresnelSection::Dielectric { eta }) => Fresnel::Dielectric { eta: *eta },
        };
        self.checked_fresnel(field, fresnel)
    }

    fn glint(&self, field: &str, g: &GlintSection) -> Checked<Material> {
        let distribution = self.microfacet(field, g.distribution, g.alpha)?;
        let mut parameters = GlintParameters::new(distribution);
        // 2⁵³, the count tree's limit: every whole number up to it is a double.
        if !(g.particles >= 1.0
            && g.particles <= 9_007_199_254_740_992.0
            && g.particles.fract() == 0.0)
        {
            return self.fail(
                format!("{field}.particles"),
                format!(
                    "must be a whole number in [1, 2^53], got {}",
                    shown(g.particles)
                ),
            );
        }
        parameters.particles = g.particles as u64;
        // glint-brdf's range, [10⁻⁶ rad, 60°].
        let smallest = 1e-6f64.to_degrees();
        if !(g.gamma_degrees >= smallest && g.gamma_degrees <= 60.0) {
            return self.fail(
                format!("{field}.gamma_degrees"),
                format!(
                    "the cone radius must be in [{smallest:.3e}°, 60°] (10⁻⁶ rad to 60°), got {}°",
                    shown(g.gamma_degrees)
                ),
            );
        }
        parameters.gamma_radians = g.gamma_degrees.to_radians();
        if let Some(epsilon) = g.epsilon {
            parameters.epsilon = epsilon;
        }
        parameters.seed = g.seed.unwrap_or(0);
        parameters.fresnel = self.fresnel(&format!("{field}.fresnel"), g.fresnel.as_ref())?;
        parameters.multinomial = match g.multinomial {
            None | Some(MultinomialName::Exact) => MultinomialMode::Exact,
            Some(MultinomialName::Normal) => MultinomialMode::Normal,
        };
        parameters.colour_channels = if g.coloured { 3 } else { 0 };
        if let Some(s) = g.sampling_scale {
            parameters.sampling_scale = s;
        }
        if let Some(q) = g.pdf_quadrature {
            parameters.pdf_quadrature = match q {
                PdfQuadratureName::Cubature => PdfQuadrature::Cubature,
                PdfQuadratureName::Qmc => PdfQuadrature::QuasiMonteCarlo,
            };
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
                format!(
                    "must be finite and ≥ 0 (0 traverses every query), got {}",
                    shown(negligible_count)
                ),
            );
        }
        parameters.negligible_count = negligible_count;
        let uv_scale = self.positive(&format!("{field}.uv_scale"), g.uv_scale.unwrap_or(1.0))?;
        let brdf = DiscreteBrdf::new(parameters).map_err(|e| self.brdf_error(field, &e))?;
        Ok(Material::Glint(GlintMaterial {
            brdf: Arc::new(brdf),
            uv_scale,
            plan_footprint_area: g.expected_footprint_area.is_none(),
        }))
    }

    fn transform(&self, field: &str, t: &TransformSection) -> Checked<DAffine3> {
        let scale = match t.scale {
            None => DVec3::ONE,
            Some(s) => s.rgb(),
        };
        if !(scale.is_finite()
            && scale.abs().max_element() <= limits::MAX_COORDINATE
            && scale.abs().min_element() > 0.0)
        {
            return self.fail(
                format!("{field}.scale"),
                format!(
                    "must be non-zero and within ±{:e}, got {}",
                    limits::MAX_COORDINATE,
                    limits::vector(scale)
                ),
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
        let translation = self.point(
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
        let center = self.point(&format!("{field}.center"), center)?;
        let u = self.point(&format!("{field}.u"), u)?;
        let v = self.point(&format!("{field}.v"), v)?;
        match Rectangle::new(center, u, v) {
            Some(r) => Ok(r),
            None => self.fail(
                format!("{field}.v"),
                "the edges u and v are parallel, zero or too small: the rectangle has no area",
            ),
        }
    }

    fn sphere(&self, field: &str, center: [f64; 3], radius: f64) -> Checked<Sphere> {
        Ok(Sphere {
            center: self.point(&format!("{field}.center"), center)?,
            radius: self.within(
                &format!("{field}.radius"),
                radius,
                limits::MIN_RADIUS,
                limits::MAX_COORDINATE,
            )?,
        })
    }

    /// Exactly one of `power` and `radiance`, converted to radiance by `radiance_per_watt`;
    /// the radiance at most [`limits::MAX_EMISSION`].
    fn emission(
        &self,
        field: &str,
        power: Option<Colour>,
        radiance: Option<Colour>,
        radiance_per_watt: f64,
    ) -> Checked<DVec3> {
        match (power, radiance) {
            (Some(p), None) => {
                let power_field = format!("{field}.power");
                let p = self.colour_at_most(&power_field, p, f64::MAX, "power")?;
                let radiance = p * radiance_per_watt;
                if radiance.is_finite() && radiance.max_element() <= limits::MAX_EMISSION {
                    Ok(radiance)
                } else {
                    self.fail(
                        power_field,
                        format!(
                            "{} W gives a radiance of {}, above the limit {:e}: lower the power or enlarge the light",
                            limits::vector(p),
                            limits::vector(radiance),
                            limits::MAX_EMISSION
                        ),
                    )
                }
            }
            (None, Some(l)) => self.emitted(&format!("{field}.radiance"), l.rgb(), "radiance"),
            (Some(_), Some(_)) => self.fail(field, "give either power or radiance, not both"),
            (None, None) => self.fail(field, "an emitter needs power (watts) or radiance"),
        }
    }

    /// A keyframe's or the camera's pose, checked.
    fn pose(&self, field: &str, pose: CameraPose) -> Checked<CameraPose> {
        match pose_problem(&pose) {
            None => Ok(pose),
            Some(problem) => self.fail(field, format!("degenerate pose: {problem}")),
        }
    }

    fn camera(&self, value: toml::Value) -> Checked<Camera> {
        let c: CameraSection = self.section("camera", value)?;
        let base = CameraPose {
            position: self.point("camera.position", c.position)?,
            look_at: self.point("camera.look_at", c.look_at)?,
            up: self.point("camera.up", c.up)?,
            fov_degrees: c.fov,
        };
        let mut keyframes = vec![];
        if c.keyframes.is_empty() {
            keyframes.push(Keyframe {
                frame: 0.0,
                pose: self.pose("camera", base)?,
            });
        }
        for (i, k) in c.keyframes.into_iter().enumerate() {
            let field = format!("camera.keyframes[{i}]");
            let k: KeyframeSection = self.section(&field, k)?;
            let pose = CameraPose {
                position: k.position.map_or(Ok(base.position), |p| {
                    self.point(&format!("{field}.position"), p)
                })?,
                look_at: k.look_at.map_or(Ok(base.look_at), |p| {
                    self.point(&format!("{field}.look_at"), p)
                })?,
                up: k
                    .up
                    .map_or(Ok(base.up), |p| self.point(&format!("{field}.up"), p))?,
                fov_degrees: k.fov.unwrap_or(base.fov_degrees),
            };
            if !k.frame.is_finite() {
                return self.fail(format!("{field}.frame"), "must be finite");
            }
            // Two poses at one frame would make the camera there depend on their order.
            if let Some(j) = keyframes.iter().position(|other| other.frame == k.frame) {
                return self.fail(
                    format!("{field}.frame"),
                    format!(
                        "frame {} is also camera.keyframes[{j}]'s: each keyframe needs a frame of its own",
                        shown(k.frame)
                    ),
                );
            }
            keyframes.push(Keyframe {
                frame: k.frame,
                pose: self.pose(&field, pose)?,
            });
        }
        match Camera::new(keyframes) {
            Some(camera) => Ok(camera),
            None => self.fail("camera", "a keyframe's pose is degenerate"),
        }
    }

    fn settings(&self, value: Option<toml::Value>) -> Checked<RenderSettings> {
        let r: RenderSection = match value {
            None => RenderSection::default(),
            Some(value) => self.section("render", value)?,
        };
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
                FootprintName::All => GlintFootprints::All,
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
        if let Some(cones) = r.glint_light_cones {
            s.glint_light_cones = cones;
        }
        if let Some([x0, x1, y0, y1]) = r.pixel_bounds {
            s.pixel_bounds = Some(PixelBounds { x0, x1, y0, y1 });
        }
        if let Some(b) = r.bloom {
            if !(b.threshold >= 0.0 && b.threshold.is_finite()) {
                return self.fail(
                    "render.bloom.threshold",
                    format!("must be finite and ≥ 0, got {}", shown(b.threshold)),
                );
            }
            let radius = self.positive("render.bloom.radius", b.radius)?;
            if !(radius <= 256.0) {
                return self.fail(
                    "render.bloom.radius",
                    format!("at most 256 pixels, got {}", shown(radius)),
                );
            }
            if !(b.strength >= 0.0 && b.strength.is_finite()) {
                return self.fail(
                    "render.bloom.strength",
                    format!("must be finite and ≥ 0, got {}", shown(b.strength)),
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

    /// Checks that `more` primitives fit [`limits::MAX_PRIMITIVES`] after `count`.
    fn room_for(&self, field: &str, count: usize, more: usize) -> Checked<()> {
        if count.saturating_add(more) > limits::MAX_PRIMITIVES {
            return self.fail(
                field,
                format!(
                    "the scene would have more than {} primitives (shapes, area lights and triangles)",
                    limits::MAX_PRIMITIVES
                ),
            );
        }
        Ok(())
    }

    fn build(&self, file: SceneFile) -> Checked<Scene> {
        let settings = self.settings(file.render)?;
        let camera = self.camera(file.camera)?;
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
                let material = self.material(name, field, &file.materials, &mut Vec::new())?;
                materials.push(material);
                material_names.push(name.to_string());
                let i = (materials.len() - 1) as u32;
                material_index.insert(name.to_string(), i);
                Ok(i)
            };
        for (i, shape) in file.shapes.into_iter().enumerate() {
            let field = format!("shapes[{i}]");
            self.room_for(&field, primitives.len(), 1)?;
            let (kind, shape) = self.tagged(&field, shape, SHAPE_TYPES)?;
            match kind.as_str() {
                "sphere" => {
                    let s: SphereSection = self.section(&field, shape)?;
                    let sphere = self.sphere(&field, s.center, s.radius)?;
                    let material =
                        use_material(&s.material, &format!("{field}.material"), &mut materials)?;
                    primitives.push(Primitive {
                        geometry: Geometry::Sphere(sphere),
                        material,
                        light: None,
                    });
                }
                "rectangle" => {
                    let r: RectangleSection = self.section(&field, shape)?;
                    let rectangle = self.rectangle(&field, r.center, r.u, r.v)?;
                    let material =
                        use_material(&r.material, &format!("{field}.material"), &mut materials)?;
                    primitives.push(Primitive {
                        geometry: Geometry::Rectangle(rectangle),
                        material,
                        light: None,
                    });
                }
                _ => {
                    let m: MeshSection = self.section(&field, shape)?;
                    let material =
                        use_material(&m.material, &format!("{field}.material"), &mut materials)?;
                    let transform = self.transform(&format!("{field}.transform"), &m.transform)?;
                    let path = self.asset(&m.file);
                    let file_field = format!("{field}.file");
                    self.spend_asset_bytes(&file_field, &path)?;
                    let mesh = Mesh::load_obj(&path).map_err(|e| TracerError::Scene {
                        file: self.file.to_path_buf(),
                        field: file_field.clone(),
                        problem: e.to_string(),
                    })?;
                    let mesh = mesh.transformed(&transform);
                    // The transform may carry vertices past the coordinate limit.
                    mesh.validate().map_err(|problem| TracerError::Scene {
                        file: self.file.to_path_buf(),
                        field: format!("{field}.transform"),
                        problem: format!("{}: after the transform, {problem}", echo(&m.file)),
                    })?;
                    self.room_for(&file_field, primitives.len(), mesh.triangles.len())?;
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
        for (i, light) in file.lights.into_iter().enumerate() {
            let field = format!("lights[{i}]");
            self.room_for(&field, primitives.len(), 1)?;
            let index = lights.len() as u32;
            let (kind, light) = self.tagged(&field, light, LIGHT_TYPES)?;
            match kind.as_str() {
                "sphere" => {
                    let s: SphereLightSection = self.section(&field, light)?;
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
                "rectangle" => {
                    let r: RectangleLightSection = self.section(&field, light)?;
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
                            let texture_field = format!("{field}.texture");
                            let image = self.image(&texture_field, file)?;
                            // With power given, the texture's mean carries that power.
                            if r.power.is_some() {
                                let mean = crate::light::luminance(image.mean());
                                if !(mean > 0.0) {
                                    return self
                                        .fail(texture_field, "a black texture cannot carry power");
                                }
                                colour /= mean;
                            }
                            let brightest = image.max_value() * colour.max_element();
                            if !(brightest <= limits::MAX_EMISSION) {
                                return self.fail(
                                    texture_field,
                                    format!(
                                        "the brightest texel emits {brightest:e}, above the limit {:e}",
                                        limits::MAX_EMISSION
                                    ),
                                );
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
                "directional" => {
                    let d: DirectionalSection = self.section(&field, light)?;
                    lights.push(Light::Directional {
                        direction: self.direction(&format!("{field}.direction"), d.direction)?,
                        irradiance: self.emitted(
                            &format!("{field}.irradiance"),
                            d.irradiance.rgb(),
                            "irradiance",
                        )?,
                    });
                }
                _ => {
                    let e: EnvironmentSection = self.section(&field, light)?;
                    let rotation = e.rotation.unwrap_or(0.0);
                    if !rotation.is_finite() {
                        return self.fail(format!("{field}.rotation"), "must be finite");
                    }
                    if lights.iter().any(|l| matches!(l, Light::Environment(_))) {
                        return self.fail(field, "a scene has at most one environment");
                    }
                    let scale = match e.scale {
                        Some(s) => {
                            self.colour_at_most(&format!("{field}.scale"), s, f64::MAX, "scale")?
                        }
                        None => DVec3::ONE,
                    };
                    let map = match (&e.file, e.radiance) {
                        (Some(file), None) => {
                            let file_field = format!("{field}.file");
                            let image = self.image(&file_field, file)?;
                            let brightest = image.max_value() * scale.max_element();
                            self.emitted(
                                &file_field,
                                DVec3::splat(brightest),
                                "radiance (texel times scale)",
                            )?;
                            EnvironmentMap::new(image, scale, rotation.to_radians())
                        }
                        (None, Some(l)) => {
                            let radiance = l.rgb() * scale;
                            self.colour_at_most(
                                &format!("{field}.radiance"),
                                l,
                                f64::MAX,
                                "radiance",
                            )?;
                            EnvironmentMap::constant(self.emitted(
                                &format!("{field}.radiance"),
                                radiance,
                                "radiance (times scale)",
                            )?)
                        }
                        _ => {
                            return self.fail(
                                field,
                                "an environment needs exactly one of file and radiance",
                            );
                        }
                    };
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
        let mut scene = Scene {
            accelerator: Accelerator::new(primitives, meshes),
            materials,
            material_names,
            lights,
            camera,
            settings,
            assets: self.budget.assets.take(),
        };
        // Eq. 11's prior run plans the glint trees' footprint area from this scene's view.
        crate::plan::apply(&mut scene).map_err(|e| self.brdf_error("materials", &e))?;
        Ok(scene)
    }
}

/// Reads and builds the scene in `path`: a regular file of at most
/// [`limits::MAX_SCENE_FILE_BYTES`], UTF-8 TOML.
///
/// # Errors
/// [`TracerError::Scene`] naming the file, the field and the problem.
pub fn load_scene(path: &Path) -> Result<Scene, TracerError> {
    let error = |problem: String| TracerError::Scene {
        file: path.to_path_buf(),
        field: String::new(),
        problem,
    };
    let bytes = limits::read_file(path, limits::MAX_SCENE_FILE_BYTES)
        .map_err(|e| error(format!("cannot read the scene file: {e}")))?;
    let text = String::from_utf8(bytes)
        .map_err(|e| error(format!("the scene file is not UTF-8 text: {e}")))?;
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
        budget: Budget::default(),
    };
    let table: toml::Table = toml::from_str(text).map_err(|e| TracerError::Scene {
        file: path.to_path_buf(),
        field: String::new(),
        problem: limits::echo_lines(e.to_string().trim_end()),
    })?;
    let file: SceneFile = builder.section("", toml::Value::Table(table))?;
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

    /// `gamma_degrees` names the cone radius; `gamma`, its older name, is still read with the
    /// same meaning; both at once are an error naming the duplicate.
    #[test]
    fn gamma_degrees_and_its_older_name_mean_the_same() {
        let gamma = |scene: &Scene| {
            let glint = scene.materials.iter().find_map(|m| match m {
                Material::Mix(parts) => parts.iter().find_map(|(_, m)| match m {
                    Material::Glint(g) => Some(g.brdf.parameters().gamma_radians),
                    _ => None,
                }),
                _ => None,
            });
            glint.expect("VALID mixes a glint material")
        };
        assert!(VALID.contains("gamma = 2"));
        let old = parse_scene(VALID, Path::new("old.toml")).unwrap();
        let new = parse_scene(
            &VALID.replace("gamma = 2", "gamma_degrees = 2"),
            Path::new("new.toml"),
        )
        .unwrap();
        assert_eq!(gamma(&old), 2f64.to_radians());
        assert_eq!(gamma(&old), gamma(&new));
        let both = parse_scene(
            &VALID.replace("gamma = 2", "gamma = 2\ngamma_degrees = 2"),
            Path::new("both.toml"),
        );
        let message = both.unwrap_err().to_string();
        assert!(message.contains("gamma_degrees"), "{message}");
    }

    /// Each mistake gets an error naming the field and the problem, never a panic.
    #[test]
    fn scene_errors_name_the_field_and_the_problem() {
        let cases: &[(&str, &str, &str, &str)] = &[
            // (replace, with, expected field, expected words in the problem)
            (
                "radius = 0.5",
                "radus = 0.5",
                "shapes[0]",
                "unknown field `radus`",
            ),
            (
                "radius = 0.5",
                "radius = -0.5",
                "shapes[0].radius",
                "must be in",
            ),
            (
                "radius = 0.5",
                "radius = nan",
                "shapes[0].radius",
                "must be in",
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
                "materials.sparkle.gamma_degrees",
                "[5.730e-5°, 60°]",
            ),
            (
                "particles = 1e6",
                "particles = 0.5",
                "materials.sparkle.particles",
                "whole number",
            ),
            ("power = 10", "power = -10", "lights[0].power", "in [0,"),
            ("power = 10", "", "lights[0]", "power (watts) or radiance"),
            ("spp = 2", "spp = 0", "render.spp", "outside"),
            (
                "type = \"sphere\"\ncenter = [0, 0, 0]",
                "type = \"cube\"\ncenter = [0, 0, 0]",
                "shapes[0].type",
                "unknown type `cube`",
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
                "must be in [0, 1]",
            ),
            (
                "gamma = 2",
                "gamma = 2\nnegligible_count = -1e-9",
                "materials.sparkle.negligible_count",
                "≥ 0",
            ),
            ("[render]", "[render", "", "TOML parse error"),
            ("spp = 2", "spp = \"many\"", "render.spp", "invalid type"),
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

#[cfg(test)]
mod limit_tests {
    use super::*;
    use crate::fuzz::{Fixture, render_tiny};
    use proptest::prelude::*;

    /// A scene whose values are slots: `{center}`, `{radius}`, `{u}`, `{scale}`, `{translate}`,
    /// `{position}`, `{power}`, `{light_radius}`, `{radiance}`, `{irradiance}`, `{env}`,
    /// `{env_scale}`, `{albedo}`, `{weight}`, `{obj_x}`, `{uv_scale}`, `{eta}`, `{k}`,
    /// `{mirror_colour}`, `{mirror_eta}`.
    const TEMPLATE: &str = r#"
[render]
integrator = "path"
max_depth = 3
[camera]
position = [{position}, 1, 4]
look_at = [0, 0, 0]
[materials.white]
type = "diffuse"
colour = {albedo}
[materials.sparkle]
type = "glint"
alpha = 0.2
particles = 1e6
gamma = 2
negligible_count = 0
uv_scale = {uv_scale}
fresnel = { type = "conductor", eta = {eta}, k = {k} }
[materials.shiny]
type = "mirror"
colour = [0.9, {mirror_colour}, 0.8]
fresnel = { type = "dielectric", eta = {mirror_eta} }
[materials.both]
type = "mix"
components = [{ material = "white", weight = {weight} }, { material = "sparkle", weight = 0.5 }]
[[shapes]]
type = "sphere"
center = [{center}, 0, 0]
radius = {radius}
material = "both"
[[shapes]]
type = "rectangle"
center = [0, -1, 0]
u = [{u}, 0, 0]
v = [0, 0, -8]
material = "white"
[[shapes]]
type = "mesh"
file = "mesh.obj"
material = "both"
transform = { scale = {scale}, translate = [{translate}, 0, 0] }
[[shapes]]
type = "rectangle"
center = [0, 0, -3]
u = [3, 0, 0]
v = [0, 3, 0]
material = "shiny"
[[lights]]
type = "sphere"
center = [1, 2, 1]
radius = {light_radius}
power = {power}
[[lights]]
type = "rectangle"
center = [0, 3, 0]
u = [1, 0, 0]
v = [0, 0, 1]
radiance = {radiance}
[[lights]]
type = "directional"
direction = [0, 1, 0.3]
irradiance = {irradiance}
[[lights]]
type = "environment"
radiance = {env}
scale = {env_scale}
"#;

    const SLOTS: [&str; 20] = [
        "center",
        "radius",
        "u",
        "scale",
        "translate",
        "position",
        "power",
        "light_radius",
        "radiance",
        "irradiance",
        "env",
        "env_scale",
        "albedo",
        "weight",
        "obj_x",
        "uv_scale",
        "eta",
        "k",
        "mirror_colour",
        "mirror_eta",
    ];

    /// Ordinary values for every slot.
    fn ordinary(slot: &str) -> f64 {
        match slot {
            "radius" | "scale" | "albedo" | "weight" | "env" | "env_scale" | "eta" => 0.5,
            "uv_scale" => 1.0,
            "k" => 3.0,
            "mirror_colour" => 0.9,
            "mirror_eta" => 1.5,
            "u" => 8.0,
            "light_radius" => 0.1,
            "power" => 10.0,
            "radiance" | "irradiance" => 2.0,
            _ => 0.25,
        }
    }

    /// The scene with `values` in its slots and the mesh beside it, written in the fixture.
    fn scene(fixture: &Fixture, values: &BTreeMap<&str, f64>) -> String {
        let number = |x: f64| {
            if x.is_nan() {
                "nan".to_string()
            } else if x.is_infinite() {
                if x > 0.0 { "inf" } else { "-inf" }.to_string()
            } else {
                format!("{x:e}")
            }
        };
        std::fs::write(
            fixture.dir.join("mesh.obj"),
            format!(
                "v {} 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\n",
                number(values["obj_x"])
            ),
        )
        .unwrap();
        let mut text = TEMPLATE.to_string();
        for slot in SLOTS {
            text = text.replace(&format!("{{{slot}}}"), &number(values[slot]));
        }
        text
    }

    fn error_in(fixture: &Fixture, values: &BTreeMap<&str, f64>) -> (String, String) {
        match parse_scene(&scene(fixture, values), &fixture.scene_path()) {
            Err(TracerError::Scene { field, problem, .. }) => (field, problem),
            Err(other) => panic!("{other}"),
            Ok(_) => panic!("accepted {values:?}"),
        }
    }

    /// Each (slot, value, field, words): the scene with `value` in `slot` is refused, naming
    /// `field`, with a problem containing `words`.
    fn assert_slot_errors(fixture: &Fixture, cases: &[(&str, f64, &str, &str)]) {
        for &(slot, value, field, words) in cases {
            let mut values = ordinary_values();
            values.insert(slot, value);
            let (f, problem) = error_in(fixture, &values);
            assert_eq!(f, field, "{slot} = {value}: {problem}");
            assert!(
                problem.contains(words),
                "{slot} = {value}: `{problem}` lacks `{words}`"
            );
        }
    }

    /// Each (from, to, field, words): `text` with `from` replaced by `to` is refused, naming
    /// `field`, with a problem containing `words`.
    fn assert_edit_errors(fixture: &Fixture, text: &str, cases: &[(&str, &str, &str, &str)]) {
        for &(from, to, field, words) in cases {
            assert!(text.contains(from), "{from}");
            match parse_scene(&text.replacen(from, to, 1), &fixture.scene_path()) {
                Err(TracerError::Scene {
                    field: f, problem, ..
                }) => {
                    assert_eq!(f, field, "{to}: {problem}");
                    assert!(problem.contains(words), "{to}: `{problem}` lacks `{words}`");
                }
                other => panic!("{to}: {other:?}"),
            }
        }
    }

    fn ordinary_values() -> BTreeMap<&'static str, f64> {
        SLOTS.iter().map(|s| (*s, ordinary(s))).collect()
    }

    /// Whether `value` in `slot` is within the documented limits.
    fn within_limits(slot: &str, value: f64) -> bool {
        let coordinate = value.abs() <= limits::MAX_COORDINATE;
        match slot {
            // The rectangle's area 8|u| must square to a positive double.
            "u" => coordinate && (8.0 * value).powi(2) > 0.0,
            "radius" | "light_radius" => {
                (limits::MIN_RADIUS..=limits::MAX_COORDINATE).contains(&value)
            }
            "scale" => coordinate && value != 0.0,
            "albedo" | "mirror_colour" => (0.0..=limits::MAX_ALBEDO).contains(&value),
            // Any positive scale: a footprint beyond ±10¹⁵ texture units is shaded smooth.
            "uv_scale" => value > 0.0 && value.is_finite(),
            "eta" | "mirror_eta" => (Fresnel::MIN_ETA..=Fresnel::MAX_ETA).contains(&value),
            "k" => (0.0..=Fresnel::MAX_K).contains(&value),
            "weight" => (0.0..=limits::MAX_MIX_WEIGHT).contains(&value),
            // Power P over a sphere of radius 0.1: radiance P/(4π²·0.01).
            "power" => value >= 0.0 && value / (4.0 * PI * PI * 0.01) <= limits::MAX_EMISSION,
            "radiance" | "irradiance" => (0.0..=limits::MAX_EMISSION).contains(&value),
            // The environment's radiance times its scale (the other at 0.5).
            "env" | "env_scale" => value >= 0.0 && value * 0.5 <= limits::MAX_EMISSION,
            // The mesh's vertex, scaled by 0.5.
            _ => coordinate,
        }
    }

    /// A number of any magnitude from 10⁻³⁰⁸ to 10³⁰⁸, either sign, or zero, NaN, infinity.
    fn any_number() -> impl Strategy<Value = f64> {
        prop_oneof![
            8 => (any::<bool>(), 1.0..10.0f64, -308i32..=307).prop_map(|(negative, m, e)| {
                let x = m * 10f64.powi(e);
                if negative { -x } else { x }
            }),
            1 => prop_oneof![Just(0.0), Just(f64::NAN), Just(f64::INFINITY), Just(f64::MAX)],
        ]
    }

    proptest! {
        #![proptest_config(crate::fuzz::config(64))]

        /// Any value of any magnitude up to 10³⁰⁸ in a coordinate, length, power, radiance,
        /// irradiance, albedo or mix weight: the scene is accepted exactly when the value is
        /// within its documented limit, and an accepted scene renders to finite, non-negative
        /// pixels no larger than the film's cap (path tracing, glints and a mix included).
        #[test]
        fn values_are_accepted_within_their_limits_and_render_finite(
            slot in proptest::sample::select(SLOTS.to_vec()),
            value in any_number(),
        ) {
            let fixture = Fixture::new("limits-property");
            let mut values = ordinary_values();
            values.insert(slot, value);
            let text = scene(&fixture, &values);
            let result = render_tiny(&fixture, &text, 0.0);
            prop_assert_eq!(
                result.is_ok(),
                within_limits(slot, value),
                "{} = {}: {:?}",
                slot,
                value,
                result.err()
            );
        }
    }

    /// Values that slipped through: a mirror colour of NaN, η and k of 10³⁰⁰ (glint-brdf's
    /// Fresnel range is every interface's), particles above 2⁵³ (the tree's limit), a
    /// keyframe repeating another's frame: each an error naming its field; a footprint_scale
    /// of 10³⁰⁰ is named in a short message with the range (not 301 digits).
    #[test]
    fn slipped_values_are_named_errors() {
        let fixture = Fixture::new("limits-slipped");
        assert_slot_errors(
            &fixture,
            &[
                (
                    "mirror_colour",
                    f64::NAN,
                    "materials.shiny.colour",
                    "reflectance factor components must be in [0, 1], got [0.9, NaN, 0.8]",
                ),
                (
                    "eta",
                    1e300,
                    "materials.sparkle.fresnel.eta",
                    "Fresnel eta = 1e300",
                ),
                ("eta", 0.0, "materials.sparkle.fresnel.eta", "[1e-3, 1e3]"),
                (
                    "k",
                    1001.0,
                    "materials.sparkle.fresnel.k",
                    "Fresnel k = 1001.0",
                ),
                (
                    "mirror_eta",
                    1e-4,
                    "materials.shiny.fresnel.eta",
                    "[1e-3, 1e3]",
                ),
                (
                    "uv_scale",
                    0.0,
                    "materials.sparkle.uv_scale",
                    "positive and finite",
                ),
                (
                    "uv_scale",
                    f64::NAN,
                    "materials.sparkle.uv_scale",
                    "positive and finite",
                ),
            ],
        );
        let text = scene(&fixture, &ordinary_values());
        assert_edit_errors(
            &fixture,
            &text,
            &[
                (
                    "particles = 1e6",
                    "particles = 9007199254740994",
                    "materials.sparkle.particles",
                    "must be a whole number in [1, 2^53]",
                ),
                (
                    "look_at = [0, 0, 0]\n",
                    "look_at = [0, 0, 0]\n[[camera.keyframes]]\nframe = 3\n[[camera.keyframes]]\nframe = 1\n[[camera.keyframes]]\nframe = 3.0\n",
                    "camera.keyframes[2].frame",
                    "frame 3 is also camera.keyframes[0]'s",
                ),
                (
                    "max_depth = 3\n",
                    "max_depth = 3\nfootprint_scale = 1e300\n",
                    "render.footprint_scale",
                    "1e300 must be in (0, 1e6] pixels",
                ),
            ],
        );
    }

    /// A glint material with `uv_scale` = 10³⁰⁰ (footprints of 10²⁹⁸ texture units, beyond
    /// the ±10¹⁵ a footprint may span) shades its smooth limit: no sample is discarded (every
    /// one was, and the image was black), the floor is lit, and every scale beyond the limit
    /// gives the same image.
    #[test]
    fn a_huge_uv_scale_shades_the_smooth_limit() {
        let fixture = Fixture::new("limits-uv-scale");
        let image = |uv_scale: f64| {
            let mut values = ordinary_values();
            values.insert("uv_scale", uv_scale);
            render_tiny(&fixture, &scene(&fixture, &values), 0.0).unwrap()
        };
        let huge = image(1e300);
        assert!(huge.mean().max_element() > 0.0);
        assert_eq!(huge.pixels, image(1e200).pixels);
        assert_eq!(huge.pixels, image(f64::MAX).pixels);
    }

    /// Coordinates beyond ±10¹⁵ (the reported inputs: a sphere of radius 10²⁰⁰, a centre at
    /// 10³⁰⁰, a transform scaling by 10³⁰⁰, an OBJ vertex at 3·10³⁸) are errors naming the file
    /// and the field, and for an OBJ the vertex.
    #[test]
    fn huge_coordinates_are_named_errors() {
        let fixture = Fixture::new("limits-coordinates");
        for (slot, value, field, words) in [
            ("radius", 1e200, "shapes[0].radius", "must be in"),
            ("center", 1e300, "shapes[0].center", "within ±1e15"),
            ("u", 1e16, "shapes[1].u", "within ±1e15"),
            ("position", 2e15, "camera.position", "within ±1e15"),
            ("scale", 1e300, "shapes[2].transform.scale", "within ±1e15"),
            (
                "translate",
                1e16,
                "shapes[2].transform.translate",
                "within ±1e15",
            ),
            ("scale", 1e14, "shapes[2].transform", "after the transform"),
            ("obj_x", 3e38, "shapes[2].file", "v 1 (line 1)"),
            ("obj_x", -3e38, "shapes[2].file", "mesh.obj"),
        ] {
            let mut values = ordinary_values();
            values.insert(slot, value);
            if slot == "scale" && value == 1e14 {
                values.insert("obj_x", 100.0);
            }
            let (f, problem) = error_in(&fixture, &values);
            assert_eq!(f, field, "{slot} = {value}: {problem}");
            assert!(
                problem.contains(words),
                "{slot} = {value}: `{problem}` lacks `{words}`"
            );
        }
    }

    /// Light values that overflowed to infinite pixels are errors naming the field; an albedo
    /// above 1 and a mix weight above 1 too; a sphere light too small to be seen is refused.
    #[test]
    fn light_and_reflectance_values_are_bounded() {
        let fixture = Fixture::new("limits-light");
        assert_slot_errors(
            &fixture,
            &[
                (
                    "power",
                    1e300,
                    "lights[0].power",
                    "lower the power or enlarge the light",
                ),
                ("radiance", 1e300, "lights[1].radiance", "[0, 1e20]"),
                ("irradiance", 1e21, "lights[2].irradiance", "[0, 1e20]"),
                ("env", 1e300, "lights[3].radiance", "times scale"),
                ("env_scale", 1e300, "lights[3].radiance", "times scale"),
                (
                    "albedo",
                    5.0,
                    "materials.white.colour",
                    "albedo components must be in [0, 1]",
                ),
                (
                    "weight",
                    2.0,
                    "materials.both.components[0].weight",
                    "must be in [0, 1]",
                ),
                (
                    "light_radius",
                    1e-170,
                    "lights[0].radius",
                    "must be in [1e-9",
                ),
            ],
        );
    }

    /// Mistakes inside sections are named by their field: a short array, an unknown material
    /// in a mix component, a type that does not exist.
    #[test]
    fn errors_name_the_field_inside_sections() {
        let fixture = Fixture::new("limits-fields");
        let text = scene(&fixture, &ordinary_values());
        assert_edit_errors(
            &fixture,
            &text,
            &[
                (
                    "center = [2.5e-1, 0, 0]",
                    "center = [0.25, 0]",
                    "shapes[0].center",
                    "invalid length 2",
                ),
                (
                    "{ material = \"white\", weight",
                    "{ material = \"chalk\", weight",
                    "materials.both.components[0].material",
                    "unknown material `chalk`",
                ),
                (
                    "weight = 0.5 }",
                    "weight = \"half\" }",
                    "materials.both.components[1].weight",
                    "invalid type",
                ),
                (
                    "colour = 5e-1",
                    "colour = [0.5, 0.5]",
                    "materials.white.colour",
                    "a number or an array of 3 numbers",
                ),
                (
                    "type = \"directional\"",
                    "type = \"spot\"",
                    "lights[2].type",
                    "unknown type `spot`",
                ),
                (
                    "transform = { scale",
                    "transform = { skew = 1, scale",
                    "shapes[2].transform",
                    "unknown field `skew`",
                ),
            ],
        );
    }

    /// Input quoted in errors is bounded: a TOML nested 10⁵ deep, a material name of 10⁶
    /// characters, an unknown field of 10⁶ characters give messages of at most a few hundred
    /// characters.
    #[test]
    fn echoed_input_is_bounded() {
        let fixture = Fixture::new("limits-echo");
        let deep = format!("a = {}{}", "[".repeat(100_000), "]".repeat(100_000));
        let long_name = "m".repeat(1_000_000);
        let text = scene(&fixture, &ordinary_values());
        for input in [
            deep,
            text.replacen(
                "material = \"both\"",
                &format!("material = \"{long_name}\""),
                1,
            ),
            text.replacen("[render]", &format!("[render]\n{long_name} = 1"), 1),
        ] {
            let message = parse_scene(&input, &fixture.scene_path())
                .unwrap_err()
                .to_string();
            assert!(message.len() < 2000, "{} characters", message.len());
        }
    }

    /// Work is bounded by construction: mixes nested deeper than 16 levels, and mixes of mixes
    /// that would build exponentially many parts (each naming the previous twice) are errors.
    #[test]
    fn mix_nesting_and_expansion_are_bounded() {
        let fixture = Fixture::new("limits-mix");
        let chain = |width: usize, depth: usize| {
            let mut text = String::from(
                "[camera]\nposition = [0, 1, 3]\nlook_at = [0, 0, 0]\n[materials.m0]\ntype = \"diffuse\"\n",
            );
            for level in 1..=depth {
                let parts =
                    vec![format!("{{ material = \"m{}\", weight = 0.5 }}", level - 1); width];
                text += &format!(
                    "[materials.m{level}]\ntype = \"mix\"\ncomponents = [{}]\n",
                    parts.join(", ")
                );
            }
            text + &format!(
                "[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m{depth}\"\n[[lights]]\ntype = \"directional\"\ndirection = [0, 1, 0]\nirradiance = 1\n"
            )
        };
        assert!(parse_scene(&chain(1, 15), &fixture.scene_path()).is_ok());
        let deep = parse_scene(&chain(1, 40), &fixture.scene_path()).unwrap_err();
        assert!(deep.to_string().contains("nest deeper than 16"), "{deep}");
        let wide = parse_scene(&chain(2, 12), &fixture.scene_path()).unwrap_err();
        assert!(wide.to_string().contains("material parts"), "{wide}");
    }

    /// A mesh read from a device (`/dev/zero`, which never ends) or a directory is refused
    /// before reading, naming the field and the file.
    #[test]
    fn assets_must_be_bounded_regular_files() {
        let fixture = Fixture::new("limits-assets");
        let text = scene(&fixture, &ordinary_values());
        for file in ["/dev/zero", "."] {
            if !Path::new(file).exists() {
                continue;
            }
            let changed = text.replacen("file = \"mesh.obj\"", &format!("file = \"{file}\""), 1);
            let (field, problem) = match parse_scene(&changed, &fixture.scene_path()) {
                Err(TracerError::Scene { field, problem, .. }) => (field, problem),
                other => panic!("{file}: {other:?}"),
            };
            assert_eq!(field, "shapes[2].file");
            assert!(problem.contains("not a regular file"), "{problem}");
        }
        let missing = load_scene(Path::new("/dev/zero")).unwrap_err().to_string();
        assert!(missing.contains("not a regular file"), "{missing}");
    }
}
