//! The error type of glint-tree.

use std::fmt;

/// Why a count tree or a query could not be built from the given parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TreeError {
    /// The particle count N must be an integer in [1, 2⁵³].
    ParticleCountOutOfRange {
        /// The rejected value.
        particles: u64,
    },
    /// ε (Eq. 10) must be in [0, 1]: it is a relative error, and above 1 Eq. 10 would accept
    /// any partial node's expected share as its count.
    InvalidEpsilon {
        /// The rejected value.
        epsilon: f64,
    },
    /// The dense regime's node scale must be in (0, 16]: the largest node answered from its
    /// sample, in widths of the query.
    InvalidDenseNodeScale {
        /// The rejected value.
        node_scale: f64,
    },
    /// The dense regime's mode must be one of `DenseCounts::NAMES`.
    UnknownDenseMode,
    /// The expected query area and solid angle (Eq. 11) must be finite and > 0.
    InvalidExpectedQuery,
    /// The quadrature tolerances δ_abs, δ_rel must be finite and ≥ 0.
    InvalidTolerance,
    /// The normal density was negative or not finite somewhere, or integrates to zero.
    InvalidDensity,
    /// A footprint had a NaN or infinite component.
    NonFiniteFootprint,
    /// A footprint edge had a component beyond ±[`crate::Footprint::MAX_EDGE`].
    FootprintTooLarge {
        /// The largest edge component's magnitude.
        component: f64,
    },
    /// Colour channels for particle areas must be 0 (none) to 3.
    InvalidColourChannels {
        /// The rejected value.
        channels: usize,
    },
    /// TEA needs at least one cycle.
    InvalidRounds,
    /// The top-level cache may hold at most 8 levels.
    TooManyCachedLevels {
        /// The rejected value.
        levels: u32,
    },
}

impl fmt::Display for TreeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::ParticleCountOutOfRange { particles } => {
                write!(
                    f,
                    "particle count {particles} is out of range: it must be in [1, 2^53]"
                )
            }
            Self::InvalidEpsilon { epsilon } => {
                write!(
                    f,
                    "epsilon = {epsilon:?} is invalid: it must be in [0, 1] (a relative error; 0 = exact)"
                )
            }
            Self::InvalidDenseNodeScale { node_scale } => write!(
                f,
                "dense_node_scale = {node_scale:?} is invalid: it must be in (0, 16] (the \
                 largest node answered from its sample, in widths of the query)"
            ),
            Self::UnknownDenseMode => write!(
                f,
                "dense must be \"lattice\" (the default: queries expecting many particles \
                 answer from a Poisson process at their own scale), \"sampled\" (dense nodes \
                 answer from rescaled samples) or \"exact\" (every particle resolved)"
            ),
            Self::InvalidExpectedQuery => write!(
                f,
                "expected query area and solid angle must be finite and > 0"
            ),
            Self::InvalidTolerance => {
                write!(
                    f,
                    "quadrature tolerances must be finite and >= 0, and the maximum depth below 30"
                )
            }
            Self::InvalidDensity => write!(
                f,
                "the normal density is negative or not finite somewhere, or integrates to zero"
            ),
            Self::NonFiniteFootprint => write!(f, "footprint has a NaN or infinite component"),
            Self::FootprintTooLarge { component } => write!(
                f,
                "footprint edge component {component:e} is beyond ±1e15 texture units"
            ),
            Self::InvalidColourChannels { channels } => {
                write!(f, "{channels} colour channels requested: use 0 (none) to 3")
            }
            Self::InvalidRounds => write!(f, "TEA needs at least one round"),
            Self::TooManyCachedLevels { levels } => {
                write!(f, "{levels} cached levels requested: use 0 to 8")
            }
        }
    }
}

impl std::error::Error for TreeError {}
