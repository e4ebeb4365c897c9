//! The `[render]` section: its form in the file and its building into [`RenderSettings`],
//! checked by the film's own validation with errors naming `render.<setting>`.

use serde::Deserialize;

use super::builder::{Builder, Checked, shown};
use crate::error::TracerError;
use crate::settings::{
    Bloom, GlintFootprints, GlintRandomness, IntegratorKind, LightStrategy, PixelBounds,
    PixelFilter, RenderSettings,
};

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

impl Builder<'_> {
    pub(super) fn settings(&self, value: Option<toml::Value>) -> Checked<RenderSettings> {
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
}
