//! Fuzz targets that run in `cargo test`: proptest with a fixed seed (deterministic), tiny
//! inputs and renders (bounded time by construction). Each feeds mutated input to one way in
//! (scene files, OBJ text, PNG and EXR bytes) and asserts that nothing panics, that an error is
//! an error value, and that what is accepted is within the limits and renders to finite,
//! non-negative pixels. The class tests beside the code (`limits`, `accel`, `scene_file`, …)
//! state each limit; these look for what they missed.

use std::path::{Path, PathBuf};

use glam::DVec3;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};

use crate::error::TracerError;
use crate::image::RgbImage;
use crate::limits;
use crate::mesh::Mesh;
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
/// [`limits::MAX_SAMPLE_RADIANCE`], and no sample of which may be non-finite (a discarded
/// sample is a NaN or an overflow that an accepted value let through).
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
    assert_eq!(
        output.statistics.discarded_samples, 0,
        "non-finite samples from\n{text}"
    );
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

/// The scene files of `scenes/`, with their relative weight in the fuzzing (the twisted tori
/// build 16 glint materials each, about 0.5 s).
const SCENES: &[(&str, &str, u32)] = &[
    (
        "sphere_lights.toml",
        include_str!("../../../scenes/sphere_lights.toml"),
        4,
    ),
    (
        "glitter_object.toml",
        include_str!("../../../scenes/glitter_object.toml"),
        4,
    ),
    (
        "glitter_mirror.toml",
        include_str!("../../../scenes/glitter_mirror.toml"),
        2,
    ),
    (
        "glitter_polished.toml",
        include_str!("../../../scenes/glitter_polished.toml"),
        2,
    ),
    (
        "stained_glass.toml",
        include_str!("../../../scenes/stained_glass.toml"),
        3,
    ),
    (
        "stained_glass_closeup.toml",
        include_str!("../../../scenes/stained_glass_closeup.toml"),
        1,
    ),
    (
        "ornaments.toml",
        include_str!("../../../scenes/ornaments.toml"),
        2,
    ),
    (
        "twisted_torus.toml",
        include_str!("../../../scenes/twisted_torus.toml"),
        1,
    ),
    (
        "twisted_torus_coloured.toml",
        include_str!("../../../scenes/twisted_torus_coloured.toml"),
        1,
    ),
];

/// Extreme and boundary numbers: zeros, the smallest and largest doubles, the limits and just
/// beyond them, NaN and infinities, large integers.
fn extreme() -> impl Strategy<Value = toml::Value> {
    let floats = [
        0.0,
        -0.0,
        5e-324,
        1e-308,
        -1e-308,
        1e-170,
        1e-9,
        9.9e-10,
        0.5,
        1.0,
        1.0000001,
        2.0,
        -1.0,
        5.0,
        60.0,
        180.0,
        1e15,
        1.01e15,
        1e16,
        1e20,
        1.01e20,
        1e30,
        3e38,
        1e200,
        1e300,
        -1e300,
        1e308,
        f64::MAX,
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ];
    let integers = [0i64, -1, 1, 3, 65_537, 4_294_967_295, i64::MAX, i64::MIN];
    prop_oneof![
        4 => proptest::sample::select(floats.to_vec()).prop_map(toml::Value::Float),
        1 => proptest::sample::select(integers.to_vec()).prop_map(toml::Value::Integer),
    ]
}

/// One step of a path into a TOML document.
#[derive(Clone, Debug)]
enum Step {
    Key(String),
    Index(usize),
}

/// The paths to every value in `value` (tables and arrays included), depth first.
fn paths(value: &toml::Value, prefix: &mut Vec<Step>, out: &mut Vec<Vec<Step>>) {
    out.push(prefix.clone());
    match value {
        toml::Value::Table(table) => {
            for (key, v) in table {
                prefix.push(Step::Key(key.clone()));
                paths(v, prefix, out);
                prefix.pop();
            }
        }
        toml::Value::Array(array) => {
            for (i, v) in array.iter().enumerate() {
                prefix.push(Step::Index(i));
                paths(v, prefix, out);
                prefix.pop();
            }
        }
        _ => {}
    }
}

fn get<'a>(value: &'a toml::Value, path: &[Step]) -> &'a toml::Value {
    path.iter().fold(value, |v, step| match (step, v) {
        (Step::Key(k), toml::Value::Table(t)) => &t[k],
        (Step::Index(i), toml::Value::Array(a)) => &a[*i],
        _ => unreachable!("paths come from the same document"),
    })
}

fn at<'a>(value: &'a mut toml::Value, path: &[Step]) -> &'a mut toml::Value {
    path.iter().fold(value, |v, step| match (step, v) {
        (Step::Key(k), toml::Value::Table(t)) => t.get_mut(k).unwrap(),
        (Step::Index(i), toml::Value::Array(a)) => &mut a[*i],
        _ => unreachable!("paths come from the same document"),
    })
}

/// A mutation of a scene document.
#[derive(Clone, Debug)]
enum Mutation {
    /// Replace a number (or any value) by an extreme number.
    Number(usize, toml::Value),
    /// Remove a key or an array element.
    Remove(usize),
    /// Duplicate an array element (another shape, light, keyframe, component).
    Duplicate(usize),
    /// Replace a value by a string.
    Text(usize, String),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let strings = prop_oneof![
        Just(String::new()),
        Just("/dev/zero".to_string()),
        Just("assets".to_string()),
        Just("assets/sky.png".to_string()),
        Just("assets/vase.obj".to_string()),
        Just("red".to_string()),
        Just("glint".to_string()),
        Just("mix".to_string()),
        Just("x".repeat(300)),
    ];
    prop_oneof![
        6 => (any::<usize>(), extreme()).prop_map(|(i, v)| Mutation::Number(i, v)),
        2 => any::<usize>().prop_map(Mutation::Remove),
        1 => any::<usize>().prop_map(Mutation::Duplicate),
        1 => (any::<usize>(), strings).prop_map(|(i, s)| Mutation::Text(i, s)),
    ]
}

/// `document` with `mutation` applied (numbers are preferred as targets of `Number`).
fn mutate(document: &mut toml::Value, mutation: &Mutation) {
    let mut all = Vec::new();
    paths(document, &mut Vec::new(), &mut all);
    let numbers: Vec<&Vec<Step>> = all
        .iter()
        .filter(|p| {
            matches!(
                get(document, p),
                toml::Value::Float(_) | toml::Value::Integer(_)
            )
        })
        .collect();
    match mutation {
        Mutation::Number(i, value) => {
            let path = if numbers.is_empty() {
                &all[i % all.len()]
            } else {
                numbers[i % numbers.len()]
            };
            *at(document, path) = value.clone();
        }
        Mutation::Remove(i) | Mutation::Duplicate(i) => {
            let path = &all[i % all.len()];
            let Some((last, parent)) = path.split_last() else {
                return;
            };
            match (at(document, parent), last) {
                (toml::Value::Table(t), Step::Key(k)) => {
                    if matches!(mutation, Mutation::Remove(_)) {
                        t.remove(k);
                    }
                }
                (toml::Value::Array(a), Step::Index(i)) => {
                    if matches!(mutation, Mutation::Remove(_)) {
                        a.remove(*i);
                    } else {
                        let copy = a[*i].clone();
                        a.push(copy);
                    }
                }
                _ => {}
            }
        }
        Mutation::Text(i, text) => {
            let path = &all[i % all.len()];
            if !path.is_empty() {
                *at(document, path) = toml::Value::String(text.clone());
            }
        }
    }
}

fn weighted_scene() -> impl Strategy<Value = usize> {
    let total: u32 = SCENES.iter().map(|s| s.2).sum();
    (0..total).prop_map(|mut x| {
        SCENES
            .iter()
            .position(|s| {
                if x < s.2 {
                    true
                } else {
                    x -= s.2;
                    false
                }
            })
            .unwrap()
    })
}

/// Replaces bytes (`flips`: position modulo the length, new value) and cuts the tail.
fn mutate_bytes(bytes: &mut Vec<u8>, flips: &[(usize, u8)], cut: Option<usize>) {
    for &(at, value) in flips {
        let n = bytes.len();
        if n > 0 {
            bytes[at % n] = value;
        }
    }
    if let Some(cut) = cut {
        let n = bytes.len();
        bytes.truncate(cut % (n + 1));
    }
}

/// One OBJ statement with extreme or ordinary numbers and any indices.
fn obj_line() -> impl Strategy<Value = String> {
    let number = prop_oneof![
        4 => (-2.0..2.0f64).prop_map(|x| format!("{x}")),
        1 => proptest::sample::select(vec![
            "nan", "inf", "-inf", "1e39", "3e38", "-3e38", "1e15", "1.1e15", "1e-45", "0", "-0",
            "x", "",
        ])
        .prop_map(str::to_string),
    ];
    let index = prop_oneof![
        4 => (1..8i64).prop_map(|i| i.to_string()),
        1 => proptest::sample::select(vec![0i64, -1, -9, 9, 4_294_967_296, i64::MAX])
            .prop_map(|i| i.to_string()),
    ];
    let corner = prop_oneof![
        index.clone(),
        (index.clone(), index.clone()).prop_map(|(a, b)| format!("{a}/{b}")),
        (index.clone(), index.clone(), index.clone()).prop_map(|(a, b, c)| format!("{a}/{b}/{c}")),
        (index.clone(), index.clone()).prop_map(|(a, c)| format!("{a}//{c}")),
    ];
    prop_oneof![
        4 => prop::collection::vec(number.clone(), 3).prop_map(|v| format!("v {}", v.join(" "))),
        1 => prop::collection::vec(number.clone(), 3).prop_map(|v| format!("vn {}", v.join(" "))),
        1 => prop::collection::vec(number.clone(), 2).prop_map(|v| format!("vt {}", v.join(" "))),
        3 => prop::collection::vec(corner, 1..6).prop_map(|v| format!("f {}", v.join(" "))),
        1 => proptest::sample::select(vec![
            "mtllib /dev/zero", "usemtl red", "o thing", "g group", "s 1", "# comment", "v 1",
            "vt", "f", "l 1 2", "\u{0}\u{ff}", "v 1 2 3 4", "v 1 2 3 0",
        ])
        .prop_map(str::to_string),
    ]
}

thread_local! {
    /// The small EXR, written once per thread.
    static EXR: Vec<u8> = {
        let dir = std::env::temp_dir().join(format!("glint-fuzz-exr-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let bytes = small_exr(&dir);
        let _ = std::fs::remove_dir_all(&dir);
        bytes
    };
}

proptest! {
    #![proptest_config(config(48))]

    /// The scene files of `scenes/` with one to four mutations (numbers replaced by extremes,
    /// keys removed, elements duplicated, values replaced by strings) and optionally bytes cut
    /// from the text: loading never panics, and an accepted scene renders (tiny) to finite,
    /// non-negative pixels, or reports a degenerate camera at the frame.
    #[test]
    fn mutated_scene_files_load_or_fail_cleanly(
        scene in weighted_scene(),
        mutations in prop::collection::vec(mutation(), 1..5),
        cut in prop::option::weighted(0.2, (any::<usize>(), 1..40usize)),
        frame in prop_oneof![Just(0.0), Just(7.5), Just(23.0), Just(-1e300)],
    ) {
        let fixture = Fixture::new("fuzz-scene");
        let (_, text, _) = SCENES[scene];
        let mut document = toml::Value::Table(toml::from_str(text).unwrap());
        for m in &mutations {
            mutate(&mut document, m);
        }
        let mut text = toml::to_string(&document).unwrap_or_default();
        if let Some((at, length)) = cut {
            let start = text.floor_char_boundary(at % text.len().max(1));
            let end = text.floor_char_boundary(start + length);
            text.replace_range(start..end, "");
        }
        match render_tiny(&fixture, &text, frame) {
            Ok(_) | Err(TracerError::Scene { .. } | TracerError::Camera { .. }) => {}
            Err(other) => prop_assert!(false, "unexpected error {other}"),
        }
    }

    /// OBJ text of random statements (positions, normals and texture coordinates with extreme
    /// numbers, faces with any indices, material libraries, garbage): parsing never panics; an
    /// accepted mesh has every vertex within the coordinate limit and finite attributes, and
    /// rays through it find finite hits.
    #[test]
    fn random_obj_text_parses_or_fails_cleanly(
        lines in prop::collection::vec(obj_line(), 0..40),
    ) {
        let text = lines.join("\n");
        if let Ok(mesh) = Mesh::from_obj_bytes(text.as_bytes(), Path::new("fuzz.obj")) {
            prop_assert!(mesh.validate().is_ok());
            let primitives = (0..mesh.triangles.len() as u32)
                .map(|triangle| crate::accel::Primitive {
                    geometry: crate::accel::Geometry::Triangle { mesh: 0, triangle },
                    material: 0,
                    light: None,
                })
                .collect();
            let accel = crate::accel::Accelerator::new(primitives, vec![mesh]);
            for direction in [DVec3::X, DVec3::new(0.3, -0.8, 0.52).normalize()] {
                let ray = crate::shape::Ray { origin: DVec3::new(-3.0, 2.0, 0.1), direction };
                if let Some(hit) = accel.intersect(&ray, f64::INFINITY) {
                    prop_assert!(hit.surface.point.is_finite() && hit.surface.t > 0.0);
                }
            }
        }
    }

    /// PNG bytes, valid ones mutated (bytes changed, cut short, the header's size replaced
    /// with or without a matching checksum): decoding never panics nor allocates beyond the
    /// limits, and an accepted image is within them with pixels in [0, 1].
    #[test]
    fn mutated_png_bytes_decode_or_fail_cleanly(
        (width, height) in (1..6u32, 1..5u32),
        size in prop::option::of((0..100_000u32, 0..100_000u32, any::<bool>())),
        flips in prop::collection::vec((any::<usize>(), any::<u8>()), 0..4),
        cut in prop::option::of(any::<usize>()),
    ) {
        let mut bytes = small_png(width, height);
        if let Some((w, h, fix_crc)) = size {
            patch_png_size(&mut bytes, w, h, fix_crc);
        }
        mutate_bytes(&mut bytes, &flips, cut);
        if let Ok(image) = RgbImage::from_png_bytes(&bytes) {
            prop_assert!(image.width <= limits::MAX_IMAGE_SIDE && image.height <= limits::MAX_IMAGE_SIDE);
            prop_assert_eq!(image.pixels.len(), image.width * image.height);
            prop_assert!(image.pixels.iter().all(|p| p.min_element() >= 0.0 && p.max_element() <= 1.0));
        }
    }

    /// EXR bytes, a valid file mutated (bytes changed, cut short, the data window enlarged):
    /// decoding never panics nor allocates beyond the limits, and an accepted image has finite
    /// pixels.
    #[test]
    fn mutated_exr_bytes_decode_or_fail_cleanly(
        window in prop::option::of((0..i32::MAX, 0..i32::MAX)),
        flips in prop::collection::vec((any::<usize>(), any::<u8>()), 0..4),
        cut in prop::option::of(any::<usize>()),
    ) {
        let bytes = EXR.with(|b| b.clone());
        let mut bytes = bytes;
        if let Some((x, y)) = window {
            patch_exr_data_window(&mut bytes, x, y);
        }
        mutate_bytes(&mut bytes, &flips, cut);
        if let Ok(image) = RgbImage::from_exr_bytes(&bytes) {
            prop_assert!(image.pixels.len() <= limits::MAX_IMAGE_PIXELS);
            prop_assert!(image.pixels.iter().all(|p| p.is_finite()));
        }
    }
}

/// The fixture's stand-in assets load, and every scene of `scenes/` renders with them (the
/// fuzz targets start from valid scenes).
#[test]
fn the_fuzzed_scenes_load_with_the_stand_in_assets() {
    let fixture = Fixture::new("fuzz-base");
    for (name, text, _) in SCENES {
        let image = render_tiny(&fixture, text, 0.0).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(image.pixels.len(), 24);
    }
}
