//! One JSON line in, one JSON answer out (`docs/eval.md`), with a cache of built materials.

use std::collections::HashMap;

use glint_brdf::{DVec3, QueryScratch};
use serde_json::{Map, Value, json};

use crate::material::{MaterialSpec, numbers_in};
use crate::request::{EvalMaterial, uniforms_from_three};

/// Answers JSON requests, building each distinct `material` object once.
#[derive(Debug, Default)]
pub struct JsonLines {
    materials: HashMap<String, EvalMaterial>,
    scratch: QueryScratch,
}

impl JsonLines {
    /// A reader with no material built yet.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// The answer to one request line.
    ///
    /// # Errors
    /// The message of `docs/eval.md`'s `{"error": ...}` answer (without the line number).
    pub fn answer(&mut self, line: &str) -> Result<Value, String> {
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
            let built = MaterialSpec::from_json(material)?.build()?;
            self.materials.insert(key.clone(), built);
        }
        let material = &self.materials[&key];
        let colour = |c: DVec3| {
            if material.is_gray() {
                json!(c.x)
            } else {
                json!([c.x, c.y, c.z])
            }
        };
        let wi = numbers::<3>(request, "wi")?;
        match op {
            "eval" => {
                let e = material.eval(
                    &mut self.scratch,
                    wi,
                    numbers::<3>(request, "wo")?,
                    numbers::<2>(request, "uv")?,
                    numbers::<2>(request, "duv_dx")?,
                    numbers::<2>(request, "duv_dy")?,
                )?;
                let mut answer = json!({
                    "count": e.count,
                    "expected_count": e.expected_count,
                    "d_hat": e.d_hat,
                    "f_hat": colour(e.f_hat),
                    "f_smooth": colour(e.f_smooth),
                    "nodes_visited": e.nodes_visited,
                });
                if let Some(bound) = e.negligible_bound {
                    answer["negligible_bound"] = json!(bound);
                }
                Ok(answer)
            }
            "sample" => {
                let given = request
                    .get("u")
                    .and_then(Value::as_array)
                    .map_or(0, Vec::len);
                let u = if given == 3 {
                    uniforms_from_three(numbers::<3>(request, "u")?)?
                } else {
                    numbers::<4>(request, "u")
                        .map_err(|e| format!("{e} (or 3 in the original form), each in [0, 1)"))?
                };
                Ok(match material.sample(wi, u)? {
                    Some(s) => {
                        json!({ "wo": [s.wo.x, s.wo.y, s.wo.z], "pdf": s.pdf, "weight": colour(s.weight) })
                    }
                    None => json!({ "wo": null }),
                })
            }
            _ => Ok(json!({ "pdf": material.pdf(wi, numbers::<3>(request, "wo")?)? })),
        }
    }
}

fn numbers<const N: usize>(request: &Map<String, Value>, key: &str) -> Result<[f64; N], String> {
    numbers_in::<N>(request, key, key)
}
