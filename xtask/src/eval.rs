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

/// The longest request line read, in bytes (a request is well under a kilobyte): a longer
/// line is answered with an error and skipped without being held in memory.
pub(crate) const MAX_LINE_BYTES: usize = 1 << 20;

/// One line of input: its bytes, or how long it was when it exceeded [`MAX_LINE_BYTES`].
enum Line {
    Text(Vec<u8>),
    TooLong(usize),
}

/// The next line of `input` without its newline, holding at most [`MAX_LINE_BYTES`] of it;
/// `None` at the end of the input.
fn next_line(input: &mut impl BufRead) -> std::io::Result<Option<Line>> {
    let mut bytes = Vec::new();
    let mut length = 0usize;
    loop {
        let buffer = input.fill_buf()?;
        if buffer.is_empty() {
            return Ok((length > 0).then(|| finish(bytes, length)));
        }
        let (chunk, ends_line) = match buffer.iter().position(|&b| b == b'\n') {
            Some(end) => (&buffer[..end], true),
            None => (buffer, false),
        };
        length += chunk.len();
        if length <= MAX_LINE_BYTES {
            bytes.extend_from_slice(chunk);
        } else {
            bytes = Vec::new();
        }
        let consumed = chunk.len() + usize::from(ends_line);
        input.consume(consumed);
        if ends_line {
            return Ok(Some(finish(bytes, length)));
        }
    }
}

fn finish(mut bytes: Vec<u8>, length: usize) -> Line {
    if length > MAX_LINE_BYTES {
        return Line::TooLong(length);
    }
    if bytes.last() == Some(&b'\r') {
        bytes.pop();
    }
    Line::Text(bytes)
}

/// The UTF-8 encoding of U+FEFF, accepted (and dropped) at the start of the input.
const BYTE_ORDER_MARK: &[u8] = b"\xef\xbb\xbf";

/// Answers every line of `input` on `output`; returns how many lines failed. A line that is
/// too long or not UTF-8 fails alone: the lines after it are answered.
pub(crate) fn process(mut input: impl BufRead, output: &mut impl Write) -> anyhow::Result<usize> {
    let mut requests = JsonLines::new();
    let mut failed = 0;
    let mut number = 0;
    while let Some(line) = next_line(&mut input).context("reading the input")? {
        number += 1;
        let answer = match line {
            Line::TooLong(length) => Err(format!(
                "the line is {length} bytes long, more than the {MAX_LINE_BYTES} a request may take"
            )),
            Line::Text(mut bytes) => {
                // A UTF-8 byte-order mark (which some editors write) may open the input.
                if number == 1 && bytes.starts_with(BYTE_ORDER_MARK) {
                    bytes.drain(..BYTE_ORDER_MARK.len());
                }
                match String::from_utf8(bytes) {
                    Err(e) => Err(format!(
                        "the line is not UTF-8 text (invalid byte at offset {})",
                        e.utf8_error().valid_up_to()
                    )),
                    Ok(text) if text.trim().is_empty() => continue,
                    Ok(text) => requests.answer(&text),
                }
            }
        };
        let answer = answer.unwrap_or_else(|message| {
            failed += 1;
            json!({ "error": format!("line {number}: {message}") })
        });
        writeln!(output, "{answer}")?;
    }
    Ok(failed)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glint_brdf::{Bxdf, DVec3, DistributionKind, Fresnel, Microfacet};
    use serde_json::Value;

    const MATERIAL: &str = r#"{"distribution": "beckmann", "alpha": 0.1, "alpha_y": 0.1, "particles": 1e6, "gamma_degrees": 1.0, "epsilon": 0.1, "seed": 7, "fresnel": "none"}"#;

    /// `cargo xtask eval` skips negligible queries by default at the tracer's τ for scene
    /// files, so its answers and a render's agree on which queries are skipped.
    #[test]
    fn the_default_negligible_count_is_the_tracers() {
        assert_eq!(
            glint_eval::DEFAULT_NEGLIGIBLE_COUNT.to_bits(),
            glint_tracer::scene_file::SCENE_NEGLIGIBLE_COUNT.to_bits()
        );
    }

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

    /// A line too long to hold, or not UTF-8, fails alone; the next line is answered.
    #[test]
    fn bad_lines_fail_alone() {
        let eval = format!(
            r#"{{"op": "pdf", "material": {MATERIAL}, "wi": [0.2, 0.0, 1.0], "wo": [-0.2, 0.0, 1.0]}}"#
        );
        let mut input = Vec::new();
        input.extend_from_slice(&vec![b'x'; MAX_LINE_BYTES + 10]);
        input.push(b'\n');
        input.extend_from_slice(b"{\"op\": \xff\xfe}\n");
        input.extend_from_slice(eval.as_bytes());
        input.extend_from_slice(b"\r\n");
        input.extend_from_slice(&vec![b' '; MAX_LINE_BYTES + 1]);
        let mut output = Vec::new();
        let failed = process(&input[..], &mut output).unwrap();
        let values: Vec<Value> = String::from_utf8(output)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert_eq!(values.len(), 4, "{values:?}");
        assert_eq!(failed, 3);
        assert!(
            values[0]["error"]
                .as_str()
                .unwrap()
                .starts_with("line 1: the line is 1048586 bytes")
        );
        assert!(
            values[1]["error"]
                .as_str()
                .unwrap()
                .contains("line 2: the line is not UTF-8")
        );
        assert!(values[2]["pdf"].as_f64().unwrap() > 0.0, "{}", values[2]);
        assert!(
            values[3]["error"]
                .as_str()
                .unwrap()
                .starts_with("line 4: the line is")
        );
    }

    /// Nonsense is refused with a message naming the field and echoing the value as given.
    #[test]
    fn out_of_range_values_are_named_and_echoed() {
        let eval = format!(
            r#"{{"op": "eval", "material": {MATERIAL}, "uv": [0.3, 0.4], "duv_dx": [0.001, 0.0], "duv_dy": [0.0, 0.001], "wi": [0.0, 0.0, 1.0], "wo": [0.1, 0.0, 0.99]}}"#
        );
        let with = |field: &str| eval.replace("\"seed\": 7", &format!("\"seed\": 7, {field}"));
        let fresnel =
            |value: &str| eval.replace("\"fresnel\": \"none\"", &format!("\"fresnel\": {value}"));
        let cases = [
            (
                with("\"pdf_points\": -3"),
                "material.pdf_points = -3.0 must be a whole number",
            ),
            (
                with("\"pdf_points\": 1e30"),
                "material.pdf_points = 1e30 must be",
            ),
            (
                with("\"pdf_quadrature\": \"gauss\""),
                "material.pdf_quadrature \"gauss\" is unknown",
            ),
            (
                with("\"pdf_quadrature\": 7"),
                "material.pdf_quadrature 7 is unknown",
            ),
            (
                eval.replace("\"epsilon\": 0.1", "\"epsilon\": 1e300"),
                "epsilon = 1e300 is invalid",
            ),
            (
                with("\"epsilon\": 0.2"),
                "invalid JSON: duplicate key `epsilon`",
            ),
            (
                with("\"expected_footprint_area\": 0"),
                "expected footprint area 0.0",
            ),
            (
                eval.replace("\"gamma_degrees\": 1.0", "\"gamma_degrees\": 1e-300"),
                "material.gamma_degrees = 1e-300",
            ),
            (eval.replace("\"op\"", "\"opp\""), "unknown field `opp`"),
            (
                fresnel("{\"conductor\": {\"eta\": [1, 1, 1], \"k\": [0, 0, 0], \"kk\": 1}}"),
                "unknown material.fresnel.conductor field `kk` (known: eta, k)",
            ),
            (
                fresnel("{\"dielectric\": {\"eta\": 1.5, \"k\": 0}}"),
                "unknown material.fresnel.dielectric field `k` (known: eta)",
            ),
            (
                fresnel("{\"conductor\": {\"eta\": [1e300, 1, 1], \"k\": [1e300, 0, 0]}}"),
                "material.fresnel.conductor.eta: Fresnel eta = 1e300 is invalid: eta must be in [1e-3, 1e3] and k in [0, 1e3]",
            ),
            (
                fresnel("{\"conductor\": {\"eta\": [1, 1, 1], \"k\": [0, 1001, 0]}}"),
                "material.fresnel.conductor.k: Fresnel k = 1001.0",
            ),
            (
                fresnel("{\"dielectric\": {\"eta\": 0.0001}}"),
                "material.fresnel.dielectric.eta: Fresnel eta = 0.0001",
            ),
            (
                eval.replace("\"duv_dx\": [0.001, 0.0]", "\"duv_dx\": [1e300, 0.0]"),
                "duv_dx must hold numbers within ±1e15, not [1e300, 0.0]",
            ),
            (
                eval.replace("\"duv_dy\": [0.0, 0.001]", "\"duv_dy\": [0.0, -1e154]"),
                "duv_dy must hold numbers within ±1e15",
            ),
            (
                eval.replace("\"particles\": 1e6", "\"particles\": 9007199254740993"),
                "material.particles = 9007199254740993 must be a whole number in [1, 2^53]",
            ),
            (
                eval.replace("\"seed\": 7", "\"seed\": -1"),
                "material.seed = -1.0 must be a whole number in [0, 2^64)",
            ),
            (
                eval.replace("\"seed\": 7", "\"seed\": 1.8446744073709552e19"),
                "material.seed = 1.8446744073709552e19 must be a whole number in [0, 2^64)",
            ),
            (
                eval.replace("\"uv\"", "\"colour\": 1, \"uv\""),
                "unknown field `colour`",
            ),
        ];
        let lines: Vec<String> = cases.iter().map(|(l, _)| l.clone()).collect();
        let (values, failed) = run_lines(&lines);
        assert_eq!(failed, cases.len());
        for (value, (_, expected)) in values.iter().zip(&cases) {
            let message = value["error"].as_str().unwrap_or_default();
            assert!(message.contains(expected), "{message} lacks {expected}");
            assert!(message.len() < 400, "{message}");
        }
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

    /// Whole-number fields are read exactly: seeds are every 64-bit number (2⁵³ + 1 is not
    /// 2⁵³, and u64::MAX is a seed), N = 2⁵³ is the largest count.
    #[test]
    fn integers_are_exact() {
        let line = |seed: &str, particles: &str| {
            format!(
                r#"{{"op": "eval", "material": {}, "uv": [0.3, 0.4], "duv_dx": [0.2, 0.0], "duv_dy": [0.0, 0.2], "wi": [0.0, 0.0, 1.0], "wo": [0.1, 0.0, 0.99]}}"#,
                MATERIAL
                    .replace("\"seed\": 7", &format!("\"seed\": {seed}"))
                    .replace("\"particles\": 1e6", &format!("\"particles\": {particles}"))
            )
        };
        let lines = vec![
            line("9007199254740992", "1e6"),
            line("9007199254740993", "1e6"),
            line("18446744073709551615", "1e6"),
            line("7", "9007199254740992"),
        ];
        let (values, failed) = run_lines(&lines);
        assert_eq!(failed, 0, "{values:?}");
        assert_ne!(values[0]["count"], values[1]["count"], "{values:?}");
        assert!(values[3]["count"].as_f64().unwrap() > 0.0, "{}", values[3]);
    }

    /// A sampled direction passed back as `wo` gives the sample's own pdf, bit for bit
    /// (unit vectors are used as given); a near-unit direction is not normalized again.
    #[test]
    fn a_sample_gives_back_its_pdf() {
        let mut lines = Vec::new();
        for i in 0..40 {
            let u = [0.013 * f64::from(i), 0.61, 0.27, 0.9 - 0.02 * f64::from(i)];
            lines.push(format!(
                r#"{{"op": "sample", "material": {MATERIAL}, "wi": [0.3, 0.1, 0.9], "u": {u:?}}}"#
            ));
        }
        let (samples, failed) = run_lines(&lines);
        assert_eq!(failed, 0);
        let pdfs: Vec<String> = samples
            .iter()
            .map(|s| {
                format!(
                    r#"{{"op": "pdf", "material": {MATERIAL}, "wi": [0.3, 0.1, 0.9], "wo": {}}}"#,
                    s["wo"]
                )
            })
            .collect();
        let (answers, failed) = run_lines(&pdfs);
        assert_eq!(failed, 0);
        for (sample, answer) in samples.iter().zip(&answers) {
            assert_eq!(sample["pdf"], answer["pdf"], "{sample}");
        }
    }

    /// A UTF-8 byte-order mark at the start of the input is skipped; anywhere else it is not
    /// JSON.
    #[test]
    fn a_byte_order_mark_may_open_the_input() {
        let line = format!(
            r#"{{"op": "pdf", "material": {MATERIAL}, "wi": [0.2, 0.0, 1.0], "wo": [-0.2, 0.0, 1.0]}}"#
        );
        let input = format!("\u{feff}{line}\n\u{feff}{line}\n");
        let mut output = Vec::new();
        let failed = process(input.as_bytes(), &mut output).unwrap();
        let values: Vec<Value> = String::from_utf8(output)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert_eq!(failed, 1, "{values:?}");
        assert!(values[0]["pdf"].as_f64().unwrap() > 0.0);
        assert!(
            values[1]["error"]
                .as_str()
                .unwrap()
                .contains("line 2: invalid JSON")
        );
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
