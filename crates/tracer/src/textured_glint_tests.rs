//! Renders of glint materials with maps, checked against their definition: a dense material
//! (N = 10¹²) converges to its smooth limit weighted by the maps (the smooth render of the same
//! mapped material), and where the density map is 0 a mix renders exactly its base.

use std::path::{Path, PathBuf};

use glam::DVec3;

use crate::image::RgbImage;
use crate::scene::Scene;
use crate::scene_file::parse_scene;

/// The maps: 8 × 8 texels over the floor (`uv_scale` 1). Density by column: 1, then 0 in
/// columns 1–3 (a mask), then 1, 0.4, 1, 0.4; roughness by row: α = 0.3 in the top half, 0.1 in the bottom
/// (two values: two exact levels); tint gold in rows 2–5, white elsewhere. The tint's edges lie
/// where neither the density nor the roughness changes: the bound BRDF's tint is the mean of
/// t over the footprint, not weighted by the flakes' density, so a footprint across a tint edge
/// that is also a density or roughness edge would not converge to the map-weighted smooth limit
/// there (on this floor, with gold in columns 4–5 beside the mask instead: 6% of the brightest
/// block in one block).
fn write_maps(dir: &Path) {
    let (width, height) = (8, 8);
    let texels = |f: &dyn Fn(usize, usize) -> DVec3| RgbImage {
        width,
        height,
        pixels: (0..width * height)
            .map(|k| f(k % width, k / width))
            .collect(),
    };
    let density = texels(&|column, _| {
        DVec3::splat(match column {
            1..=3 => 0.0,
            c if c % 2 == 0 => 1.0,
            _ => 102.0 / 255.0,
        })
    });
    let alpha = texels(&|_, row| DVec3::splat(if row < 4 { 77.0 } else { 26.0 } / 255.0));
    let tint = texels(&|_, row| {
        if (2..=5).contains(&row) {
            DVec3::new(1.0, 0.8, 0.4)
        } else {
            DVec3::ONE
        }
    });
    for (name, image) in [("d.png", &density), ("a.png", &alpha)] {
        std::fs::write(dir.join(name), image.encode_png_linear().unwrap()).unwrap();
    }
    tint.write_exr(&dir.join("t.exr")).unwrap();
}

/// A floor seen from above under a sphere light out of view (its highlight in view), direct
/// illumination, shaded by `material`
/// (`glitter`, or `both`: a grey diffuse base plus the glitter).
fn scene(dir: &Path, material: &str) -> Scene {
    let text = format!(
        r#"
[render]
resolution = [48, 48]
spp = 16
integrator = "direct"
[camera]
position = [0, 2.2, 0]
look_at = [0, 0, 0]
up = [0, 0, -1]
fov = 45
[materials.glitter]
type = "glint"
particles = 1e12
gamma_degrees = 1
density_texture = "d.png"
alpha_texture = "a.png"
tint_texture = "t.exr"
[materials.grey]
type = "diffuse"
colour = 0.3
[materials.both]
type = "mix"
components = [{{ material = "grey", weight = 1 }}, {{ material = "glitter", weight = 1 }}]
[[shapes]]
type = "rectangle"
center = [0, 0, 0]
u = [2, 0, 0]
v = [0, 0, -2]
material = "{material}"
[[lights]]
type = "sphere"
center = [0.3, 0.9, 1.0]
radius = 0.25
power = 60
"#
    );
    parse_scene(&text, &dir.join("scene.toml")).unwrap()
}

fn render(scene: &Scene) -> RgbImage {
    crate::render(scene, &scene.settings, 0.0, &|_, _| {})
        .unwrap()
        .image
}

fn smooth(mut scene: Scene) -> Scene {
    scene.make_smooth();
    scene
}

fn folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("glint-textured-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    write_maps(&dir);
    dir
}

/// The side of the blocks compared, in pixels.
const BLOCK: usize = 16;

/// Means over [`BLOCK`] × [`BLOCK`]-pixel blocks, per channel.
fn block_means(image: &RgbImage) -> Vec<DVec3> {
    let mut means = Vec::new();
    for by in 0..image.height / BLOCK {
        for bx in 0..image.width / BLOCK {
            let mut sum = DVec3::ZERO;
            for y in 0..BLOCK {
                for x in 0..BLOCK {
                    sum += image.pixels[(by * BLOCK + y) * image.width + bx * BLOCK + x];
                }
            }
            means.push(sum / (BLOCK * BLOCK) as f64);
        }
    }
    means
}

/// A dense mapped material (N = 10¹² per square, ~10⁸ flakes per pixel) renders as its smooth
/// limit weighted by the maps: every 16 × 16-pixel block mean of the glint render is within 3%
/// of the smooth render's (of 5% of the brightest block, for dim blocks), per channel.
/// Measured: at most 0.88%. The glint render counts flakes over each sample's footprint (a
/// pixel-sized parallelogram) where the smooth one reads the maps at the sample's point, so at
/// a map edge beside the highlight a block gains what its neighbour loses: 8 × 8 blocks differ
/// by up to 4% there, 16 × 16 ones by under 1%. The maps matter: against the smooth render of
/// the material without them (its first level's α ≈ 0.1 everywhere, no mask, no tint) the
/// same measure is 0.58.
#[test]
fn a_dense_mapped_material_converges_to_its_map_weighted_smooth_limit() {
    let dir = folder("dense");
    let glint = render(&scene(&dir, "glitter"));
    let limit = render(&smooth(scene(&dir, "glitter")));
    let (g, s) = (block_means(&glint), block_means(&limit));
    let brightest = s.iter().map(|m| m.max_element()).fold(0.0, f64::max);
    assert!(brightest > 0.0);
    let error = |a: &[DVec3], b: &[DVec3]| {
        a.iter()
            .zip(b)
            .map(|(a, b)| ((*a - *b).abs() / b.max(DVec3::splat(0.05 * brightest))).max_element())
            .fold(0.0, f64::max)
    };
    let measured = error(&g, &s);
    eprintln!("largest block error against the map-weighted smooth render: {measured:.4}");
    assert!(measured < 0.03, "{measured}");
    // Without the maps (the first level's smooth BRDF everywhere), the blocks are far apart.
    let mut uniform = smooth(scene(&dir, "glitter"));
    for material in &mut uniform.materials {
        if let crate::material::Material::SmoothGlint(g) = material {
            *material = crate::material::Material::Microfacet(*g.brdf.smooth());
        }
    }
    let unmapped = block_means(&render(&uniform));
    let unmapped_error = error(&g, &unmapped);
    eprintln!("against the smooth render without maps: {unmapped_error:.4}");
    assert!(unmapped_error > 0.1, "{unmapped_error}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Where the density map is 0, a mix of a base and the glint material renders exactly the base:
/// the glint render equals, bit for bit, the smooth render (whose glint part is d(x)·f = 0
/// there) at every pixel at least 3 pixels from any pixel where the smooth glint part is not 0,
/// and those pixels are not black (the base shows). Elsewhere the two differ.
#[test]
fn a_masked_region_renders_exactly_the_base() {
    let dir = folder("mask");
    let glint_part = render(&smooth(scene(&dir, "glitter")));
    let with_glints = render(&scene(&dir, "both"));
    let without = render(&smooth(scene(&dir, "both")));
    let (width, height) = (glint_part.width as i64, glint_part.height as i64);
    let lit = |x: i64, y: i64| glint_part.texel(x, y) != DVec3::ZERO;
    let (mut masked, mut differing) = (0, 0);
    for y in 0..height {
        for x in 0..width {
            let near_glitter = (-3..=3).any(|dy| {
                (-3..=3).any(|dx| {
                    let (a, b) = (x + dx, y + dy);
                    (0..width).contains(&a) && (0..height).contains(&b) && lit(a, b)
                })
            });
            let k = (y * width + x) as usize;
            if near_glitter {
                differing += usize::from(with_glints.pixels[k] != without.pixels[k]);
            } else {
                masked += 1;
                assert_eq!(with_glints.pixels[k], without.pixels[k], "pixel ({x}, {y})");
                assert!(with_glints.pixels[k].min_element() > 0.0, "({x}, {y})");
            }
        }
    }
    eprintln!("{masked} masked pixels, {differing} glittering pixels differ");
    assert!(masked > 48 * 48 / 5, "{masked}");
    assert!(differing > 48 * 48 / 4, "{differing}");
    std::fs::remove_dir_all(&dir).unwrap();
}
