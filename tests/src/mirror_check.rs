//! The definition check of footprints through mirrors: a flat mirror makes a virtual camera.
//! Run small by `tests/footprints.rs` and large by
//! `cargo xtask validate`.
//!
//! A glittery panel stands behind the camera, facing a flat reflector that fills the view: a
//! Fresnel-free perfect mirror (reflectance 1), or a near-specular glossy one ([`Reflector`]).
//! Seen in a mirror with [`GlintFootprints::All`] (path depth 2: the mirror, then light at the
//! panel), the panel must look as it does seen directly from the camera mirrored in the
//! mirror's plane (depth 1, no mirror in the scene), the image flipped left to right: the same
//! particles in the same footprints, the same radiance, up to Monte Carlo noise. Under
//! [`GlintFootprints::FirstHit`] the panel in the mirror is the smooth limit and must not match;
//! nor must a direct view from a camera moved sideways.
//!
//! A glossy reflector of roughness α → 0 converges to the mirror: its glints must match the
//! virtual camera's as the mirror's do at α = 10⁻⁴ (the footprint widening is then 0.16% of
//! these pixels, `glint_tracer::differentials`), and fade continuously as α grows
//! ([`alpha_sweep`]): the reflection blurs and the footprints widen.

use std::path::Path;

use glam::DVec3;

use glint_tracer::camera::CameraPose;
use glint_tracer::image::RgbImage;
use glint_tracer::light::luminance;
use glint_tracer::scene_file::parse_scene;
use glint_tracer::{GlintFootprints, TracerError, render};

/// The flat reflector the panel is seen in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reflector {
    /// A perfect mirror (`type = "mirror"`, no Fresnel: reflectance 1).
    Mirror,
    /// A smooth microfacet conductor of roughness `alpha` (Beckmann) with η = 1, k = 1000:
    /// F = ((η − 1)² + k²)/((η + 1)² + k²) is within 4·10⁻⁶ of 1 at every angle, so the
    /// conductor differs from the mirror by its lobe alone.
    Conductor {
        /// The roughness α.
        alpha: f64,
    },
    /// Black plastic (base albedo 0) whose dielectric coat (η = 1.5, Beckmann) has roughness
    /// `alpha`: a glossy lacquer reflecting F(θ) ≈ 4% of the light.
    PlasticCoat {
        /// The coat's roughness α.
        alpha: f64,
    },
}

impl Reflector {
    /// The reflector's material section.
    fn material(self) -> String {
        match self {
            Self::Mirror => "type = \"mirror\"".to_owned(),
            Self::Conductor { alpha } => format!(
                "type = \"conductor\"\nalpha = {alpha:?}\neta = [1.0, 1.0, 1.0]\n\
                 k = [1000.0, 1000.0, 1000.0]"
            ),
            Self::PlasticCoat { alpha } => {
                format!("type = \"plastic\"\nalpha = {alpha:?}\ncolour = 0.0\neta = 1.5")
            }
        }
    }
}

/// How a render sees the panel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PanelView {
    /// In the reflector, from the camera.
    InMirror(Reflector),
    /// Directly, from the camera mirrored in the mirror's plane and moved sideways by `shift`
    /// (0: the exact virtual camera), with the image flipped left to right.
    Direct {
        /// The sideways move, in metres.
        shift: f64,
    },
}

/// The camera: 3 m in front of the mirror (the plane z = 0), looking into it.
#[must_use]
pub fn camera_pose() -> CameraPose {
    CameraPose {
        position: DVec3::new(0.3, 1.0, 3.0),
        look_at: DVec3::new(0.0, 0.8, 0.0),
        up: DVec3::Y,
        fov_degrees: 24.0,
    }
}

/// `point` mirrored in the plane z = 0.
fn mirrored(point: DVec3) -> DVec3 {
    DVec3::new(point.x, point.y, -point.z)
}

/// The scene text for `view` under `footprints` at `width` × `height` pixels and `spp` samples.
fn scene_text(
    view: PanelView,
    footprints: GlintFootprints,
    [width, height, spp]: [u32; 3],
    particles: f64,
    planned_area: Option<f64>,
) -> String {
    let pose = camera_pose();
    let footprints = match footprints {
        GlintFootprints::FirstHit => "first_hit",
        GlintFootprints::All => "all",
        GlintFootprints::Never => "never",
    };
    let (position, look_at, up, depth, mirror) = match view {
        PanelView::InMirror(reflector) => {
            let mirror = format!(
                r#"
[materials.mirror]
{}
[[shapes]]
type = "rectangle"
center = [0.0, 1.0, 0.0]
u = [12.0, 0.0, 0.0]
v = [0.0, 12.0, 0.0]
material = "mirror"
"#,
                reflector.material()
            );
            (pose.position, pose.look_at, pose.up, 2, mirror)
        }
        PanelView::Direct { shift } => (
            mirrored(pose.position) + DVec3::new(shift, 0.0, 0.0),
            mirrored(pose.look_at) + DVec3::new(shift, 0.0, 0.0),
            mirrored(pose.up),
            1,
            String::new(),
        ),
    };
    let v = |p: DVec3| format!("[{:?}, {:?}, {:?}]", p.x, p.y, p.z);
    format!(
        r#"
[render]
resolution = [{width}, {height}]
spp = {spp}
max_depth = {depth}
integrator = "path"
glint_footprints = "{footprints}"
filter = "box"
[camera]
position = {position}
look_at = {look_at}
up = {up}
fov = {fov}
[materials.glitter]
type = "glint"
alpha = 0.3
particles = {particles:e}
{area}gamma = 2.0
seed = 3
[[shapes]]
type = "rectangle"
center = [0.0, 1.0, 4.0]
u = [-8.0, 0.0, 0.0]
v = [0.0, 8.0, 0.0]
material = "glitter"
[[lights]]
type = "sphere"
center = [1.6, 3.2, 1.5]
radius = 0.05
power = 60.0
{mirror}"#,
        position = v(position),
        look_at = v(look_at),
        up = v(up),
        fov = pose.fov_degrees,
        area = planned_area.map_or_else(String::new, |a| format!(
            "expected_footprint_area = {a:e}\n"
        )),
    )
}

/// The luminance image of the panel seen as `view` under `footprints` (flipped left to right
/// for direct views), at `[width, height, spp]`, with `particles` flakes per unit texture
/// square.
///
/// # Errors
/// A [`TracerError`] if the scene does not build or render (not expected).
pub fn render_panel(
    view: PanelView,
    footprints: GlintFootprints,
    size: [u32; 3],
    particles: f64,
) -> Result<Vec<f64>, TracerError> {
    render_panel_planned(view, footprints, size, particles, None)
}

/// [`render_panel`] with the panel's `expected_footprint_area` fixed to `area` (`None`: the
/// prior run plans it, [`glint_tracer::plan`]). The plan selects the particle set, so renders
/// whose footprints differ (reflectors of different α) show the same particles only with a
/// fixed area.
///
/// # Errors
/// A [`TracerError`] if the scene does not build or render (not expected).
pub fn render_panel_planned(
    view: PanelView,
    footprints: GlintFootprints,
    size: [u32; 3],
    particles: f64,
    area: Option<f64>,
) -> Result<Vec<f64>, TracerError> {
    let scene = parse_scene(
        &scene_text(view, footprints, size, particles, area),
        Path::new("mirror-check.toml"),
    )?;
    let output = render(&scene, &scene.settings, 0.0, &|_, _| {})?;
    let flip = matches!(view, PanelView::Direct { .. });
    Ok(flipped_luminance(&output.image, flip))
}

fn flipped_luminance(image: &RgbImage, flip: bool) -> Vec<f64> {
    let (w, h) = (image.width, image.height);
    (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let x = if flip { w - 1 - x } else { x };
            luminance(image.pixels[y * w + x])
        })
        .collect()
}

/// The glints without the highlight's slow variation: each pixel minus the mean of its 8 × 8
/// block (`width` pixels per row), so that correlations measure where glints are, not the
/// smooth highlight that every render shares.
#[must_use]
pub fn detail(image: &[f64], width: usize) -> Vec<f64> {
    const BLOCK: usize = 8;
    let means = block_means(image, width, BLOCK);
    let blocks_x = width.max(1).div_ceil(BLOCK);
    image
        .iter()
        .enumerate()
        .map(|(i, v)| v - means[(i / width / BLOCK) * blocks_x + (i % width) / BLOCK])
        .collect()
}

/// The mean of each `block` × `block` square of `image` (`width` pixels per row; partial
/// squares at the right and bottom edges), row by row.
#[must_use]
pub fn block_means(image: &[f64], width: usize, block: usize) -> Vec<f64> {
    let (width, block) = (width.max(1), block.max(1));
    let height = image.len() / width;
    let blocks_x = width.div_ceil(block);
    let mut sums = vec![(0.0, 0.0); blocks_x * height.div_ceil(block)];
    for (i, v) in image.iter().enumerate() {
        let s = &mut sums[(i / width / block) * blocks_x + (i % width) / block];
        *s = (s.0 + v, s.1 + 1.0);
    }
    sums.iter()
        .map(|(sum, n)| sum / f64::max(*n, 1.0))
        .collect()
}

/// Pearson's correlation of two equally long sequences (0 when either is constant).
#[must_use]
pub fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len()) as f64;
    let mean = |s: &[f64]| s.iter().sum::<f64>() / n;
    let (ma, mb) = (mean(a), mean(b));
    let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        ab += (x - ma) * (y - mb);
        aa += (x - ma) * (x - ma);
        bb += (y - mb) * (y - mb);
    }
    if aa > 0.0 && bb > 0.0 {
        ab / (aa * bb).sqrt()
    } else {
        0.0
    }
}

/// The figures of one run of the check (correlations are of [`detail`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MirrorCheck {
    /// Correlation of per-pixel luminance: in the mirror ("all") against the virtual camera.
    pub matched: f64,
    /// The same against the virtual camera moved sideways by a few pixels' width.
    pub shifted: f64,
    /// The same for the "first_hit" render in the mirror (smooth there) against the virtual
    /// camera.
    pub first_hit: f64,
    /// Relative difference of the mean luminance, "all" in the mirror against the virtual
    /// camera.
    pub mean_difference: f64,
}

impl MirrorCheck {
    /// Runs the check with the panel seen in `reflector`, at `width` × `height` pixels and
    /// `spp` samples with `particles` flakes per unit texture square. `mean_difference`
    /// compares the mean luminance with the virtual camera's as it is: meaningful for the
    /// mirror and the conductor (reflectance 1), not for the plastic coat (F ≈ 4%).
    ///
    /// # Errors
    /// A [`TracerError`] if a scene does not build or render (not expected).
    pub fn run(
        reflector: Reflector,
        width: u32,
        height: u32,
        spp: u32,
        particles: f64,
    ) -> Result<Self, TracerError> {
        let panel =
            |view, footprints| render_panel(view, footprints, [width, height, spp], particles);
        let all = panel(PanelView::InMirror(reflector), GlintFootprints::All)?;
        let first_hit = panel(PanelView::InMirror(reflector), GlintFootprints::FirstHit)?;
        let direct = panel(PanelView::Direct { shift: 0.0 }, GlintFootprints::FirstHit)?;
        // Eight pixels' width at the panel, 7 m from the virtual camera.
        let pixel =
            2.0 * 7.0 * (0.5 * camera_pose().fov_degrees.to_radians()).tan() / f64::from(height);
        let shifted = panel(
            PanelView::Direct { shift: 8.0 * pixel },
            GlintFootprints::FirstHit,
        )?;
        let mean = |s: &[f64]| s.iter().sum::<f64>() / s.len() as f64;
        let d = |image: &[f64]| detail(image, width as usize);
        let (all_detail, direct_detail) = (d(&all), d(&direct));
        Ok(Self {
            matched: correlation(&all_detail, &direct_detail),
            shifted: correlation(&all_detail, &d(&shifted)),
            first_hit: correlation(&d(&first_hit), &direct_detail),
            mean_difference: (mean(&all) / mean(&direct) - 1.0).abs(),
        })
    }
}

/// Dense glints converge to the smooth model at every depth: the panel in `reflector` under
/// `"all"` (footprints at the second hit) against the same render with every glint material's
/// smooth limit (`"never"`, equal samples and seeds, so only f̂ against f differs). Returns the
/// relative difference of the mean luminance and the largest difference of a 16 × 16 block's
/// mean relative to the smooth image's mean (blocks in the highlight's dim tail, where a
/// relative figure per block would measure little, count by their share of the image).
///
/// # Errors
/// A [`TracerError`] if a scene does not build or render (not expected).
pub fn smooth_agreement(
    reflector: Reflector,
    size: [u32; 3],
    particles: f64,
) -> Result<(f64, f64), TracerError> {
    let view = PanelView::InMirror(reflector);
    let all = render_panel(view, GlintFootprints::All, size, particles)?;
    let smooth = render_panel(view, GlintFootprints::Never, size, particles)?;
    let width = size[0] as usize;
    let blocks = |image: &[f64]| {
        let (with_detail, pixels) = (block_means(image, width, 16), image.len() as f64);
        (with_detail, image.iter().sum::<f64>() / pixels)
    };
    let ((all_blocks, all_mean), (smooth_blocks, smooth_mean)) = (blocks(&all), blocks(&smooth));
    let worst = all_blocks
        .iter()
        .zip(&smooth_blocks)
        .map(|(a, s)| (a - s).abs() / smooth_mean)
        .fold(0.0, f64::max);
    Ok(((all_mean / smooth_mean - 1.0).abs(), worst))
}

/// The roughnesses of the continuity check: 10⁻⁴, then steps of √2 from 10⁻³ to 1.6·10⁻²
/// (where the glints fade at the checks' pixel sizes), then 0.032 and the roughness limit 0.05.
pub const SWEEP_ALPHAS: [f64; 12] = [
    1e-4, 1e-3, 1.4e-3, 2e-3, 2.8e-3, 4e-3, 5.7e-3, 8e-3, 1.1e-2, 1.6e-2, 3.2e-2, 0.05,
];

/// The panel's `expected_footprint_area` in [`alpha_sweep`] (any fixed area would do; this
/// is near what the prior run plans for the mirror's footprints).
pub const SWEEP_PLANNED_AREA: f64 = 1e-6;

/// Continuity in α: the correlation of the glints ([`detail`]) of the panel seen under `"all"`
/// in a conductor of each roughness in `alphas` with those seen in the perfect mirror, at
/// `[width, height, spp]` with `particles` flakes per unit texture square, in order. Every
/// render fixes the panel's `expected_footprint_area` ([`SWEEP_PLANNED_AREA`]): the prior run
/// would plan each α its own area, and so its own particle set. The conductor's vertex draws
/// light and lobe samples the mirror's does not, so the panel's samples differ and the figure
/// at α → 0 stays below 1 by the noise of either render.
///
/// # Errors
/// A [`TracerError`] if a scene does not build or render (not expected).
pub fn alpha_sweep(
    alphas: &[f64],
    size: [u32; 3],
    particles: f64,
) -> Result<Vec<f64>, TracerError> {
    let width = size[0] as usize;
    let in_reflector = |reflector| {
        render_panel_planned(
            PanelView::InMirror(reflector),
            GlintFootprints::All,
            size,
            particles,
            Some(SWEEP_PLANNED_AREA),
        )
        .map(|image| detail(&image, width))
    };
    let mirror = in_reflector(Reflector::Mirror)?;
    alphas
        .iter()
        .map(|&alpha| {
            Ok(correlation(
                &in_reflector(Reflector::Conductor { alpha })?,
                &mirror,
            ))
        })
        .collect()
}
