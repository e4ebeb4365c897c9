//! How an image is rendered, as opposed to what is in it: [`RenderSettings`] and the choices
//! it holds. Scene files fill it (`[render]`, see `scenes/README.md`), and the film, the
//! integrators and the prior run read it.

/// Which integrator.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum IntegratorKind {
    /// Emission plus one bounce of light (next-event estimation and BRDF sampling, with MIS).
    Direct,
    /// Full path tracing up to the maximum depth.
    #[default]
    Path,
}

/// How direct light is estimated.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LightStrategy {
    /// Light sampling and BRDF sampling combined by the power heuristic.
    #[default]
    Mis,
    /// Light sampling only (BRDF-sampled rays that hit emitters are ignored).
    LightOnly,
    /// BRDF sampling only (no next-event estimation; delta lights are then invisible).
    BrdfOnly,
}

/// Where glint materials use the pixel footprint.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GlintFootprints {
    /// At the first hit seen from the camera; the smooth limit after (the paper's choice).
    #[default]
    FirstHit,
    /// Wherever the path from the camera has met only perfect mirrors and near-specular glossy
    /// lobes: ray differentials are reflected at each mirror, and at each glossy bounce about
    /// the sampled facet normal and widened by the lobe's spread ([`crate::differentials`]).
    /// Renders as `FirstHit` in scenes without mirrors and without conductors or plastics of
    /// α ≤ [`crate::differentials::GLOSSY_FOOTPRINT_MAX_ALPHA`].
    All,
    /// Nowhere: every glint material evaluates its smooth limit (with its glint sampler).
    Never,
}

/// How a glint material's particles relate across the frames of an animation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GlintRandomness {
    /// The same particles in every frame: glints appear, persist and vanish coherently (the
    /// paper's model).
    #[default]
    Coherent,
    /// A new particle set per frame (the material seed mixed with the frame number), like
    /// per-frame independent noise in the style of Ershov et al.: for contrast, it flickers.
    PerFrame,
}

/// Bloom applied to the PNG (the EXR stays linear): see [`crate::image::RgbImage::bloomed`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bloom {
    /// Radiance above which light spreads.
    pub threshold: f64,
    /// The Gaussian's standard deviation in pixels.
    pub radius: f64,
    /// The factor on the spread light.
    pub strength: f64,
}

/// The pixel filter.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PixelFilter {
    /// Uniform over the pixel.
    Box,
    /// A Gaussian of standard deviation 0.5 pixel truncated at radius 1.5 pixels.
    #[default]
    Gaussian,
}

/// A rectangle of pixels, half-open as pbrt's `--pixelbounds`: columns `x0..x1` and rows
/// `y0..y1`, row 0 at the top. A render of these bounds gives exactly the same pixels as the
/// full image (each pixel's samples depend on the pixel alone, see [`crate::film`]), so a
/// frame may be rendered in pieces on many machines and put together.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PixelBounds {
    /// The first column.
    pub x0: u32,
    /// One past the last column.
    pub x1: u32,
    /// The first row.
    pub y0: u32,
    /// One past the last row.
    pub y1: u32,
}

impl PixelBounds {
    /// The whole `width` × `height` image.
    #[must_use]
    pub fn full(width: u32, height: u32) -> Self {
        Self {
            x0: 0,
            x1: width,
            y0: 0,
            y1: height,
        }
    }

    /// Columns covered.
    #[must_use]
    pub fn width(&self) -> u32 {
        self.x1.saturating_sub(self.x0)
    }

    /// Rows covered.
    #[must_use]
    pub fn height(&self) -> u32 {
        self.y1.saturating_sub(self.y0)
    }

    /// What is wrong with these bounds in a `width` × `height` image: empty, or reaching
    /// outside it.
    #[must_use]
    pub fn problem(&self, width: u32, height: u32) -> Option<String> {
        let shown = format!("[{}, {}, {}, {}]", self.x0, self.x1, self.y0, self.y1);
        if self.x0 >= self.x1 || self.y0 >= self.y1 {
            Some(format!(
                "{shown} is empty: [x0, x1, y0, y1] needs x0 < x1 and y0 < y1 (half-open)"
            ))
        } else if self.x1 > width || self.y1 > height {
            Some(format!(
                "{shown} reaches outside the {width}x{height} image (x1 ≤ {width}, y1 ≤ {height})"
            ))
        } else {
            None
        }
    }
}

/// Everything about how an image is rendered (not what is in it).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel.
    pub samples_per_pixel: u32,
    /// The longest path, in bounces (1 = direct light only).
    pub max_depth: u32,
    /// Path tracing or direct illumination.
    pub integrator: IntegratorKind,
    /// How direct light is estimated.
    pub light_strategy: LightStrategy,
    /// Where glints use footprints.
    pub glint_footprints: GlintFootprints,
    /// The footprint's size in pixels (1: the pixel's own footprint).
    pub footprint_scale: f64,
    /// The pixel filter.
    pub filter: PixelFilter,
    /// Exposure of the PNG in stops.
    pub exposure: f64,
    /// The sampler seed.
    pub seed: u64,
    /// Bounces before Russian roulette may end a path.
    pub roulette_depth: u32,
    /// Coherent particles across frames, or a new set per frame.
    pub glint_randomness: GlintRandomness,
    /// Bloom on the PNG, if any.
    pub bloom: Option<Bloom>,
    /// Sphere lights at glint hits with a footprint are shaded by one query in the light's own
    /// cone instead of light samples through the material's γ (see [`crate::light_cone`]).
    pub glint_light_cones: bool,
    /// Only these pixels of the `width` × `height` image, or all of them (`None`).
    pub pixel_bounds: Option<PixelBounds>,
}

impl RenderSettings {
    /// The pixels a render covers: [`RenderSettings::pixel_bounds`] or the whole image.
    #[must_use]
    pub fn bounds(&self) -> PixelBounds {
        self.pixel_bounds
            .unwrap_or_else(|| PixelBounds::full(self.width, self.height))
    }
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            width: 640,
            height: 360,
            samples_per_pixel: 16,
            max_depth: 5,
            integrator: IntegratorKind::Path,
            light_strategy: LightStrategy::Mis,
            glint_footprints: GlintFootprints::FirstHit,
            footprint_scale: 1.0,
            filter: PixelFilter::Gaussian,
            exposure: 0.0,
            seed: 0,
            roulette_depth: 3,
            glint_randomness: GlintRandomness::Coherent,
            bloom: None,
            glint_light_cones: false,
            pixel_bounds: None,
        }
    }
}
