//! `cargo xtask eval`: the model from any language, as JSON Lines (specified in `docs/eval.md`).
//!
//! Each input line is one request (`op` = `eval`, `sample` or `pdf`); each output line answers
//! it, in order. A line that is not valid JSON or holds invalid values yields
//! `{"error": "..."}` naming the problem; the run goes on and the exit status is non-zero.
//! The requests themselves are answered by glint-eval, which the Python package shares.

use std::io::{BufRead, Write};

use anyhow::Context;
use glint_eval::JsonLines;
use serde_json::json;

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
    let mut requests = JsonLines::new();
    let mut failed = 0;
    for (number, line) in input.lines().enumerate() {
        let line = line.with_context(|| format!("reading line {}", number + 1))?;
        if line.trim().is_empty() {
            continue;
        }
        let answer = match requests.answer(&line) {
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

#[cfg(test)]
mod tests {
    use super::*;
    use glint_brdf::{Bxdf, DVec3, DistributionKind, Fresnel, Microfacet};
    use serde_json::Value;

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

    /// The three-number `u` is the four-number one with its third number split; both forms
    /// sample, and a fourth number out of [0, 1) is an error.
    #[test]
    fn sample_takes_three_or_four_uniforms() {
        let line = |u: &str| {
            format!(
                r#"{{"op": "sample", "material": {MATERIAL}, "wi": [0.2, 0.0, 1.0], "u": {u}}}"#
            )
        };
        let [c0, c1] = glint_eval::split_uniform(0.2);
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
