//! `cargo xtask validate`, maps suite (issue 31): counts under density maps against
//! Binomial(N·∫_A d·∫p), masks, and the roughness levels' trade between speed and the error of
//! the lobe mixture against the exact per-texel lobe.

use std::fmt::Write as _;
use std::sync::Arc;
use std::time::Instant;

use glam::{DVec2, DVec3};
use glint_brdf::{
    Bxdf, DensityMap, DiscreteBrdf, DistributionKind, Footprint, Fresnel, GlintParameters,
    MapFilter, Microfacet, MicrofacetBrdf, NormalSampling, QueryScratch, RoughnessMap,
};
use glint_tests::SplitMix64;
use glint_tests::geometry::direction;
use glint_tests::maps::{count_cases, mapped_count_sums};

use crate::validate::Check;

/// Counts on checkerboard, gradient, disc and sparse maps, nearest and bilinear, ε = 0 and
/// 0.1: Σ counts against Σ N·∫_A d·∫p over the dense and light halves of the footprints, the
/// dispersion at ε = 0, and no particle in footprints where d = 0.
pub(crate) fn counts(quick: bool, report: &mut String) -> anyhow::Result<Check> {
    let (sets, per_set) = if quick { (20, 100) } else { (100, 200) };
    writeln!(
        report,
        "\n## Maps: counts under density maps\n\n{sets} particle sets × {per_set} square \
         footprints of 1.3 texels at random positions per row; expected = Σ N·∫_A d·∫p with ∫_A d \
         texel by texel from the map's values (bilinear: each texel's tents) and ∫p by Monte Carlo; z over the footprints of \
         mean density ≥ ½ (dense) and < ½ (light); dispersion Σ(count − mean)²/Σ mean(1 − q) \
         at ε = 0; masked: particles found in footprints where d = 0. Pass: |z| < 4.5, \
         |dispersion − 1| < {}, masked 0.\n\n\
         | map | filter | N | γ | ε | z dense | z light | dispersion dense | dispersion light | masked footprints | masked count | ok |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|",
        if quick { 0.25 } else { 0.1 }
    )?;
    let cases = count_cases();
    let mut failures = 0;
    for (name, w, h, values, particles, gamma) in cases {
        for (filter, epsilon) in [
            (MapFilter::Nearest, 0.0),
            (MapFilter::Nearest, 0.1),
            (MapFilter::Bilinear, 0.0),
            (MapFilter::Bilinear, 0.1),
        ] {
            let sums = mapped_count_sums(
                (w, h, &values),
                filter,
                particles,
                gamma,
                epsilon,
                (sets, per_set),
            );
            let z = sums.map(|s| if s.means > 0.0 { s.z() } else { 0.0 });
            let dispersion = sums.map(|s| if s.means > 0.0 { s.dispersion() } else { 1.0 });
            let masked = sums[0].masked_footprints + sums[1].masked_footprints;
            let masked_count = sums[0].masked_count + sums[1].masked_count;
            let tolerance = if quick { 0.25 } else { 0.1 };
            let ok = z.iter().all(|z| z.abs() < 4.5)
                && (epsilon > 0.0 || dispersion.iter().all(|d| (d - 1.0).abs() < tolerance))
                && masked_count == 0.0;
            failures += usize::from(!ok);
            writeln!(
                report,
                "| {name} ({w} × {h}) | {} | {particles:.0e} | {gamma}° | {epsilon} | {:.2} | {:.2} | {:.3} | {:.3} | {masked} | {masked_count} | {} |",
                filter.name(),
                z[0],
                z[1],
                dispersion[0],
                dispersion[1],
                if ok { "yes" } else { "**no**" }
            )?;
        }
    }
    Ok(Check {
        name: "maps: counts",
        passed: failures == 0,
        summary: format!("16 rows (nearest and bilinear), {failures} failed, masks hold 0"),
    })
}

/// The roughness levels' trade: a 16 × 16 map of 256 distinct α (log-uniform in [0.02, 0.5])
/// and a density map, with K = 2 … 16 levels. Error: the lobe the material converges to
/// (`smooth_at`, the levels' mixture) against the exact per-texel lobe d(x)·f(α(x)): relative
/// L1 distance of f·cos θ_o over the sphere of ω_o, at three incidences, per texel (mean and
/// worst); time: one glint evaluation of a pixel footprint (one tree query per level).
pub(crate) fn roughness_levels(quick: bool, report: &mut String) -> anyhow::Result<Check> {
    let n = 16;
    let mut rng = SplitMix64::new(31);
    let alphas: Vec<f64> = (0..n * n)
        .map(|_| (0.02f64.ln() + rng.uniform() * (0.5f64.ln() - 0.02f64.ln())).exp())
        .collect();
    let densities: Vec<f64> = (0..n * n).map(|_| 0.3 + 0.7 * rng.uniform()).collect();
    let texels: Vec<usize> = (0..n * n).step_by(if quick { 16 } else { 4 }).collect();
    let queries = if quick { 2000 } else { 20_000 };
    writeln!(
        report,
        "\n## Trade: roughness levels of a roughness map\n\nA 16 × 16 `alpha_map` of 256 \
         distinct α, log-uniform in [0.02, 0.5], with a density map in [0.3, 1]. With K levels \
         evenly spaced in log α, each texel's flakes are shared between the two levels around \
         its α (weights linear in log α). Error: the lobe the material converges to \
         (Σ_k d_k·f(α_k)) against the exact per-texel lobe d·f(α(x)), the relative L1 distance \
         ∫|f_K − f|·cos θ_o dω / ∫f·cos θ_o dω at θ_i = 0°, 30°, 60°, mean and worst over {} \
         texels. Time: `eval` of a footprint of 10⁻³ near the highlight, N = 10⁸, ε = 0.1, \
         {queries} queries, one thread. Build: the material (K count trees). An `alpha_map` of \
         at most K distinct values is exact (error 0). Pass: the error falls as K grows.\n\n\
         | K | mean error | worst texel | time per query | build |\n|---|---|---|---|---|",
        texels.len()
    )?;
    let mut errors = Vec::new();
    for levels in [2, 4, 8, 16] {
        let mut parameters =
            GlintParameters::new(Microfacet::new(DistributionKind::Beckmann, 0.1, 0.1)?);
        parameters.particles = 100_000_000;
        parameters.roughness_levels = levels;
        parameters.alpha_map = Some(Arc::new(RoughnessMap::new(n, n, &alphas)?));
        parameters.density_map = Some(Arc::new(DensityMap::new(n, n, &densities)?));
        let started = Instant::now();
        let material = DiscreteBrdf::new(parameters)?;
        let build = started.elapsed().as_secs_f64();
        let (mut sum, mut worst) = (0.0, 0.0f64);
        for &k in &texels {
            let (column, row) = (k % n, k / n);
            let uv = DVec2::new(
                (column as f64 + 0.5) / n as f64,
                1.0 - (row as f64 + 0.5) / n as f64,
            );
            let exact = MicrofacetBrdf::new(
                Microfacet::new(DistributionKind::Beckmann, alphas[k], alphas[k])?,
                Fresnel::None,
                NormalSampling::Distribution,
            )?;
            let (mut difference, mut total) = (0.0, 0.0);
            for theta in [0.0f64, 30.0, 60.0] {
                let wi = direction(theta.to_radians(), 0.4);
                let [d, t] = lobe_l1(wi, |wo| {
                    let reference = densities[k] * exact.eval(wi, wo).x;
                    [
                        (material.smooth_at(wi, wo, uv).x - reference).abs(),
                        reference,
                    ]
                });
                difference += d;
                total += t;
            }
            let error = difference / total;
            sum += error;
            worst = worst.max(error);
        }
        let per_query = time_per_query(&material, queries)?;
        let mean = sum / texels.len() as f64;
        errors.push(mean);
        writeln!(
            report,
            "| {levels} | {:.2}% | {:.2}% | {:.2} µs | {:.0} ms |",
            100.0 * mean,
            100.0 * worst,
            per_query * 1e6,
            build * 1e3
        )?;
    }
    // The same queries on α = 0.1 without maps, with a density map alone (a 256 × 256
    // gradient, so that texel edges cut many nodes) and with a map of ones: what a density
    // map costs a query, alternating the three so that the machine's load falls on each.
    let with = |density: Option<Vec<f64>>| -> anyhow::Result<DiscreteBrdf> {
        let mut parameters =
            GlintParameters::new(Microfacet::new(DistributionKind::Beckmann, 0.1, 0.1)?);
        parameters.particles = 100_000_000;
        if let Some(values) = density {
            parameters.density_map = Some(Arc::new(DensityMap::new(256, 256, &values)?));
        }
        Ok(DiscreteBrdf::new(parameters)?)
    };
    let gradient = (0..256 * 256)
        .map(|k| 0.2 + 0.8 * (k % 256) as f64 / 255.0)
        .collect();
    let materials = [
        ("no maps (α = 0.1)", with(None)?),
        (
            "density map, 256² gradient (α = 0.1)",
            with(Some(gradient))?,
        ),
        (
            "density map of ones (α = 0.1)",
            with(Some(vec![1.0; 256 * 256]))?,
        ),
    ];
    let mut times = [0.0; 3];
    for _ in 0..3 {
        for (time, (_, material)) in times.iter_mut().zip(&materials) {
            *time += time_per_query(material, queries / 3)?;
        }
    }
    for (time, (label, _)) in times.iter().zip(&materials) {
        writeln!(
            report,
            "| {label} | – | – | {:.2} µs ({:.2}×) | – |",
            time / 3.0 * 1e6,
            time / times[0]
        )?;
    }
    let falling = errors.windows(2).all(|pair| pair[1] < pair[0]);
    Ok(Check {
        name: "trade: roughness levels",
        passed: falling,
        summary: format!(
            "mean lobe error {:.2}% (K = 2) … {:.2}% (K = 16)",
            100.0 * errors[0],
            100.0 * errors[errors.len() - 1]
        ),
    })
}

/// ∫ over the sphere of ω_o of the two values of `f` (each times cos θ_o where ω_o is above
/// the horizon, 0 below), by a midpoint rule in the frame of the mirror direction of `wi`
/// whose points crowd around it (cos ϑ = 1 − t², on both hemispheres of that frame), so that
/// lobes of α = 0.02 are resolved.
fn lobe_l1(wi: DVec3, f: impl Fn(DVec3) -> [f64; 2]) -> [f64; 2] {
    let mirror = DVec3::new(-wi.x, -wi.y, wi.z);
    let helper = if mirror.z.abs() < 0.9 {
        DVec3::Z
    } else {
        DVec3::X
    };
    let t1 = helper.cross(mirror).normalize();
    let t2 = mirror.cross(t1);
    let (n_t, n_phi) = (160, 320);
    let mut sums = [0.0; 2];
    for side in [1.0, -1.0] {
        for i in 0..n_t {
            let t = (i as f64 + 0.5) / n_t as f64;
            let cos = 1.0 - t * t;
            let sin = (1.0 - cos * cos).max(0.0).sqrt();
            let weight = 2.0 * t / n_t as f64 * std::f64::consts::TAU / n_phi as f64;
            for j in 0..n_phi {
                let phi = (j as f64 + 0.5) / n_phi as f64 * std::f64::consts::TAU;
                let wo = t1 * (sin * phi.cos()) + t2 * (sin * phi.sin()) + mirror * (side * cos);
                if wo.z <= 0.0 {
                    continue;
                }
                let values = f(wo);
                for (sum, value) in sums.iter_mut().zip(values) {
                    *sum += value * wo.z * weight;
                }
            }
        }
    }
    sums
}

/// Seconds per `eval` of a 10⁻³ footprint at a random position near the highlight, one thread.
fn time_per_query(material: &DiscreteBrdf, queries: u32) -> anyhow::Result<f64> {
    let mut scratch = QueryScratch::new();
    let mut rng = SplitMix64::new(7);
    let (wi, wo) = (
        direction(0.3, 0.2),
        direction(0.3, 0.2 + std::f64::consts::PI),
    );
    let started = Instant::now();
    let mut found = 0.0;
    for _ in 0..queries {
        let uv = DVec2::new(rng.uniform(), rng.uniform());
        let footprint = Footprint::new(uv, DVec2::new(1e-3, 0.0), DVec2::new(0.0, 1e-3))?;
        found += material.at(&footprint, &mut scratch).evaluate(wi, wo).count;
    }
    std::hint::black_box(found);
    Ok(started.elapsed().as_secs_f64() / f64::from(queries))
}
