//! One JSON line in, one JSON answer out (`docs/eval.md`), with a bounded cache of built
//! materials.

use std::collections::HashMap;

use glint_brdf::{DVec3, QueryScratch};
use serde_json::{Map, Value, json};

use crate::material::{MaterialSpec, known_fields, numbers_in};
use crate::request::{EvalMaterial, uniforms_from_three};
use crate::strict_json;

/// How many built materials [`JsonLines`] keeps at most. Beyond it, or beyond
/// [`MATERIAL_CACHE_BYTES`], the least recently used material is dropped and rebuilt (a few ms,
/// up to 0.3 s for the most anisotropic) if it comes back.
pub const MATERIAL_CACHE_SIZE: usize = 64;

/// The most memory the cached materials may take together, by [`material_bytes`]: 64 ordinary
/// materials (about 2 MB each) fit; of the most anisotropic (α = 10⁻⁴ against α_y = 1, about
/// 50 MB each), five. A single material larger than this (large maps at many roughness
/// levels, up to [`glint_brdf::MAX_MAP_BYTES`]) is kept alone, only while the lines that use
/// it follow each other.
pub const MATERIAL_CACHE_BYTES: usize = 256 << 20;

/// A built material's memory: the bytes its maps hold ([`glint_brdf::DiscreteBrdf::map_bytes`],
/// exact) plus, for each roughness level's count tree, an estimate from its Alg. 2 table:
/// 1.6 MB plus 530 bytes per entry (the table, the directional split of each entry's cell,
/// its descent steps), plus the quadrature's refinement (`NdfQuadrature::heap_bytes`,
/// which also counts the table's map again). The estimate was measured as the peak resident memory of
/// `cargo xtask eval` on one line per material, less that of the process: Beckmann α = 0.1,
/// 684 entries, 2.0 MB; α = 10⁻³ and α_y = 0.3, 13 380 entries, 6.6 MB; α = 10⁻⁴ and
/// α_y = 1, 78 560 entries, 43 MB; GGX at those, 97 472 entries, 52 MB (`docs/eval.md`,
/// "Limits", gives the command).
fn material_bytes(material: &EvalMaterial) -> usize {
    let brdf = material.brdf();
    let trees: usize = brdf
        .level_trees()
        .map(|(_, tree)| {
            let quadrature = tree.quadrature();
            1_600_000 + 530 * quadrature.len() + quadrature.heap_bytes()
        })
        .sum();
    trees.saturating_add(usize::try_from(brdf.map_bytes()).unwrap_or(usize::MAX))
}

/// The fields a request may hold.
const REQUEST_FIELDS: [&str; 8] = ["op", "material", "wi", "wo", "uv", "duv_dx", "duv_dy", "u"];

/// Answers JSON requests, building each distinct `material` object once while it stays among
/// the most recently used ([`MATERIAL_CACHE_SIZE`], [`MATERIAL_CACHE_BYTES`]).
#[derive(Debug, Default)]
pub struct JsonLines {
    /// Built materials by their JSON text, with the request number that last used each and
    /// their estimated memory.
    materials: HashMap<String, Cached>,
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

    /// The memory of the cached materials ([`material_bytes`]): at most
    /// [`MATERIAL_CACHE_BYTES`], or one material's when that one alone is larger. A new
    /// material is built before older ones make room for it, so while it is built the
    /// process holds the cache and it.
    #[must_use]
    pub fn cached_bytes(&self) -> usize {
        self.materials.values().map(|c| c.bytes).sum()
    }

    /// The answer to one request line.
    ///
    /// # Errors
    /// The message of `docs/eval.md`'s `{"error": ...}` answer (without the line number).
    pub fn answer(&mut self, line: &str) -> Result<Value, String> {
        let request = strict_json::parse(line).map_err(|e| format!("invalid JSON: {e}"))?;
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
                let uv = optional_uv(request)?;
                Ok(match material.sample(wi, u, uv)? {
                    Some(s) => {
                        json!({ "wo": [s.wo.x, s.wo.y, s.wo.z], "pdf": s.pdf, "weight": colour(s.weight) })
                    }
                    None => json!({ "wo": null }),
                })
            }
            _ => {
                let wo = numbers::<3>(request, "wo")?;
                Ok(json!({ "pdf": material.pdf(wi, wo, optional_uv(request)?)? }))
            }
        }
    }
}

/// The request's `uv`, where a `sample` or `pdf` request gives one (the texture position a
/// material with maps samples at).
fn optional_uv(request: &Map<String, Value>) -> Result<Option<[f64; 2]>, String> {
    if request.contains_key("uv") {
        numbers::<2>(request, "uv").map(Some)
    } else {
        Ok(None)
    }
}

fn numbers<const N: usize>(request: &Map<String, Value>, key: &str) -> Result<[f64; N], String> {
    numbers_in::<N>(request, key, key)
}

/// A built material in the cache.
#[derive(Debug)]
struct Cached {
    material: EvalMaterial,
    /// The request number that last used it.
    used: u64,
    /// [`material_bytes`].
    bytes: usize,
}

/// The material of `key` (its JSON text) from `materials`, built if it is not there, marked as
/// used by request `now`; the least recently used ones make room when the cache is full (in
/// number or in memory). A material larger than the cache empties it and stays alone.
fn cached<'a>(
    materials: &'a mut HashMap<String, Cached>,
    now: u64,
    key: String,
    material: &Value,
) -> Result<&'a EvalMaterial, String> {
    if !materials.contains_key(&key) {
        let built = MaterialSpec::from_json(material)?.build()?;
        let bytes = material_bytes(&built);
        let mut total: usize = materials.values().map(|c| c.bytes).sum();
        while materials.len() >= MATERIAL_CACHE_SIZE
            || total.saturating_add(bytes) > MATERIAL_CACHE_BYTES
        {
            let Some(oldest) = materials
                .iter()
                .min_by_key(|(_, c)| c.used)
                .map(|(k, _)| k.clone())
            else {
                break;
            };
            total -= materials.remove(&oldest).map_or(0, |c| c.bytes);
        }
        materials.insert(
            key.clone(),
            Cached {
                material: built,
                used: now,
                bytes,
            },
        );
    }
    let entry = materials.get_mut(&key).expect("present or inserted above");
    entry.used = now;
    Ok(&entry.material)
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
                r#"{{"op": "eval", "material": {{"distribution": "beckmann", "alpha": 0.1, "particles": 1e6, "gamma_degrees": 1.0, "seed": {seed}}}, "uv": [0.3, 0.4], "duv_dx": [0.01, 0.0], "duv_dy": [0.0, 0.01], "wi": [0.0, 0.0, 1.0], "wo": [0.1, 0.0, 0.99]}}"#
            )
        };
        let mut requests = JsonLines::new();
        let first = requests.answer(&line(0)).unwrap();
        for seed in 1..MATERIAL_CACHE_SIZE + 20 {
            requests.answer(&line(seed)).unwrap();
            assert!(requests.cached_materials() <= MATERIAL_CACHE_SIZE);
        }
        assert_eq!(requests.cached_materials(), MATERIAL_CACHE_SIZE);
        assert!(requests.cached_bytes() <= MATERIAL_CACHE_BYTES);
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

    /// The most anisotropic materials (α = 10⁻⁴ against α_y = 1, about 50 MB each) are
    /// bounded by memory, not by number: a handful stay cached, and an evicted one answers as
    /// before when it comes back.
    #[test]
    fn the_material_cache_is_bounded_in_memory() {
        let line = |seed: usize| {
            format!(
                r#"{{"op": "eval", "material": {{"distribution": "ggx", "alpha": 1e-4, "alpha_y": 1, "particles": 1e6, "gamma_degrees": 1.0, "seed": {seed}}}, "uv": [0.3, 0.4], "duv_dx": [0.01, 0.0], "duv_dy": [0.0, 0.01], "wi": [0.0, 0.0, 1.0], "wo": [0.1, 0.0, 0.99]}}"#
            )
        };
        let mut requests = JsonLines::new();
        let first = requests.answer(&line(0)).unwrap();
        let one = requests.cached_bytes();
        assert!(one > 40_000_000, "{one} bytes estimated");
        for seed in 1..8 {
            requests.answer(&line(seed)).unwrap();
            assert!(requests.cached_bytes() <= MATERIAL_CACHE_BYTES);
        }
        assert_eq!(requests.cached_materials(), MATERIAL_CACHE_BYTES / one);
        assert_eq!(requests.answer(&line(0)).unwrap(), first);
    }

    /// A material's maps count in the cache's memory: materials with a 512² bilinear
    /// roughness map at 20 levels (the map's α, its levels' shared texels and tables, and 20
    /// count trees: about 46 MB each) leave as many cached as fit the cache's bytes, not 64
    /// (each was counted as 2 MB, and the cache grew by the maps' size with every line).
    #[test]
    fn the_material_cache_counts_the_maps() {
        let side = 512;
        let rows: Vec<String> = (0..side)
            .map(|j| {
                let row: Vec<String> = (0..side)
                    .map(|i| format!("{}", 0.05 + 0.2 * ((i * 7 + j * 13) % 101) as f64 / 100.0))
                    .collect();
                format!("[{}]", row.join(","))
            })
            .collect();
        let alpha_map = format!("[{}]", rows.join(","));
        let line = |seed: usize| {
            format!(
                r#"{{"op": "eval", "material": {{"distribution": "beckmann", "alpha": 0.1, "particles": 1e6, "gamma_degrees": 1.0, "seed": {seed}, "alpha_map": {alpha_map}, "map_filter": "bilinear", "roughness_levels": 20}}, "uv": [0.3, 0.4], "duv_dx": [0.01, 0.0], "duv_dy": [0.0, 0.01], "wi": [0.0, 0.0, 1.0], "wo": [0.1, 0.0, 0.99]}}"#
            )
        };
        let mut requests = JsonLines::new();
        requests.answer(&line(0)).unwrap();
        let one = requests.cached_bytes();
        // α (8 bytes a texel), the levels' family of texels (9) and their 20 blocked tables.
        let maps =
            17 * side * side + 20 * glint_brdf::DensityMap::roughness_level_bytes(side, side);
        assert!(one > maps, "{one} bytes counted");
        let fit = MATERIAL_CACHE_BYTES / one;
        assert!((2..10).contains(&fit), "{one} bytes counted");
        for seed in 1..=fit {
            requests.answer(&line(seed)).unwrap();
            assert!(requests.cached_bytes() <= MATERIAL_CACHE_BYTES);
        }
        assert_eq!(requests.cached_materials(), fit);
    }

    /// A coloured tint map makes the answers colours even without a Fresnel term: a cyan tint
    /// gives red 0 and green = blue (it answered one number, the red channel's 0).
    #[test]
    fn a_coloured_tint_answers_colours_without_fresnel() {
        let line = |tint: &str| {
            format!(
                r#"{{"op": "eval", "material": {{"distribution": "beckmann", "alpha": 0.1, "particles": 1e9, "gamma_degrees": 1.0, "tint_map": [[{tint}]]}}, "uv": [0.3, 0.4], "duv_dx": [0.01, 0.0], "duv_dy": [0.0, 0.01], "wi": [0.0, 0.0, 1.0], "wo": [0.1, 0.0, 0.99]}}"#
            )
        };
        let mut requests = JsonLines::new();
        let cyan = requests.answer(&line("[0, 1, 1]")).unwrap();
        for column in ["f_hat", "f_smooth"] {
            let [r, g, b] = [0, 1, 2].map(|c| cyan[column][c].as_f64().unwrap());
            assert!(r == 0.0 && g > 0.0 && g == b, "{column}: {cyan}");
        }
        let grey = requests.answer(&line("[0.5, 0.5, 0.5]")).unwrap();
        assert!(grey["f_hat"].is_number(), "{grey}");
    }

    /// `gamma_degrees` names γ; `gamma_deg`, its older name, answers the same, bit for bit;
    /// both at once are an error naming them.
    #[test]
    fn gamma_deg_is_read_as_gamma_degrees() {
        let line = |field: &str| {
            format!(
                r#"{{"op": "eval", "material": {{"distribution": "beckmann", "alpha": 0.1, "particles": 1e6, {field}, "seed": 4}}, "uv": [0.3, 0.4], "duv_dx": [0.01, 0.0], "duv_dy": [0.0, 0.01], "wi": [0.0, 0.0, 1.0], "wo": [0.1, 0.0, 0.99]}}"#
            )
        };
        let mut requests = JsonLines::new();
        let new = requests.answer(&line(r#""gamma_degrees": 2.5"#)).unwrap();
        let old = requests.answer(&line(r#""gamma_deg": 2.5"#)).unwrap();
        assert_eq!(new, old);
        let both = requests.answer(&line(r#""gamma_degrees": 2.5, "gamma_deg": 2.5"#));
        let message = both.unwrap_err();
        assert!(
            message.contains("both gamma_degrees and gamma_deg"),
            "{message}"
        );
    }
}
