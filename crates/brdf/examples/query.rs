//! One glint query, as a renderer makes it at a shading point, with what it found.
//!
//! ```text
//! cargo run --release -p glint-brdf --example query
//! ```
//!
//! A Beckmann surface (α = 0.1) with 10⁶ flakes per unit texture square is seen through a
//! pixel whose footprint is a 0.02 square in texture space (about 400 flakes), from 20° off the
//! normal, toward a light in the mirror direction: the centre of the highlight. The query
//! counts the flakes whose normal reflects ω_i into the cone of radius γ = 1° around ω_o, a
//! few of the 400.

use glint_brdf::{
    Bxdf, DVec2, DVec3, DiscreteBrdf, DistributionKind, Footprint, GlintParameters, Microfacet,
    QueryScratch,
};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let distribution = Microfacet::new(DistributionKind::Beckmann, 0.1, 0.1)?;
    let mut parameters = GlintParameters::new(distribution);
    parameters.particles = 1_000_000;
    parameters.gamma_radians = 1f64.to_radians();
    parameters.expected_footprint_area = 4e-4;
    let material = DiscreteBrdf::new(parameters)?;
    // One scratch per thread, reused by every query that thread makes.
    let mut scratch = QueryScratch::new();

    // Directions in the local shading frame (n = +z), both pointing away from the surface.
    let theta = 20f64.to_radians();
    let wi = DVec3::new(theta.sin(), 0.0, theta.cos());
    let wo = DVec3::new(-theta.sin(), 0.0, theta.cos());
    println!("ω_i = {wi:.4}, ω_o = {wo:.4} (mirror directions: the highlight's centre)\n");
    println!("  pixel centre (u, v)   count  expected       f̂    smooth f   nodes");

    // Eight neighbouring pixels along u: the count is a different draw in each, the expected
    // count the same; f̂ averages to the smooth BRDF convolved with the cone.
    let side = 0.02;
    for i in 0..8 {
        let uv = DVec2::new(0.1 + side * f64::from(i), 0.4);
        let footprint = Footprint::new(uv, DVec2::new(side, 0.0), DVec2::new(0.0, side))?;
        let bxdf = material.at(&footprint, &mut scratch);
        let e = bxdf.evaluate(wi, wo);
        println!(
            "  ({:.2}, {:.2})          {:>7.1}  {:>8.3}  {:>8.2}  {:>8.2}  {:>6}",
            uv.x,
            uv.y,
            e.count,
            bxdf.expected_count(wi, wo),
            e.f_hat.x,
            material.smooth().eval(wi, wo).x,
            e.nodes_visited,
        );
    }

    // Sampling: four uniform numbers, two for the widened lobe and two for the cone; the weight
    // f̂·cos θ_o / pdf uses the glint BRDF of this footprint. Averaged over many samples it is
    // the share of light from a uniform sky that this footprint's flakes reflect toward ω_i
    // (a Kronecker sequence stands in for the renderer's sampler).
    let footprint = Footprint::new(
        DVec2::new(0.1, 0.4),
        DVec2::new(side, 0.0),
        DVec2::new(0.0, side),
    )?;
    let bxdf = material.at(&footprint, &mut scratch);
    let steps = [
        0.618_033_988_7,
        0.414_213_562_4,
        0.732_050_807_6,
        0.236_067_977_5,
    ];
    let samples = 4000;
    let (mut glinting, mut sum, mut smooth_sum) = (0, 0.0, 0.0);
    for i in 0..samples {
        let u = steps.map(|step| (0.5 + step * f64::from(i)).fract());
        if let Some(s) = bxdf.sample(wi, u) {
            glinting += usize::from(s.f.x > 0.0);
            sum += s.weight.x;
            smooth_sum += material.smooth().eval(wi, s.wo).x * s.wo.z / s.pdf;
        }
    }
    let n = f64::from(samples);
    println!(
        "\n{samples} samples at (0.10, 0.40): {glinting} meet flakes; mean weight {:.3} \
         (the smooth BRDF's: {:.3})",
        sum / n,
        smooth_sum / n
    );
    Ok(())
}
