//! Fine slope squares remembered across queries. A square's probability under P22 (the 2 × 2
//! Gauss rule) and its log-linear law depend on the tree, the square's level and its indices
//! only, not on the query: a pixel's samples, and neighbouring pixels, meet the same squares
//! about the lobe, and each square costs four evaluations of the distribution and four
//! logarithms. The remembered values are the computed ones, so counts do not depend on what
//! the memo holds.

use super::tilt::Tilt;

/// log₂ of the memo's entries (512, about 37 KB).
const SQUARE_MEMO_BITS: u32 = 9;

/// What a fine slope square holds, whatever the query.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SquareLaw {
    /// Whether the 2 × 2 Gauss rule's mean of P22 is positive (else the square holds nothing).
    pub(super) positive: bool,
    /// Its probability under P22 by that rule.
    pub(super) probability: f64,
    /// Its log-linear law, `None` where a Gauss point's density vanishes (the log-slope is not
    /// finite).
    pub(super) tilt: Option<Tilt>,
}

#[derive(Clone, Copy, Debug)]
struct SquareEntry {
    /// The tree's id; 0 (no tree has it) for an empty slot.
    tree: u64,
    level: i32,
    index: [i64; 2],
    law: SquareLaw,
}

/// The memo: a direct-mapped table, each square in one slot.
#[derive(Clone, Debug, Default)]
pub(crate) struct SquareMemo {
    entries: Vec<SquareEntry>,
}

impl SquareMemo {
    const EMPTY: SquareEntry = SquareEntry {
        tree: 0,
        level: 0,
        index: [0, 0],
        law: SquareLaw {
            positive: false,
            probability: 0.0,
            tilt: None,
        },
    };

    /// The law of square `index` at `level` of tree `tree`: remembered, or `compute`d and
    /// remembered.
    #[inline]
    pub(super) fn law(
        &mut self,
        tree: u64,
        level: i32,
        index: [i64; 2],
        compute: impl FnOnce() -> SquareLaw,
    ) -> SquareLaw {
        if self.entries.is_empty() {
            self.entries = vec![Self::EMPTY; 1 << SQUARE_MEMO_BITS];
        }
        let key = (index[0] as u64).wrapping_mul(0xD6E8_FEB8_6659_FD93)
            ^ (index[1] as u64)
            ^ (level as u64).rotate_left(32)
            ^ tree.rotate_left(47);
        let slot = (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> (64 - SQUARE_MEMO_BITS)) as usize;
        let entry = &mut self.entries[slot];
        if entry.tree == tree && entry.level == level && entry.index == index {
            return entry.law;
        }
        let law = compute();
        *entry = SquareEntry {
            tree,
            level,
            index,
            law,
        };
        law
    }
}
