//! `cargo xtask eval`: the model from any language, as JSON Lines (specified in `docs/eval.md`).
//!
//! Each input line is one request (`op` = `eval`, `sample` or `pdf`); each output line answers
//! it, in order. A line that is not valid JSON or holds invalid values yields
//! `{"error": "..."}` naming the problem; the run goes on and the exit status is non-zero.
//! Materials are built once per distinct `material` object and reused.
//!
//! Every answer goes through glint-brdf's public path: `eval` binds the material to the line's
//! footprint (`DiscreteBrdf::at`) and asks that BxDF for f̂, its statistics and the expected
//! count; `sample` and `pdf` use the material's glint sampler, which needs no footprint, and
//! weigh samples with the smooth BRDF.

use std::collections::HashMap;
use std::io::{BufRead, Write};

use anyhow::Context;
use glam::{DVec2, DVec3};
use glint_brdf::{
    Bxdf, BxdfSample, DiscreteBrdf, DistributionKind, Footprint, Fresnel, GlintParameters,
    Microfacet, MultinomialMode, QueryScratch,
};
use serde_json::{Map, Value, json};

/// Reads requests from `path` (or standard input) and writes answers to standard output.
/// Returns the number of failed lines.
pub(crate) fn run(path: Option<&std::path::Path>) -> anyhow::Result<usize> {
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let failed = match path {
        Some(path) => {
            let file =
                std::fs::File::open(path).with_context(|| format!("opening {}", path.display()))?;
            process(std::io::BufReader::new(file), &mut out)?
        }
        None => process(std::io::stdin().lock(), &mut out)?,
    };
    out.flush()?;
    Ok(failed)
}

/// Answers every line of `input` on `output`; returns how many lines failed.
pub(crate) fn process(input: impl BufRead, output: &mut impl Write) -> anyhow::Result<usize> {
    let mut evaluator = Evaluator::default();
    let mut failed = 0;
    for (number, line) in input.lines().enumerate() {
        let line = line.with_context(|| format!("reading line {}", number + 1))?;
        if line.trim().is_empty() {
            continue;
        }
        let answer = match evaluator.answer(&line) {
            Ok(value) => value,
            Err(message) => {
                failed += 1;
                json!({ "error": format!("line {}: {message}", number + 1) })
            }
        };
        writeln!(output, "{answer}")?;
    }
    Ok(failed)
}

#[derive(Default)]
struct Evaluator {
    materials: HashMap<String, (DiscreteBrdf, bool)>,
    scratch: QueryScratch,
}

type Answer = Result<Value, String>;

impl Evaluator {
    fn answer(&mut self, line: &str) -> Answer {
        let request: Value =
            serde_json::from_str(line).map_err(|e| format!("invalid JSON: {e}"))?;
        let request = request
            .as_object()
            .ok_or("a request must be a JSON object")?;
        let op = match request.get("op") {
            None => "eval",
            Some(Value::String(op)) => op.as_str(),
            Some(other) => return Err(format!("`op` must be a string, not {other}")),
        };
        if !matches!(op, "eval" | "sample" | "pdf") {
            return Err(format!("unknown op `{op}`: use eval, sample or pdf"));
        }
        let material = request.get("material").ok_or("missing field `material`")?;
        let key = material.to_string();
        if !self.materials.contains_key(&key) {
            let (parameters, gray) = parse_material(material)?;
            let brdf = DiscreteBrdf::new(parameters).map_err(|e| format!("material: {e}"))?;
            self.materials.insert(key.clone(), (brdf, gray));
        }
        let (brdf, gray) = &self.materials[&key];
        let colour = |c: DVec3| {
            if *gray {
                json!(c.x)
            } else {
                json!([c.x, c.y, c.z])
            }
        };
        let wi = direction(request, "wi")?;
        match op {
            "eval" => {
                let wo = direction(request, "wo")?;
                let footprint = Footprint::new(
                    vector2(request, "uv")?,
                    vector2(request, "duv_dx")?,
                    vector2(request, "duv_dy")?,
                )
                .map_err(|e| format!("footprint: {e}"))?;
                let bxdf = brdf.at(&footprint, &mut self.scratch);
                let e = bxdf.evaluate(wi, wo);
                let mut answer = json!({
                    "count": e.count,
                    "expected_count": bxdf.expected_count(wi, wo),
                    "d_hat": e.d_hat.x,
                    "f_hat": colour(e.f_hat),
                    "f_smooth": colour(brdf.smooth().eval(wi, wo)),
                    "nodes_visited": e.nodes_visited,
                });
                if let Some(bound) = e.negligible {
                    answer["negligible_bound"] = json!(bound);
                }
                Ok(answer)
            }
            "sample" => {
                let u = sample_uniforms(request)?;
                let sample = brdf.sample_direction(wi, u).and_then(|wo| {
                    BxdfSample::weighted(wo, brdf.smooth().eval(wi, wo), brdf.sampling_pdf(wi, wo))
                });
                Ok(match sample {
                    Some(s) => {
                        json!({ "wo": [s.wo.x, s.wo.y, s.wo.z], "pdf": s.pdf, "weight": colour(s.weight) })
                    }
                    None => json!({ "wo": null }),
                })
            }
            _ => {
                let wo = direction(request, "wo")?;
                Ok(json!({ "pdf": brdf.sampling_pdf(wi, wo) }))
            }
        }
    }
}

/// The material's parameters and whether its Fresnel term is gray.
fn parse_material(material: &Value) -> Result<(GlintParameters, bool), String> {
    let m = material.as_object().ok_or("`material` must be an object")?;
    const KNOWN: [&str; 12] = [
        "distribution",
        "alpha",
        "alpha_y",
        "particles",
        "gamma_deg",
        "epsilon",
        "seed",
        "fresnel",
        "multinomial",
        "expected_footprint_area",
        "pdf_points",
        "negligible_count",
    ];
    if let Some(unknown) = m.keys().find(|k| !KNOWN.contains(&k.as_str())) {
        return Err(format!(
            "unknown material field `{unknown}` (known: {})",
            KNOWN.join(", ")
        ));
    }
    let kind = match m.get("distribution").and_then(Value::as_str) {
        Some("beckmann") => DistributionKind::Beckmann,
        Some("ggx") => DistributionKind::Ggx,
        Some(other) => {
            return Err(format!(
                "material.distribution `{other}` is unknown: use beckmann or ggx"
            ));
        }
        None => return Err("material.distribution is missing: use beckmann or ggx".to_owned()),
    };
    let alpha = number(m, "alpha", "material.alpha")?;
    let alpha_y = optional_number(m, "alpha_y", "material.alpha_y")?.unwrap_or(alpha);
    let distribution =
        Microfacet::new(kind, alpha, alpha_y).map_err(|e| format!("material: {e}"))?;
    let mut parameters = GlintParameters::new(distribution);
    let particles = number(m, "particles", "material.particles")?;
    if !(particles >= 1.0 && particles.fract() == 0.0 && particles <= 9.007_199_254_740_992e15) {
        return Err(format!(
            "material.particles = {particles} must be a whole number in [1, 2^53]"
        ));
    }
    parameters.particles = particles as u64;
    parameters.gamma = number(m, "gamma_deg", "material.gamma_deg")?.to_radians();
    if let Some(epsilon) = optional_number(m, "epsilon", "material.epsilon")? {
        parameters.epsilon = epsilon;
    }
    if let Some(seed) = optional_number(m, "seed", "material.seed")? {
        if !(seed >= 0.0 && seed.fract() == 0.0 && seed < 1.8e19) {
            return Err(format!(
                "material.seed = {seed} must be a non-negative whole number"
            ));
        }
        parameters.seed = seed as u64;
    }
    if let Some(area) = optional_number(
        m,
        "expected_footprint_area",
        "material.expected_footprint_area",
    )? {
        parameters.expected_footprint_area = area;
    }
    if let Some(count) = optional_number(m, "negligible_count", "material.negligible_count")? {
        parameters.negligible_count = count;
    }
    if let Some(points) = optional_number(m, "pdf_points", "material.pdf_points")? {
        parameters.pdf_points = points as usize;
    }
    parameters.multinomial = match m.get("multinomial") {
        None => MultinomialMode::Exact,
        Some(Value::String(s)) if s == "exact" => MultinomialMode::Exact,
        Some(Value::String(s)) if s == "normal" => MultinomialMode::Normal,
        Some(other) => {
            return Err(format!(
                "material.multinomial {other} is unknown: use \"exact\" or \"normal\""
            ));
        }
    };
    parameters.fresnel = parse_fresnel(m.get("fresnel"))?;
    let gray = parameters.fresnel.is_gray();
    Ok((parameters, gray))
}

fn parse_fresnel(value: Option<&Value>) -> Result<Fresnel, String> {
    let fresnel = match value {
        None => Fresnel::None,
        Some(Value::String(s)) if s == "none" => Fresnel::None,
        Some(Value::Object(o)) if o.len() == 1 && o.contains_key("conductor") => {
            let c = o["conductor"]
                .as_object()
                .ok_or("material.fresnel.conductor must be an object")?;
            Fresnel::Conductor {
                eta: DVec3::from_array(numbers_in::<3>(
                    c,
                    "eta",
                    "material.fresnel.conductor.eta",
                )?),
                k: DVec3::from_array(numbers_in::<3>(c, "k", "material.fresnel.conductor.k")?),
            }
        }
        Some(Value::Object(o)) if o.len() == 1 && o.contains_key("dielectric") => {
            let d = o["dielectric"]
                .as_object()
                .ok_or("material.fresnel.dielectric must be an object")?;
            Fresnel::Dielectric {
                eta: number(d, "eta", "material.fresnel.dielectric.eta")?,
            }
        }
        Some(other) => {
            return Err(format!(
                "material.fresnel {other} is unknown: use \"none\", {{\"conductor\": {{\"eta\": [r,g,b], \"k\": [r,g,b]}}}} or {{\"dielectric\": {{\"eta\": x}}}}"
            ));
        }
    };
    fresnel.validated().map_err(|e| format!("material: {e}"))
}

fn number(object: &Map<String, Value>, key: &str, name: &str) -> Result<f64, String> {
    optional_number(object, key, name)?.ok_or_else(|| format!("{name} is missing"))
}

fn optional_number(
    object: &Map<String, Value>,
    key: &str,
    name: &str,
) -> Result<Option<f64>, String> {
    match object.get(key) {
        None => Ok(None),
        Some(value) => match value.as_f64() {
            Some(x) if x.is_finite() => Ok(Some(x)),
            _ => Err(format!("{name} must be a finite number, not {value}")),
        },
    }
}

fn numbers_in<const N: usize>(
    object: &Map<String, Value>,
    key: &str,
    name: &str,
) -> Result<[f64; N], String> {
    let array = object
        .get(key)
        .ok_or_else(|| format!("{name} is missing"))?
        .as_array()
        .filter(|a| a.len() == N)
        .ok_or_else(|| format!("{name} must be an array of {N} numbers"))?;
    let mut out = [0.0; N];
    for (slot, value) in out.iter_mut().zip(array) {
        *slot = value
            .as_f64()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("{name} must hold finite numbers, not {value}"))?;
    }
    Ok(out)
}

fn numbers<const N: usize>(request: &Map<String, Value>, key: &str) -> Result<[f64; N], String> {
    numbers_in::<N>(request, key, key)
}

fn vector2(request: &Map<String, Value>, key: &str) -> Result<DVec2, String> {
    Ok(DVec2::from_array(numbers::<2>(request, key)?))
}

/// The glint sampler's four uniform numbers from a `sample` line's `u`: `[u0, u1, u2, u3]` as
/// they are, or the three-number form `[u0, u1, u2]`, whose third number's odd and even bits
/// give the cone's two numbers (the form `eval` accepted first; kept so that its lines keep
/// their meaning).
fn sample_uniforms(request: &Map<String, Value>) -> Result<[f64; 4], String> {
    let given = request
        .get("u")
        .and_then(Value::as_array)
        .map_or(0, Vec::len);
    let u = if given == 3 {
        let [u0, u1, u2] = numbers::<3>(request, "u")?;
        check_uniforms(&[u0, u1, u2])?;
        let [u2, u3] = split_uniform(u2);
        [u0, u1, u2, u3]
    } else {
        numbers::<4>(request, "u")
            .map_err(|e| format!("{e} (or 3 in the original form), each in [0, 1)"))?
    };
    check_uniforms(&u)?;
    Ok(u)
}

fn check_uniforms(u: &[f64]) -> Result<(), String> {
    if u.iter().any(|x| !(0.0..1.0).contains(x)) {
        return Err("`u` must hold numbers in [0, 1)".to_owned());
    }
    Ok(())
}

/// Two uniforms from one: the odd and the even bits of its 52-bit mantissa fraction, bit
/// 2k + 1 being the more significant of each pair (so the first carries the coarse half).
fn split_uniform(u: f64) -> [f64; 2] {
    let bits = (u.clamp(0.0, 1.0 - f64::EPSILON) * (1u64 << 52) as f64) as u64;
    let (mut odd, mut even) = (0u64, 0u64);
    for k in 0..26 {
        odd |= ((bits >> (2 * k + 1)) & 1) << k;
        even |= ((bits >> (2 * k)) & 1) << k;
    }
    let scale = 1.0 / (1u64 << 26) as f64;
    [odd as f64 * scale, even as f64 * scale]
}

/// A direction, normalized; zero vectors are rejected.
fn direction(request: &Map<String, Value>, key: &str) -> Result<DVec3, String> {
    let v = DVec3::from_array(numbers::<3>(request, key)?);
    if v.length_squared() == 0.0 {
        return Err(format!("{key} has zero length"));
    }
    Ok(v.normalize())
}

#[cfg(test)]
mod tests {
    use super::*;

    const MATERIAL: &str = r#"{"distribution": "beckmann", "alpha": 0.1, "alpha_y": 0.1, "particles": 1e6, "gamma_deg": 1.0, "epsilon": 0.1, "seed": 7, "fresnel": "none"}"#;

    fn run_lines(lines: &[String]) -> (Vec<Value>, usize) {
        let input = lines.join("\n");
        let mut output = Vec::new();
        let failed = process(input.as_bytes(), &mut output).unwrap();
        let values = String::from_utf8(output)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        (values, failed)
    }

    /// `negligible_count`: a far query is skipped and says so; a near one is not; a negative
    /// threshold is an error naming the field.
    #[test]
    fn negligible_queries_are_reported() {
        let material = MATERIAL.replace("\"seed\": 7", "\"seed\": 7, \"negligible_count\": 1e-12");
        let eval = |wo: &str| {
            format!(
                r#"{{"op": "eval", "material": {material}, "uv": [0.3, 0.4], "duv_dx": [0.001, 0.0], "duv_dy": [0.0, 0.001], "wi": [0.0, 0.0, 1.0], "wo": {wo}}}"#
            )
        };
        let lines = vec![
            eval("[0.9, 0.0, 0.3]"),
            eval("[0.01, 0.0, 1.0]"),
            eval("[0.9, 0.0, 0.3]").replace("1e-12", "-1"),
        ];
        let (values, failed) = run_lines(&lines);
        assert_eq!(failed, 1);
        let bound = values[0]["negligible_bound"].as_f64().expect("skipped");
        assert!((0.0..1e-12).contains(&bound), "{}", values[0]);
        assert_eq!(values[0]["count"].as_f64(), Some(0.0));
        assert!(values[1].get("negligible_bound").is_none(), "{}", values[1]);
        let message = values[2]["error"].as_str().unwrap_or_default();
        assert!(message.contains("negligible count"), "{message}");
    }

    #[test]
    fn split_uniform_gives_two_uniforms() {
        let [a, b] = split_uniform(0.75);
        assert!((0.0..1.0).contains(&a) && (0.0..1.0).contains(&b));
        // 0.75 = 0b11 followed by zeros: the two coarsest bits go one to each half.
        assert_eq!([a, b], [0.5, 0.5]);
        // 0.5 + 2⁻³: bits 1 and 3 from the top, both odd-positioned (counting from bit 51).
        assert_eq!(split_uniform(0.625), [0.75, 0.0]);
    }

    /// The three-number `u` is the four-number one with its third number split; both forms
    /// sample, and a fourth number out of [0, 1) is an error.
    #[test]
    fn sample_takes_three_or_four_uniforms() {
        let line = |u: &str| {
            format!(
                r#"{{"op": "sample", "material": {MATERIAL}, "wi": [0.2, 0.0, 1.0], "u": {u}}}"#
            )
        };
        let [c0, c1] = split_uniform(0.2);
        let lines = vec![
            line("[0.3, 0.6, 0.2]"),
            line(&format!("[0.3, 0.6, {c0:?}, {c1:?}]")),
            line("[0.3, 0.6, 0.2, 0.9]"),
            line("[0.3, 0.6, 0.2, 1.0]"),
            line("[0.3, 0.6]"),
        ];
        let (values, failed) = run_lines(&lines);
        assert_eq!(failed, 2, "{values:?}");
        assert!(values[0]["wo"].is_array(), "{}", values[0]);
        assert_eq!(values[0], values[1]);
        assert!(values[2]["wo"].is_array() && values[2] != values[0]);
        for bad in [3, 4] {
            let message = values[bad]["error"].as_str().unwrap_or_default();
            assert!(
                message.contains("`u`") || message.contains("u "),
                "{message}"
            );
        }
    }

    #[test]
    fn mixed_valid_and_invalid_lines() {
        let eval = format!(
            r#"{{"op": "eval", "material": {MATERIAL}, "uv": [0.3, 0.4], "duv_dx": [0.001, 0.0], "duv_dy": [0.0, 0.001], "wi": [0.0, 0.0, 1.0], "wo": [0.1, 0.0, 0.99]}}"#
        );
        let lines = vec![
            eval.clone(),
            "this is not json".to_owned(),
            eval.replace("\"beckmann\"", "\"beckman\""),
            eval.replace("\"alpha\": 0.1", "\"alpha\": -0.1"),
            eval.replace("\"wi\": [0.0, 0.0, 1.0]", "\"wi\": [0.0, 0.0, 0.0]"),
            format!(
                r#"{{"op": "sample", "material": {MATERIAL}, "wi": [0.2, 0.0, 1.0], "u": [0.3, 0.6, 0.2]}}"#
            ),
            format!(
                r#"{{"op": "pdf", "material": {MATERIAL}, "wi": [0.2, 0.0, 1.0], "wo": [-0.2, 0.0, 1.0]}}"#
            ),
            eval.replace("\"seed\": 7", "\"sed\": 7"),
            format!(
                r#"{{"op": "sample", "material": {MATERIAL}, "wi": [0.2, 0.0, 1.0], "u": [0.3, 1.5, 0.2]}}"#
            ),
            eval.clone(),
        ];
        let (values, failed) = run_lines(&lines);
        assert_eq!(values.len(), lines.len());
        assert_eq!(failed, 6);
        for (i, expected_error) in [
            (1, "invalid JSON"),
            (2, "beckman"),
            (3, "alpha"),
            (4, "zero length"),
            (7, "unknown material field `sed`"),
            (8, "[0, 1)"),
        ] {
            let message = values[i]["error"].as_str().unwrap_or_default();
            assert!(message.contains(expected_error), "line {i}: {message}");
        }
        // The eval answer: finite fields, the smooth BRDF as glint-brdf computes it, and the
        // same answer for the same request.
        let first = &values[0];
        for key in [
            "count",
            "expected_count",
            "d_hat",
            "f_hat",
            "f_smooth",
            "nodes_visited",
        ] {
            assert!(
                first[key].as_f64().is_some_and(f64::is_finite),
                "{key}: {first}"
            );
        }
        let d = Microfacet::new(DistributionKind::Beckmann, 0.1, 0.1).unwrap();
        let smooth = glint_brdf::MicrofacetBrdf::new(
            d,
            Fresnel::None,
            glint_brdf::NormalSampling::Distribution,
        )
        .unwrap();
        let expected = smooth
            .eval(DVec3::Z, DVec3::new(0.1, 0.0, 0.99).normalize())
            .x;
        assert!((first["f_smooth"].as_f64().unwrap() - expected).abs() < 1e-12 * expected);
        assert_eq!(values[9], values[0]);
        let sample = &values[5];
        assert!(sample["wo"].is_null() || sample["pdf"].as_f64().unwrap() > 0.0);
        assert!(values[6]["pdf"].as_f64().unwrap() > 0.0);
    }

    #[test]
    fn coloured_fresnel_gives_rgb() {
        let material = MATERIAL.replace(
            "\"fresnel\": \"none\"",
            "\"fresnel\": {\"conductor\": {\"eta\": [0.2, 0.9, 1.1], \"k\": [3.9, 2.4, 2.2]}}",
        );
        let line = format!(
            r#"{{"material": {material}, "uv": [0.3, 0.4], "duv_dx": [0.01, 0.0], "duv_dy": [0.0, 0.01], "wi": [0.0, 0.0, 1.0], "wo": [0.02, 0.0, 1.0]}}"#
        );
        let (values, failed) = run_lines(&[line]);
        assert_eq!(failed, 0, "{:?}", values);
        assert_eq!(values[0]["f_smooth"].as_array().map(Vec::len), Some(3));
    }
}
