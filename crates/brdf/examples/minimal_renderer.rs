//! A minimal renderer with glints, using glint-brdf alone (no glint-tracer): a glittery plane
//! under a small light, one glint query per pixel, written to a PNG.
//!
//! ```text
//! cargo run --release -p glint-brdf --example minimal_renderer [out.png]
//! ```
//!
//! What a renderer must supply is the pixel's footprint in texture space. Here it comes from
//! screen-space derivatives of (u, v): the rays through the neighbouring pixels hit the plane
//! at (u, v) + ∂(u, v)/∂x and (u, v) + ∂(u, v)/∂y, which for a plane is exactly what ray
//! differentials give. The footprint is the whole pixel, so one query per pixel already
//! integrates the flakes the pixel sees: no supersampling is needed for the glints.

use glint_brdf::{
    Bxdf, DVec2, DVec3, DiscreteBrdf, DistributionKind, Footprint, GlintParameters, Microfacet,
    QueryScratch,
};

const WIDTH: usize = 480;
const HEIGHT: usize = 320;
/// Texture repetitions per world unit: the flakes' unit square covers 1/TILES of a unit.
const TILES: f64 = 1.0;

/// A pinhole camera: the ray direction through film position (x, y) in pixels.
struct Camera {
    eye: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    /// tan(vertical fov / 2) / (HEIGHT / 2): world units per pixel at distance 1.
    pixel_scale: f64,
}

impl Camera {
    fn looking_at(eye: DVec3, target: DVec3, vertical_fov_degrees: f64) -> Self {
        let forward = (target - eye).normalize();
        let right = forward.cross(DVec3::Z).normalize();
        let up = right.cross(forward);
        let pixel_scale = (0.5 * vertical_fov_degrees.to_radians()).tan() / (0.5 * HEIGHT as f64);
        Self {
            eye,
            forward,
            right,
            up,
            pixel_scale,
        }
    }

    fn direction(&self, x: f64, y: f64) -> DVec3 {
        let (sx, sy) = (x - 0.5 * WIDTH as f64, 0.5 * HEIGHT as f64 - y);
        (self.forward + self.pixel_scale * (sx * self.right + sy * self.up)).normalize()
    }

    /// Where the ray through (x, y) meets the plane z = 0, if in front of the camera.
    fn hit_plane(&self, x: f64, y: f64) -> Option<DVec3> {
        let d = self.direction(x, y);
        let t = -self.eye.z / d.z;
        (t > 0.0 && t.is_finite()).then(|| self.eye + t * d)
    }
}

/// The plane's texture coordinates at a point on it.
fn uv_at(p: DVec3) -> DVec2 {
    DVec2::new(p.x, p.y) * TILES
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let output = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "minimal_renderer.png".into());
    let camera = Camera::looking_at(DVec3::new(0.0, -3.0, 1.8), DVec3::new(0.0, 0.1, 0.0), 40.0);
    // A small light: a point of intensity I. γ = 1.5° stands for its size (Sec. 3.1).
    let (light, intensity) = (DVec3::new(0.0, 2.0, 1.2), 3.0);
    let footprint_side = 3.0 * camera.pixel_scale * TILES; // about a pixel's, near the highlight
    let mut parameters =
        GlintParameters::new(Microfacet::new(DistributionKind::Beckmann, 0.15, 0.15)?);
    parameters.particles = 200_000;
    parameters.gamma_radians = 1.5f64.to_radians();
    parameters.expected_footprint_area = footprint_side * footprint_side;
    let material = DiscreteBrdf::new(parameters)?;
    let base_albedo = 0.03; // a faint diffuse base under the flakes, so the plane shows

    // Rows in parallel; each thread owns a scratch, reused by all its queries.
    let mut radiance = vec![0.0f64; WIDTH * HEIGHT];
    let threads = std::thread::available_parallelism().map_or(1, usize::from);
    let rows_per_thread = HEIGHT.div_ceil(threads);
    std::thread::scope(|scope| {
        for (chunk, rows) in radiance.chunks_mut(rows_per_thread * WIDTH).enumerate() {
            let (camera, material) = (&camera, &material);
            scope.spawn(move || {
                let mut scratch = QueryScratch::new();
                for (i, pixel) in rows.iter_mut().enumerate() {
                    let (x, y) = (
                        (i % WIDTH) as f64 + 0.5,
                        (chunk * rows_per_thread + i / WIDTH) as f64 + 0.5,
                    );
                    let (Some(p), Some(px), Some(py)) = (
                        camera.hit_plane(x, y),
                        camera.hit_plane(x + 1.0, y),
                        camera.hit_plane(x, y + 1.0),
                    ) else {
                        continue;
                    };
                    // The plane's shading frame is the world frame: n = +z.
                    let wi = (camera.eye - p).normalize();
                    let to_light = light - p;
                    let wo = to_light.normalize();
                    let uv = uv_at(p);
                    let Ok(footprint) = Footprint::new(uv, uv_at(px) - uv, uv_at(py) - uv) else {
                        continue;
                    };
                    let f = material.at(&footprint, &mut scratch).eval(wi, wo).x
                        + base_albedo / std::f64::consts::PI;
                    *pixel = f * wo.z * intensity / to_light.length_squared();
                }
            });
        }
    });

    // Exposure, clamp, sRGB.
    let srgb = |v: f64| {
        let c = (v * 4.0).clamp(0.0, 1.0);
        let c = if c <= 0.003_130_8 {
            12.92 * c
        } else {
            1.055 * c.powf(1.0 / 2.4) - 0.055
        };
        (c * 255.0).round() as u8
    };
    let bytes: Vec<u8> = radiance.iter().flat_map(|&v| [srgb(v); 3]).collect();
    let mut encoder = png::Encoder::new(
        std::io::BufWriter::new(std::fs::File::create(&output)?),
        WIDTH as u32,
        HEIGHT as u32,
    );
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.write_header()?.write_image_data(&bytes)?;
    let lit = radiance.iter().filter(|&&v| v * 4.0 >= 1.0).count();
    println!("wrote {output}: {WIDTH}×{HEIGHT}, {lit} saturated (glinting) pixels");
    Ok(())
}
