//! `cargo xtask validate`, footprints through mirrors (`glint_tests::mirror_check`):
//!
//! 1. A flat mirror makes a virtual camera: the glittery panel seen in the mirror under
//!    `glint_footprints = "all"` against the mirrored camera's direct view (flipped): the
//!    correlation of their glints must be high (≥ 0.85), and low (≤ 0.4) for the `"first_hit"`
//!    render (smooth in the mirror) and for a camera moved sideways by eight pixels.
//! 2. Dense materials converge to the smooth render at the second hit: with N = 10¹² the
//!    `"all"` render of the panel in the mirror matches the smooth render (equal samples and
//!    seeds) within 2% in mean and in every 16 × 16 block within 5% of the image's mean. At γ = 2° f̂ converges to f
//!    convolved with the cone, not to f, which leaves a bias of about 1% (see
//!    `validate_render.rs`).

use std::fmt::Write as _;

use glint_tests::mirror_check::{MirrorCheck, smooth_agreement};

use crate::validate::Check;

pub(crate) fn footprints(quick: bool, report: &mut String) -> anyhow::Result<Check> {
    let (width, height, spp) = if quick { (64, 48, 16) } else { (160, 120, 64) };
    let check = MirrorCheck::run(width, height, spp, 3e6)?;
    let mirror_ok = check.matched >= 0.85
        && check.mean_difference <= 0.05
        && check.shifted <= 0.4
        && check.first_hit <= 0.4;
    let (mean, worst) = smooth_agreement([width, height, spp / 2], 1e12)?;
    let dense_ok = mean <= 0.02 && worst <= 0.05;
    writeln!(
        report,
        "## Footprints through mirrors\n\n\
         A glittery panel (N = 3·10⁶, α = 0.3, γ = 2°) seen in a flat mirror at {width} × \
         {height}, {spp} spp, against the mirrored camera's direct view (the correlation of the \
         glints, each pixel minus its 8 × 8 block mean):\n\n\
         | render in the mirror | correlation with the virtual camera |\n|---|---|\n\
         | `\"all\"` | {:.3} (mean luminance within {:.2}%) |\n\
         | `\"all\"`, virtual camera moved 8 pixels | {:.3} |\n\
         | `\"first_hit\"` (smooth in the mirror) | {:.3} |\n\n\
         N = 10¹², `\"all\"` against the smooth limit in the mirror ({} spp): mean {:.2}%, worst \
         16 × 16 block {:.2}% of the mean (tolerances 2%, 5%).\n",
        check.matched,
        100.0 * check.mean_difference,
        check.shifted,
        check.first_hit,
        spp / 2,
        100.0 * mean,
        100.0 * worst,
    )?;
    Ok(Check {
        name: "renders: footprints in mirrors",
        passed: mirror_ok && dense_ok,
        summary: format!(
            "virtual camera r = {:.3} (first_hit {:.3}, moved {:.3}); N = 1e12 vs smooth: \
             mean {:.2}%, worst block {:.2}%",
            check.matched,
            check.first_hit,
            check.shifted,
            100.0 * mean,
            100.0 * worst
        ),
    })
}
