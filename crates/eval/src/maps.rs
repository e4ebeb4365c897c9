//! A material's maps as `docs/eval.md` specifies them (density, roughness and tint over the
//! texture square, row 0 at the top, and how the density and roughness are reconstructed
//! between texels), shared by `cargo xtask eval`, the C API and the Python package so that
//! each refuses the same texels with the same message.

use std::sync::Arc;

use glint_brdf::{DensityMap, GlintParameters, MapFilter, RoughnessMap, TintMap};
use serde_json::{Map, Value};

use crate::material::optional_name;

/// A map's texels: `width` × `height`, row by row from the top of the texture, `channels`
/// numbers per texel (1, or 3 for a tint) in `values`.
#[derive(Clone, Debug, PartialEq)]
pub struct MapSpec {
    /// Texels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// width × height × channels numbers.
    pub values: Vec<f64>,
}

/// The maps of a material; `None` fields leave the material uniform in that respect.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MapsSpec {
    /// d(x) ∈ [0, 1]: N·d(x) flakes per unit area.
    pub density_map: Option<MapSpec>,
    /// α(x) ∈ [10⁻⁴, 1], isotropic, in place of `alpha`/`alpha_y`.
    pub alpha_map: Option<MapSpec>,
    /// t(x) ∈ [0, 1]³, three numbers per texel.
    pub tint_map: Option<MapSpec>,
    /// K, the most roughness levels of an `alpha_map` (1 to 64; 8 when absent).
    pub roughness_levels: Option<f64>,
    /// How `density_map` and `alpha_map` are reconstructed between texels: one of
    /// [`MapFilter::NAMES`], `"nearest"` when absent. The tint stays nearest.
    pub map_filter: Option<String>,
}

/// The JSON fields of [`MapsSpec`].
pub(crate) const MAP_FIELDS: [&str; 5] = [
    "density_map",
    "alpha_map",
    "tint_map",
    "roughness_levels",
    "map_filter",
];

/// The filters' names as an error lists them: `"nearest" or "bilinear"`.
fn filter_names() -> String {
    MapFilter::NAMES
        .map(|name| format!("\"{name}\""))
        .join(" or ")
}

impl MapsSpec {
    /// Validates the maps and sets them on `parameters`.
    ///
    /// # Errors
    /// A message naming the map and, for a bad value, its texel (column, row from the top).
    pub fn apply(&self, parameters: &mut GlintParameters) -> Result<(), String> {
        let filter = self.filter()?;
        if let Some(map) = &self.density_map {
            let built = DensityMap::with_filter(map.width, map.height, &map.values, filter)
                .map_err(|e| format!("material.density_map: {e}"))?;
            parameters.density_map = Some(Arc::new(built));
        }
        if let Some(map) = &self.alpha_map {
            let built = RoughnessMap::new(map.width, map.height, &map.values)
                .map_err(|e| format!("material.{e}"))?
                .with_filter(filter);
            parameters.alpha_map = Some(Arc::new(built));
        }
        if let Some(map) = &self.tint_map {
            let texels: Vec<[f64; 3]> = map
                .values
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect();
            if texels.len() * 3 != map.values.len() {
                return Err("material.tint_map must hold three numbers per texel".to_owned());
            }
            let built = TintMap::new(map.width, map.height, &texels)
                .map_err(|e| format!("material.{e}"))?;
            parameters.tint_map = Some(Arc::new(built));
        }
        if let Some(levels) = self.roughness_levels {
            if !(levels.fract() == 0.0 && (1.0..=64.0).contains(&levels)) {
                return Err(format!(
                    "material.roughness_levels = {levels:?} must be a whole number in [1, 64]"
                ));
            }
            parameters.roughness_levels = levels as usize;
        }
        Ok(())
    }

    /// The filter `map_filter` names (nearest when absent).
    ///
    /// # Errors
    /// A message naming `material.map_filter` and the filters, for an unknown name.
    pub fn filter(&self) -> Result<MapFilter, String> {
        match self.map_filter.as_deref() {
            None => Ok(MapFilter::Nearest),
            Some(name) => MapFilter::from_name(name).ok_or_else(|| {
                format!(
                    "material.map_filter \"{name}\" is unknown: use {}",
                    filter_names()
                )
            }),
        }
    }

    /// The maps of a JSON material object: each an array of rows, top row first, of numbers
    /// (`density_map`, `alpha_map`) or of [r, g, b] triples (`tint_map`), and `map_filter`.
    ///
    /// # Errors
    /// A message naming the map whose shape or values are not numbers.
    pub(crate) fn from_json(m: &Map<String, Value>) -> Result<Self, String> {
        let levels = match m.get("roughness_levels") {
            None => None,
            Some(value) => Some(value.as_f64().filter(|x| x.is_finite()).ok_or_else(|| {
                format!("material.roughness_levels must be a finite number, not {value}")
            })?),
        };
        Ok(Self {
            density_map: map_from_json(m, "density_map", 1)?,
            alpha_map: map_from_json(m, "alpha_map", 1)?,
            tint_map: map_from_json(m, "tint_map", 3)?,
            roughness_levels: levels,
            map_filter: optional_name(m, "map_filter", &filter_names())?,
        })
    }
}

/// The map `key` of a JSON material: rows of equal length, each texel a number (`channels`
/// 1) or an array of `channels` numbers.
fn map_from_json(
    m: &Map<String, Value>,
    key: &str,
    channels: usize,
) -> Result<Option<MapSpec>, String> {
    let Some(value) = m.get(key) else {
        return Ok(None);
    };
    let texel_form = if channels == 1 {
        "numbers".to_owned()
    } else {
        format!("[{}] arrays", vec!["x"; channels].join(", "))
    };
    let shape_error = || format!("material.{key} must be an array of rows of {texel_form}");
    let rows = value
        .as_array()
        .filter(|r| !r.is_empty())
        .ok_or_else(shape_error)?;
    let width = rows[0].as_array().map_or(0, Vec::len);
    if width == 0 {
        return Err(shape_error());
    }
    let mut values = Vec::with_capacity(width * rows.len() * channels);
    for (row, texels) in rows.iter().enumerate() {
        let texels = texels
            .as_array()
            .filter(|t| t.len() == width)
            .ok_or_else(|| {
                format!("material.{key}: row {row} must hold {width} texels like row 0")
            })?;
        for (column, texel) in texels.iter().enumerate() {
            let numbers: Vec<Option<f64>> = match (channels, texel) {
                (1, texel) => vec![texel.as_f64()],
                (_, Value::Array(parts)) if parts.len() == channels => {
                    parts.iter().map(Value::as_f64).collect()
                }
                _ => vec![None],
            };
            for number in numbers {
                values.push(number.ok_or_else(|| {
                    format!(
                        "material.{key}: texel (column {column}, row {row}) is {texel}, not {}",
                        if channels == 1 {
                            "a number"
                        } else {
                            "three numbers"
                        }
                    )
                })?);
            }
        }
    }
    Ok(Some(MapSpec {
        width,
        height: rows.len(),
        values,
    }))
}

#[cfg(test)]
mod tests {
    use serde_json::json;

    use crate::MaterialSpec;

    fn error_of(material: serde_json::Value) -> String {
        MaterialSpec::from_json(&material)
            .and_then(|spec| spec.build())
            .map(|_| ())
            .unwrap_err()
    }

    fn with(field: &str, value: serde_json::Value) -> serde_json::Value {
        let mut material = json!({"distribution": "beckmann", "alpha": 0.1, "particles": 1e6, "gamma_degrees": 1.0});
        material[field] = value;
        material
    }

    /// Maps read as rows from the top, texels named by (column, row) in every error.
    #[test]
    fn maps_are_rows_from_the_top_and_errors_name_the_texel() {
        let spec =
            MaterialSpec::from_json(&with("tint_map", json!([[[1, 0.5, 0], [0, 0, 1]]]))).unwrap();
        let tint = spec.maps.tint_map.unwrap();
        assert_eq!((tint.width, tint.height), (2, 1));
        assert_eq!(tint.values, [1.0, 0.5, 0.0, 0.0, 0.0, 1.0]);
        let spec =
            MaterialSpec::from_json(&with("density_map", json!([[1, 0.5], [0.25, 0]]))).unwrap();
        assert_eq!(spec.maps.density_map.unwrap().values, [1.0, 0.5, 0.25, 0.0]);
        for (field, value, message) in [
            (
                "density_map",
                json!([[1, 1.5], [0, 0]]),
                "material.density_map: texel (column 1, row 0) is 1.5",
            ),
            (
                "density_map",
                json!([[1, 1], [0]]),
                "material.density_map: row 1 must hold 2 texels like row 0",
            ),
            (
                "density_map",
                json!([[1, "x"]]),
                "material.density_map: texel (column 1, row 0) is \"x\", not a number",
            ),
            (
                "density_map",
                json!(3),
                "material.density_map must be an array of rows of numbers",
            ),
            (
                "density_map",
                json!([[0, 0]]),
                "material.density_map: every texel is 0",
            ),
            (
                "alpha_map",
                json!([[0.1], [0.0]]),
                "material.alpha_map: texel (column 0, row 1) is 0.0",
            ),
            (
                "tint_map",
                json!([[[1, 1]]]),
                "material.tint_map: texel (column 0, row 0) is [1,1], not three numbers",
            ),
            (
                "tint_map",
                json!([[[1, 1, -1]]]),
                "material.tint_map: texel (column 0, row 0) is -1.0",
            ),
            (
                "roughness_levels",
                json!(0),
                "material.roughness_levels = 0.0 must be a whole number in [1, 64]",
            ),
            (
                "map_filter",
                json!("cubic"),
                "material.map_filter \"cubic\" is unknown: use \"nearest\" or \"bilinear\"",
            ),
            (
                "map_filter",
                json!(1),
                "material.map_filter 1 is unknown: use \"nearest\" or \"bilinear\"",
            ),
        ] {
            let error = error_of(with(field, value));
            assert!(error.starts_with(message), "{field}: {error}");
        }
        let mut both = with("density_map", json!([[1, 1]]));
        both["alpha_map"] = json!([[0.1], [0.2]]);
        assert!(error_of(both).contains("they must have the same size"));
    }

    /// `map_filter` reaches the density and roughness maps (not the tint, which stays nearest);
    /// "nearest" is the material without the field, bit for bit, and "bilinear" answers
    /// otherwise where the map has an edge.
    #[test]
    fn map_filter_applies_to_the_density_and_roughness_maps() {
        use glint_brdf::{DVec2, DVec3, MapFilter, QueryScratch};

        let mapped = |filter: Option<&str>| {
            let mut material = with("density_map", json!([[1, 0], [0.5, 1]]));
            material["alpha_map"] = json!([[0.1, 0.2], [0.3, 0.1]]);
            material["tint_map"] = json!([[[1, 0.5, 0], [0, 0, 1]], [[1, 1, 1], [0.2, 0.4, 0.6]]]);
            if let Some(filter) = filter {
                material["map_filter"] = json!(filter);
            }
            MaterialSpec::from_json(&material).unwrap().build().unwrap()
        };
        let (absent, nearest, bilinear) = (
            mapped(None),
            mapped(Some("nearest")),
            mapped(Some("bilinear")),
        );
        for (material, filter) in [
            (&absent, MapFilter::Nearest),
            (&nearest, MapFilter::Nearest),
            (&bilinear, MapFilter::Bilinear),
        ] {
            let parameters = material.brdf().parameters();
            assert_eq!(parameters.density_map.as_ref().unwrap().filter(), filter);
            assert_eq!(parameters.alpha_map.as_ref().unwrap().filter(), filter);
        }
        let (wi, wo) = (
            DVec3::new(0.1, 0.0, 1.0).normalize(),
            DVec3::new(-0.1, 0.05, 1.0).normalize(),
        );
        // Halfway between the centres of texels (0, 1) and (1, 1), where the filters differ.
        let uv = DVec2::new(0.5, 0.25);
        let smooth =
            |m: &crate::EvalMaterial| m.brdf().smooth_at(wi, wo, uv).to_array().map(f64::to_bits);
        assert_eq!(smooth(&absent), smooth(&nearest));
        assert_ne!(smooth(&absent), smooth(&bilinear));
        let mut scratch = QueryScratch::new();
        let mut eval = |m: &crate::EvalMaterial| {
            let e = m
                .eval(
                    &mut scratch,
                    wi.to_array(),
                    wo.to_array(),
                    uv.to_array(),
                    [0.2, 0.0],
                    [0.0, 0.2],
                )
                .unwrap();
            [e.count, e.expected_count].map(f64::to_bits)
        };
        assert_eq!(eval(&absent), eval(&nearest));
        assert_ne!(eval(&absent), eval(&bilinear));
    }
}
