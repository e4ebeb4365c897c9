//! Fine slope squares remembered across queries. A square's probability under P22 (the 2 × 2
//! Gauss rule) and its log-linear law depend on the tree, the square's level and its indices
//! only, not on the query: a pixel's samples, and neighbouring pixels, meet the same squares
//! about the lobe, and each square costs four evaluations of the distribution and four
//! logarithms. The remembered values are the computed ones, so counts do not depend on what
//! the memo holds. A square met for the first time is computed whole (its logarithms and law
//! too, even where the query's conic does not meet it).

use super::tilt::Tilt;
use crate::tree::scratch::memo_slot;

/// log₂ of the memo's entries (512 of 88 bytes, 45 KB).
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

/// One slot: the square it holds (a tree's id, a level, indices) and the square's law.
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
        let entry = &mut self.entries[memo_slot(key, SQUARE_MEMO_BITS)];
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

#[cfg(test)]
mod tests {
    use glam::DVec2;

    use super::*;

    /// A law that names its square, so that a wrong slot shows.
    fn law_of(tree: u64, level: i32, index: [i64; 2]) -> SquareLaw {
        SquareLaw {
            positive: true,
            probability: tree as f64 * 1e6
                + f64::from(level) * 1e3
                + (index[0] * 31 + index[1]) as f64,
            tilt: Some(Tilt::new(DVec2::new(index[0] as f64, index[1] as f64))),
        }
    }

    /// The memo's size is what its docs say.
    #[test]
    fn the_memo_holds_512_entries_of_88_bytes() {
        assert_eq!(std::mem::size_of::<SquareEntry>(), 88);
        let mut memo = SquareMemo::default();
        let _ = memo.law(1, 0, [0, 0], || law_of(1, 0, [0, 0]));
        assert_eq!(memo.entries.len(), 512);
    }

    /// Every answer is its own square's, whatever the memo held: the same square of two trees,
    /// and far more squares than slots (evictions and collisions), each computed once while it
    /// stays, again once evicted.
    #[test]
    fn the_memo_answers_each_square_with_its_own_law() {
        let mut memo = SquareMemo::default();
        let mut computed = 0;
        for round in 0..2 {
            for tree in [1, 2] {
                for level in [3, 4] {
                    for jx in -20..20 {
                        for jy in -20..20 {
                            let index = [jx, jy];
                            let law = memo.law(tree, level, index, || {
                                computed += 1;
                                law_of(tree, level, index)
                            });
                            let expected = law_of(tree, level, index);
                            assert_eq!(law.probability, expected.probability, "round {round}");
                        }
                    }
                }
            }
        }
        // 6400 squares a round in 512 slots: most are evicted before the second round.
        assert!(computed > 6400 + 5000, "{computed}");
        // A square met again at once is remembered, each tree's its own.
        let mut computed = 0;
        for _ in 0..3 {
            for tree in [1, 2] {
                let law = memo.law(tree, 7, [5, -5], || {
                    computed += 1;
                    law_of(tree, 7, [5, -5])
                });
                assert_eq!(law.probability, law_of(tree, 7, [5, -5]).probability);
            }
        }
        assert!(computed <= 2 + 2, "{computed}");
    }
}
