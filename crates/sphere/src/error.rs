//! The error type of glint-sphere: every way a caller's input can be rejected.

use std::fmt;

/// Why a spherical object could not be built from the given input.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SphereError {
    /// A direction had a NaN or infinite component.
    NonFiniteDirection {
        /// Which argument, e.g. `"wi"`.
        name: &'static str,
    },
    /// A direction had zero length and so names no direction.
    ZeroDirection {
        /// Which argument, e.g. `"wo"`.
        name: &'static str,
    },
    /// The cone radius γ (radians) was not a finite number in (0, π).
    ConeRadiusOutOfRange {
        /// The rejected value.
        gamma: f64,
    },
    /// The three vertices of a triangle lie on one great circle (or two coincide).
    DegenerateTriangle,
}

impl fmt::Display for SphereError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NonFiniteDirection { name } => {
                write!(f, "direction `{name}` has a NaN or infinite component")
            }
            Self::ZeroDirection { name } => write!(f, "direction `{name}` has zero length"),
            Self::ConeRadiusOutOfRange { gamma } => write!(
                f,
                "cone radius gamma = {gamma} rad is out of range: it must be finite and in (0, pi)"
            ),
            Self::DegenerateTriangle => write!(
                f,
                "triangle vertices lie on one great circle (or coincide): the triangle has no area"
            ),
        }
    }
}

impl std::error::Error for SphereError {}

/// Normalizes `v`, naming it `name` in the error if it is not a usable direction.
pub(crate) fn unit_direction(
    v: glam::DVec3,
    name: &'static str,
) -> Result<glam::DVec3, SphereError> {
    if !v.is_finite() {
        return Err(SphereError::NonFiniteDirection { name });
    }
    // The common case: the squared length is a normal number, so v·(1/|v|) neither under- nor
    // overflows (two roundings per component, like `normalize`).
    let length_squared = v.length_squared();
    if length_squared > 1e-300 && length_squared < 1e300 {
        return Ok(v * (1.0 / length_squared.sqrt()));
    }
    // Scale first so that tiny and huge (finite) inputs normalize without under/overflow.
    let scale = v.abs().max_element();
    if scale == 0.0 {
        return Err(SphereError::ZeroDirection { name });
    }
    Ok((v / scale).normalize())
}
