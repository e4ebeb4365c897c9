//! Footprints through a flat mirror, from the definition: a flat mirror makes a virtual camera
//! (see `glint_tests::mirror_check`). Small here; `cargo xtask validate` runs it larger.

use glint_tests::mirror_check::{MirrorCheck, PanelView, render_panel};
use glint_tracer::GlintFootprints;

/// The glittery panel seen in the mirror with `"all"` matches the virtual camera's direct view
/// pixel by pixel (correlation of the glints, [`glint_tests::mirror_check::detail`]: 0.95
/// measured at 16 spp, the rest is noise; mean luminance within 0.1%), and does not under
/// `"first_hit"` (smooth in the mirror: 0.23) nor from a camera moved sideways by eight pixels
/// (0.03).
#[test]
fn a_flat_mirror_makes_a_virtual_camera() {
    let check = MirrorCheck::run(64, 48, 16, 3e6).unwrap();
    eprintln!("{check:?}");
    assert!(check.matched > 0.8, "{check:?}");
    assert!(check.mean_difference < 0.05, "{check:?}");
    assert!(check.shifted < 0.4, "{check:?}");
    assert!(check.first_hit < 0.4, "{check:?}");
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

/// Dense glints (N = 10¹²) in the mirror converge to the smooth limit.
#[test]
fn dense_glints_in_a_mirror_are_smooth() {
    let (mean, worst) = glint_tests::mirror_check::smooth_agreement([32, 32, 2], 1e12).unwrap();
    eprintln!("mean {mean}, worst block {worst}");
    assert!(
        mean < 0.03 && worst < 0.08,
        "mean {mean}, worst block {worst}"
    );
}
