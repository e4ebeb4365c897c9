//! The checks of plain values that every section uses: points and vectors within the
//! coordinate limit, unit directions, positive numbers, numbers in a range and bounded colours.

use glam::DVec3;

use super::builder::{Builder, Checked, shown};
use super::numbers::Colour;
use crate::limits;

impl Builder<'_> {
    /// A position or vector: finite and within [`limits::MAX_COORDINATE`] per component.
    pub(super) fn point(&self, field: &str, v: [f64; 3]) -> Checked<DVec3> {
        let v = DVec3::from_array(v);
        // `max_element` skips NaN: finiteness is checked on its own.
        if v.is_finite() && v.abs().max_element() <= limits::MAX_COORDINATE {
            Ok(v)
        } else {
            self.fail(
                field,
                format!(
                    "{}: coordinates must be finite and within ±{:e}",
                    limits::vector(v),
                    limits::MAX_COORDINATE
                ),
            )
        }
    }

    /// A unit direction from any finite, non-zero vector (scaled first, so that neither tiny
    /// nor huge components underflow or overflow).
    pub(super) fn direction(&self, field: &str, v: [f64; 3]) -> Checked<DVec3> {
        let v = DVec3::from_array(v);
        if !v.is_finite() {
            return self.fail(field, format!("{} is not finite", limits::vector(v)));
        }
        let largest = v.abs().max_element();
        if largest > 0.0 {
            Ok((v / largest).normalize())
        } else {
            self.fail(field, "a direction cannot be the zero vector")
        }
    }

    pub(super) fn positive(&self, field: &str, x: f64) -> Checked<f64> {
        if x > 0.0 && x.is_finite() {
            Ok(x)
        } else {
            self.fail(
                field,
                format!("must be positive and finite, got {}", shown(x)),
            )
        }
    }

    /// A number in [lowest, highest] (NaN is not).
    pub(super) fn within(&self, field: &str, x: f64, lowest: f64, highest: f64) -> Checked<f64> {
        if x >= lowest && x <= highest {
            Ok(x)
        } else {
            self.fail(
                field,
                format!(
                    "must be in [{}, {}], got {}",
                    shown(lowest),
                    shown(highest),
                    shown(x)
                ),
            )
        }
    }

    /// A colour with every component in [0, `highest`]; `what` names the quantity.
    pub(super) fn colour_at_most(
        &self,
        field: &str,
        c: Colour,
        highest: f64,
        what: &str,
    ) -> Checked<DVec3> {
        let c = c.rgb();
        if c.is_finite() && c.min_element() >= 0.0 && c.max_element() <= highest {
            Ok(c)
        } else {
            self.fail(
                field,
                format!(
                    "{what} components must be in [0, {}], got {}",
                    shown(highest),
                    limits::vector(c)
                ),
            )
        }
    }
}
