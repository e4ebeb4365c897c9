//! Fuzzing of request lines, kept as a property test that runs in `cargo test`: valid
//! requests (with a conductor's Fresnel term) whose values are replaced by extremes, truncated,
//! or given the wrong types. Each answer is an error message of bounded length or an answer
//! whose numbers are finite and non-negative (directions excepted, which are unit vectors;
//! no number is null); nothing panics, and the work is
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
            // The ends of the accepted ranges (η, k, footprint edges) and just beyond.
            1e-3,
            9.99e-4,
            1e3,
            1.001e3,
            1e15,
            1.01e15,
            1e154,
        ])
        .prop_map(|x| json!(x)),
        (-1e6f64..1e6).prop_map(|x| json!(x)),
        Just(json!(null)),
        Just(json!("1")),
        Just(json!([])),
        Just(json!({})),
    ]
}

/// One of `numbers`, with either sign.
fn signed(numbers: Vec<f64>) -> impl Strategy<Value = f64> {
    (prop::sample::select(numbers), any::<bool>())
        .prop_map(|(x, negative)| if negative { -x } else { x })
}

/// Footprint edge components: tiny, ordinary, at and beyond the limit ±1e15, huge. (Slivers
/// a thousand tiles long and under a tile wide, which the tree resolves exactly at a cost of
/// seconds, are left out to keep the test short.)
fn extreme_edge() -> impl Strategy<Value = f64> {
    signed(vec![
        0.0,
        1e-300,
        1e-3,
        0.5,
        1.0,
        1e15,
        1.01e15,
        1e154,
        1e300,
        f64::MAX,
    ])
}

/// Fresnel indices: at and beyond the ends of the accepted ranges, tiny and huge.
fn extreme_index() -> impl Strategy<Value = f64> {
    signed(vec![
        0.0,
        1e-300,
        1e-3,
        9.99e-4,
        0.5,
        1.0,
        1e3,
        1.001e3,
        1e154,
        1e300,
        f64::MAX,
    ])
}

fn base() -> Value {
    json!({
        "op": "eval",
        "material": {"distribution": "beckmann", "alpha": 0.1, "alpha_y": 0.2,
                     "particles": 1e6, "gamma_degrees": 1.0, "epsilon": 0.1, "seed": 3,
                     "pdf_points": 16,
                     "fresnel": {"conductor": {"eta": [0.2, 1.0, 1.1], "k": [3.9, 0.0, 2.2]}}},
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
                // Only a sample's `wo` may be null (no direction); a null number is a
                // non-finite one that JSON cannot write.
                let numbers: Vec<f64> = match v {
                    Value::Null => {
                        assert_eq!(key, "wo", "{key} is null in {value}");
                        vec![]
                    }
                    Value::Array(items) => items
                        .iter()
                        .map(|x| x.as_f64().unwrap_or_else(|| panic!("{key}: {value}")))
                        .collect(),
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

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 200,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x6578_7472),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// Footprint edges drawn from the extremes only (a random pick of four numbers among
    /// all of a request's rarely lands on them): an `eval` answers with finite numbers or an
    /// error naming the edge.
    #[test]
    fn extreme_footprints_give_errors_or_finite_answers(
        edges in prop::collection::vec(extreme_edge(), 4),
    ) {
        let mut request = base();
        request["duv_dx"] = json!([edges[0], edges[1]]);
        request["duv_dy"] = json!([edges[2], edges[3]]);
        let answer = JsonLines::new().answer(&request.to_string());
        if let Err(message) = &answer {
            prop_assert!(message.starts_with("duv_d"), "{message}");
        }
        check_answer(&answer);
    }

    /// A conductor's η and k drawn from the extremes only, each channel: an `eval` answers
    /// with finite numbers or an error naming the index.
    #[test]
    fn extreme_indices_give_errors_or_finite_answers(
        indices in prop::collection::vec(extreme_index(), 2),
        wi in prop::sample::select(vec![[0.0, 0.0, 1.0], [1.0, 0.0, 1e-6], [0.3, 0.2, 0.9]]),
    ) {
        let mut request = base();
        request["material"]["fresnel"] = json!({"conductor": {
            "eta": [indices[0], 1.0, indices[0].abs()], "k": [indices[1].abs(), 0.0, indices[1]]
        }});
        request["wi"] = json!(wi);
        request["wo"] = json!([-wi[0], -wi[1], wi[2]]);
        let answer = JsonLines::new().answer(&request.to_string());
        if let Err(message) = &answer {
            prop_assert!(message.starts_with("material.fresnel.conductor"), "{message}");
        }
        check_answer(&answer);
    }
}
