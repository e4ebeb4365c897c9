//! The tracer's errors: each names the file, the field or asset, and the problem.

use std::fmt;
use std::path::PathBuf;

/// What went wrong loading a scene or writing an image.
#[derive(Clone, Debug, PartialEq)]
pub enum TracerError {
    /// The scene file is not valid: `field` is the path to the offending value
    /// (e.g. `shapes[2].radius`), or empty when the file itself cannot be parsed.
    Scene {
        /// The scene file.
        file: PathBuf,
        /// The field at fault.
        field: String,
        /// What is wrong with it.
        problem: String,
    },
    /// An asset (mesh, texture, environment map) could not be read.
    Asset {
        /// The asset's path.
        path: PathBuf,
        /// What is wrong with it.
        problem: String,
    },
    /// An image could not be written.
    Output {
        /// The output path.
        path: PathBuf,
        /// What went wrong.
        problem: String,
    },
    /// Render settings out of range (resolution, samples per pixel, depth).
    Settings {
        /// The setting at fault.
        setting: &'static str,
        /// What is wrong with it.
        problem: String,
    },
}

impl fmt::Display for TracerError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Scene {
                file,
                field,
                problem,
            } => {
                if field.is_empty() {
                    write!(f, "{}: {problem}", file.display())
                } else {
                    write!(f, "{}: {field}: {problem}", file.display())
                }
            }
            Self::Asset { path, problem } => write!(f, "asset {}: {problem}", path.display()),
            Self::Output { path, problem } => {
                write!(f, "cannot write {}: {problem}", path.display())
            }
            Self::Settings { setting, problem } => write!(f, "render setting {setting}: {problem}"),
        }
    }
}

impl std::error::Error for TracerError {}
