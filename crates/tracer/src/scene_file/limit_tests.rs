//! Tests of the limits of every section, probed through one template scene whose values are
//! slots: a value is accepted exactly within its documented limit, an accepted scene renders to
//! finite pixels, and a refused one gets an error naming its field and the problem.

use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::path::Path;

use glint_brdf::Fresnel;
use proptest::prelude::*;

use crate::error::TracerError;
use crate::fuzz::{Fixture, render_tiny};
use crate::limits;
use crate::scene_file::{load_scene, parse_scene};

/// A scene whose values are slots: `{center}`, `{radius}`, `{u}`, `{scale}`, `{translate}`,
/// `{position}`, `{power}`, `{light_radius}`, `{radiance}`, `{irradiance}`, `{env}`,
/// `{env_scale}`, `{albedo}`, `{weight}`, `{obj_x}`, `{uv_scale}`, `{eta}`, `{k}`,
/// `{mirror_colour}`, `{mirror_eta}`.
const TEMPLATE: &str = r#"
[render]
integrator = "path"
max_depth = 3
[camera]
position = [{position}, 1, 4]
look_at = [0, 0, 0]
[materials.white]
type = "diffuse"
colour = {albedo}
[materials.sparkle]
type = "glint"
alpha = 0.2
particles = 1e6
gamma = 2
negligible_count = 0
uv_scale = {uv_scale}
fresnel = { type = "conductor", eta = {eta}, k = {k} }
[materials.shiny]
type = "mirror"
colour = [0.9, {mirror_colour}, 0.8]
fresnel = { type = "dielectric", eta = {mirror_eta} }
[materials.both]
type = "mix"
components = [{ material = "white", weight = {weight} }, { material = "sparkle", weight = 0.5 }]
[[shapes]]
type = "sphere"
center = [{center}, 0, 0]
radius = {radius}
material = "both"
[[shapes]]
type = "rectangle"
center = [0, -1, 0]
u = [{u}, 0, 0]
v = [0, 0, -8]
material = "white"
[[shapes]]
type = "mesh"
file = "mesh.obj"
material = "both"
transform = { scale = {scale}, translate = [{translate}, 0, 0] }
[[shapes]]
type = "rectangle"
center = [0, 0, -3]
u = [3, 0, 0]
v = [0, 3, 0]
material = "shiny"
[[lights]]
type = "sphere"
center = [1, 2, 1]
radius = {light_radius}
power = {power}
[[lights]]
type = "rectangle"
center = [0, 3, 0]
u = [1, 0, 0]
v = [0, 0, 1]
radiance = {radiance}
[[lights]]
type = "directional"
direction = [0, 1, 0.3]
irradiance = {irradiance}
[[lights]]
type = "environment"
radiance = {env}
scale = {env_scale}
"#;

const SLOTS: [&str; 20] = [
    "center",
    "radius",
    "u",
    "scale",
    "translate",
    "position",
    "power",
    "light_radius",
    "radiance",
    "irradiance",
    "env",
    "env_scale",
    "albedo",
    "weight",
    "obj_x",
    "uv_scale",
    "eta",
    "k",
    "mirror_colour",
    "mirror_eta",
];

/// Ordinary values for every slot.
fn ordinary(slot: &str) -> f64 {
    match slot {
        "radius" | "scale" | "albedo" | "weight" | "env" | "env_scale" | "eta" => 0.5,
        "uv_scale" => 1.0,
        "k" => 3.0,
        "mirror_colour" => 0.9,
        "mirror_eta" => 1.5,
        "u" => 8.0,
        "light_radius" => 0.1,
        "power" => 10.0,
        "radiance" | "irradiance" => 2.0,
        _ => 0.25,
    }
}

/// The scene with `values` in its slots and the mesh beside it, written in the fixture.
fn scene(fixture: &Fixture, values: &BTreeMap<&str, f64>) -> String {
    let number = |x: f64| {
        if x.is_nan() {
            "nan".to_string()
        } else if x.is_infinite() {
            if x > 0.0 { "inf" } else { "-inf" }.to_string()
        } else {
            format!("{x:e}")
        }
    };
    std::fs::write(
        fixture.dir.join("mesh.obj"),
        format!(
            "v {} 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\n",
            number(values["obj_x"])
        ),
    )
    .unwrap();
    let mut text = TEMPLATE.to_string();
    for slot in SLOTS {
        text = text.replace(&format!("{{{slot}}}"), &number(values[slot]));
    }
    text
}

fn error_in(fixture: &Fixture, values: &BTreeMap<&str, f64>) -> (String, String) {
    match parse_scene(&scene(fixture, values), &fixture.scene_path()) {
        Err(TracerError::Scene { field, problem, .. }) => (field, problem),
        Err(other) => panic!("{other}"),
        Ok(_) => panic!("accepted {values:?}"),
    }
}

/// Each (slot, value, field, words): the scene with `value` in `slot` is refused, naming
/// `field`, with a problem containing `words`.
fn assert_slot_errors(fixture: &Fixture, cases: &[(&str, f64, &str, &str)]) {
    for &(slot, value, field, words) in cases {
        let mut values = ordinary_values();
        values.insert(slot, value);
        let (f, problem) = error_in(fixture, &values);
        assert_eq!(f, field, "{slot} = {value}: {problem}");
        assert!(
            problem.contains(words),
            "{slot} = {value}: `{problem}` lacks `{words}`"
        );
    }
}

/// Each (from, to, field, words): `text` with `from` replaced by `to` is refused, naming
/// `field`, with a problem containing `words`.
fn assert_edit_errors(fixture: &Fixture, text: &str, cases: &[(&str, &str, &str, &str)]) {
    for &(from, to, field, words) in cases {
        assert!(text.contains(from), "{from}");
        match parse_scene(&text.replacen(from, to, 1), &fixture.scene_path()) {
            Err(TracerError::Scene {
                field: f, problem, ..
            }) => {
                assert_eq!(f, field, "{to}: {problem}");
                assert!(problem.contains(words), "{to}: `{problem}` lacks `{words}`");
            }
            other => panic!("{to}: {other:?}"),
        }
    }
}

fn ordinary_values() -> BTreeMap<&'static str, f64> {
    SLOTS.iter().map(|s| (*s, ordinary(s))).collect()
}

/// Whether `value` in `slot` is within the documented limits.
fn within_limits(slot: &str, value: f64) -> bool {
    let coordinate = value.abs() <= limits::MAX_COORDINATE;
    match slot {
        // The rectangle's area 8|u| must square to a positive double.
        "u" => coordinate && (8.0 * value).powi(2) > 0.0,
        "radius" | "light_radius" => (limits::MIN_RADIUS..=limits::MAX_COORDINATE).contains(&value),
        "scale" => coordinate && value != 0.0,
        "albedo" | "mirror_colour" => (0.0..=limits::MAX_ALBEDO).contains(&value),
        // Any positive scale: a footprint beyond ±10¹⁵ texture units is shaded smooth.
        "uv_scale" => value > 0.0 && value.is_finite(),
        "eta" | "mirror_eta" => (Fresnel::MIN_ETA..=Fresnel::MAX_ETA).contains(&value),
        "k" => (0.0..=Fresnel::MAX_K).contains(&value),
        "weight" => (0.0..=limits::MAX_MIX_WEIGHT).contains(&value),
        // Power P over a sphere of radius 0.1: radiance P/(4π²·0.01).
        "power" => value >= 0.0 && value / (4.0 * PI * PI * 0.01) <= limits::MAX_EMISSION,
        "radiance" | "irradiance" => (0.0..=limits::MAX_EMISSION).contains(&value),
        // The environment's radiance times its scale (the other at 0.5).
        "env" | "env_scale" => value >= 0.0 && value * 0.5 <= limits::MAX_EMISSION,
        // The mesh's vertex, scaled by 0.5.
        _ => coordinate,
    }
}

/// A number of any magnitude from 10⁻³⁰⁸ to 10³⁰⁸, either sign, or zero, NaN, infinity.
fn any_number() -> impl Strategy<Value = f64> {
    prop_oneof![
        8 => (any::<bool>(), 1.0..10.0f64, -308i32..=307).prop_map(|(negative, m, e)| {
            let x = m * 10f64.powi(e);
            if negative { -x } else { x }
        }),
        1 => prop_oneof![Just(0.0), Just(f64::NAN), Just(f64::INFINITY), Just(f64::MAX)],
    ]
}

proptest! {
    #![proptest_config(crate::fuzz::config(64))]

    /// Any value of any magnitude up to 10³⁰⁸ in a coordinate, length, power, radiance,
    /// irradiance, albedo or mix weight: the scene is accepted exactly when the value is
    /// within its documented limit, and an accepted scene renders to finite, non-negative
    /// pixels no larger than the film's cap (path tracing, glints and a mix included).
    #[test]
    fn values_are_accepted_within_their_limits_and_render_finite(
        slot in proptest::sample::select(SLOTS.to_vec()),
        value in any_number(),
    ) {
        let fixture = Fixture::new("limits-property");
        let mut values = ordinary_values();
        values.insert(slot, value);
        let text = scene(&fixture, &values);
        let result = render_tiny(&fixture, &text, 0.0);
        prop_assert_eq!(
            result.is_ok(),
            within_limits(slot, value),
            "{} = {}: {:?}",
            slot,
            value,
            result.err()
        );
    }
}

/// Values that slipped through: a mirror colour of NaN, η and k of 10³⁰⁰ (glint-brdf's
/// Fresnel range is every interface's), particles above 2⁵³ (the tree's limit), a
/// keyframe repeating another's frame: each an error naming its field; a footprint_scale
/// of 10³⁰⁰ is named in a short message with the range (not 301 digits).
#[test]
fn slipped_values_are_named_errors() {
    let fixture = Fixture::new("limits-slipped");
    assert_slot_errors(
        &fixture,
        &[
            (
                "mirror_colour",
                f64::NAN,
                "materials.shiny.colour",
                "reflectance factor components must be in [0, 1], got [0.9, NaN, 0.8]",
            ),
            (
                "eta",
                1e300,
                "materials.sparkle.fresnel.eta",
                "Fresnel eta = 1e300",
            ),
            ("eta", 0.0, "materials.sparkle.fresnel.eta", "[1e-3, 1e3]"),
            (
                "k",
                1001.0,
                "materials.sparkle.fresnel.k",
                "Fresnel k = 1001.0",
            ),
            (
                "mirror_eta",
                1e-4,
                "materials.shiny.fresnel.eta",
                "[1e-3, 1e3]",
            ),
            (
                "uv_scale",
                0.0,
                "materials.sparkle.uv_scale",
                "positive and finite",
            ),
            (
                "uv_scale",
                f64::NAN,
                "materials.sparkle.uv_scale",
                "positive and finite",
            ),
        ],
    );
    let text = scene(&fixture, &ordinary_values());
    assert_edit_errors(
        &fixture,
        &text,
        &[
            (
                "particles = 1e6",
                "particles = 9007199254740994",
                "materials.sparkle.particles",
                "must be a whole number in [1, 2^53]",
            ),
            (
                "look_at = [0, 0, 0]\n",
                "look_at = [0, 0, 0]\n[[camera.keyframes]]\nframe = 3\n[[camera.keyframes]]\nframe = 1\n[[camera.keyframes]]\nframe = 3.0\n",
                "camera.keyframes[2].frame",
                "frame 3 is also camera.keyframes[0]'s",
            ),
            (
                "max_depth = 3\n",
                "max_depth = 3\nfootprint_scale = 1e300\n",
                "render.footprint_scale",
                "1e300 must be in (0, 1e6] pixels",
            ),
        ],
    );
}

/// A glint material with `uv_scale` = 10³⁰⁰ (footprints of 10²⁹⁸ texture units, beyond
/// the ±10¹⁵ a footprint may span) shades its smooth limit: no sample is discarded (every
/// one was, and the image was black), the floor is lit, and every scale beyond the limit
/// gives the same image.
#[test]
fn a_huge_uv_scale_shades_the_smooth_limit() {
    let fixture = Fixture::new("limits-uv-scale");
    let image = |uv_scale: f64| {
        let mut values = ordinary_values();
        values.insert("uv_scale", uv_scale);
        render_tiny(&fixture, &scene(&fixture, &values), 0.0).unwrap()
    };
    let huge = image(1e300);
    assert!(huge.mean().max_element() > 0.0);
    assert_eq!(huge.pixels, image(1e200).pixels);
    assert_eq!(huge.pixels, image(f64::MAX).pixels);
}

/// Coordinates beyond ±10¹⁵ (the reported inputs: a sphere of radius 10²⁰⁰, a centre at
/// 10³⁰⁰, a transform scaling by 10³⁰⁰, an OBJ vertex at 3·10³⁸) are errors naming the file
/// and the field, and for an OBJ the vertex.
#[test]
fn huge_coordinates_are_named_errors() {
    let fixture = Fixture::new("limits-coordinates");
    for (slot, value, field, words) in [
        ("radius", 1e200, "shapes[0].radius", "must be in"),
        ("center", 1e300, "shapes[0].center", "within ±1e15"),
        ("u", 1e16, "shapes[1].u", "within ±1e15"),
        ("position", 2e15, "camera.position", "within ±1e15"),
        ("scale", 1e300, "shapes[2].transform.scale", "within ±1e15"),
        (
            "translate",
            1e16,
            "shapes[2].transform.translate",
            "within ±1e15",
        ),
        ("scale", 1e14, "shapes[2].transform", "after the transform"),
        ("obj_x", 3e38, "shapes[2].file", "v 1 (line 1)"),
        ("obj_x", -3e38, "shapes[2].file", "mesh.obj"),
    ] {
        let mut values = ordinary_values();
        values.insert(slot, value);
        if slot == "scale" && value == 1e14 {
            values.insert("obj_x", 100.0);
        }
        let (f, problem) = error_in(&fixture, &values);
        assert_eq!(f, field, "{slot} = {value}: {problem}");
        assert!(
            problem.contains(words),
            "{slot} = {value}: `{problem}` lacks `{words}`"
        );
    }
}

/// Light values that overflowed to infinite pixels are errors naming the field; an albedo
/// above 1 and a mix weight above 1 too; a sphere light too small to be seen is refused.
#[test]
fn light_and_reflectance_values_are_bounded() {
    let fixture = Fixture::new("limits-light");
    assert_slot_errors(
        &fixture,
        &[
            (
                "power",
                1e300,
                "lights[0].power",
                "lower the power or enlarge the light",
            ),
            ("radiance", 1e300, "lights[1].radiance", "[0, 1e20]"),
            ("irradiance", 1e21, "lights[2].irradiance", "[0, 1e20]"),
            ("env", 1e300, "lights[3].radiance", "times scale"),
            ("env_scale", 1e300, "lights[3].radiance", "times scale"),
            (
                "albedo",
                5.0,
                "materials.white.colour",
                "albedo components must be in [0, 1]",
            ),
            (
                "weight",
                2.0,
                "materials.both.components[0].weight",
                "must be in [0, 1]",
            ),
            (
                "light_radius",
                1e-170,
                "lights[0].radius",
                "must be in [1e-9",
            ),
        ],
    );
}

/// Mistakes inside sections are named by their field: a short array, an unknown material
/// in a mix component, a type that does not exist.
#[test]
fn errors_name_the_field_inside_sections() {
    let fixture = Fixture::new("limits-fields");
    let text = scene(&fixture, &ordinary_values());
    assert_edit_errors(
        &fixture,
        &text,
        &[
            (
                "center = [2.5e-1, 0, 0]",
                "center = [0.25, 0]",
                "shapes[0].center",
                "invalid length 2",
            ),
            (
                "{ material = \"white\", weight",
                "{ material = \"chalk\", weight",
                "materials.both.components[0].material",
                "unknown material `chalk`",
            ),
            (
                "weight = 0.5 }",
                "weight = \"half\" }",
                "materials.both.components[1].weight",
                "invalid type",
            ),
            (
                "colour = 5e-1",
                "colour = [0.5, 0.5]",
                "materials.white.colour",
                "a number or an array of 3 numbers",
            ),
            (
                "type = \"directional\"",
                "type = \"spot\"",
                "lights[2].type",
                "unknown type `spot`",
            ),
            (
                "transform = { scale",
                "transform = { skew = 1, scale",
                "shapes[2].transform",
                "unknown field `skew`",
            ),
        ],
    );
}

/// Input quoted in errors is bounded: a TOML nested 10⁵ deep, a material name of 10⁶
/// characters, an unknown field of 10⁶ characters give messages of at most a few hundred
/// characters.
#[test]
fn echoed_input_is_bounded() {
    let fixture = Fixture::new("limits-echo");
    let deep = format!("a = {}{}", "[".repeat(100_000), "]".repeat(100_000));
    let long_name = "m".repeat(1_000_000);
    let text = scene(&fixture, &ordinary_values());
    for input in [
        deep,
        text.replacen(
            "material = \"both\"",
            &format!("material = \"{long_name}\""),
            1,
        ),
        text.replacen("[render]", &format!("[render]\n{long_name} = 1"), 1),
    ] {
        let message = parse_scene(&input, &fixture.scene_path())
            .unwrap_err()
            .to_string();
        assert!(message.len() < 2000, "{} characters", message.len());
    }
}

/// Work is bounded by construction: mixes nested deeper than 16 levels, and mixes of mixes
/// that would build exponentially many parts (each naming the previous twice) are errors.
#[test]
fn mix_nesting_and_expansion_are_bounded() {
    let fixture = Fixture::new("limits-mix");
    let chain = |width: usize, depth: usize| {
        let mut text = String::from(
            "[camera]\nposition = [0, 1, 3]\nlook_at = [0, 0, 0]\n[materials.m0]\ntype = \"diffuse\"\n",
        );
        for level in 1..=depth {
            let parts = vec![format!("{{ material = \"m{}\", weight = 0.5 }}", level - 1); width];
            text += &format!(
                "[materials.m{level}]\ntype = \"mix\"\ncomponents = [{}]\n",
                parts.join(", ")
            );
        }
        text + &format!(
            "[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m{depth}\"\n[[lights]]\ntype = \"directional\"\ndirection = [0, 1, 0]\nirradiance = 1\n"
        )
    };
    assert!(parse_scene(&chain(1, 15), &fixture.scene_path()).is_ok());
    let deep = parse_scene(&chain(1, 40), &fixture.scene_path()).unwrap_err();
    assert!(deep.to_string().contains("nest deeper than 16"), "{deep}");
    let wide = parse_scene(&chain(2, 12), &fixture.scene_path()).unwrap_err();
    assert!(wide.to_string().contains("material parts"), "{wide}");
}

/// A mesh read from a device (`/dev/zero`, which never ends) or a directory is refused
/// before reading, naming the field and the file.
#[test]
fn assets_must_be_bounded_regular_files() {
    let fixture = Fixture::new("limits-assets");
    let text = scene(&fixture, &ordinary_values());
    for file in ["/dev/zero", "."] {
        if !Path::new(file).exists() {
            continue;
        }
        let changed = text.replacen("file = \"mesh.obj\"", &format!("file = \"{file}\""), 1);
        let (field, problem) = match parse_scene(&changed, &fixture.scene_path()) {
            Err(TracerError::Scene { field, problem, .. }) => (field, problem),
            other => panic!("{file}: {other:?}"),
        };
        assert_eq!(field, "shapes[2].file");
        assert!(problem.contains("not a regular file"), "{problem}");
    }
    let missing = load_scene(Path::new("/dev/zero")).unwrap_err().to_string();
    assert!(missing.contains("not a regular file"), "{missing}");
}
