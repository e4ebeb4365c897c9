//! Albedo textures of diffuse and plastic materials: a colour, or an image tinted by it, every
//! texel times the tint at most [`limits::MAX_ALBEDO`].

use std::sync::Arc;

use glam::{DVec2, DVec3};

use super::builder::{Builder, Checked, shown};
use super::numbers::Colour;
use crate::limits;
use crate::material::Texture;

impl Builder<'_> {
    /// An albedo: components in [0, [`limits::MAX_ALBEDO`]].
    fn albedo(&self, field: &str, c: Colour) -> Checked<DVec3> {
        self.colour_at_most(field, c, limits::MAX_ALBEDO, "albedo")
    }

    /// An albedo: a colour, or an image tinted by it; every texel times the tint at most
    /// [`limits::MAX_ALBEDO`].
    pub(super) fn texture(
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
}
