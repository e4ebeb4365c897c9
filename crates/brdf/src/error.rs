//! The error type of glint-brdf.

use std::fmt;

/// Why a BRDF or material could not be built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BrdfError {
    /// Roughness α must be finite and in [1e-4, 1].
    InvalidRoughness {
        /// The rejected value.
        alpha: f64,
    },
    /// A Fresnel parameter is outside its range: η in [10⁻³, 10³], k in [0, 10³]
    /// ([`crate::Fresnel::MIN_ETA`], [`crate::Fresnel::MAX_ETA`], [`crate::Fresnel::MAX_K`]).
    InvalidFresnel {
        /// `"eta"` or `"k"`.
        parameter: &'static str,
        /// The rejected value.
        value: f64,
    },
    /// The cone radius γ must be in [10⁻⁶ rad, 60°] (below 10⁻⁶ rad, about 0.2 arc seconds, the
    /// conic's solid angle loses its precision).
    InvalidConeRadius {
        /// The rejected value (radians).
        gamma: f64,
    },
    /// The sampling roughness scale must be finite and ≥ 1.
    InvalidSamplingScale {
        /// The rejected value.
        scale: f64,
    },
    /// The negligible-count threshold must be finite and ≥ 0.
    InvalidNegligibleCount {
        /// The rejected value.
        count: f64,
    },
    /// The expected footprint area (Eq. 11) must be finite and > 0.
    InvalidExpectedFootprintArea {
        /// The rejected value.
        area: f64,
    },
    /// The pdf's quadrature needs 1 to 4096 points.
    InvalidPdfPoints {
        /// The rejected value.
        points: usize,
    },
    /// The count tree rejected the material.
    Tree(glint_tree::TreeError),
}

impl fmt::Display for BrdfError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::InvalidRoughness { alpha } => {
                write!(
                    f,
                    "roughness alpha = {alpha:?} is invalid: it must be finite and in [1e-4, 1]"
                )
            }
            Self::InvalidFresnel { parameter, value } => write!(
                f,
                "Fresnel {parameter} = {value:?} is invalid: eta must be in [1e-3, 1e3] and k in [0, 1e3]"
            ),
            Self::InvalidConeRadius { gamma } => write!(
                f,
                "cone radius gamma = {gamma:?} rad is invalid: it must be in [1e-6 rad, 60 degrees]"
            ),
            Self::InvalidSamplingScale { scale } => {
                write!(
                    f,
                    "sampling roughness scale {scale:?} is invalid: it must be finite and >= 1"
                )
            }
            Self::InvalidNegligibleCount { count } => write!(
                f,
                "negligible count {count:?} is invalid: it must be finite and >= 0 (0 disables it)"
            ),
            Self::InvalidExpectedFootprintArea { area } => write!(
                f,
                "expected footprint area {area:?} is invalid: it must be finite and > 0 (texture units)"
            ),
            Self::InvalidPdfPoints { points } => {
                write!(f, "{points} pdf quadrature points requested: use 1 to 4096")
            }
            Self::Tree(error) => write!(f, "count tree: {error}"),
        }
    }
}

impl std::error::Error for BrdfError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Tree(error) => Some(error),
            _ => None,
        }
    }
}

impl From<glint_tree::TreeError> for BrdfError {
    fn from(error: glint_tree::TreeError) -> Self {
        Self::Tree(error)
    }
}
