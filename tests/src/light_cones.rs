//! The check of light cones (`glint_light_cones`, `glint_tracer::light_cone`) against fixed-γ
//! light sampling: block means of two sets of renders of one scene, compared by their standard
//! errors. Run small by `tests/light_cones.rs` and larger by `cargo xtask validate`.

use glint_tracer::image::RgbImage;
use glint_tracer::light::luminance;

/// How two sets of renders of one scene agree in the mean radiance of image blocks: the
/// checker of light cones against fixed-γ light sampling (`cargo test` small, `cargo xtask
/// validate` larger).
#[derive(Clone, Debug, PartialEq)]
pub struct BlockAgreement {
    /// Per compared block, (mean of the first set − mean of the second) over its standard
    /// error, estimated from the spread across each set's renders (independent seeds).
    pub z: Vec<f64>,
    /// Per compared block, the relative difference of the means (first / second − 1).
    pub relative: Vec<f64>,
}

impl BlockAgreement {
    /// Compares the `blocks` × `blocks` block means (luminance) of two sets of at least two
    /// renders each, over the blocks whose mean in `second` is at least `floor` × the brightest.
    #[must_use]
    pub fn new(first: &[RgbImage], second: &[RgbImage], blocks: usize, floor: f64) -> Self {
        let means = |set: &[RgbImage]| -> Vec<Vec<f64>> {
            set.iter().map(|image| block_means(image, blocks)).collect()
        };
        let (a, b) = (means(first), means(second));
        let stats = |set: &[Vec<f64>], k: usize| -> (f64, f64) {
            let n = set.len() as f64;
            let mean = set.iter().map(|r| r[k]).sum::<f64>() / n;
            let variance = set.iter().map(|r| (r[k] - mean).powi(2)).sum::<f64>() / (n - 1.0);
            (mean, variance / n)
        };
        let count = b.first().map_or(0, Vec::len);
        let brightest = (0..count).map(|k| stats(&b, k).0).fold(0.0, f64::max);
        let (mut z, mut relative) = (vec![], vec![]);
        for k in 0..count {
            let ((ma, va), (mb, vb)) = (stats(&a, k), stats(&b, k));
            if mb >= floor * brightest && mb > 0.0 {
                z.push((ma - mb) / (va + vb).sqrt().max(1e-9 * mb));
                relative.push(ma / mb - 1.0);
            }
        }
        Self { z, relative }
    }

    /// The largest |z|.
    #[must_use]
    pub fn worst_z(&self) -> f64 {
        self.z.iter().fold(0.0, |m, z| m.max(z.abs()))
    }

    /// The root mean square of z (about 1 when the means agree).
    #[must_use]
    pub fn rms_z(&self) -> f64 {
        (self.z.iter().map(|z| z * z).sum::<f64>() / self.z.len().max(1) as f64).sqrt()
    }

    /// The mean relative difference over the compared blocks.
    #[must_use]
    pub fn mean_relative(&self) -> f64 {
        self.relative.iter().sum::<f64>() / self.relative.len().max(1) as f64
    }
}

/// Mean luminance of each square block of side `width / blocks` over the image (a `blocks` ×
/// `blocks` grid on the square test images; partial blocks at the edges otherwise).
fn block_means(image: &RgbImage, blocks: usize) -> Vec<f64> {
    let luminance: Vec<f64> = image.pixels.iter().map(|&p| luminance(p)).collect();
    crate::mirror_check::block_means(&luminance, image.width, image.width / blocks.max(1))
}

/// A test scene for light cones: a glint floor under one sphere light of radius `radius`
/// (radiance fixed, so a wrong radius is a wrong light), optionally half hidden behind a
/// wall (a penumbra over the highlight), direct light. `side` pixels square at `spp`.
#[must_use]
pub fn test_scene_text(radius: f64, gamma_degrees: f64, wall: bool, side: u32, spp: u32) -> String {
    let wall = if wall {
        // A thin box edge between floor and light: its shadow edge crosses the highlight.
        r#"
[materials.wall]
type = "diffuse"
colour = [0.0, 0.0, 0.0]
[[shapes]]
type = "rectangle"
center = [0.15, 0.9, -2.2]
u = [0.3, 0.0, 0.0]
v = [0.0, 0.3, 0.3]
material = "wall"
"#
    } else {
        ""
    };
    format!(
        r#"
[render]
resolution = [{side}, {side}]
spp = {spp}
integrator = "direct"
filter = "box"
[camera]
position = [0.0, 1.0, 2.0]
look_at = [0.0, 0.0, -1.0]
fov = 30
[materials.floor]
type = "glint"
alpha = 0.1
particles = 1e9
gamma = {gamma_degrees}
epsilon = 0.0
negligible_count = 0
seed = 3
uv_scale = 0.05
[[shapes]]
type = "rectangle"
center = [0.0, 0.0, 0.0]
u = [8.0, 0.0, 0.0]
v = [0.0, 0.0, -8.0]
material = "floor"
[[lights]]
type = "sphere"
center = [0.0, 1.2, -3.0]
radius = {radius}
radiance = 50.0
{wall}"#
    )
}
