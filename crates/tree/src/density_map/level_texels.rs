//! The texels of a family of density maps that share their support two at a time: a roughness
//! map's levels d·w_k, where each texel has weight on two neighbouring levels at most (the hat
//! functions of log α; one where the levels are exact).
//!
//! Stored per level, each map needs its own summed-area tables over every texel it touches, and
//! where α changes at every texel every level touches every tile: K levels cost K × 12.7 bytes
//! a texel. [`LevelTexels`] holds each texel's two levels' fixed-point values once, in 9 bytes,
//! and a level's map built on it ([`super::DensityMap::roughness_level`]) keeps only tables
//! over blocks of [`BLOCK`] × [`BLOCK`] texels (about 0.36 bytes a texel a level), reading the
//! texels themselves where a rectangle cuts a block (`density_map/blocked.rs`).
//!
//! A texel's entry: its lower level k (6 bits; [`MAX_LEVELS`] levels at most), its value q on
//! level k and q′ on level k + 1, each a fixed-point value in [0, 2³²] (33 bits). The 72 bits
//! are a `u64` (q and the low 31 bits of q′) and a `u8` (k and the two high bits of q′).
//!
//! A large map of its own (a density map of more than [`super::DensityMap`]'s
//! `BLOCKED_FROM_TEXELS` texels, `tables.rs`) is a family of one level stored in 33 bits a
//! texel ([`LevelTexels::single`]): q's low 32 bits in a `u32` and its 33rd (set only for
//! d = 1, q = 2³²) in a bit set, about 4.1 bytes a texel, with the same tables over blocks.

use super::{DensityMapError, fixed_point};

/// The most levels a family may have (k takes 6 bits).
pub const MAX_LEVELS: usize = 64;

/// The side, in texels, of the blocks a level's own tables cover (see `blocked.rs`).
pub(super) const BLOCK_SHIFT: u32 = 3;

/// 2^[`BLOCK_SHIFT`]: 8.
pub(super) const BLOCK: usize = 1 << BLOCK_SHIFT;

/// 33 bits: a fixed-point value (2³² is d = 1).
const VALUE_MASK: u64 = (1 << 33) - 1;

/// The texels of up to [`MAX_LEVELS`] density maps, each texel non-zero on two neighbouring
/// maps at most (see the module docs).
#[derive(Clone, PartialEq)]
pub struct LevelTexels {
    width: usize,
    height: usize,
    levels: usize,
    storage: Storage,
}

/// How a family holds its texels, by texel (i, j), j from v = 0, at j·W + i.
#[derive(Clone, PartialEq)]
enum Storage {
    /// Two levels a texel, 9 bytes.
    Pairs {
        /// q on the lower level | q′'s low 31 bits << 33.
        words: Vec<u64>,
        /// The lower level | q′'s two high bits << 6.
        tags: Vec<u8>,
    },
    /// One level, a map's own texels ([`LevelTexels::single`]), 33 bits.
    Single {
        /// q's low 32 bits.
        low: Vec<u32>,
        /// q's 33rd bit, texel t at bit t mod 64 of word t / 64.
        high: Vec<u64>,
    },
}

impl std::fmt::Debug for LevelTexels {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LevelTexels")
            .field("width", &self.width)
            .field("height", &self.height)
            .field("levels", &self.levels)
            .finish_non_exhaustive()
    }
}

impl LevelTexels {
    /// The bytes a family of `width` × `height` texels holds: 9 a texel, whatever the number
    /// of levels.
    #[must_use]
    pub fn bytes_for(width: usize, height: usize) -> usize {
        9 * width * height
    }

    /// The bytes a [`Self::single`] map of `width` × `height` texels holds: 33 bits a texel.
    pub(super) fn single_bytes_for(width: usize, height: usize) -> usize {
        let texels = width * height;
        4 * texels + 8 * texels.div_ceil(64)
    }

    /// One map's own texels, a family of one level in 33 bits a texel: `q(i, j)` gives texel
    /// (i, j)'s fixed-point value (j from v = 0), at most 2³² (d = 1). The caller has checked
    /// the size and the values (`DensityMap::with_filter`).
    pub(super) fn single(width: usize, height: usize, q: &dyn Fn(usize, usize) -> u64) -> Self {
        let texels = width * height;
        let mut low = Vec::with_capacity(texels);
        let mut high = vec![0u64; texels.div_ceil(64)];
        for j in 0..height {
            for i in 0..width {
                let value = q(i, j);
                debug_assert!(value <= 1 << 32);
                let at = j * width + i;
                high[at >> 6] |= (value >> 32) << (at & 63);
                low.push(value as u32);
            }
        }
        Self {
            width,
            height,
            levels: 1,
            storage: Storage::Single { low, high },
        }
    }

    /// Whether these are one map's own texels ([`Self::single`]), not a family its levels
    /// share.
    pub(super) fn is_single(&self) -> bool {
        matches!(self.storage, Storage::Single { .. })
    }

    /// The texels of `levels` maps of `width` × `height` texels: `texel(k)` gives texel k's
    /// (given row by row, row 0 at the top, as a map's values are) lower level and its values
    /// on that level and the next, each in [0, 1] (a texel on one level gives 0 for the next).
    ///
    /// # Errors
    /// [`DensityMapError::InvalidSize`] for no texel or more than
    /// [`super::DensityMap::MAX_TEXELS`]; [`DensityMapError::InvalidLevels`] for no level or
    /// more than [`MAX_LEVELS`]; [`DensityMapError::InvalidTexel`] for a value not in [0, 1], a
    /// lower level outside the family, or a non-zero value on the level past the last (its
    /// value reported).
    pub fn new(
        width: usize,
        height: usize,
        levels: usize,
        texel: impl Fn(usize) -> (usize, [f64; 2]),
    ) -> Result<Self, DensityMapError> {
        let texels = width.saturating_mul(height);
        if width == 0 || height == 0 || texels > super::DensityMap::MAX_TEXELS {
            return Err(DensityMapError::InvalidSize { width, height });
        }
        if !(1..=MAX_LEVELS).contains(&levels) {
            return Err(DensityMapError::InvalidLevels { levels });
        }
        let mut words = vec![0u64; texels];
        let mut tags = vec![0u8; texels];
        for k in 0..texels {
            let (lower, values) = texel(k);
            let (column, row) = (k % width, k / width);
            if let Some(&value) = values.iter().find(|v| !(0.0..=1.0).contains(*v)) {
                return Err(DensityMapError::InvalidTexel { column, row, value });
            }
            if lower >= levels {
                return Err(DensityMapError::InvalidTexel {
                    column,
                    row,
                    value: lower as f64,
                });
            }
            let [q, q_next] = values.map(fixed_point);
            if lower + 1 == levels && q_next != 0 {
                return Err(DensityMapError::InvalidTexel {
                    column,
                    row,
                    value: values[1],
                });
            }
            let at = (height - 1 - row) * width + column;
            words[at] = q | (q_next << 33);
            tags[at] = lower as u8 | (((q_next >> 31) as u8) << 6);
        }
        Ok(Self {
            width,
            height,
            levels,
            storage: Storage::Pairs { words, tags },
        })
    }

    /// Width and height in texels.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// How many levels the family has.
    #[must_use]
    pub fn levels(&self) -> usize {
        self.levels
    }

    /// The heap memory it holds, in bytes ([`Self::bytes_for`] its size; a single map's
    /// texels, `single_bytes_for`).
    #[must_use]
    pub fn heap_bytes(&self) -> usize {
        match &self.storage {
            Storage::Pairs { words, tags } => 8 * words.len() + tags.len(),
            Storage::Single { low, high } => 4 * low.len() + 8 * high.len(),
        }
    }

    /// The fixed-point value q of texel (i, j) (j from v = 0) on `level`.
    #[inline]
    pub(super) fn fixed(&self, level: usize, i: usize, j: usize) -> u64 {
        let at = j * self.width + i;
        let (words, tags) = match &self.storage {
            Storage::Pairs { words, tags } => (words, tags),
            Storage::Single { low, high } if level == 0 => {
                return u64::from(low[at]) | (((high[at >> 6] >> (at & 63)) & 1) << 32);
            }
            Storage::Single { .. } => return 0,
        };
        let tag = tags[at];
        let lower = usize::from(tag & 63);
        let word = words[at];
        if level == lower {
            word & VALUE_MASK
        } else if level == lower + 1 {
            (word >> 33) | (u64::from(tag >> 6) << 31)
        } else {
            0
        }
    }

    /// Σ of `level`'s q over texels [i0, i1) of row j (j from v = 0): a single map's row read
    /// as a slice (its low words summed, its 33rd bits counted), a family's texel by texel.
    #[inline]
    pub(super) fn row_sum(&self, level: usize, j: usize, (i0, i1): (usize, usize)) -> u64 {
        match &self.storage {
            Storage::Single { low, high } if level == 0 => {
                let (a, b) = (j * self.width + i0, j * self.width + i1);
                let lows: u64 = low[a..b].iter().map(|&v| u64::from(v)).sum();
                lows + (ones_in(high, a, b) << 32)
            }
            _ => (i0..i1).map(|i| self.fixed(level, i, j)).sum(),
        }
    }

    /// Whether `level`'s q is `value` at every texel [i0, i1) of row j (as [`Self::row_sum`]
    /// reads a row).
    #[inline]
    pub(super) fn row_is(
        &self,
        level: usize,
        j: usize,
        (i0, i1): (usize, usize),
        value: u64,
    ) -> bool {
        match &self.storage {
            Storage::Single { low, high } if level == 0 => {
                let (a, b) = (j * self.width + i0, j * self.width + i1);
                let top = value >> 32;
                low[a..b].iter().all(|&v| v == value as u32)
                    && ones_in(high, a, b) == if top == 1 { (b - a) as u64 } else { 0 }
            }
            _ => (i0..i1).all(|i| self.fixed(level, i, j) == value),
        }
    }

    /// The value changes g(i, j) = [q(i, j) ≠ q(i + 1, j)] + [q(i, j) ≠ q(i, j + 1)] of `level`
    /// at texel (i, j), a neighbour outside the map counting as no change (as a map's table of
    /// changes counts them).
    #[inline]
    pub(super) fn changes(&self, level: usize, i: usize, j: usize) -> u32 {
        let q = self.fixed(level, i, j);
        u32::from(i + 1 < self.width && self.fixed(level, i + 1, j) != q)
            + u32::from(j + 1 < self.height && self.fixed(level, i, j + 1) != q)
    }
}

/// How many bits [a, b) of the bit set `bits` are set (bit t at bit t mod 64 of word t / 64).
fn ones_in(bits: &[u64], a: usize, b: usize) -> u64 {
    if a >= b {
        return 0;
    }
    let (first, last) = (a >> 6, (b - 1) >> 6);
    let mask = |word: usize| {
        let low = if word == first {
            u64::MAX << (a & 63)
        } else {
            u64::MAX
        };
        let high = if word == last {
            u64::MAX >> (63 - ((b - 1) & 63))
        } else {
            u64::MAX
        };
        low & high
    };
    (first..=last)
        .map(|word| u64::from((bits[word] & mask(word)).count_ones()))
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every value in [0, 1] at every level, including d = 1 (2³², the 33rd bit) on the upper
    /// level, reads back as the fixed-point value given, and 0 on every other level.
    #[test]
    fn texels_read_back_their_two_levels() {
        let (width, height, levels) = (5, 3, 64);
        let values = [0.0, 1.0, 0.5, 1e-9, 0.999_999_999_9, 0.25];
        let texel = |k: usize| {
            let lower = (k * 13) % (levels - 1);
            (lower, [values[k % 6], values[(k + 1) % 6]])
        };
        let family = LevelTexels::new(width, height, levels, texel).unwrap();
        assert_eq!(family.heap_bytes(), LevelTexels::bytes_for(width, height));
        for k in 0..width * height {
            let (lower, [a, b]) = texel(k);
            let (i, j) = (k % width, height - 1 - k / width);
            for level in 0..levels {
                let expected = if level == lower {
                    fixed_point(a)
                } else if level == lower + 1 {
                    fixed_point(b)
                } else {
                    0
                };
                assert_eq!(
                    family.fixed(level, i, j),
                    expected,
                    "texel {k} level {level}"
                );
            }
        }
    }

    /// A single map's rows read as slices ([`LevelTexels::row_sum`], [`LevelTexels::row_is`])
    /// give what its texels give one by one, over spans that start and end anywhere in the
    /// bit set's words, d = 1 (the 33rd bit) included, and rows of one value.
    #[test]
    fn single_rows_read_what_their_texels_hold() {
        let mut rng = crate::tea::TeaRng::new([5, 6, 7, 8], 0, 8);
        for (width, height) in [(1, 3), (63, 2), (64, 3), (130, 5)] {
            let pattern: Vec<u64> = (0..width * height)
                .map(|k| match rng.next_bits() % 4 {
                    0 => 1 << 32,
                    1 => 0,
                    _ if k % 7 == 0 => rng.next_bits() >> 32,
                    _ => 1 << 32,
                })
                .collect();
            let single = LevelTexels::single(width, height, &|i, j| pattern[j * width + i]);
            assert_eq!(
                single.heap_bytes(),
                LevelTexels::single_bytes_for(width, height)
            );
            for j in 0..height {
                for i0 in 0..=width {
                    for i1 in i0..=width {
                        let texels = || (i0..i1).map(|i| single.fixed(0, i, j));
                        assert_eq!(single.row_sum(0, j, (i0, i1)), texels().sum::<u64>());
                        for value in [1 << 32, 0, single.fixed(0, i0.min(width - 1), j)] {
                            assert_eq!(
                                single.row_is(0, j, (i0, i1), value),
                                texels().all(|q| q == value),
                                "{width} x {height}: row {j} [{i0}, {i1}) = {value}"
                            );
                        }
                    }
                }
                for i in 0..width {
                    assert_eq!(single.fixed(0, i, j), pattern[j * width + i]);
                    assert_eq!(single.fixed(1, i, j), 0);
                }
            }
        }
    }

    #[test]
    fn invalid_families_are_refused() {
        let ok = |_| (0, [0.5, 0.5]);
        assert!(LevelTexels::new(0, 3, 2, ok).is_err());
        assert_eq!(
            LevelTexels::new(3, 3, 65, ok).unwrap_err(),
            DensityMapError::InvalidLevels { levels: 65 }
        );
        assert!(matches!(
            LevelTexels::new(3, 3, 2, |k| (0, [if k == 4 { 1.5 } else { 0.0 }, 0.0])),
            Err(DensityMapError::InvalidTexel {
                column: 1,
                row: 1,
                ..
            })
        ));
        assert!(LevelTexels::new(3, 3, 2, |_| (2, [0.5, 0.0])).is_err());
        assert_eq!(
            LevelTexels::new(3, 3, 0, ok).unwrap_err(),
            DensityMapError::InvalidLevels { levels: 0 }
        );
        // A value on the level past the last would be lost: refused.
        assert!(matches!(
            LevelTexels::new(3, 3, 2, |_| (1, [0.5, 0.25])),
            Err(DensityMapError::InvalidTexel { value: 0.25, .. })
        ));
        assert!(LevelTexels::new(3, 3, 2, |_| (1, [0.5, 0.0])).is_ok());
    }
}
