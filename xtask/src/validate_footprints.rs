//! `cargo xtask validate`, footprints through mirrors and near-specular glossy reflectors
//! (`glint_tests::mirror_check`):
//!
//! 1. A flat mirror makes a virtual camera: the glittery panel seen in the mirror under
//!    `glint_footprints = "all"` against the mirrored camera's direct view (flipped): the
//!    correlation of their glints must be high (≥ 0.85), and low (≤ 0.4) for the `"first_hit"`
//!    render (smooth in the mirror) and for a camera moved sideways by eight pixels. The same
//!    holds for a polished conductor (α = 10⁻⁴, F ≈ 1, also its mean luminance) and a black
//!    lacquer (a plastic coat of α = 10⁻⁴), whose footprints go on through the sampled lobe
//!    (at a quarter of the samples in the full run).
//! 2. Continuity in α: the correlation of the glints in a conductor with the mirror's, for α
//!    in steps of √2 from 10⁻³ toward the roughness limit 0.05 (`SWEEP_ALPHAS`; in the full
//!    run at half the width and height and a quarter of the samples): it must not
//!    rise by more than 0.05 (noise) nor fall by more than 0.2 per step, and end below 0.3.
//! 3. Dense materials converge to the smooth render at the second hit: with N = 10¹² the
//!    `"all"` render of the panel in each reflector (the mirror, conductors of α = 10⁻⁴ and
//!    0.02, the plastic coat) matches the smooth render (equal samples and seeds) within 2% in
//!    mean and in every 16 × 16 block within 5% of the image's mean. At γ = 2° f̂ converges to
//!    f convolved with the cone, not to f, which leaves a bias of about 1% (see
//!    `validate_render.rs`).
//!
//! The full run takes 163–214 s on two cores (33 renders at full size took 606 s, hence the
//! smaller glossy checks).

use std::fmt::Write as _;

use glint_tests::mirror_check::{
    MirrorCheck, Reflector, SWEEP_ALPHAS, alpha_sweep, smooth_agreement,
};

use crate::validate::Check;

pub(crate) fn footprints(quick: bool, report: &mut String) -> anyhow::Result<Check> {
    let (width, height, spp) = if quick { (64, 48, 16) } else { (160, 120, 64) };
    // The glossy reflectors at a quarter of the mirror's samples, and the sweep also at a
    // quarter of its pixels, in the full run.
    let glossy_spp = if quick { spp } else { spp / 4 };
    let reflectors = [
        ("mirror", Reflector::Mirror, spp),
        (
            "conductor α = 10⁻⁴",
            Reflector::Conductor { alpha: 1e-4 },
            glossy_spp,
        ),
        (
            "plastic coat α = 10⁻⁴",
            Reflector::PlasticCoat { alpha: 1e-4 },
            glossy_spp,
        ),
    ];
    writeln!(
        report,
        "## Footprints through mirrors and glossy reflectors\n\n\
         A glittery panel (N = 3·10⁶, α = 0.3, γ = 2°) seen in a flat reflector at {width} × \
         {height} against the mirrored camera's direct view (the correlation of the glints, each \
         pixel minus its 8 × 8 block mean):\n\n\
         | reflector | spp | `\"all\"` | mean luminance | virtual camera moved 8 pixels | \
         `\"first_hit\"` (smooth in the reflector) |\n|---|---|---|---|---|---|"
    )?;
    let mut checks_ok = true;
    let mut summary = String::new();
    for (name, reflector, spp) in reflectors {
        let check = MirrorCheck::run(reflector, width, height, spp, 3e6)?;
        let scaled = matches!(reflector, Reflector::PlasticCoat { .. });
        let ok = check.matched >= 0.85
            && (scaled || check.mean_difference <= 0.05)
            && check.shifted <= 0.4
            && check.first_hit <= 0.4;
        checks_ok &= ok;
        let mean = if scaled {
            "(F ≈ 4%)".to_owned()
        } else {
            format!("within {:.2}%", 100.0 * check.mean_difference)
        };
        writeln!(
            report,
            "| {name} | {spp} | {:.3} | {mean} | {:.3} | {:.3} |",
            check.matched, check.shifted, check.first_hit
        )?;
        write!(
            summary,
            "{name}: r = {:.3} (first_hit {:.3}); ",
            check.matched, check.first_hit
        )?;
    }
    let sweep_size = if quick {
        [width, height, spp]
    } else {
        [width / 2, height / 2, spp / 4]
    };
    let sweep = alpha_sweep(&SWEEP_ALPHAS, sweep_size, 3e6)?;
    let sweep_ok = sweep[0] >= 0.85
        && sweep
            .windows(2)
            .all(|p| p[1] < p[0] + 0.05 && p[0] - p[1] < 0.2)
        && sweep[SWEEP_ALPHAS.len() - 1] < 0.3;
    writeln!(
        report,
        "\nThe glints in a conductor (F ≈ 1) against those in the mirror, as α grows, at {} × {}, \
         {} spp (each pixel minus its 8 × 8 block mean):\n\n\
         | α | correlation with the mirror's |\n|---|---|",
        sweep_size[0], sweep_size[1], sweep_size[2]
    )?;
    for (alpha, r) in SWEEP_ALPHAS.iter().zip(&sweep) {
        writeln!(report, "| {alpha} | {r:.3} |")?;
    }
    write!(
        summary,
        "sweep α 1e-4..0.05: {}; ",
        sweep
            .iter()
            .map(|r| format!("{r:.2}"))
            .collect::<Vec<_>>()
            .join(", ")
    )?;
    writeln!(
        report,
        "\nN = 10¹², `\"all\"` against the smooth limit in the reflector ({} spp; tolerances \
         2% in mean, 5% for the worst 16 × 16 block):\n\n| reflector | mean | worst block |\n\
         |---|---|---|",
        spp / 2
    )?;
    let mut dense_ok = true;
    for (name, reflector) in [
        ("mirror", Reflector::Mirror),
        ("conductor α = 10⁻⁴", Reflector::Conductor { alpha: 1e-4 }),
        ("conductor α = 0.02", Reflector::Conductor { alpha: 0.02 }),
        (
            "plastic coat α = 10⁻⁴",
            Reflector::PlasticCoat { alpha: 1e-4 },
        ),
    ] {
        let (mean, worst) = smooth_agreement(reflector, [width, height, spp / 2], 1e12)?;
        dense_ok &= mean <= 0.02 && worst <= 0.05;
        writeln!(
            report,
            "| {name} | {:.2}% | {:.2}% |",
            100.0 * mean,
            100.0 * worst
        )?;
        write!(
            summary,
            "N = 1e12 in {name}: {:.2}%/{:.2}%; ",
            100.0 * mean,
            100.0 * worst
        )?;
    }
    writeln!(report)?;
    Ok(Check {
        name: "renders: footprints in mirrors and glossy reflectors",
        passed: checks_ok && sweep_ok && dense_ok,
        summary: summary.trim_end_matches("; ").to_owned(),
    })
}
