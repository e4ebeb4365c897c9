//! Scene files: TOML, documented field by field in `scenes/README.md`. Loading validates every
//! value and reports the file, the field (e.g. `shapes[2].radius`) and the problem; asset paths
//! (meshes, textures, environment maps) are relative to the scene file. Values are bounded
//! where they enter ([`crate::limits`]): magnitudes, sizes, counts, so that an accepted scene
//! builds and renders in bounded memory without overflowing.
//!
//! The TOML is read in two steps: into a table (syntax errors, with line and column), then each
//! section into its typed form with the path to it, so that a mistake deep inside
//! (`shapes[2].center` with two numbers) is named by its field.
//!
//! Its parts, one section of the format each, all building through one `Builder`:
//!
//! - `builder`: the `Builder`, its errors naming the file and the field, and the reading of a
//!   section into its typed form.
//! - `budget`: what a scene may use of asset bytes, image pixels, material parts and
//!   primitives.
//! - `values`: checks of the plain values every section uses (points, directions, ranges,
//!   colours).
//! - `numbers`: colours and roughnesses, given as one number or an array.
//! - `render`: the `[render]` section, into [`RenderSettings`](crate::settings::RenderSettings).
//! - `camera`: the `[camera]` section and its keyframes.
//! - `materials`: the `[materials.<name>]` sections, mixes, Fresnel terms; `glint`: glint
//!   materials; `glint_maps`: their density, roughness and tint maps; `textures`: albedo
//!   textures.
//! - `shapes`: the `[[shapes]]` sections: spheres, rectangles, OBJ meshes.
//! - `lights`: the `[[lights]]` sections: area lights, a directional light, an environment.
//! - `limit_tests`: the limits of every section, probed through one template scene.

use std::collections::BTreeMap;
use std::path::Path;

use glam::DVec3;
use serde::Deserialize;

use crate::accel::Accelerator;
use crate::error::TracerError;
use crate::limits;
use crate::material::{Material, Texture};
use crate::scene::Scene;

mod budget;
mod builder;
mod camera;
mod glint;
mod glint_maps;
mod lights;
#[cfg(test)]
mod limit_tests;
mod materials;
mod numbers;
mod render;
mod shapes;
mod textures;
mod values;

use budget::Budget;
use builder::{Builder, Checked};
use materials::UsedMaterials;

/// A glint material's `negligible_count` when the scene file gives none: queries provably
/// expecting fewer particles are skipped (glint-brdf's "Negligible queries"). At ε = 0 a render
/// of Q queries then differs from the fully traversed one anywhere with probability below
/// Q·10⁻¹² (10⁻⁴ for 10⁸ queries); with ε > 0 the traversal's own early stops may also add
/// fractional expectations of order ε²E² there. The render statistics report the bound's sum
/// over skipped queries.
pub const SCENE_NEGLIGIBLE_COUNT: f64 = 1e-12;

/// The file's top level; each section is read on its own, with its path.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    /// The length of one scene unit in metres, for glint materials in `flakes_per_mm2`.
    metres_per_unit: Option<f64>,
    render: Option<toml::Value>,
    camera: toml::Value,
    #[serde(default)]
    materials: BTreeMap<String, toml::Value>,
    #[serde(default)]
    shapes: Vec<toml::Value>,
    #[serde(default)]
    lights: Vec<toml::Value>,
}

impl Builder<'_> {
    fn build(&self, file: SceneFile) -> Checked<Scene> {
        let settings = self.settings(file.render)?;
        let camera = self.camera(file.camera)?;
        // Materials by name, in name order; only those used are built (a glint material builds
        // its NDF quadrature).
        let metres_per_unit = match file.metres_per_unit {
            Some(metres) => Some(self.positive("metres_per_unit", metres)?),
            None => None,
        };
        let mut used = UsedMaterials::new(&file.materials, metres_per_unit);
        let mut primitives = Vec::new();
        let mut meshes = Vec::new();
        self.shapes(file.shapes, &mut used, &mut primitives, &mut meshes)?;
        let lights = self.lights(file.lights, &mut primitives)?;
        if lights.is_empty() {
            return self.fail("lights", "the scene has no lights: it would render black");
        }
        let mut material_names = used.names;
        let mut materials = used.materials;
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

    /// `flakes_per_mm2` converts to N per shape, N = ρ·10⁶·metres_per_unit²·S/(uv_scale²·U):
    /// a sphere and a rectangle using one material get one material each (named after the
    /// shape), a second sphere of the same radius shares the first's; a material given in
    /// `particles` stays one; the conversion's errors name the field.
    #[test]
    fn flakes_per_mm2_convert_per_shape() {
        let text = |top: &str, paint: &str| {
            format!(
                r#"{top}
[camera]
position = [0, 1, 30]
look_at = [0, 0, 0]
[materials.paint]
type = "glint"
alpha = 0.1
gamma_degrees = 1
uv_scale = 2
{paint}
[materials.plain]
type = "glint"
alpha = 0.1
gamma_degrees = 1
particles = 1000
[[shapes]]
type = "sphere"
center = [0, 0, 0]
radius = 2
material = "paint"
[[shapes]]
type = "rectangle"
center = [0, -3, 0]
u = [4, 0, 0]
v = [0, 0, -3]
material = "paint"
[[shapes]]
type = "sphere"
center = [5, 0, 0]
radius = 2
material = "paint"
[[shapes]]
type = "sphere"
center = [-5, 0, 0]
radius = 1
material = "plain"
[[shapes]]
type = "sphere"
center = [-5, 3, 0]
radius = 3
material = "plain"
[[lights]]
type = "sphere"
center = [1, 20, 1]
radius = 1
power = 10
"#
            )
        };
        let path = Path::new("scenes/test.toml");
        // Centimetres; 0.5 flakes per mm² = 50 per cm².
        let scene = parse_scene(
            &text("metres_per_unit = 0.01", "flakes_per_mm2 = 0.5"),
            path,
        )
        .unwrap();
        let particles = |name: &str| {
            let i = scene.material_names.iter().position(|n| n == name).unwrap();
            scene.materials[i].glint_particles()
        };
        let per_cm2 = 50.0;
        let sphere = (per_cm2 * 4.0 * std::f64::consts::PI * 4.0 / 4.0).round() as u64;
        let rectangle = (per_cm2 * 12.0 / 4.0).round() as u64;
        assert_eq!(particles("paint (shapes[0])"), vec![sphere]);
        assert_eq!(particles("paint (shapes[1])"), vec![rectangle]);
        assert_eq!(particles("plain"), vec![1000]);
        assert_eq!(scene.materials.len(), 3, "{:?}", scene.material_names);
        let primitives = scene.accelerator.primitives();
        assert_eq!(primitives[0].material, primitives[2].material);
        for (top, paint, field, part) in [
            (
                "",
                "flakes_per_mm2 = 0.5",
                "paint.flakes_per_mm2",
                "metres_per_unit",
            ),
            (
                "metres_per_unit = 0.01",
                "flakes_per_mm2 = 0.5\nparticles = 7",
                "paint.flakes_per_mm2",
                "not both",
            ),
            (
                "metres_per_unit = 0.01",
                "",
                "paint.particles",
                "flakes_per_mm2",
            ),
            (
                "metres_per_unit = -1",
                "flakes_per_mm2 = 0.5",
                "metres_per_unit",
                "positive",
            ),
            (
                "metres_per_unit = 0.01",
                "flakes_per_mm2 = 1e-9",
                "paint.flakes_per_mm2",
                "outside [1, 2^53]",
            ),
        ] {
            let (f, problem) = error_of(&text(top, paint));
            assert!(
                f.ends_with(field) && problem.contains(part),
                "{f}: {problem}"
            );
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
