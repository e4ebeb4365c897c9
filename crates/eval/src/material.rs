//! Materials as `docs/eval.md` specifies them: field names, units (γ in degrees), defaults and
//! the messages that name a rejected field.

use glint_brdf::{
    BrdfError, DVec3, DenseCounts, DiscreteBrdf, DistributionKind, Fresnel, GlintParameters,
    Microfacet, MultinomialMode, PdfQuadrature,
};
use serde_json::{Map, Value};

use crate::maps::{MAP_FIELDS, MapsSpec};
use crate::request::EvalMaterial;

/// A material's Fresnel term as `docs/eval.md` writes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FresnelSpec {
    /// F = 1 (`"none"`).
    None,
    /// A conductor with complex index η + ik per RGB channel.
    Conductor {
        /// η per channel.
        eta: [f64; 3],
        /// k per channel.
        k: [f64; 3],
    },
    /// A dielectric of index η.
    Dielectric {
        /// η.
        eta: f64,
    },
}

/// The default `negligible_count`: glint-tracer's τ for scene files
/// (`SCENE_NEGLIGIBLE_COUNT`, 10⁻¹²; a test of `cargo xtask eval` checks they agree). A query whose
/// expected count is provably below it is skipped (its count is 0, as a traversal finds with
/// probability at least 1 − 10⁻¹²) and answers with its bound as `negligible_bound`.
pub const DEFAULT_NEGLIGIBLE_COUNT: f64 = 1e-12;

/// A material as `docs/eval.md` specifies it; `None` fields take the documented defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialSpec {
    /// A [`DistributionKind::name`]: `"beckmann"`, `"ggx"` or `"ashikhmin_shirley"`.
    pub distribution: String,
    /// α (α_x of an anisotropic material).
    pub alpha: f64,
    /// α_y; defaults to `alpha`.
    pub alpha_y: Option<f64>,
    /// N, a whole number in [1, 2⁵³].
    pub particles: f64,
    /// γ in degrees, in [5.73·10⁻⁵, 60] (10⁻⁶ rad to 60°). JSON's `gamma_degrees` (or its
    /// older name `gamma_deg`, deprecated).
    pub gamma_degrees: f64,
    /// ε of Eq. 10; defaults to 0.1.
    pub epsilon: Option<f64>,
    /// How dense queries are answered: `"lattice"` (the default), `"sampled"` or `"exact"`.
    pub dense: Option<String>,
    /// The largest node `"sampled"` (and `"lattice"` where it leaves a query to the tree)
    /// answers from its sample, in widths of the query; defaults to 1.
    pub dense_node_scale: Option<f64>,
    /// The particle set, any 64-bit unsigned number; defaults to 0.
    pub seed: Option<u64>,
    /// The Fresnel term.
    pub fresnel: FresnelSpec,
    /// `"exact"` (the default) or `"normal"`.
    pub multinomial: Option<String>,
    /// The footprint area Eq. 11 plans for; defaults to 10⁻⁶.
    pub expected_footprint_area: Option<f64>,
    /// The sampling pdf's rule over the cone: `"cubature"` (the default) or `"qmc"`.
    pub pdf_quadrature: Option<String>,
    /// QMC points of the sampling pdf (under `"qmc"`, and for cones the cubature does not
    /// cover); defaults to 64.
    pub pdf_points: Option<f64>,
    /// Skip queries whose expected count is provably below this; defaults to
    /// [`DEFAULT_NEGLIGIBLE_COUNT`] (10⁻¹², the tracer's τ); 0 traverses every query.
    pub negligible_count: Option<f64>,
    /// Density, roughness and tint maps over the texture square and their filter; none by
    /// default.
    pub maps: MapsSpec,
}

/// The fields a JSON material may hold.
const KNOWN_FIELDS: [&str; 21] = [
    MAP_FIELDS[0],
    MAP_FIELDS[1],
    MAP_FIELDS[2],
    MAP_FIELDS[3],
    MAP_FIELDS[4],
    "distribution",
    "alpha",
    "alpha_y",
    "particles",
    "gamma_degrees",
    "gamma_deg",
    "epsilon",
    "dense",
    "dense_node_scale",
    "seed",
    "fresnel",
    "multinomial",
    "expected_footprint_area",
    "pdf_quadrature",
    "pdf_points",
    "negligible_count",
];

impl MaterialSpec {
    /// The required fields, every optional one at its default.
    #[must_use]
    pub fn new(distribution: &str, alpha: f64, particles: f64, gamma_degrees: f64) -> Self {
        Self {
            distribution: distribution.to_owned(),
            alpha,
            alpha_y: None,
            particles,
            gamma_degrees,
            epsilon: None,
            dense: None,
            dense_node_scale: None,
            seed: None,
            fresnel: FresnelSpec::None,
            multinomial: None,
            expected_footprint_area: None,
            pdf_quadrature: None,
            pdf_points: None,
            negligible_count: None,
            maps: MapsSpec::default(),
        }
    }

    /// Validates the specification and builds the material (its count tree: a few ms).
    ///
    /// # Errors
    /// A message naming the rejected field, as `docs/eval.md` lists them.
    pub fn build(&self) -> Result<EvalMaterial, String> {
        let parameters = self.parameters()?;
        let brdf = DiscreteBrdf::new(parameters).map_err(|e| format!("material: {e}"))?;
        Ok(EvalMaterial::new(brdf))
    }

    /// The validated parameters.
    fn parameters(&self) -> Result<GlintParameters, String> {
        let kind = DistributionKind::from_name(&self.distribution).ok_or_else(|| {
            format!(
                "material.distribution `{}` is unknown: use one of {}",
                self.distribution,
                DistributionKind::names()
            )
        })?;
        let alpha = finite(self.alpha, "material.alpha")?;
        let alpha_y = match self.alpha_y {
            Some(a) => finite(a, "material.alpha_y")?,
            None => alpha,
        };
        let distribution =
            Microfacet::new(kind, alpha, alpha_y).map_err(|e| format!("material: {e}"))?;
        let mut parameters = GlintParameters::new(distribution);
        let particles = finite(self.particles, "material.particles")?;
        if !(particles >= 1.0 && particles.fract() == 0.0 && particles <= MAX_PARTICLES) {
            return Err(particles_error(particles));
        }
        parameters.particles = particles as u64;
        let gamma_deg = finite(self.gamma_degrees, "material.gamma_degrees")?;
        // The library's bounds, [10⁻⁶ rad, 60°], in the unit of this field.
        if !(gamma_deg >= 1e-6f64.to_degrees() && gamma_deg <= 60.0) {
            return Err(format!(
                "material.gamma_degrees = {gamma_deg:?} must be in [{:.3e}, 60] degrees",
                1e-6f64.to_degrees()
            ));
        }
        parameters.gamma_radians = gamma_deg.to_radians();
        if let Some(epsilon) = self.epsilon {
            parameters.epsilon = finite(epsilon, "material.epsilon")?;
        }
        if let Some(seed) = self.seed {
            parameters.seed = seed;
        }
        if let Some(area) = self.expected_footprint_area {
            parameters.expected_footprint_area = finite(area, "material.expected_footprint_area")?;
        }
        parameters.negligible_count = match self.negligible_count {
            Some(count) => finite(count, "material.negligible_count")?,
            None => DEFAULT_NEGLIGIBLE_COUNT,
        };
        if let Some(points) = self.pdf_points {
            let points = finite(points, "material.pdf_points")?;
            if !(points.fract() == 0.0 && (1.0..=4096.0).contains(&points)) {
                return Err(format!(
                    "material.pdf_points = {points:?} must be a whole number in [1, 4096]"
                ));
            }
            parameters.pdf_points = points as usize;
        }
        let node_scale = self
            .dense_node_scale
            .map(|scale| finite(scale, "material.dense_node_scale"))
            .transpose()?;
        parameters.dense =
            DenseCounts::from_name(self.dense.as_deref().unwrap_or("lattice"), node_scale)
                .map_err(|e| format!("material: {e}"))?;
        parameters.multinomial = match self.multinomial.as_deref() {
            None | Some("exact") => MultinomialMode::Exact,
            Some("normal") => MultinomialMode::Normal,
            Some(other) => {
                return Err(format!(
                    "material.multinomial \"{other}\" is unknown: use \"exact\" or \"normal\""
                ));
            }
        };
        parameters.pdf_quadrature = match self.pdf_quadrature.as_deref() {
            None | Some("cubature") => PdfQuadrature::Cubature,
            Some("qmc") => PdfQuadrature::QuasiMonteCarlo,
            Some(other) => {
                return Err(format!(
                    "material.pdf_quadrature \"{other}\" is unknown: use \"cubature\" or \"qmc\""
                ));
            }
        };
        let (fresnel, kind) = match self.fresnel {
            FresnelSpec::None => (Fresnel::None, "none"),
            FresnelSpec::Conductor { eta, k } => (
                Fresnel::Conductor {
                    eta: DVec3::from_array(eta),
                    k: DVec3::from_array(k),
                },
                "conductor",
            ),
            FresnelSpec::Dielectric { eta } => (Fresnel::Dielectric { eta }, "dielectric"),
        };
        parameters.fresnel = fresnel.validated().map_err(|e| match e {
            BrdfError::InvalidFresnel { parameter, .. } => {
                format!("material.fresnel.{kind}.{parameter}: {e}")
            }
            other => format!("material: {other}"),
        })?;
        self.maps.apply(&mut parameters)?;
        Ok(parameters)
    }

    /// The specification a JSON `material` object gives.
    ///
    /// # Errors
    /// A message naming the field that is unknown, missing or of the wrong type.
    pub fn from_json(material: &Value) -> Result<Self, String> {
        let m = material.as_object().ok_or("`material` must be an object")?;
        known_fields(m, &KNOWN_FIELDS, "material field")?;
        let distribution = match m.get("distribution") {
            Some(Value::String(name)) => name.clone(),
            Some(other) => {
                return Err(format!(
                    "material.distribution {other} is unknown: use one of {}",
                    DistributionKind::names()
                ));
            }
            None => {
                return Err(format!(
                    "material.distribution is missing: use one of {}",
                    DistributionKind::names()
                ));
            }
        };
        let multinomial = optional_name(m, "multinomial", "\"exact\" or \"normal\"")?;
        let dense = optional_name(m, "dense", "\"sampled\", \"exact\" or \"lattice\"")?;
        let pdf_quadrature = optional_name(m, "pdf_quadrature", "\"cubature\" or \"qmc\"")?;
        Ok(Self {
            distribution,
            alpha: number(m, "alpha", "material.alpha")?,
            alpha_y: optional_number(m, "alpha_y", "material.alpha_y")?,
            particles: particles_from_json(m)?,
            gamma_degrees: gamma_degrees_from_json(m)?,
            epsilon: optional_number(m, "epsilon", "material.epsilon")?,
            dense,
            dense_node_scale: optional_number(m, "dense_node_scale", "material.dense_node_scale")?,
            seed: seed_from_json(m.get("seed"))?,
            fresnel: fresnel_from_json(m.get("fresnel"))?,
            multinomial,
            expected_footprint_area: optional_number(
                m,
                "expected_footprint_area",
                "material.expected_footprint_area",
            )?,
            pdf_quadrature,
            pdf_points: optional_number(m, "pdf_points", "material.pdf_points")?,
            negligible_count: optional_number(m, "negligible_count", "material.negligible_count")?,
            maps: MapsSpec::from_json(m)?,
        })
    }
}

/// An error naming the first key of `object` not in `known`, "unknown {what} `key`"
/// (`docs/eval.md`: unknown fields are errors, so that a typo does not pass unnoticed).
pub(crate) fn known_fields(
    object: &Map<String, Value>,
    known: &[&str],
    what: &str,
) -> Result<(), String> {
    match object.keys().find(|k| !known.contains(&k.as_str())) {
        None => Ok(()),
        Some(unknown) => Err(format!(
            "unknown {what} `{unknown}` (known: {})",
            known.join(", ")
        )),
    }
}

/// `gamma_degrees` of a JSON material, or `gamma_deg`, its older name (deprecated, read for
/// one more version); both at once are an error.
fn gamma_degrees_from_json(m: &Map<String, Value>) -> Result<f64, String> {
    match (m.contains_key("gamma_degrees"), m.contains_key("gamma_deg")) {
        (true, true) => {
            Err("material has both gamma_degrees and gamma_deg (its older name): give one".into())
        }
        (false, true) => number(m, "gamma_deg", "material.gamma_deg"),
        _ => number(m, "gamma_degrees", "material.gamma_degrees"),
    }
}

/// The most particles a material may have, 2⁵³: every whole number up to it is a double, and
/// it is the count tree's limit.
const MAX_PARTICLES: f64 = 9_007_199_254_740_992.0;

fn particles_error(particles: impl std::fmt::Debug) -> String {
    format!("material.particles = {particles:?} must be a whole number in [1, 2^53]")
}

/// `particles` of a JSON material: a JSON integer above 2⁵³ is refused as it is written (read
/// as a double it would round to a whole number within the range).
fn particles_from_json(m: &Map<String, Value>) -> Result<f64, String> {
    if let Some(n) = m.get("particles").and_then(Value::as_u64)
        && n > 1 << 53
    {
        return Err(particles_error(n));
    }
    number(m, "particles", "material.particles")
}

/// `seed` of a JSON material: a JSON integer is read exactly (every 64-bit unsigned number is
/// a seed); any other number must be a whole number below 2⁶⁴.
fn seed_from_json(value: Option<&Value>) -> Result<Option<u64>, String> {
    let Some(value) = value else {
        return Ok(None);
    };
    if let Some(seed) = value.as_u64() {
        return Ok(Some(seed));
    }
    match value.as_f64() {
        // 2⁶⁴ = 18446744073709551616 is the first double past u64::MAX.
        Some(x) if x >= 0.0 && x.fract() == 0.0 && x < 18_446_744_073_709_551_616.0 => {
            Ok(Some(x as u64))
        }
        Some(x) if x.is_finite() => Err(format!(
            "material.seed = {x:?} must be a whole number in [0, 2^64)"
        )),
        _ => Err(format!(
            "material.seed must be a finite number, not {value}"
        )),
    }
}

/// An optional string field, `use_` naming its values for the error a non-string gets.
pub(crate) fn optional_name(
    m: &Map<String, Value>,
    field: &str,
    use_: &str,
) -> Result<Option<String>, String> {
    match m.get(field) {
        None => Ok(None),
        Some(Value::String(s)) => Ok(Some(s.clone())),
        Some(other) => Err(format!("material.{field} {other} is unknown: use {use_}")),
    }
}

fn finite(x: f64, name: &str) -> Result<f64, String> {
    if x.is_finite() {
        Ok(x)
    } else {
        Err(format!("{name} must be a finite number, not {x:?}"))
    }
}

fn fresnel_from_json(value: Option<&Value>) -> Result<FresnelSpec, String> {
    Ok(match value {
        None => FresnelSpec::None,
        Some(Value::String(s)) if s == "none" => FresnelSpec::None,
        Some(Value::Object(o)) if o.len() == 1 && o.contains_key("conductor") => {
            let c = o["conductor"]
                .as_object()
                .ok_or("material.fresnel.conductor must be an object")?;
            known_fields(c, &["eta", "k"], "material.fresnel.conductor field")?;
            FresnelSpec::Conductor {
                eta: numbers_in::<3>(c, "eta", "material.fresnel.conductor.eta")?,
                k: numbers_in::<3>(c, "k", "material.fresnel.conductor.k")?,
            }
        }
        Some(Value::Object(o)) if o.len() == 1 && o.contains_key("dielectric") => {
            let d = o["dielectric"]
                .as_object()
                .ok_or("material.fresnel.dielectric must be an object")?;
            known_fields(d, &["eta"], "material.fresnel.dielectric field")?;
            FresnelSpec::Dielectric {
                eta: number(d, "eta", "material.fresnel.dielectric.eta")?,
            }
        }
        Some(other) => {
            return Err(format!(
                "material.fresnel {other} is unknown: use \"none\", {{\"conductor\": {{\"eta\": [r,g,b], \"k\": [r,g,b]}}}} or {{\"dielectric\": {{\"eta\": x}}}}"
            ));
        }
    })
}

/// A required finite number of a JSON object.
pub(crate) fn number(object: &Map<String, Value>, key: &str, name: &str) -> Result<f64, String> {
    optional_number(object, key, name)?.ok_or_else(|| format!("{name} is missing"))
}

/// An optional finite number of a JSON object.
pub(crate) fn optional_number(
    object: &Map<String, Value>,
    key: &str,
    name: &str,
) -> Result<Option<f64>, String> {
    match object.get(key) {
        None => Ok(None),
        Some(value) => match value.as_f64() {
            Some(x) if x.is_finite() => Ok(Some(x)),
            _ => Err(format!("{name} must be a finite number, not {value}")),
        },
    }
}

/// An array of N finite numbers of a JSON object.
pub(crate) fn numbers_in<const N: usize>(
    object: &Map<String, Value>,
    key: &str,
    name: &str,
) -> Result<[f64; N], String> {
    let array = object
        .get(key)
        .ok_or_else(|| format!("{name} is missing"))?
        .as_array()
        .filter(|a| a.len() == N)
        .ok_or_else(|| format!("{name} must be an array of {N} numbers"))?;
    let mut out = [0.0; N];
    for (slot, value) in out.iter_mut().zip(array) {
        *slot = value
            .as_f64()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("{name} must hold finite numbers, not {value}"))?;
    }
    Ok(out)
}
