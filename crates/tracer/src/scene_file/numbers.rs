//! The scene format's numbers given as one number or an array: [`Colour`] (grey or linear RGB)
//! and [`Roughness`] (isotropic or [α_x, α_y]), with an error that says which forms are
//! accepted.

use glam::DVec3;
use serde::Deserialize;

/// A colour: one number (grey) or three (linear RGB).
#[derive(Clone, Copy, Debug)]
pub(super) struct Colour(DVec3);

impl Colour {
    pub(super) fn rgb(self) -> DVec3 {
        self.0
    }
}

/// Roughness: one number (isotropic) or [α_x, α_y].
#[derive(Clone, Copy, Debug)]
pub(super) struct Roughness(pub(super) f64, pub(super) f64);

/// Reads one number or an array of `N` numbers, for [`Colour`] and [`Roughness`], with an error
/// that says which forms are accepted.
struct NumbersVisitor<const N: usize>(&'static str);

impl<'de, const N: usize> serde::de::Visitor<'de> for NumbersVisitor<N> {
    type Value = [f64; N];

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "a number or an array of {N} numbers {}", self.0)
    }

    fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<Self::Value, E> {
        Ok([v; N])
    }

    fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<Self::Value, E> {
        Ok([v as f64; N])
    }

    fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<Self::Value, E> {
        Ok([v as f64; N])
    }

    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
        let mut values = [0.0; N];
        for (i, value) in values.iter_mut().enumerate() {
            *value = seq
                .next_element()?
                .ok_or_else(|| serde::de::Error::invalid_length(i, &self))?;
        }
        if seq.next_element::<serde::de::IgnoredAny>()?.is_some() {
            return Err(serde::de::Error::invalid_length(N + 1, &self));
        }
        Ok(values)
    }
}

impl<'de> Deserialize<'de> for Colour {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let [r, g, b] = d.deserialize_any(NumbersVisitor::<3>("[r, g, b]"))?;
        Ok(Self(DVec3::new(r, g, b)))
    }
}

impl<'de> Deserialize<'de> for Roughness {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let [x, y] = d.deserialize_any(NumbersVisitor::<2>("[α_x, α_y]"))?;
        Ok(Self(x, y))
    }
}
