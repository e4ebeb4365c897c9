//! One JSON line in, one JSON answer out (`docs/eval.md`), with a bounded cache of built
//! materials.

use std::collections::HashMap;

use glint_brdf::{DVec3, QueryScratch};
use serde_json::{Map, Value, json};

use crate::material::{MaterialSpec, known_fields, numbers_in};
use crate::request::{EvalMaterial, uniforms_from_three};

/// How many built materials [`JsonLines`] keeps: a material holds its count tree's caches
/// (about 2 MB), so the cache stays under about 130 MB whatever the input. Beyond it the least
/// recently used material is dropped and rebuilt (a few ms) if it comes back.
pub const MATERIAL_CACHE_SIZE: usize = 64;

/// The fields a request may hold.
const REQUEST_FIELDS: [&str; 8] = ["op", "material", "wi", "wo", "uv", "duv_dx", "duv_dy", "u"];

/// Answers JSON requests, building each distinct `material` object once while it stays among
/// the [`MATERIAL_CACHE_SIZE`] most recently used.
#[derive(Debug, Default)]
pub struct JsonLines {
    /// Built materials by their JSON text, with the request number that last used each.
    materials: HashMap<String, (EvalMaterial, u64)>,
    requests: u64,
    scratch: QueryScratch,
}

impl JsonLines {
    /// A reader with no material built yet.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// How many materials are cached (at most [`MATERIAL_CACHE_SIZE`]).
    #[must_use]
    pub fn cached_materials(&self) -> usize {
        self.materials.len()
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
        known_fields(request, &REQUEST_FIELDS, "field")?;
        let material = request.get("material").ok_or("missing field `material`")?;
        let key = material.to_string();
        self.requests += 1;
        let material = cached(&mut self.materials, self.requests, key, material)?;
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

/// The material of `key` (its JSON text) from `materials`, built if it is not there, marked as
/// used by request `now`; the least recently used one makes room when the cache is full.
fn cached<'a>(
    materials: &'a mut HashMap<String, (EvalMaterial, u64)>,
    now: u64,
    key: String,
    material: &Value,
) -> Result<&'a EvalMaterial, String> {
    if !materials.contains_key(&key) {
        let built = MaterialSpec::from_json(material)?.build()?;
        if materials.len() >= MATERIAL_CACHE_SIZE
            && let Some(oldest) = materials
                .iter()
                .min_by_key(|(_, (_, used))| *used)
                .map(|(k, _)| k.clone())
        {
            materials.remove(&oldest);
        }
        materials.insert(key.clone(), (built, now));
    }
    let entry = materials.get_mut(&key).expect("present or inserted above");
    entry.1 = now;
    Ok(&entry.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Materials past the cache's size evict the least recently used; an evicted material is
    /// rebuilt on its next request and answers as before.
    #[test]
    fn the_material_cache_is_bounded() {
        let line = |seed: usize| {
            format!(
                r#"{{"op": "eval", "material": {{"distribution": "beckmann", "alpha": 0.1, "particles": 1e6, "gamma_deg": 1.0, "seed": {seed}}}, "uv": [0.3, 0.4], "duv_dx": [0.01, 0.0], "duv_dy": [0.0, 0.01], "wi": [0.0, 0.0, 1.0], "wo": [0.1, 0.0, 0.99]}}"#
            )
        };
        let mut requests = JsonLines::new();
        let first = requests.answer(&line(0)).unwrap();
        for seed in 1..MATERIAL_CACHE_SIZE + 20 {
            requests.answer(&line(seed)).unwrap();
            assert!(requests.cached_materials() <= MATERIAL_CACHE_SIZE);
        }
        assert_eq!(requests.cached_materials(), MATERIAL_CACHE_SIZE);
        // Seed 0 was evicted long ago; its answer is the same after a rebuild.
        assert_eq!(requests.answer(&line(0)).unwrap(), first);
        // The most recently used survive: seed 1 was evicted, the last one was not.
        let last = MATERIAL_CACHE_SIZE + 19;
        assert!(
            requests
                .materials
                .keys()
                .any(|k| k.contains(&format!("\"seed\":{last}")))
        );
    }
}
