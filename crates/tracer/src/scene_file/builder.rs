//! The [`Builder`] that turns a scene file's sections into a scene, naming the file in every
//! error: its errors, the reading of a section into its typed form with the path to the field,
//! and the `type` of tagged tables (materials, shapes, lights). Each section's building is in
//! the module of that section.

use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;

use super::budget::Budget;
use crate::error::TracerError;
use crate::limits::{self, echo};

/// A number for an error message (see [`limits::number`]).
pub(super) fn shown(x: f64) -> String {
    limits::number(x)
}

/// `name` and up to nine more of `names`, quoted and bounded, for an error message.
pub(super) fn name_list<'a>(names: impl ExactSizeIterator<Item = &'a str>) -> String {
    const SHOWN: usize = 10;
    let total = names.len();
    let mut out: Vec<String> = names.take(SHOWN).map(echo).collect();
    if total > SHOWN {
        out.push(format!("… {total} in all"));
    }
    out.join(", ")
}

/// Builds scenes from one file, naming it in every error.
pub(super) struct Builder<'a> {
    pub(super) file: &'a Path,
    pub(super) directory: PathBuf,
    pub(super) budget: Budget,
}

pub(super) type Checked<T> = Result<T, TracerError>;

impl Builder<'_> {
    pub(super) fn fail<T>(
        &self,
        field: impl Into<String>,
        problem: impl Into<String>,
    ) -> Checked<T> {
        Err(TracerError::Scene {
            file: self.file.to_path_buf(),
            field: field.into(),
            problem: problem.into(),
        })
    }

    pub(super) fn asset(&self, relative: &str) -> PathBuf {
        self.directory.join(relative)
    }

    pub(super) fn brdf_error(&self, field: &str, e: &glint_brdf::BrdfError) -> TracerError {
        TracerError::Scene {
            file: self.file.to_path_buf(),
            field: field.into(),
            problem: e.to_string(),
        }
    }

    /// `value` read as a `T`, errors naming the field by `field` and the path inside it.
    pub(super) fn section<T: DeserializeOwned>(
        &self,
        field: &str,
        value: toml::Value,
    ) -> Checked<T> {
        value.try_into().map_err(|e: toml::de::Error| {
            // The path inside the value is only in the error's display: "message\nin `a.b`".
            let shown = e.to_string();
            let inner = shown
                .lines()
                .rev()
                .find_map(|line| line.strip_prefix("in `")?.strip_suffix('`'))
                .filter(|keys| !keys.is_empty());
            let field = match (field.is_empty(), inner) {
                (_, None) => field.to_string(),
                (true, Some(keys)) => keys.to_string(),
                (false, Some(keys)) => format!("{field}.{keys}"),
            };
            TracerError::Scene {
                file: self.file.to_path_buf(),
                field,
                problem: echo(e.message()),
            }
        })
    }

    /// The `type` of a tagged table (a material, shape or light) among `types`, and the table
    /// without it.
    pub(super) fn tagged(
        &self,
        field: &str,
        value: toml::Value,
        types: &[&str],
    ) -> Checked<(String, toml::Value)> {
        let expected = types
            .iter()
            .map(|t| format!("`{t}`"))
            .collect::<Vec<_>>()
            .join(", ");
        let toml::Value::Table(mut table) = value else {
            return self.fail(
                field,
                format!("expected a table with a `type` (one of {expected})"),
            );
        };
        let kind = match table.remove("type") {
            None => return self.fail(field, format!("missing `type` (one of {expected})")),
            Some(toml::Value::String(kind)) if types.contains(&kind.as_str()) => kind,
            Some(toml::Value::String(kind)) => {
                return self.fail(
                    format!("{field}.type"),
                    format!("unknown type `{}`, expected one of {expected}", echo(&kind)),
                );
            }
            Some(other) => {
                return self.fail(
                    format!("{field}.type"),
                    format!(
                        "expected a string, one of {expected}, got {}",
                        echo(&other.to_string())
                    ),
                );
            }
        };
        Ok((kind, toml::Value::Table(table)))
    }
}
