//! A glint material's maps in the file (`density_texture`, `alpha_texture`, `tint_texture`):
//! images read into glint-brdf's [`DensityMap`], [`RoughnessMap`] and [`TintMap`], every
//! texel checked, errors naming the field, the file and the texel. Density and roughness are
//! data: one channel, read linearly (a PNG is not sRGB-decoded), reconstructed between texels
//! by the material's `map_filter`; the tint is a colour, read as other colour textures are (a
//! PNG sRGB-decoded), and stays nearest.

use std::sync::Arc;

use glint_brdf::{BrdfError, DensityMap, DensityMapError, MapFilter, RoughnessMap, TintMap};

use super::builder::{Builder, Checked, shown};
use crate::error::TracerError;
use crate::image::{PngValues, RgbImage};
use crate::limits::echo;

/// A one-channel map's texels: width, height and values row by row from the top.
struct DataTexels {
    width: usize,
    height: usize,
    values: Vec<f64>,
}

impl Builder<'_> {
    /// The texels of the one-channel data image `file` at `field`: a grey image, or a colour
    /// one whose three channels are equal in every texel (else an error naming the first texel
    /// where they differ), read linearly.
    fn data_texels(&self, field: &str, file: &str) -> Checked<DataTexels> {
        let image = self.image_as(field, file, PngValues::Linear)?;
        let RgbImage {
            width,
            height,
            pixels,
        } = image;
        if let Some(k) = pixels.iter().position(|p| p.x != p.y || p.x != p.z) {
            let p = pixels[k];
            return self.fail(
                field,
                format!(
                    "{}: texel (column {}, row {}) has channels ({}, {}, {}) that differ: \
                     the map is one channel of data (a grey image, or a colour one with equal \
                     channels)",
                    echo(file),
                    k % width,
                    k / width,
                    shown(p.x),
                    shown(p.y),
                    shown(p.z)
                ),
            );
        }
        Ok(DataTexels {
            width,
            height,
            values: pixels.iter().map(|p| p.x).collect(),
        })
    }

    /// The `map_filter` of glint material `field`: nearest when absent.
    pub(super) fn map_filter(&self, field: &str, name: Option<&str>) -> Checked<MapFilter> {
        let Some(name) = name else {
            return Ok(MapFilter::Nearest);
        };
        match MapFilter::from_name(name) {
            Some(filter) => Ok(filter),
            None => self.fail(
                format!("{field}.map_filter"),
                format!(
                    "unknown filter \"{}\": use {}",
                    echo(name),
                    MapFilter::NAMES.map(|n| format!("\"{n}\"")).join(" or ")
                ),
            ),
        }
    }

    /// The density map d(x) ∈ [0, 1] of `{field}.density_texture`, reconstructed by `filter`.
    pub(super) fn density_map(
        &self,
        field: &str,
        file: &str,
        filter: MapFilter,
    ) -> Checked<Arc<DensityMap>> {
        let field = format!("{field}.density_texture");
        let t = self.data_texels(&field, file)?;
        DensityMap::with_filter(t.width, t.height, &t.values, filter)
            .map(Arc::new)
            .map_err(|e| match e {
                DensityMapError::Empty => self.scene_error(
                    &field,
                    format!(
                        "{}: every texel is 0: the material would hold no particle",
                        echo(file)
                    ),
                ),
                other => self.scene_error(&field, format!("{}: {other}", echo(file))),
            })
    }

    /// The roughness map α(x) ∈ [10⁻⁴, 1] of `{field}.alpha_texture`, its levels'
    /// densities reconstructed by `filter`.
    pub(super) fn alpha_map(
        &self,
        field: &str,
        file: &str,
        filter: MapFilter,
    ) -> Checked<Arc<RoughnessMap>> {
        let field = format!("{field}.alpha_texture");
        let t = self.data_texels(&field, file)?;
        RoughnessMap::new(t.width, t.height, &t.values)
            .map(|map| Arc::new(map.with_filter(filter)))
            .map_err(|e| self.map_error(&field, file, &e))
    }

    /// The tint map t(x) ∈ [0, 1]³ of `{field}.tint_texture`, a colour image.
    pub(super) fn tint_map(&self, field: &str, file: &str) -> Checked<Arc<TintMap>> {
        let field = format!("{field}.tint_texture");
        let image = self.image_as(&field, file, PngValues::Srgb)?;
        let values: Vec<[f64; 3]> = image.pixels.iter().map(|p| p.to_array()).collect();
        TintMap::new(image.width, image.height, &values)
            .map(Arc::new)
            .map_err(|e| self.map_error(&field, file, &e))
    }

    fn scene_error(&self, field: &str, problem: String) -> TracerError {
        TracerError::Scene {
            file: self.file.to_path_buf(),
            field: field.into(),
            problem,
        }
    }

    /// A map's error at `field`, naming `file` and the texel (glint-brdf's message names it).
    fn map_error(&self, field: &str, file: &str, error: &BrdfError) -> TracerError {
        let problem = match error {
            BrdfError::InvalidMapTexel {
                column, row, value, ..
            } => {
                let range = if field.ends_with("alpha_texture") {
                    "roughness must be in [1e-4, 1]"
                } else {
                    "every channel must be in [0, 1]"
                };
                format!(
                    "{}: texel (column {column}, row {row}) is {}: {range}",
                    echo(file),
                    shown(*value)
                )
            }
            other => format!("{}: {other}", echo(file)),
        };
        self.scene_error(field, problem)
    }
}

#[cfg(test)]
mod tests {
    use std::path::{Path, PathBuf};

    use glam::{DVec2, DVec3};

    use crate::error::TracerError;
    use crate::image::RgbImage;
    use crate::material::{GlintMaterial, Material};
    use crate::scene::Scene;
    use crate::scene_file::parse_scene;

    /// A glint sphere whose material section ends with `extra` lines.
    fn scene_text(extra: &str) -> String {
        format!(
            r#"
[camera]
position = [0, 1, 3]
look_at = [0, 0, 0]
[materials.sparkle]
type = "glint"
particles = 1e6
gamma_degrees = 2
{extra}
[[shapes]]
type = "sphere"
center = [0, 0, 0]
radius = 0.5
material = "sparkle"
[[lights]]
type = "sphere"
center = [1, 2, 1]
radius = 0.1
power = 10
"#
        )
    }

    /// A fresh folder for one test's files.
    fn folder(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!(
            "glint-maps-{name}-{}-{:?}",
            std::process::id(),
            std::thread::current().id()
        ));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn grey(width: usize, values: &[f64]) -> RgbImage {
        RgbImage {
            width,
            height: values.len() / width,
            pixels: values.iter().map(|&v| DVec3::splat(v)).collect(),
        }
    }

    fn write_data(dir: &Path, name: &str, image: &RgbImage) {
        std::fs::write(dir.join(name), image.encode_png_linear().unwrap()).unwrap();
    }

    fn load(dir: &Path, extra: &str) -> Result<Scene, TracerError> {
        parse_scene(&scene_text(extra), &dir.join("scene.toml"))
    }

    fn glint(scene: &Scene) -> &GlintMaterial {
        match &scene.materials[0] {
            Material::Glint(g) => g,
            other => panic!("expected a glint material, got {other:?}"),
        }
    }

    fn error_of(dir: &Path, extra: &str) -> (String, String) {
        match load(dir, extra) {
            Err(TracerError::Scene { field, problem, .. }) => (field, problem),
            Err(other) => panic!("expected a scene error, got {other}"),
            Ok(_) => panic!("expected an error for {extra}"),
        }
    }

    /// `gamma`, the older name, beside `gamma_degrees` is an error saying so (it read
    /// "duplicate field `gamma_degrees`"); a grey EXR map (one `Y` channel) loads as data;
    /// one roughness level for a map of two values is an error naming `roughness_levels`.
    #[test]
    fn named_errors_and_grey_exr_maps() {
        let dir = folder("named");
        let (field, problem) = error_of(&dir, "alpha = 0.2\ngamma = 2");
        assert!(field.ends_with("sparkle.gamma_degrees"), "{field}");
        assert!(problem.contains("`gamma` is the older name"), "{problem}");
        {
            use exr::prelude::*;
            let pixels = SpecificChannels::build()
                .with_channel("Y")
                .with_pixel_fn(|p: Vec2<usize>| (if p.x() == 0 { 0.25_f32 } else { 1.0 },));
            Image::from_channels((2, 1), pixels)
                .write()
                .to_file(dir.join("d.exr"))
                .unwrap();
        }
        let scene = load(&dir, "alpha = 0.2\ndensity_texture = \"d.exr\"").unwrap();
        let density = glint(&scene).brdf.parameters().density_map.clone().unwrap();
        assert_eq!((density.texel(0, 0), density.texel(1, 0)), (0.25, 1.0));
        write_data(&dir, "a.png", &grey(2, &[13.0 / 255.0, 64.0 / 255.0]));
        let (field, problem) = error_of(&dir, "alpha_texture = \"a.png\"\nroughness_levels = 1");
        assert!(problem.contains("roughness_levels"), "{field}: {problem}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Density and roughness PNGs are read as linear data (a value of 102 is 102/255, not its
    /// sRGB decoding), the tint PNG as sRGB colour; the maps keep the image's rows (row 0 at
    /// the top, v near 1) and are listed among the scene's assets.
    #[test]
    fn maps_load_as_data_and_colour() {
        let dir = folder("load");
        // 2 × 2 texels: top row (v near 1) then bottom row.
        write_data(&dir, "d.png", &grey(2, &[1.0, 102.0 / 255.0, 0.0, 1.0]));
        write_data(
            &dir,
            "a.png",
            &grey(2, &[13.0 / 255.0, 64.0 / 255.0, 64.0 / 255.0, 13.0 / 255.0]),
        );
        let tint = RgbImage {
            width: 1,
            height: 1,
            pixels: vec![DVec3::new(1.0, 0.5, 0.25)],
        };
        std::fs::write(dir.join("t.png"), tint.encode_png(0.0).unwrap()).unwrap();
        let scene = load(
            &dir,
            "density_texture = \"d.png\"\nalpha_texture = \"a.png\"\ntint_texture = \"t.png\"\nroughness_levels = 3",
        )
        .unwrap();
        let parameters = glint(&scene).brdf.parameters();
        let density = parameters.density_map.as_ref().unwrap();
        // 102/255 (not its sRGB decoding, 0.133), to the map's fixed point.
        assert!((density.texel(1, 0) - 102.0 / 255.0).abs() < 1e-9);
        assert_eq!(density.texel(0, 1), 0.0);
        // Row 0 is the top: (u, v) = (0.75, 0.75) is texel (1, 0).
        assert_eq!(
            density.value_at(DVec2::new(0.75, 0.75)),
            density.texel(1, 0)
        );
        let alpha = parameters.alpha_map.as_ref().unwrap();
        assert_eq!(alpha.texel(1, 0), 64.0 / 255.0);
        assert_eq!(parameters.distribution.alpha().0, 64.0 / 255.0);
        assert_eq!(parameters.roughness_levels, 3);
        let t = parameters
            .tint_map
            .as_ref()
            .unwrap()
            .value_at(DVec2::splat(0.5));
        // 8-bit sRGB: within half a step of the colour written.
        assert!(
            (t - DVec3::new(1.0, 0.5, 0.25)).abs().max_element() < 3e-3,
            "{t}"
        );
        let assets: Vec<&str> = scene
            .assets
            .iter()
            .filter_map(|p| p.file_name()?.to_str())
            .collect();
        assert_eq!(assets, ["a.png", "d.png", "t.png"]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Each bad map gets an error naming the field, the file and, for a bad value, the texel.
    #[test]
    fn bad_maps_are_named_with_the_file_and_the_texel() {
        let dir = folder("errors");
        write_data(&dir, "ok.png", &grey(2, &[1.0, 0.5, 0.0, 1.0]));
        write_data(&dir, "wide.png", &grey(4, &[1.0; 8]));
        write_data(&dir, "zeros.png", &grey(2, &[0.0; 4]));
        // Texel (column 1, row 0) is coloured.
        let mut coloured = grey(2, &[0.5; 4]);
        coloured.pixels[1] = DVec3::new(0.5, 0.2, 0.5);
        write_data(&dir, "coloured.png", &coloured);
        // α = 0 at texel (column 0, row 1).
        write_data(&dir, "smooth.png", &grey(2, &[0.1, 0.1, 0.0, 0.1]));
        // A tint of 2 (EXR is linear, unbounded) at texel (column 1, row 1).
        let mut bright = RgbImage::filled(2, 2, DVec3::splat(0.5));
        bright.pixels[3] = DVec3::new(0.5, 2.0, 0.5);
        bright.write_exr(&dir.join("bright.exr")).unwrap();
        let field = |name: &str| format!("materials.sparkle.{name}");
        let cases: &[(&str, String, &[&str])] = &[
            (
                "alpha = 0.1\ndensity_texture = \"coloured.png\"",
                field("density_texture"),
                &["coloured.png", "column 1, row 0", "one channel"],
            ),
            (
                "alpha = 0.1\ndensity_texture = \"zeros.png\"",
                field("density_texture"),
                &["zeros.png", "every texel is 0"],
            ),
            (
                "alpha_texture = \"smooth.png\"",
                field("alpha_texture"),
                &["smooth.png", "column 0, row 1", "[1e-4, 1]"],
            ),
            (
                "alpha = 0.1\ntint_texture = \"bright.exr\"",
                field("tint_texture"),
                &["bright.exr", "column 1, row 1", "is 2"],
            ),
            (
                "alpha = 0.1\ndensity_texture = \"missing.png\"",
                field("density_texture"),
                &["missing.png"],
            ),
            (
                "alpha = 0.1\nalpha_texture = \"ok.png\"",
                field("alpha"),
                &["replaces"],
            ),
            ("", field("alpha"), &["alpha_texture"]),
            (
                "density_texture = \"ok.png\"\nalpha_texture = \"wide.png\"",
                field("alpha_texture"),
                &["same size"],
            ),
            (
                "alpha = 0.1\nroughness_levels = 0",
                field("roughness_levels"),
                &["[1, 64]"],
            ),
            (
                "alpha = 0.1\ndensity_texture = \"ok.png\"\nmap_filter = \"cubic\"",
                field("map_filter"),
                &["\"cubic\"", "\"nearest\" or \"bilinear\""],
            ),
        ];
        for (extra, expected, words) in cases {
            let (f, problem) = error_of(&dir, extra);
            assert_eq!(&f, expected, "{extra}: {problem}");
            for word in *words {
                assert!(
                    problem.contains(word),
                    "{extra}: `{problem}` lacks `{word}`"
                );
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// `map_filter` reaches the density and roughness textures: "nearest" is the material
    /// without the field, bit for bit; "bilinear" evaluates otherwise on maps with edges (the
    /// smooth limit between texel centres, f̂ over footprints across the edges) and exactly
    /// as "nearest" on a density map of ones and a roughness map of one value.
    #[test]
    fn map_filter_bilinear_differs_on_edges_and_not_on_constant_maps() {
        use glint_brdf::{Bxdf, Footprint, MapFilter, QueryScratch};

        let dir = folder("filter");
        write_data(&dir, "edges_d.png", &grey(2, &[1.0, 0.0, 0.0, 1.0]));
        write_data(
            &dir,
            "edges_a.png",
            &grey(2, &[13.0 / 255.0, 77.0 / 255.0, 77.0 / 255.0, 13.0 / 255.0]),
        );
        write_data(&dir, "ones_d.png", &grey(2, &[1.0; 4]));
        write_data(&dir, "ones_a.png", &grey(2, &[26.0 / 255.0; 4]));
        let material = |maps: &str, filter: &str| {
            let scene = load(
                &dir,
                &format!(
                    "density_texture = \"{maps}_d.png\"\nalpha_texture = \"{maps}_a.png\"\n{filter}"
                ),
            )
            .unwrap();
            glint(&scene).brdf.clone()
        };
        // Directions near the mirror configuration and footprints from a tenth of a texel to
        // a few texels, at positions all over the square.
        let queries: Vec<(DVec3, DVec3, DVec2, f64)> = (0..400)
            .map(|k| {
                let t = f64::from(k);
                let wi = DVec3::new(0.3 * (0.7 * t).sin(), 0.3 * (1.3 * t).cos(), 1.0).normalize();
                let wo = (DVec3::new(-wi.x, -wi.y, wi.z)
                    + 0.05 * DVec3::new((2.1 * t).sin(), (3.7 * t).cos(), 0.0))
                .normalize();
                let uv = DVec2::new((0.618_034 * t).fract(), (0.414_214 * t).fract());
                (wi, wo, uv, 0.05 * 60f64.powf((0.271_828 * t).fract()))
            })
            .collect();
        let answers = |brdf: &glint_brdf::DiscreteBrdf| {
            let mut scratch = QueryScratch::new();
            queries
                .iter()
                .map(|&(wi, wo, uv, side)| {
                    let footprint =
                        Footprint::new(uv, DVec2::new(side, 0.0), DVec2::new(0.0, 0.6 * side))
                            .unwrap();
                    let f = brdf.at(&footprint, &mut scratch).eval(wi, wo);
                    [f.x, brdf.smooth_at(wi, wo, uv).x].map(f64::to_bits)
                })
                .collect::<Vec<_>>()
        };
        for maps in ["edges", "ones"] {
            let (absent, nearest, bilinear) = (
                material(maps, ""),
                material(maps, "map_filter = \"nearest\""),
                material(maps, "map_filter = \"bilinear\""),
            );
            for (brdf, filter) in [
                (&absent, MapFilter::Nearest),
                (&nearest, MapFilter::Nearest),
                (&bilinear, MapFilter::Bilinear),
            ] {
                let parameters = brdf.parameters();
                assert_eq!(parameters.density_map.as_ref().unwrap().filter(), filter);
                assert_eq!(parameters.alpha_map.as_ref().unwrap().filter(), filter);
            }
            let reference = answers(&absent);
            assert!(
                reference.iter().filter(|a| a[0] != 0).count() > 40,
                "{maps}: lit"
            );
            assert_eq!(answers(&nearest), reference, "{maps}: nearest");
            let differ = answers(&bilinear)
                .iter()
                .zip(&reference)
                .filter(|(b, n)| b[0] != n[0])
                .count();
            if maps == "edges" {
                assert!(differ > 40, "bilinear f̂ differs in only {differ} queries");
                // Halfway between two texel centres across the density edge: d = 1/2.
                let (wi, wo) = (DVec3::Z, DVec3::new(0.05, 0.0, 1.0).normalize());
                let at = DVec2::new(0.5, 0.75);
                let (b, n) = (bilinear.smooth_at(wi, wo, at), absent.smooth_at(wi, wo, at));
                assert!(b.x > 0.0 && b != n, "{b} {n}");
            } else {
                assert_eq!(differ, 0, "a map of ones answers alike under both filters");
                assert_eq!(answers(&bilinear), reference);
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Rendered, the same: a floor under a light whose glitter has a density edge renders
    /// otherwise under "bilinear" than under "nearest"; with a density map of ones, pixel for
    /// pixel alike.
    #[test]
    fn map_filter_bilinear_renders_otherwise_on_edges_and_alike_on_ones() {
        let dir = folder("filter-render");
        write_data(
            &dir,
            "edges.png",
            &grey(4, &[1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0]),
        );
        write_data(&dir, "ones.png", &grey(4, &[1.0; 8]));
        let render = |map: &str, filter: &str| {
            let text = format!(
                r#"
[render]
resolution = [16, 16]
spp = 2
integrator = "direct"
[camera]
position = [0, 2.2, 0]
look_at = [0, 0, 0]
up = [0, 0, -1]
fov = 45
[materials.glitter]
type = "glint"
particles = 1e7
gamma_degrees = 4
alpha = 0.2
density_texture = "{map}.png"
{filter}
[[shapes]]
type = "rectangle"
center = [0, 0, 0]
u = [2, 0, 0]
v = [0, 0, -2]
material = "glitter"
[[lights]]
type = "sphere"
center = [0.3, 0.9, 1.0]
radius = 0.25
power = 60
"#
            );
            let scene = parse_scene(&text, &dir.join("scene.toml")).unwrap();
            crate::render(&scene, &scene.settings, 0.0, &|_, _| {})
                .unwrap()
                .image
                .pixels
        };
        let bilinear = "map_filter = \"bilinear\"";
        let nearest = render("edges", "");
        assert!(
            nearest.iter().filter(|p| p.x > 0.0).count() > 50,
            "lit pixels"
        );
        assert_ne!(nearest, render("edges", bilinear));
        assert_eq!(render("ones", ""), render("ones", bilinear));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
