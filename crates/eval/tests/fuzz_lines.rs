//! Fuzzing of request lines, kept as a property test that runs in `cargo test`: valid
//! requests whose values are replaced by extremes, truncated, or given the wrong types. Each
//! answer is an error message of bounded length or an answer whose numbers are finite and
//! non-negative (directions excepted, which are unit vectors); nothing panics, and the work is
//! bounded by construction (the node budget, the periodic average of footprints over many
//! tiles), so every case ends.

use glint_eval::JsonLines;
use proptest::prelude::*;
use serde_json::{Value, json};

/// Numbers a hostile user might write where a number goes.
fn extreme() -> impl Strategy<Value = Value> {
    prop_oneof![
        prop::sample::select(vec![
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.5,
            1e-300,
            -1e-300,
            1e300,
            -1e300,
            1e30,
            1e-30,
            3e38,
            f64::MAX,
            f64::MIN_POSITIVE,
            4096.0,
            4097.0,
            9.007_199_254_740_993e15,
            0.999_999,
        ])
        .prop_map(|x| json!(x)),
        (-1e6f64..1e6).prop_map(|x| json!(x)),
        Just(json!(null)),
        Just(json!("1")),
        Just(json!([])),
        Just(json!({})),
    ]
}

fn base() -> Value {
    json!({
        "op": "eval",
        "material": {"distribution": "beckmann", "alpha": 0.1, "alpha_y": 0.2,
                     "particles": 1e6, "gamma_deg": 1.0, "epsilon": 0.1, "seed": 3,
                     "pdf_points": 16},
        "uv": [0.3, 0.4], "duv_dx": [0.001, 0.0], "duv_dy": [0.0, 0.001],
        "wi": [0.0, 0.0, 1.0], "wo": [0.1, 0.0, 0.99], "u": [0.3, 0.6, 0.2, 0.9]
    })
}

/// Every number in `value`, as a JSON pointer.
fn number_paths(value: &Value, path: String, out: &mut Vec<String>) {
    match value {
        Value::Number(_) => out.push(path),
        Value::Array(items) => {
            for (i, v) in items.iter().enumerate() {
                number_paths(v, format!("{path}/{i}"), out);
            }
        }
        Value::Object(map) => {
            for (k, v) in map {
                number_paths(v, format!("{path}/{k}"), out);
            }
        }
        _ => {}
    }
}

fn check_answer(answer: &Result<Value, String>) {
    match answer {
        Err(message) => assert!(message.len() < 600, "error of {} bytes", message.len()),
        Ok(value) => {
            for (key, v) in value.as_object().expect("an object") {
                let numbers: Vec<f64> = match v {
                    Value::Array(items) => items.iter().filter_map(Value::as_f64).collect(),
                    Value::Null => vec![],
                    other => vec![other.as_f64().expect("a number")],
                };
                for x in numbers {
                    assert!(x.is_finite(), "{key} = {x}");
                    assert!(key == "wo" || x >= 0.0, "{key} = {x}");
                }
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    /// Up to four numbers of a valid request replaced by extremes, for each op.
    #[test]
    fn extreme_values_give_errors_or_finite_answers(
        op in prop::sample::select(vec!["eval", "sample", "pdf"]),
        picks in prop::collection::vec((any::<prop::sample::Index>(), extreme()), 1..5),
    ) {
        let mut request = base();
        request["op"] = json!(op);
        let mut paths = Vec::new();
        number_paths(&request, String::new(), &mut paths);
        for (index, value) in picks {
            let path = index.get(&paths).clone();
            *request.pointer_mut(&path).expect("a path of the request") = value;
        }
        let mut requests = JsonLines::new();
        check_answer(&requests.answer(&request.to_string()));
    }

    /// Truncated and byte-mutated lines.
    #[test]
    fn mangled_lines_give_errors_or_finite_answers(
        cut in 0usize..400,
        flips in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..4),
    ) {
        let text = base().to_string();
        let mut bytes = text.into_bytes();
        bytes.truncate(cut.max(1).min(bytes.len()));
        for (index, byte) in flips {
            let i = index.index(bytes.len());
            bytes[i] = byte;
        }
        let line = String::from_utf8_lossy(&bytes);
        let mut requests = JsonLines::new();
        check_answer(&requests.answer(&line));
    }
}
