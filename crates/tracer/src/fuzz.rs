//! Test support shared by the tracer's property tests: the proptest configuration (a fixed
//! seed, deterministic) and small fixtures.

use std::path::Path;

use glam::DVec3;
use proptest::test_runner::{Config, RngSeed};

use crate::image::RgbImage;

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
