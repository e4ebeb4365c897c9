//! Test support shared by the tracer's property tests: the proptest configuration (a fixed
//! seed, deterministic) and small fixtures.

use std::path::{Path, PathBuf};

use glam::DVec3;
use proptest::test_runner::{Config, RngSeed};

use crate::error::TracerError;
use crate::image::RgbImage;
use crate::limits;
use crate::scene_file::parse_scene;

/// The proptest configuration of the tracer's property and fuzz tests: `cases` cases from a
/// fixed seed, no regression files. For a longer search, `GLINT_FUZZ_SCALE=k` runs k times the
/// cases and `GLINT_FUZZ_SEED=n` another seed (both deterministic).
pub(crate) fn config(cases: u32) -> Config {
    let from_env = |name: &str| std::env::var(name).ok().and_then(|v| v.parse::<u64>().ok());
    let scale = from_env("GLINT_FUZZ_SCALE").unwrap_or(1).clamp(1, 10_000) as u32;
    Config {
        cases: cases.saturating_mul(scale),
        rng_seed: RngSeed::Fixed(from_env("GLINT_FUZZ_SEED").unwrap_or(0x6c69_6e74)),
        failure_persistence: None,
        max_shrink_iters: 512,
        ..Config::default()
    }
}

/// CRC-32 (ISO-HDLC, the PNG chunk checksum), bit by bit.
pub(crate) fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xedb8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// Writes `width` × `height` into a PNG's IHDR (bytes 16..24), and its checksum when
/// `fix_crc` (else the decoder sees a damaged header).
pub(crate) fn patch_png_size(bytes: &mut [u8], width: u32, height: u32, fix_crc: bool) {
    bytes[16..20].copy_from_slice(&width.to_be_bytes());
    bytes[20..24].copy_from_slice(&height.to_be_bytes());
    if fix_crc {
        // The CRC covers the chunk type and data: bytes 12..29; it follows at 29..33.
        let crc = crc32(&bytes[12..29]);
        bytes[29..33].copy_from_slice(&crc.to_be_bytes());
    }
}

/// Sets an EXR header's data window to (0, 0)–(`x_max`, `y_max`).
pub(crate) fn patch_exr_data_window(bytes: &mut [u8], x_max: i32, y_max: i32) {
    let name = b"dataWindow\0box2i\0";
    let Some(at) = bytes.windows(name.len()).position(|w| w == name) else {
        return;
    };
    // Name, type, a 4-byte size (16), then x_min, y_min, x_max, y_max.
    let values = at + name.len() + 4;
    bytes[values..values + 4].copy_from_slice(&0i32.to_le_bytes());
    bytes[values + 4..values + 8].copy_from_slice(&0i32.to_le_bytes());
    bytes[values + 8..values + 12].copy_from_slice(&x_max.to_le_bytes());
    bytes[values + 12..values + 16].copy_from_slice(&y_max.to_le_bytes());
}

/// A small PNG: `width` × `height`, 8-bit RGB, a gradient.
pub(crate) fn small_png(width: u32, height: u32) -> Vec<u8> {
    let pixels = (0..width * height)
        .map(|i| {
            DVec3::new(
                f64::from(i % width) / f64::from(width),
                f64::from(i / width) / f64::from(height),
                0.5,
            )
        })
        .collect();
    RgbImage {
        width: width as usize,
        height: height as usize,
        pixels,
    }
    .encode_png(0.0)
    .unwrap()
}

/// A small EXR: 5 × 3 pixels with values from 0 to 4.
pub(crate) fn small_exr(dir: &Path) -> Vec<u8> {
    let pixels = (0..15)
        .map(|i| DVec3::new(f64::from(i) / 3.5, 0.25, f64::from(15 - i) / 4.0))
        .collect();
    let path = dir.join("small.exr");
    RgbImage {
        width: 5,
        height: 3,
        pixels,
    }
    .write_exr(&path)
    .unwrap();
    std::fs::read(&path).unwrap()
}

/// A small closed mesh with normals and texture coordinates (an octahedron).
pub(crate) const OCTAHEDRON_OBJ: &str = "\
v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1
vt 0 0\nvt 1 0\nvt 0.5 1
vn 1 0 0\nvn -1 0 0\nvn 0 1 0\nvn 0 -1 0\nvn 0 0 1\nvn 0 0 -1
f 1/1/1 3/2/3 5/3/5\nf 3/1/3 2/2/2 5/3/5\nf 2/1/2 4/2/4 5/3/5\nf 4/1/4 1/2/1 5/3/5
f 3/1/3 1/2/1 6/3/6\nf 2/1/2 3/2/3 6/3/6\nf 4/1/4 2/2/2 6/3/6\nf 1/1/1 4/2/4 6/3/6
";

/// A folder of its own under the temporary directory, with tiny stand-ins for the scenes'
/// assets (`assets/vase.obj`, `assets/twisted_torus.obj`, `assets/sky.png`,
/// `assets/stained_glass.png`), removed when dropped.
pub(crate) struct Fixture {
    pub(crate) dir: PathBuf,
}

impl Fixture {
    pub(crate) fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("glint-{name}-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("assets")).unwrap();
        for mesh in ["vase.obj", "twisted_torus.obj"] {
            std::fs::write(dir.join("assets").join(mesh), OCTAHEDRON_OBJ).unwrap();
        }
        std::fs::write(dir.join("assets/sky.png"), small_png(8, 4)).unwrap();
        std::fs::write(dir.join("assets/stained_glass.png"), small_png(3, 4)).unwrap();
        Self { dir }
    }

    pub(crate) fn scene_path(&self) -> PathBuf {
        self.dir.join("scene.toml")
    }
}

impl Drop for Fixture {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// Renders `text` as a scene beside the fixture's assets at 6 × 4 pixels, one sample, paths of
/// at most three bounces, at `frame`: `Err` when the scene (or the camera at `frame`) is
/// refused, else the image, whose every pixel must be finite, non-negative and at most
/// [`limits::MAX_SAMPLE_RADIANCE`].
pub(crate) fn render_tiny(
    fixture: &Fixture,
    text: &str,
    frame: f64,
) -> Result<RgbImage, TracerError> {
    let scene = parse_scene(text, &fixture.scene_path())?;
    let mut settings = scene.settings;
    settings.width = 6;
    settings.height = 4;
    settings.samples_per_pixel = 1;
    settings.max_depth = settings.max_depth.min(3);
    let output = crate::render(&scene, &settings, frame, &|_, _| {})?;
    for p in &output.image.pixels {
        assert!(
            p.is_finite()
                && p.min_element() >= 0.0
                && p.max_element() <= limits::MAX_SAMPLE_RADIANCE,
            "pixel {p} from\n{text}"
        );
    }
    Ok(output.image)
}
