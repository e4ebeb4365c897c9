//! Node identities: the seeds of every node's random stream (Sec. 3.4).
//!
//! The paper labels the root 1 and child j ∈ {1, 2, 3, 4} of node i as 4i + j − 2. The labels
//! of depth d fill [(2·4ᵈ + 1)/3, (8·4ᵈ − 2)/3], disjoint ranges, so labels are unique. In 64
//! bits they overflow past depth 31; [`NodeId`] keeps them in 128 bits (exact to depth 62) and
//! beyond that replaces 4i + j − 2 by a 127-bit hash of (i, j) with the top bit set, which can
//! never equal a label (labels stay below 2¹²⁷). Hashed identities collide with probability
//! ~2⁻¹²⁷ per pair.

/// The identity of a count-tree node.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct NodeId(pub u128);

/// Labels at or above this value have no room for 4i + j − 2 below 2¹²⁷.
const LABEL_LIMIT: u128 = ((1u128 << 127) + 2 - 4) / 4;

impl NodeId {
    /// The root, labelled 1.
    pub const ROOT: Self = Self(1);

    /// Child `j` ∈ 0..4 (the paper's j − 1).
    #[inline]
    #[must_use]
    pub fn child(self, j: usize) -> Self {
        debug_assert!(j < 4);
        if self.0 < LABEL_LIMIT {
            // 4i + (j + 1) − 2.
            Self(4 * self.0 + j as u128 - 1)
        } else {
            Self(hash_child(self.0, j as u64) | (1u128 << 127))
        }
    }

    /// The 128-bit TEA key of this node's stream for the material `seed`. While the identity
    /// fits in 64 bits (depth ≤ 31) the key is (identity, mixed seed), injective in both.
    #[inline]
    #[must_use]
    pub fn key(self, seed: u64) -> [u32; 4] {
        let mixed = mix64(seed ^ 0x6A09_E667_F3BC_C908);
        let low = self.0 as u64;
        let high = (self.0 >> 64) as u64 ^ mixed;
        [
            low as u32,
            (low >> 32) as u32,
            high as u32,
            (high >> 32) as u32,
        ]
    }
}

/// The SplitMix64 finalizer (Steele, Lea and Flood 2014): a bijective 64-bit mix.
#[inline]
#[must_use]
pub(crate) fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A 128-bit hash of (parent, j) from two rounds of cross-mixed 64-bit finalizers.
fn hash_child(parent: u128, j: u64) -> u128 {
    let (lo, hi) = (parent as u64, (parent >> 64) as u64);
    let a = mix64(lo ^ mix64(hi ^ (j + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15)));
    let b = mix64(hi ^ mix64(a ^ lo ^ 0xD1B5_4A32_D192_ED03));
    (u128::from(b) << 64) | u128::from(a)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;

    #[test]
    fn labels_follow_the_paper() {
        let root = NodeId::ROOT;
        assert_eq!(
            (0..4).map(|j| root.child(j).0).collect::<Vec<_>>(),
            vec![3, 4, 5, 6]
        );
        assert_eq!(NodeId(3).child(0).0, 11);
        assert_eq!(NodeId(6).child(3).0, 26);
    }

    #[test]
    fn unique_at_depth_64() {
        // A complete level at depth 6, and one below depth 64 (hashed identities): distinct.
        let mut level = vec![NodeId::ROOT];
        for _ in 0..6 {
            level = level
                .iter()
                .flat_map(|n| (0..4).map(move |j| n.child(j)))
                .collect();
        }
        // Jump to depth 64 along path 0, then expand 6 levels: 4096 nodes, all distinct.
        let mut deep = NodeId::ROOT;
        for _ in 0..58 {
            deep = deep.child(1);
        }
        let mut deep_level = vec![deep];
        for _ in 0..6 {
            deep_level = deep_level
                .iter()
                .flat_map(|n| (0..4).map(move |j| n.child(j)))
                .collect();
        }
        let distinct: HashSet<_> = deep_level.iter().collect();
        assert_eq!(distinct.len(), 4096);
        assert!(
            deep_level.iter().all(|n| n.0 >> 127 == 1),
            "depth 64 uses hashed identities"
        );
        let distinct: HashSet<_> = level.iter().collect();
        assert_eq!(distinct.len(), 4096);
    }

    #[test]
    fn keys_separate_seeds_and_nodes() {
        let mut keys = HashSet::new();
        for seed in 0..64u64 {
            for id in 1..200u128 {
                assert!(keys.insert(NodeId(id).key(seed)));
            }
        }
    }
}
