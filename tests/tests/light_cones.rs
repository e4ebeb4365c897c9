//! Light cones (`glint_light_cones`) from their definition: fixed-γ light sampling converges
//! to them. Small here; `cargo xtask validate` runs the same check larger.

use std::path::Path;

use glint_tests::light_cones::{BlockAgreement, test_scene_text};
use glint_tracer::image::RgbImage;
use glint_tracer::light::Light;
use glint_tracer::scene_file::parse_scene;
use glint_tracer::{Scene, render};

fn scene(radius: f64, gamma_degrees: f64, wall: bool, cones: bool, spp: u32) -> Scene {
    let text = test_scene_text(radius, gamma_degrees, wall, 32, spp);
    let mut scene = parse_scene(&text, Path::new("light-cones.toml")).expect("a valid scene");
    scene.settings.glint_light_cones = cones;
    scene
}

fn renders(scene: &Scene, seeds: u64) -> Vec<RgbImage> {
    (0..seeds)
        .map(|seed| {
            let mut settings = scene.settings;
            settings.seed = seed;
            render(scene, &settings, 0.0, &|_, _| {})
                .expect("renders")
                .image
        })
        .collect()
}

#[test]
fn off_by_default_and_then_bit_identical() {
    let text = test_scene_text(0.15, 0.5, false, 16, 2);
    let default = parse_scene(&text, Path::new("a.toml")).expect("valid");
    assert!(!default.settings.glint_light_cones);
    let explicit = parse_scene(
        &text.replace(
            "filter = \"box\"",
            "filter = \"box\"\nglint_light_cones = false",
        ),
        Path::new("b.toml"),
    )
    .expect("valid");
    let a = render(&default, &default.settings, 0.0, &|_, _| {}).expect("renders");
    let b = render(&explicit, &explicit.settings, 0.0, &|_, _| {}).expect("renders");
    assert_eq!(a.image.pixels, b.image.pixels);
    let on = parse_scene(
        &text.replace(
            "filter = \"box\"",
            "filter = \"box\"\nglint_light_cones = true",
        ),
        Path::new("c.toml"),
    )
    .expect("valid");
    assert!(on.settings.glint_light_cones);
    let bad = parse_scene(
        &text.replace(
            "filter = \"box\"",
            "filter = \"box\"\nglint_light_cones = 3",
        ),
        Path::new("d.toml"),
    );
    assert!(bad.is_err_and(|e| e.to_string().contains("glint_light_cones")));
}

#[test]
fn fixed_gamma_light_sampling_converges_to_the_light_cone() {
    // 6 seeds × 192 spp of fixed γ = 0.05° light sampling against 6 seeds × 4 spp of light
    // cones, 4 × 4 blocks of 8 × 8 pixels over the highlight; blocks with ≥ 5% of the
    // brightest. |z| < 5 per block (two-sided p ≈ 6·10⁻⁷ under a normal law; with 6 seeds
    // per set the t law's tail is heavier, hence also RMS z < 2).
    let seeds = 6;
    let reference = renders(&scene(0.15, 0.05, false, false, 192), seeds);
    let cones = renders(&scene(0.15, 0.05, false, true, 4), seeds);
    let agreement = BlockAgreement::new(&cones, &reference, 4, 0.05);
    assert!(agreement.z.len() >= 4, "{agreement:?}");
    assert!(
        agreement.worst_z() < 5.0 && agreement.rms_z() < 2.0,
        "{agreement:?}"
    );
    // A light cone 25% too wide (the light's radiance kept) must fail the same test.
    let mut wrong = scene(0.15, 0.05, false, true, 4);
    if let Light::Sphere { sphere, .. } = &mut wrong.lights[0] {
        sphere.radius *= 1.25;
    }
    let wrong = BlockAgreement::new(&renders(&wrong, seeds), &reference, 4, 0.05);
    assert!(!(wrong.worst_z() < 5.0 && wrong.rms_z() < 2.0), "{wrong:?}");
}
