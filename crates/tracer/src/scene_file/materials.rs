//! The `[materials.<name>]` sections: their form in the file (diffuse, conductor, plastic,
//! mirror, mix; glint materials are in `glint`) and their building into [`Material`]s, mixes
//! checked for cycles, nesting and the number of parts; the Fresnel terms and microfacet
//! distributions they share; and the table of the materials a scene uses.

use std::collections::BTreeMap;

use glam::DVec3;
use glint_brdf::{DistributionKind, Fresnel, Microfacet, MicrofacetBrdf, NormalSampling};
use serde::Deserialize;

use super::builder::{Builder, Checked, name_list, shown};
use super::glint::GlintSection;
use super::numbers::{Colour, Roughness};
use crate::error::TracerError;
use crate::limits::{self, echo};
use crate::material::{Material, Mirror, Plastic};

/// A `distribution` field: one of the names of glint-brdf's table of kinds
/// ([`DistributionKind::ALL`]), Beckmann when absent.
#[derive(Clone, Copy, Debug)]
pub(super) struct DistributionName(DistributionKind);

impl Default for DistributionName {
    fn default() -> Self {
        Self(DistributionKind::Beckmann)
    }
}

impl<'de> Deserialize<'de> for DistributionName {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let name = String::deserialize(deserializer)?;
        DistributionKind::from_name(&name).map(Self).ok_or_else(|| {
            serde::de::Error::custom(format!(
                "unknown distribution `{name}`: use one of {}",
                DistributionKind::names()
            ))
        })
    }
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
pub(super) enum FresnelSection {
    None,
    Conductor { eta: Colour, k: Colour },
    Dielectric { eta: f64 },
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

/// The materials that shapes use, by name: only those used are built (a glint material builds
/// its NDF quadrature), numbered in the order of their first use.
#[derive(Debug)]
pub(super) struct UsedMaterials<'s> {
    /// Every material section of the file, by name.
    sections: &'s BTreeMap<String, toml::Value>,
    /// The file's `metres_per_unit`, for glint materials given in `flakes_per_mm2`.
    metres_per_unit: Option<f64>,
    /// Built materials by name, and for those built per shape (`flakes_per_mm2`), by the
    /// shape's surface area per unit of uv area too.
    index: BTreeMap<(String, Option<u64>), u32>,
    pub(super) materials: Vec<Material>,
    pub(super) names: Vec<String>,
}

impl<'s> UsedMaterials<'s> {
    /// None used yet of the material `sections`, in a file whose unit is `metres_per_unit`.
    pub(super) fn new(
        sections: &'s BTreeMap<String, toml::Value>,
        metres_per_unit: Option<f64>,
    ) -> Self {
        Self {
            sections,
            metres_per_unit,
            index: BTreeMap::new(),
            materials: Vec::new(),
            names: Vec::new(),
        }
    }
}

/// The shape a material is built for, as a glint material given in flakes per mm² needs it
/// (`flakes_per_mm2`): the shape's surface area per unit of uv area, S/U, and the scene's unit.
#[derive(Debug)]
pub(super) struct SurfaceScale {
    /// The scene file's `metres_per_unit`.
    pub(super) metres_per_unit: Option<f64>,
    /// S/U of the shape (`None` where its texture coordinates cover no area).
    pub(super) surface_per_uv: Option<f64>,
    /// The shape, for messages (`shapes[3]`).
    pub(super) shape: String,
    /// Set when a glint part converted `flakes_per_mm2` with it: the material is then the
    /// shape's own.
    pub(super) used: std::cell::Cell<bool>,
}

impl Builder<'_> {
    pub(super) fn microfacet(
        &self,
        field: &str,
        kind: DistributionName,
        alpha: Roughness,
    ) -> Checked<Microfacet> {
        let Roughness(ax, ay) = alpha;
        Microfacet::new(kind.0, ax, ay).map_err(|e| TracerError::Scene {
            file: self.file.to_path_buf(),
            field: format!("{field}.alpha"),
            problem: e.to_string(),
        })
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

    /// The Fresnel term of section `field` (absent: none).
    pub(super) fn fresnel(
        &self,
        field: &str,
        section: Option<&FresnelSection>,
    ) -> Checked<Fresnel> {
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

    /// The index of material `name`, used at `field` by shape `shape` whose surface area per
    /// unit of uv area is `surface_per_uv`, built on its first use. A material whose glint
    /// parts give `flakes_per_mm2` is built once per distinct S/U (its N depends on it) and
    /// named `name (shapes[i])` after the first shape that uses it; any other, once.
    pub(super) fn use_material(
        &self,
        used: &mut UsedMaterials<'_>,
        name: &str,
        field: &str,
        shape: &str,
        surface_per_uv: Option<f64>,
    ) -> Checked<u32> {
        let ratio_key = surface_per_uv.map(f64::to_bits);
        for key in [(name.to_string(), None), (name.to_string(), ratio_key)] {
            if let Some(&i) = used.index.get(&key) {
                return Ok(i);
            }
        }
        let surface = SurfaceScale {
            metres_per_unit: used.metres_per_unit,
            surface_per_uv,
            shape: shape.to_string(),
            used: std::cell::Cell::new(false),
        };
        let material = self.material(name, field, used.sections, &mut Vec::new(), &surface)?;
        used.materials.push(material);
        let i = (used.materials.len() - 1) as u32;
        if surface.used.get() {
            used.names.push(format!("{name} ({shape})"));
            used.index.insert((name.to_string(), ratio_key), i);
        } else {
            used.names.push(name.to_string());
            used.index.insert((name.to_string(), None), i);
        }
        Ok(i)
    }

    /// Builds material `name`, used at `used_at` (the field that names it). `visiting` holds
    /// the mixes being built around it (for cycles and the nesting limit).
    fn material(
        &self,
        name: &str,
        used_at: &str,
        sections: &BTreeMap<String, toml::Value>,
        visiting: &mut Vec<String>,
        surface: &SurfaceScale,
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
                self.glint(&field, &g, surface)?
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
                    let part = self.material(&c.material, &used_at, sections, visiting, surface)?;
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
}
