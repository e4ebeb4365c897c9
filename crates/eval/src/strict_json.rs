//! JSON text parsed as `serde_json` does, except that an object holding one key twice is an
//! error naming the key: `{"alpha": 0.1, "alpha": 0.5}` would otherwise keep the last value
//! silently, and a request must mean one thing.

use std::fmt;

use serde::de::{self, Deserialize, Deserializer, MapAccess, SeqAccess, Visitor};
use serde_json::{Map, Value};

/// `text` as a JSON value.
///
/// # Errors
/// serde_json's message for invalid JSON; "duplicate key `k`" for a repeated key at any depth.
pub(crate) fn parse(text: &str) -> Result<Value, String> {
    serde_json::from_str::<Strict>(text)
        .map(|strict| strict.0)
        .map_err(|e| e.to_string())
}

/// A JSON value whose objects have distinct keys.
struct Strict(Value);

impl<'de> Deserialize<'de> for Strict {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer.deserialize_any(StrictVisitor).map(Strict)
    }
}

struct StrictVisitor;

impl<'de> Visitor<'de> for StrictVisitor {
    type Value = Value;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a JSON value")
    }

    fn visit_bool<E>(self, v: bool) -> Result<Value, E> {
        Ok(Value::Bool(v))
    }

    fn visit_i64<E>(self, v: i64) -> Result<Value, E> {
        Ok(Value::from(v))
    }

    fn visit_u64<E>(self, v: u64) -> Result<Value, E> {
        Ok(Value::from(v))
    }

    fn visit_f64<E>(self, v: f64) -> Result<Value, E> {
        Ok(Value::from(v))
    }

    fn visit_str<E>(self, v: &str) -> Result<Value, E> {
        Ok(Value::String(v.to_owned()))
    }

    fn visit_string<E>(self, v: String) -> Result<Value, E> {
        Ok(Value::String(v))
    }

    fn visit_unit<E>(self) -> Result<Value, E> {
        Ok(Value::Null)
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Value, A::Error> {
        let mut values = Vec::new();
        while let Some(Strict(value)) = seq.next_element()? {
            values.push(value);
        }
        Ok(Value::Array(values))
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Value, A::Error> {
        let mut object = Map::new();
        while let Some(key) = map.next_key::<String>()? {
            if object.contains_key(&key) {
                return Err(de::Error::custom(format!("duplicate key `{key}`")));
            }
            let Strict(value) = map.next_value()?;
            object.insert(key, value);
        }
        Ok(Value::Object(object))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Valid JSON parses to serde_json's own value, numbers bit for bit; a key given twice,
    /// at the top or nested, is an error naming it.
    #[test]
    fn duplicate_keys_are_refused_and_the_rest_parses_as_serde_json() {
        for text in [
            r#"{"a": [1, -2, 3.5e-300, 0.1, true, null, "x"], "b": {"c": {}}}"#,
            "[]",
            "18446744073709551615",
            r#"{"wi": [0.1, 0.2, 0.9744], "material": {"alpha": 0.1, "alpha_y": 0.1}}"#,
        ] {
            let expected: Value = serde_json::from_str(text).unwrap();
            assert_eq!(parse(text).unwrap(), expected, "{text}");
        }
        for (text, key) in [
            (r#"{"alpha": 0.1, "alpha": 0.5}"#, "alpha"),
            (r#"{"material": {"seed": 1, "x": 2, "seed": 3}}"#, "seed"),
            (r#"[{"u": 1}, {"v": 1, "v": 1}]"#, "v"),
        ] {
            let message = parse(text).unwrap_err();
            assert!(
                message.contains(&format!("duplicate key `{key}`")),
                "{message}"
            );
        }
        assert!(parse("{\"a\": ").is_err());
    }
}
