//! The `[[lights]]` sections: their form in the file (sphere and rectangle area lights, a
//! directional light, an environment) and their building into [`Light`]s, emission given as
//! power or radiance and bounded by [`limits::MAX_EMISSION`].

use std::f64::consts::PI;
use std::sync::Arc;

use glam::{DVec2, DVec3};
use serde::Deserialize;

use super::builder::{Builder, Checked};
use super::numbers::Colour;
use crate::accel::{Geometry, Primitive};
use crate::light::{EnvironmentMap, Light};
use crate::limits;
use crate::material::Texture;

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

impl Builder<'_> {
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

    /// Builds the `[[lights]]`, adding area lights to `primitives`.
    pub(super) fn lights(
        &self,
        sections: Vec<toml::Value>,
        primitives: &mut Vec<Primitive>,
    ) -> Checked<Vec<Light>> {
        let mut lights = Vec::new();
        for (i, light) in sections.into_iter().enumerate() {
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
        Ok(lights)
    }
}
