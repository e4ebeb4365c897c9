//! Footprints through flat mirrors and near-specular glossy reflectors, from the definition: a
//! flat mirror makes a virtual camera (see `glint_tests::mirror_check`). Small here; `cargo
//! xtask validate` runs it larger.

use glint_tests::mirror_check::{
    MirrorCheck, PanelView, Reflector, SWEEP_ALPHAS, alpha_sweep, render_panel, smooth_agreement,
};
use glint_tracer::GlintFootprints;

/// The virtual-camera check through `reflector` at 64 × 48, 16 spp: the panel's glints seen in
/// it match the mirrored camera's direct view (correlation > 0.8) and neither a camera moved
/// sideways nor `"first_hit"` does (< 0.4); with `same_mean`, its mean luminance is within 5%
/// too (a lacquer coat reflects only ~4%, so its scale differs).
fn assert_virtual_camera(reflector: Reflector, same_mean: bool) {
    let check = MirrorCheck::run(reflector, 64, 48, 16, 3e6).unwrap();
    eprintln!("{check:?}");
    assert!(check.matched > 0.8, "{check:?}");
    assert!(!same_mean || check.mean_difference < 0.05, "{check:?}");
    assert!(check.shifted < 0.4, "{check:?}");
    assert!(check.first_hit < 0.4, "{check:?}");
}

/// The glittery panel seen in the mirror with `"all"` matches the virtual camera's direct view
/// pixel by pixel (correlation of the glints, [`glint_tests::mirror_check::detail`]: 0.95
/// measured at 16 spp, the rest is noise; mean luminance within 0.1%), and does not under
/// `"first_hit"` (smooth in the mirror: 0.23) nor from a camera moved sideways by eight pixels
/// (0.03).
#[test]
fn a_flat_mirror_makes_a_virtual_camera() {
    assert_virtual_camera(Reflector::Mirror, true);
}

/// A polished conductor (α = 10⁻⁴, F ≈ 1) is a mirror to within its lobe: the glints in it
/// match the virtual camera's as the mirror's do, and its mean luminance too.
#[test]
fn a_polished_conductor_makes_a_virtual_camera() {
    assert_virtual_camera(Reflector::Conductor { alpha: 1e-4 }, true);
}

/// A black lacquer (plastic of base albedo 0 under a coat of α = 10⁻⁴) reflects ~4% of the
/// light through its coat alone: the glints in it match the virtual camera's pattern (the
/// correlation does not see the scale).
#[test]
fn a_glossy_coat_makes_a_virtual_camera() {
    assert_virtual_camera(Reflector::PlasticCoat { alpha: 1e-4 }, false);
}

/// Continuity in α: the glints seen in a conductor correlate with the mirror's the less the
/// rougher it is, without a jump: near the mirror's at α = 10⁻⁴, falling with each step of √2
/// in α (within the noise: a rise of at most 0.05) by at most 0.2 a step, and low at the
/// roughness limit, where the reflection is blurred over many pixels and its footprints cover
/// many particles. Measured: 0.96 at 10⁻⁴, 0.73 at 4·10⁻³, 0.41 at 8·10⁻³, 0.15 at 0.05.
#[test]
fn glints_in_a_conductor_fade_continuously_with_roughness() {
    let correlations = alpha_sweep(&SWEEP_ALPHAS, [64, 48, 16], 3e6).unwrap();
    eprintln!("{SWEEP_ALPHAS:?}\n{correlations:?}");
    assert!(correlations[0] > 0.8, "{correlations:?}");
    for pair in correlations.windows(2) {
        assert!(pair[1] < pair[0] + 0.05, "{correlations:?}");
        assert!(pair[0] - pair[1] < 0.2, "{correlations:?}");
    }
    assert!(
        correlations[SWEEP_ALPHAS.len() - 1] < 0.3,
        "{correlations:?}"
    );
}

/// In a scene without mirrors, `"all"` renders exactly as `"first_hit"`.
#[test]
fn all_is_first_hit_without_mirrors() {
    let direct = |footprints| {
        let view = PanelView::Direct { shift: 0.0 };
        render_panel(view, footprints, [24, 16, 2], 1e7).unwrap()
    };
    assert_eq!(
        direct(GlintFootprints::All),
        direct(GlintFootprints::FirstHit)
    );
}

/// With glossy reflectors past the roughness limit only (a conductor and a plastic coat of
/// α = 0.3), `"all"` renders exactly as `"first_hit"`: their bounces end the footprint.
#[test]
fn all_is_first_hit_without_near_specular_surfaces() {
    for reflector in [
        Reflector::Conductor { alpha: 0.3 },
        Reflector::PlasticCoat { alpha: 0.3 },
    ] {
        let view = PanelView::InMirror(reflector);
        let render = |footprints| render_panel(view, footprints, [24, 16, 2], 1e7).unwrap();
        assert_eq!(
            render(GlintFootprints::All),
            render(GlintFootprints::FirstHit),
            "{reflector:?}"
        );
    }
}

/// Dense glints (N = 10¹²) converge to the smooth limit at the second hit, through the mirror
/// and through near-specular and rougher glossy reflectors alike.
#[test]
fn dense_glints_in_reflections_are_smooth() {
    for reflector in [
        Reflector::Mirror,
        Reflector::Conductor { alpha: 1e-4 },
        Reflector::Conductor { alpha: 0.02 },
        Reflector::PlasticCoat { alpha: 1e-4 },
    ] {
        let (mean, worst) = smooth_agreement(reflector, [32, 32, 2], 1e12).unwrap();
        eprintln!("{reflector:?}: mean {mean}, worst block {worst}");
        assert!(
            mean < 0.03 && worst < 0.08,
            "{reflector:?}: mean {mean}, worst block {worst}"
        );
    }
}

/// Dense glints converge to the smooth render at every depth of `scenes/glitter_polished.toml`
/// (glints seen directly, in the lacquer floor, in the silver sphere and in the floor's image
/// in the sphere): with N = 10¹² the `"all"` render matches the `"never"` one (equal samples
/// and seeds) in mean and per 16 × 16 block (measured: 5·10⁻⁷ and 1.6·10⁻⁴ of the mean).
#[test]
fn dense_glints_are_smooth_through_chains_of_glossy_bounces() {
    use glint_tests::mirror_check::block_means;
    use glint_tracer::light::luminance;
    let text = include_str!("../../scenes/glitter_polished.toml")
        .replace("particles = 2e6", "particles = 1e12")
        .replace("resolution = [480, 270]", "resolution = [96, 54]")
        .replace("spp = 16", "spp = 4");
    assert!(text.contains("particles = 1e12"));
    let render = |footprints| {
        let scene = glint_tracer::scene_file::parse_scene(
            &text,
            std::path::Path::new("scenes/glitter_polished.toml"),
        )
        .unwrap();
        let mut settings = scene.settings;
        settings.glint_footprints = footprints;
        let output = glint_tracer::render(&scene, &settings, 0.0, &|_, _| {}).unwrap();
        let image: Vec<f64> = output.image.pixels.iter().map(|p| luminance(*p)).collect();
        (image, output.statistics.glint.queries)
    };
    let (all, queries) = render(GlintFootprints::All);
    let (smooth, _) = render(GlintFootprints::Never);
    // The reflections query the tree too (with 10⁵ particles instead, the worst block
    // differs by 18%).
    let (_, first_hit_queries) = render(GlintFootprints::FirstHit);
    assert!(queries > first_hit_queries, "{queries} {first_hit_queries}");
    let mean = |s: &[f64]| s.iter().sum::<f64>() / s.len() as f64;
    let difference = (mean(&all) / mean(&smooth) - 1.0).abs();
    let worst = block_means(&all, 96, 16)
        .iter()
        .zip(block_means(&smooth, 96, 16))
        .map(|(a, s)| (a - s).abs() / mean(&smooth))
        .fold(0.0, f64::max);
    eprintln!("mean {difference}, worst block {worst}");
    assert!(
        difference < 0.03 && worst < 0.08,
        "mean {difference}, worst {worst}"
    );
}
