//! The tracer's limits on what it reads: magnitudes, sizes and counts, each checked where the
//! value enters (scene file, asset, command line), so that work and memory are bounded by
//! construction and no accepted value overflows later. `scenes/README.md` ("Limits") lists them
//! for scene authors; each constant here says why it has its value.

use std::io::Read;
use std::path::Path;

/// The largest magnitude of a scene coordinate (positions, centres, edge vectors, radii,
/// translations and mesh vertices after their transform), in scene units.
///
/// The highest-degree products of coordinates the tracer forms are fourth powers (a
/// rectangle's squared area |u × v|², the footprint's normal equations (∂p/∂u·∂p/∂u)(∂p/∂v·∂p/∂v)):
/// at 10¹⁵ they stay below 10⁶², and light densities (squared distances over areas) alike, far
/// from the double-precision overflow at 1.8·10³⁰⁸. Beyond 10¹⁵ a unit-sized object could not
/// be placed anyway: doubles there are 0.125 apart. (The BVH itself builds for any finite
/// coordinates: see [`crate::accel`].)
pub const MAX_COORDINATE: f64 = 1e15;

/// The smallest radius of a sphere (shape or light), in scene units.
///
/// A sphere light is sampled by the cone it subtends, of solid angle about π(r/d)². Within
/// [`MAX_COORDINATE`] a point is at most d ≈ 3.5·10¹⁵ from a centre, so r ≥ 10⁻⁹ keeps (r/d)² ≥
/// 8·10⁻⁵⁰, a normal double: the light is always seen. A radius of 10⁻¹⁷⁰ squared underflows to
/// 0, a cone of no width, and the light vanished from the image without a word.
pub const MIN_RADIUS: f64 = 1e-9;

/// The largest emitted radiance (W·m⁻²·sr⁻¹, per channel, after converting a light's power)
/// and the largest irradiance of a directional light (W·m⁻²).
///
/// 10¹³ times the Sun's radiance (about 2·10⁷), and ten orders of magnitude below
/// [`MAX_SAMPLE_RADIANCE`]: room for the estimator's gains (inverse densities, glint f̂, mix
/// weights) before a sample is clamped.
pub const MAX_EMISSION: f64 = 1e20;

/// The largest radiance a pixel sample may carry (per channel); larger samples are clamped to
/// it and non-finite ones discarded, each counted in [`crate::RenderStatistics`] and reported.
///
/// A pixel is a mean of samples, so it is at most this too; and the sum of every pixel of the
/// largest image (16384² ≈ 2.7·10⁸ pixels) stays below the single-precision maximum
/// (3.4·10³⁸) of the EXR the image is written to: 3.4·10³⁸ / 2.7·10⁸ ≈ 1.3·10³⁰.
pub const MAX_SAMPLE_RADIANCE: f64 = 1e30;

/// The largest albedo (a diffuse colour, a plastic base, texels times tint): a surface cannot
/// reflect more light than reaches it.
pub const MAX_ALBEDO: f64 = 1.0;

/// The largest weight of a mix component: f = Σ w_k f_k, so a component contributes at most its
/// own BRDF. (The sum may exceed 1, as for the paper's diffuse base under a glint layer.)
pub const MAX_MIX_WEIGHT: f64 = 1.0;

/// The deepest nesting of mixes (a mix of mixes of …): materials are evaluated recursively.
pub const MAX_MIX_DEPTH: usize = 16;

/// The most material parts one scene builds (each diffuse, conductor, plastic, glint or mix
/// counts once per use inside a mix): a mix may name another several times, and mixes of mixes
/// would otherwise build exponentially many parts. A glint part costs 2–40 ms to build (with
/// its negligible-query test), so 256 parts build in at most about 10 s; the scenes here use
/// fewer than 60.
pub const MAX_MATERIAL_PARTS: usize = 256;

/// The most primitives (spheres, rectangles, area lights and mesh triangles) in one scene:
/// 2²⁴ ≈ 1.7·10⁷, about 2 GB with their meshes and BVH.
pub const MAX_PRIMITIVES: usize = 1 << 24;

/// The largest width or height of an image read (texture, environment map): the render's own
/// limit.
pub const MAX_IMAGE_SIDE: usize = 16384;

/// The most pixels of one image read: 2²⁶ (8192 × 8192, a production texture), 1.6 GB once
/// decoded to linear RGB doubles (freed once its glint map is built). Checked against the
/// file's header before anything is allocated.
pub const MAX_IMAGE_PIXELS: usize = 1 << 26;

/// The most pixels of all images one scene reads together: two images of the largest size
/// (or eight of 4096 × 4096), 3.2 GB decoded.
pub const MAX_SCENE_PIXELS: usize = 1 << 27;

/// The largest scene file read: 16 MiB, far more than a scene of hand-written shapes needs.
pub const MAX_SCENE_FILE_BYTES: u64 = 16 << 20;

/// The largest OBJ file read: 256 MiB, about 7·10⁶ triangles.
pub const MAX_MESH_FILE_BYTES: u64 = 256 << 20;

/// The largest image file read: 512 MiB, which holds the largest image
/// ([`MAX_IMAGE_PIXELS`]) as uncompressed 32-bit RGBA EXR (268 MB) with room to spare.
pub const MAX_IMAGE_FILE_BYTES: u64 = 512 << 20;

/// The most bytes of assets one scene reads together: 1 GiB.
pub const MAX_SCENE_ASSET_BYTES: u64 = 1 << 30;

/// The longest piece of input an error message quotes (a name, a line of the file), in
/// characters; longer ones are cut with a note of their length.
pub const MAX_ECHO_CHARS: usize = 200;

/// A number for a message: as written between 10⁻⁴ and 10⁶, in scientific notation beyond (so
/// that 10³⁰⁰ is `1e300`, not 301 digits).
#[must_use]
pub fn number(x: f64) -> String {
    if x == 0.0 || !x.is_finite() || (1e-4..1e6).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// A vector for a message, its components as [`number`] writes them.
#[must_use]
pub fn vector(v: glam::DVec3) -> String {
    format!("[{}, {}, {}]", number(v.x), number(v.y), number(v.z))
}

/// `text` for quoting in an error: at most [`MAX_ECHO_CHARS`] characters, cut with a note of
/// the full length when longer.
#[must_use]
pub fn echo(text: &str) -> String {
    match text.char_indices().nth(MAX_ECHO_CHARS) {
        None => text.to_string(),
        Some((cut, _)) => format!(
            "{}… ({} characters in all)",
            &text[..cut],
            text.chars().count()
        ),
    }
}

/// A multi-line message that quotes input, bounded: each line cut by [`echo`], at most 12
/// lines.
#[must_use]
pub fn echo_lines(text: &str) -> String {
    const LINES: usize = 12;
    let mut out: Vec<String> = text.lines().take(LINES).map(echo).collect();
    let total = text.lines().count();
    if total > LINES {
        out.push(format!("… ({} more lines)", total - LINES));
    }
    out.join("\n")
}

/// The bytes of the regular file at `path`, of at most `max_bytes`.
///
/// # Errors
/// A description when the file is missing, is not a regular file (a device such as `/dev/zero`
/// or a FIFO, whose reading might never end, or a directory), is larger than `max_bytes`, or
/// cannot be read.
pub fn read_file(path: &Path, max_bytes: u64) -> Result<Vec<u8>, String> {
    // The kind of file is checked before opening it: opening a FIFO waits for a writer.
    let metadata = std::fs::metadata(path).map_err(|e| format!("cannot read it: {e}"))?;
    if !metadata.is_file() {
        return Err("not a regular file (a directory, device or FIFO): not read".into());
    }
    if metadata.len() > max_bytes {
        return Err(format!(
            "{} bytes, more than the limit of {max_bytes} bytes",
            metadata.len()
        ));
    }
    let file = std::fs::File::open(path).map_err(|e| format!("cannot read it: {e}"))?;
    // The file may have changed since: read one byte past the limit at most.
    let mut bytes = Vec::with_capacity(usize::try_from(metadata.len()).unwrap_or(0));
    file.take(max_bytes + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| format!("cannot read it: {e}"))?;
    if bytes.len() as u64 > max_bytes {
        return Err(format!(
            "more than the limit of {max_bytes} bytes (the file grew while read)"
        ));
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 2ⁿ as `scenes/README.md` writes a power of two: "2²⁶".
    fn power_of_two(value: u64) -> String {
        assert!(value.is_power_of_two(), "{value}");
        let digits = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
        let exponent: String = value
            .trailing_zeros()
            .to_string()
            .chars()
            .map(|d| digits[d.to_digit(10).unwrap() as usize])
            .collect();
        format!("2{exponent}")
    }

    /// The row of the Limits table of `scenes/README.md` whose first cell starts with `what`.
    fn limits_row(what: &str) -> &'static str {
        let readme = include_str!("../../../scenes/README.md");
        let table = &readme[readme.find("\n## Limits").expect("a Limits section")..];
        table
            .lines()
            .find(|line| line.starts_with(&format!("| {what}")))
            .unwrap_or_else(|| panic!("no row \"{what}\" in scenes/README.md's Limits"))
    }

    /// A tidy test: the Limits table of `scenes/README.md` states the limits these constants
    /// enforce (it said 2²⁴ and 2²⁶ pixels where the tracer read 2²⁶ and 2²⁷).
    #[test]
    fn the_scenes_readme_states_the_limits_the_tracer_enforces() {
        let side = (MAX_IMAGE_PIXELS as f64).sqrt() as usize;
        let image = limits_row("image file");
        for stated in [
            format!("{} MiB", MAX_IMAGE_FILE_BYTES >> 20),
            format!("≤ {MAX_IMAGE_SIDE} pixels a side"),
            format!(
                "≤ {} pixels ({side} × {side})",
                power_of_two(MAX_IMAGE_PIXELS as u64)
            ),
        ] {
            assert!(image.contains(&stated), "{stated:?} is not in {image:?}");
        }
        let assets = limits_row("all assets of a scene");
        for stated in [
            format!("{} GiB read", MAX_SCENE_ASSET_BYTES >> 30),
            format!("{} image pixels", power_of_two(MAX_SCENE_PIXELS as u64)),
        ] {
            assert!(assets.contains(&stated), "{stated:?} is not in {assets:?}");
        }
        let maps = limits_row("glint maps");
        let stated = format!("≤ {} GiB of tables", glint_brdf::MAX_MAP_BYTES >> 30);
        assert!(maps.contains(&stated), "{stated:?} is not in {maps:?}");
        for (what, stated) in [
            ("scene file", format!("{} MiB", MAX_SCENE_FILE_BYTES >> 20)),
            ("OBJ file", format!("{} MiB", MAX_MESH_FILE_BYTES >> 20)),
            (
                "primitives",
                format!("{} per scene", power_of_two(MAX_PRIMITIVES as u64)),
            ),
            (
                "echoed input",
                format!("{MAX_ECHO_CHARS} characters per quoted"),
            ),
        ] {
            let row = limits_row(what);
            assert!(row.contains(&stated), "{stated:?} is not in {row:?}");
        }
    }

    /// Quoted input is cut at MAX_ECHO_CHARS characters (not bytes: multi-byte characters are
    /// never split), with the full length noted; short input is unchanged.
    #[test]
    fn echoes_are_bounded() {
        assert_eq!(echo("short"), "short");
        assert_eq!(number(1e300), "1e300");
        assert_eq!(number(-2.5e-300), "-2.5e-300");
        assert_eq!(number(0.25), "0.25");
        assert_eq!(number(f64::NAN), "NaN");
        assert_eq!(vector(glam::DVec3::new(1e15, 1.0, 0.0)), "[1e15, 1, 0]");
        let long = "é".repeat(100_000);
        let cut = echo(&long);
        assert!(cut.chars().count() < MAX_ECHO_CHARS + 40, "{}", cut.len());
        assert!(cut.ends_with("(100000 characters in all)"));
        let many = "x\n".repeat(1000);
        assert_eq!(echo_lines(&many).lines().count(), 13);
        let wide = format!("a\n{}\nb", "[".repeat(100_000));
        assert!(echo_lines(&wide).len() < 2 * MAX_ECHO_CHARS + 80);
    }

    /// Only regular files within the limit are read: a device that never ends, a directory, a
    /// file one byte too large are refused before reading.
    #[test]
    fn only_bounded_regular_files_are_read() {
        let dir = std::env::temp_dir().join(format!("glint-limits-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("ten.bin");
        std::fs::write(&path, [7u8; 10]).unwrap();
        assert_eq!(read_file(&path, 10).unwrap(), [7u8; 10]);
        assert!(
            read_file(&path, 9)
                .unwrap_err()
                .contains("more than the limit")
        );
        assert!(
            read_file(&dir, 100)
                .unwrap_err()
                .contains("not a regular file")
        );
        if Path::new("/dev/zero").exists() {
            assert!(
                read_file(Path::new("/dev/zero"), 1 << 30)
                    .unwrap_err()
                    .contains("not a regular file")
            );
        }
        assert!(read_file(&dir.join("missing"), 10).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
