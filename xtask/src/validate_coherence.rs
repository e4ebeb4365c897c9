//! `cargo xtask validate`, trade suite, coherence across scales: what the dense regime's
//! settings do to a count as the camera moves closer, against exact counts.
//!
//! One material (Beckmann α = 0.1, γ = 1°, the dense suite's conic, `glint_tests::dense`),
//! N from 10⁸ to 10¹⁵. Three measures over random footprint positions:
//! - **the dolly**: a square footprint whose side shrinks by 3% a frame from 4·10⁻³ to
//!   2.5·10⁻⁴ (92 frames, 16 times closer); the correlation of each frame's count with the
//!   next (exact counts: 0.96–0.97, √(area ratio)), its lowest and the frames below 0.9, and
//!   the correlation with the frame of half the side (23 frames on), its lowest;
//! - **half side**: a footprint of side 10⁻³ against the nested one of half its side about
//!   the same centre (exact counts: √¼ = ½);
//! - **additivity**: the footprint's count against the sum of its two halves' (exact: 1).
//!
//! The check (the targets, for the default): at every N and every frame of the dolly
//! expecting a particle a footprint or more the frame-to-frame correlation is at least 0.9
//! (fewer: a few hundred particles over all positions give no correlation to check); the half-side correlation is within 0.1 of
//! ½ wherever one regime answers both footprints and (on the dolly) the smaller expects a
//! particle or more (λ̃ of the smaller at least
//! `LATTICE_ONLY`, or of the larger below `LATTICE_FROM`); where the smaller is left to the
//! tree and the larger to the lattice (the band, whose two particle sets are unrelated) the
//! figure is reported, not checked. Exact counts are measured up to N = 10⁹ on the dolly and
//! 10¹² on the half side (10⁸ and 10¹⁰ in `--quick`).

use std::fmt::Write as _;

use glint_tests::counts::beckmann_density;
use glint_tests::dense::{
    DOLLY_FRAMES, HALF_SIDE_FRAMES, SIDE, dolly_coherence, dolly_side, nested_correlations,
};
use glint_tree::{CountTree, CountTreeConfig, DenseCounts, LATTICE_FROM, LATTICE_ONLY};

use crate::validate::Check;

/// The settings compared.
const SETTINGS: [(&str, f64, DenseCounts); 3] = [
    ("exact (ε = 0)", 0.0, DenseCounts::Exact),
    (
        "sampled, node scale 1",
        0.1,
        DenseCounts::Sampled { node_scale: 1.0 },
    ),
    ("default: lattice", 0.1, DenseCounts::DEFAULT),
];

fn tree(particles: f64, epsilon: f64, dense: DenseCounts) -> anyhow::Result<CountTree> {
    let config = CountTreeConfig {
        particles: particles as u64,
        seed: 77,
        epsilon,
        dense,
        ..CountTreeConfig::default()
    };
    Ok(CountTree::new(config, beckmann_density(0.1, 0.1))?)
}

/// λ at the dense suite's conic per unit of N and footprint area (the trade table's N = 10¹⁰
/// mean of 18.03 at side 10⁻³).
const LAMBDA_PER_N_AREA: f64 = 18.03 / (1e10 * SIDE * SIDE);

pub(crate) fn coherence(quick: bool, report: &mut String) -> anyhow::Result<Check> {
    let (positions, nested_positions) = if quick { (250, 1500) } else { (1000, 6000) };
    let densities: &[f64] = if quick {
        &[1e8, 1e10, 1e12, 1e15]
    } else {
        &[1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15]
    };
    let (dolly_exact_up_to, nested_exact_up_to) = if quick { (1e8, 1e10) } else { (1e9, 1e12) };
    writeln!(
        report,
        "\n## Trade: coherence across scales\n\nBeckmann α = 0.1, γ = 1°, the dense suite's \
         conic. The dolly: a square footprint's side × 0.97 a frame from 4·10⁻³ to 2.5·10⁻⁴ \
         ({DOLLY_FRAMES} frames), {positions} positions; frame to frame: the correlation of \
         consecutive frames' counts (lowest; frames below 0.9); half side: with the frame \
         {HALF_SIDE_FRAMES} on (0.97²³ ≈ ½; lowest). At side 10⁻³, {nested_positions} \
         positions: the nested footprint of half the side (exact: ½) and the sum of the two \
         halves (exact: 1). λ at side 10⁻³ is N·1.8·10⁻⁹.\n\n\
         | N | setting | dolly: lowest frame to frame | frames below 0.9 | dolly: lowest half side \
         | half side | halves |\n|---|---|---|---|---|---|---|"
    )?;
    let mut passed = true;
    let mut notes = Vec::new();
    for &particles in densities {
        for &(label, epsilon, dense) in &SETTINGS {
            let exact = dense == DenseCounts::Exact;
            if exact && particles > nested_exact_up_to {
                continue;
            }
            let tree = tree(particles, epsilon, dense)?;
            let dolly = (!exact || particles <= dolly_exact_up_to)
                .then(|| dolly_coherence(&tree, positions, 7));
            let (half, halves) = nested_correlations(&tree, SIDE, nested_positions, 9);
            let (lowest, below, lowest_half) = dolly.as_ref().map_or(
                ("—".to_string(), "—".to_string(), "—".to_string()),
                |c| {
                    // Frames whose counts are all but empty (exact counts at N = 10⁸ near the
                    // dolly's end) give no correlation to speak of: left out.
                    let defined: Vec<f64> = c
                        .frame_to_frame
                        .iter()
                        .copied()
                        .filter(|x| x.is_finite())
                        .collect();
                    (
                        format!(
                            "{:.3}",
                            defined.iter().copied().fold(f64::INFINITY, f64::min)
                        ),
                        defined.iter().filter(|&&x| x < 0.9).count().to_string(),
                        format!(
                            "{:.2}",
                            c.half_side
                                .iter()
                                .copied()
                                .filter(|x| x.is_finite())
                                .fold(f64::INFINITY, f64::min)
                        ),
                    )
                },
            );
            writeln!(
                report,
                "| {particles:.0e} | {label} | {lowest} | {below} | {lowest_half} | {half:.3} | \
                 {halves:.3} |"
            )?;
            if dense != DenseCounts::DEFAULT {
                continue;
            }
            let dolly = dolly.expect("the default's dolly is measured");
            // Which regime answers each footprint (by λ̃ at the conic's λ).
            let lambda = |side: f64| LAMBDA_PER_N_AREA * particles * side * side;
            // Frames expecting fewer than one particle a footprint estimate their correlation
            // from a few hundred particles in all: checked where they expect one or more.
            for (frame, &c) in dolly.frame_to_frame.iter().enumerate() {
                if lambda(dolly_side(frame + 1)) >= 1.0 && !(c >= 0.9) {
                    passed = false;
                    notes.push(format!(
                        "N = {particles:.0e}: frame {frame} to the next {c:.3}"
                    ));
                }
            }
            let one_regime =
                |big: f64, small: f64| lambda(small) >= LATTICE_ONLY || lambda(big) < LATTICE_FROM;
            // Beyond sampling noise: the standard error of a correlation near ½ is about
            // 0.75/√positions; the check allows the target's 0.1 plus two of them.
            let slack = |n: usize| 2.0 * 0.75 / (n as f64).sqrt();
            if one_regime(SIDE, 0.5 * SIDE) {
                if !((half - 0.5).abs() <= 0.1 + slack(nested_positions)) {
                    passed = false;
                    notes.push(format!("N = {particles:.0e}: half side {half:.3}"));
                }
            } else {
                notes.push(format!(
                    "N = {particles:.0e}: half side {half:.3} across the band (reported)"
                ));
            }
            for (frame, &c) in dolly.half_side.iter().enumerate() {
                let (big, small) = (dolly_side(frame), dolly_side(frame + HALF_SIDE_FRAMES));
                // As frame to frame: checked where the smaller footprint expects a particle.
                if lambda(small) >= 1.0
                    && one_regime(big, small)
                    && !((c - 0.5).abs() <= 0.1 + slack(positions))
                {
                    passed = false;
                    notes.push(format!(
                        "N = {particles:.0e}: dolly frame {frame} half side {c:.3}"
                    ));
                }
            }
        }
    }
    writeln!(
        report,
        "\nThe default within the targets (frame to frame ≥ 0.9 at every frame expecting a particle \
         or more; half side within 0.1 of ½ where one regime answers both footprints and the smaller \
         expects a particle or more): \
         {passed}.{}",
        if notes.is_empty() {
            String::new()
        } else {
            format!(" Notes: {}.", notes.join("; "))
        }
    )?;
    Ok(Check {
        name: "trade: coherence across scales",
        passed,
        summary: format!(
            "default: frame to frame ≥ 0.9 and half side within 0.1 of ½ where one regime \
             answers: {passed}{}",
            if notes.is_empty() {
                String::new()
            } else {
                format!(" ({})", notes.join("; "))
            }
        ),
    })
}
