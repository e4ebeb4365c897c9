//! The tracer's errors: each names the file, the field or asset, and the problem. Input they
//! quote (names, paths, lines of a file) is cut to [`crate::limits::MAX_ECHO_CHARS`] characters
//! when displayed.

use std::fmt;
use std::path::{Path, PathBuf};

use crate::limits::{echo, echo_lines};

/// A path for an error message, bounded.
fn shown(path: &Path) -> String {
    echo(&path.display().to_string())
}

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
    /// The camera cannot form an image at a frame: the pose interpolated between keyframes is
    /// degenerate (the eye at the look-at point, up along the view direction).
    Camera {
        /// The frame.
        frame: f64,
        /// What is wrong with the pose.
        problem: String,
    },
    /// Render settings out of range (resolution, samples per pixel, depth).
    Settings {
        /// The setting at fault.
        setting: &'static str,
        /// What is wrong with it.
        problem: String,
    },
    /// The render was cancelled before it finished (see [`crate::film::render_until`]).
    Cancelled,
}

impl fmt::Display for TracerError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Scene {
                file,
                field,
                problem,
            } => {
                let (file, problem) = (shown(file), echo_lines(problem));
                if field.is_empty() {
                    write!(f, "{file}: {problem}")
                } else {
                    write!(f, "{file}: {}: {problem}", echo(field))
                }
            }
            Self::Asset { path, problem } => {
                write!(f, "asset {}: {}", shown(path), echo_lines(problem))
            }
            Self::Output { path, problem } => {
                write!(f, "cannot write {}: {}", shown(path), echo_lines(problem))
            }
            Self::Camera { frame, problem } => {
                write!(f, "camera at frame {frame}: {}", echo_lines(problem))
            }
            Self::Settings { setting, problem } => {
                write!(f, "render setting {setting}: {}", echo_lines(problem))
            }
            Self::Cancelled => write!(f, "the render was cancelled"),
        }
    }
}

impl std::error::Error for TracerError {}
