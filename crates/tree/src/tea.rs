//! The Tiny Encryption Algorithm as the source of pseudorandomness (Sec. 3.4, "Optimizations").
//!
//! TEA (Wheeler and Needham 1995) encrypts a 64-bit block (v0, v1) under a 128-bit key
//! (k0, k1, k2, k3). Each round does
//!
//! ```text
//!   sum += 0x9E3779B9
//!   v0  += ((v1 << 4) + k0) ^ (v1 + sum) ^ ((v1 >> 5) + k1)
//!   v1  += ((v0 << 4) + k2) ^ (v0 + sum) ^ ((v0 >> 5) + k3)
//! ```
//!
//! with wrapping 32-bit arithmetic. The cipher has 32 cycles (64 Feistel rounds); as a hash for
//! random numbers a few cycles suffice, and the paper uses 8. A node's stream encrypts the
//! counter (draw index, purpose) under the key (material seed, node identity), so every node has
//! its own reproducible stream and no state is carried between nodes.
//!
//! [`encrypt`] and [`encrypt_x4`] agree bit for bit; [`TeaRng`] wraps a stream in the
//! `rand_core` traits.

use core::convert::Infallible;

use rand_core::{SeedableRng, TryRng};
use wide::u32x4;

/// The round constant, ⌊2³² / φ⌋.
const DELTA: u32 = 0x9E37_79B9;

/// The number of TEA cycles the count tree uses by default (the paper's choice).
pub const DEFAULT_ROUNDS: u32 = 8;

/// Encrypts the block `(v0, v1)` under `key` with `rounds` TEA cycles.
#[inline]
#[must_use]
pub fn encrypt(mut v0: u32, mut v1: u32, key: [u32; 4], rounds: u32) -> (u32, u32) {
    let mut sum = 0u32;
    for _ in 0..rounds {
        sum = sum.wrapping_add(DELTA);
        v0 = v0.wrapping_add(
            (v1 << 4).wrapping_add(key[0]) ^ v1.wrapping_add(sum) ^ (v1 >> 5).wrapping_add(key[1]),
        );
        v1 = v1.wrapping_add(
            (v0 << 4).wrapping_add(key[2]) ^ v0.wrapping_add(sum) ^ (v0 >> 5).wrapping_add(key[3]),
        );
    }
    (v0, v1)
}

/// Four independent blocks at once: lane i of the result is `encrypt(v0[i], v1[i], key, rounds)`.
#[inline]
#[must_use]
pub fn encrypt_x4(mut v0: u32x4, mut v1: u32x4, key: [u32; 4], rounds: u32) -> (u32x4, u32x4) {
    let k = key.map(u32x4::splat);
    let mut sum = u32x4::ZERO;
    let delta = u32x4::splat(DELTA);
    for _ in 0..rounds {
        sum += delta;
        v0 += ((v1 << 4) + k[0]) ^ (v1 + sum) ^ ((v1 >> 5) + k[1]);
        v1 += ((v0 << 4) + k[2]) ^ (v0 + sum) ^ ((v0 >> 5) + k[3]);
    }
    (v0, v1)
}

/// A draw's 64 bits from its encrypted block (v0, v1): v0 high, v1 low.
#[inline]
fn join(v0: u32, v1: u32) -> u64 {
    (u64::from(v0) << 32) | u64::from(v1)
}

/// Draw `draw` of the stream (`key`, `purpose`), one scalar TEA block: the same as that draw
/// of `TeaRng::new(key, purpose, rounds)`, for a caller that needs one draw at a known index.
#[inline]
#[must_use]
pub fn draw_at(key: [u32; 4], purpose: u32, draw: u32, rounds: u32) -> u64 {
    let (a, b) = encrypt(draw, purpose, key, rounds);
    join(a, b)
}

/// Draw `draw` of the four streams (`key`, `purposes[i]`), in one 4-lane call: lane i equals
/// that draw of `TeaRng::new(key, purposes[i], rounds)`.
#[inline]
#[must_use]
pub fn draws_x4(key: [u32; 4], purposes: [u32; 4], draw: u32, rounds: u32) -> [u64; 4] {
    let (a, b) = encrypt_x4(u32x4::splat(draw), u32x4::new(purposes), key, rounds);
    let (a, b) = (a.to_array(), b.to_array());
    core::array::from_fn(|i| join(a[i], b[i]))
}

/// Maps 53 random bits to a uniform number in [0, 1).
#[inline]
#[must_use]
pub fn unit_f64(bits: u64) -> f64 {
    (bits >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// Maps 64 random bits to two uniform numbers in [0, 1), 32 bits each (high half first): a
/// point of a 2³²×2³² grid, for a leaf particle's position in its box.
#[inline]
#[must_use]
pub fn unit_pair(bits: u64) -> [f64; 2] {
    let scale = 1.0 / (1u64 << 32) as f64;
    [
        (bits >> 32) as f64 * scale,
        (bits & 0xFFFF_FFFF) as f64 * scale,
    ]
}

/// A counter-mode TEA stream: draw i is `encrypt(i, purpose, key)`. Draws are computed four at
/// a time by [`encrypt_x4`] (one 4-lane call costs little more than a scalar one) and handed
/// out in order, so the stream is the same as one scalar call per draw.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TeaRng {
    key: [u32; 4],
    purpose: u32,
    /// The index of the first draw not yet computed.
    counter: u32,
    rounds: u32,
    /// Draws counter − 4 … counter − 1; the last `buffered` of them are not handed out yet.
    buffer: [u64; 4],
    buffered: usize,
}

impl TeaRng {
    /// The stream for `key` and `purpose` (a tag that separates streams of one node), starting at
    /// draw 0, with `rounds` TEA cycles.
    #[must_use]
    pub fn new(key: [u32; 4], purpose: u32, rounds: u32) -> Self {
        Self {
            key,
            purpose,
            counter: 0,
            rounds,
            buffer: [0; 4],
            buffered: 0,
        }
    }

    /// The stream for `key` and `purpose` starting at draw `first_draw` (the draws before it
    /// are skipped, not computed).
    #[must_use]
    pub fn starting_at(key: [u32; 4], purpose: u32, rounds: u32, first_draw: u32) -> Self {
        Self {
            counter: first_draw,
            ..Self::new(key, purpose, rounds)
        }
    }

    /// The stream for `key` and `purpose` whose draw 0, `first`, the caller has computed
    /// (say, as one lane of [`draws_x4`]): the same stream as [`TeaRng::new`]'s.
    #[must_use]
    pub fn with_first_draw(key: [u32; 4], purpose: u32, rounds: u32, first: u64) -> Self {
        Self {
            counter: 1,
            buffer: [0, 0, 0, first],
            buffered: 1,
            ..Self::new(key, purpose, rounds)
        }
    }

    /// The next 64 random bits.
    #[inline]
    pub fn next_bits(&mut self) -> u64 {
        if self.buffered == 0 {
            self.refill();
        }
        let bits = self.buffer[4 - self.buffered];
        self.buffered -= 1;
        bits
    }

    /// Computes the next four draws in one 4-lane TEA call.
    #[inline]
    fn refill(&mut self) {
        let c = self.counter;
        let counters = u32x4::new([c, c.wrapping_add(1), c.wrapping_add(2), c.wrapping_add(3)]);
        let (a, b) = encrypt_x4(counters, u32x4::splat(self.purpose), self.key, self.rounds);
        let (a, b) = (a.to_array(), b.to_array());
        self.buffer = core::array::from_fn(|i| join(a[i], b[i]));
        self.counter = c.wrapping_add(4);
        self.buffered = 4;
    }

    /// The next uniform number in [0, 1).
    #[inline]
    pub fn uniform(&mut self) -> f64 {
        unit_f64(self.next_bits())
    }

    /// The next four uniform numbers in [0, 1); identical to four calls of
    /// [`TeaRng::uniform`].
    #[inline]
    pub fn uniform_x4(&mut self) -> [f64; 4] {
        core::array::from_fn(|_| self.uniform())
    }
}

impl TryRng for TeaRng {
    type Error = Infallible;

    fn try_next_u32(&mut self) -> Result<u32, Infallible> {
        Ok((self.next_bits() >> 32) as u32)
    }

    fn try_next_u64(&mut self) -> Result<u64, Infallible> {
        Ok(self.next_bits())
    }

    fn try_fill_bytes(&mut self, dst: &mut [u8]) -> Result<(), Infallible> {
        for chunk in dst.chunks_mut(8) {
            let bytes = self.next_bits().to_le_bytes();
            chunk.copy_from_slice(&bytes[..chunk.len()]);
        }
        Ok(())
    }
}

impl SeedableRng for TeaRng {
    /// The 128-bit key, little-endian words.
    type Seed = [u8; 16];

    fn from_seed(seed: [u8; 16]) -> Self {
        let word = |i: usize| u32::from_le_bytes([seed[i], seed[i + 1], seed[i + 2], seed[i + 3]]);
        Self::new([word(0), word(4), word(8), word(12)], 0, DEFAULT_ROUNDS)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_core::Rng;

    #[test]
    fn full_tea_matches_the_published_test_vector() {
        // 32 cycles, zero key, zero block: the reference implementation's output.
        assert_eq!(encrypt(0, 0, [0; 4], 32), (0x41EA_3A0A, 0x94BA_A940));
    }

    #[test]
    fn unit_pairs_take_the_two_halves() {
        assert_eq!(unit_pair(0), [0.0, 0.0]);
        assert_eq!(unit_pair(u64::MAX), [1.0 - 0.5f64.powi(32); 2]);
        assert_eq!(unit_pair(1 << 63), [0.5, 0.0]);
        assert_eq!(unit_pair(1 << 31), [0.0, 0.5]);
    }

    #[test]
    fn outputs_are_pinned() {
        // Value stability: a change here changes every rendered glint pattern.
        let key = [0x0123_4567, 0x89AB_CDEF, 0xFEDC_BA98, 0x7654_3210];
        let mut rng = TeaRng::new(key, 7, DEFAULT_ROUNDS);
        let first: [u64; 3] = [rng.next_bits(), rng.next_bits(), rng.next_bits()];
        assert_eq!(first, PINNED);
        // Draw i is the scalar encryption of (i, purpose), past the 4-draw buffer too.
        let mut rng = TeaRng::new(key, 7, DEFAULT_ROUNDS);
        for i in 0..10 {
            let (a, b) = encrypt(i, 7, key, DEFAULT_ROUNDS);
            let bits = rng.next_bits();
            assert_eq!(bits, (u64::from(a) << 32) | u64::from(b));
            assert_eq!(bits, draw_at(key, 7, i, DEFAULT_ROUNDS));
        }
    }

    #[test]
    fn a_stream_with_its_first_draw_given_is_the_stream() {
        let key = [9, 8, 7, 6];
        for purpose in [0, 5, 6] {
            let [first, ..] = draws_x4(key, [purpose, 1, 2, 3], 0, DEFAULT_ROUNDS);
            let mut given = TeaRng::with_first_draw(key, purpose, DEFAULT_ROUNDS, first);
            let mut stream = TeaRng::new(key, purpose, DEFAULT_ROUNDS);
            for _ in 0..10 {
                assert_eq!(given.next_bits(), stream.next_bits());
            }
        }
    }

    /// Recorded from this implementation when it was checked against the test vector above.
    const PINNED: [u64; 3] = [
        17_301_438_558_304_964_667,
        1_580_491_115_515_206_620,
        14_452_825_004_178_228_939,
    ];

    #[test]
    fn four_lanes_match_scalar_bit_for_bit() {
        let key = [1, 2, 3, 0xDEAD_BEEF];
        for rounds in [1, 8, 32] {
            let v0 = u32x4::new([0, 1, 0xFFFF_FFFF, 12345]);
            let v1 = u32x4::new([9, 0x8000_0000, 7, 0]);
            let (a, b) = encrypt_x4(v0, v1, key, rounds);
            for lane in 0..4 {
                let expected = encrypt(v0.to_array()[lane], v1.to_array()[lane], key, rounds);
                assert_eq!((a.to_array()[lane], b.to_array()[lane]), expected);
            }
        }
        let mut scalar = TeaRng::new(key, 3, 8);
        let mut vector = scalar.clone();
        let four = vector.uniform_x4();
        for value in four {
            assert_eq!(value.to_bits(), scalar.uniform().to_bits());
        }
        assert_eq!(scalar, vector);
    }

    #[test]
    fn streams_across_lanes_and_late_starts_match_scalar_streams() {
        let key = [11, 22, 33, 44];
        let purposes = [16, 17, 18, 99];
        for draw in 0..6 {
            let lanes = draws_x4(key, purposes, draw, DEFAULT_ROUNDS);
            for (lane, purpose) in purposes.into_iter().enumerate() {
                let mut rng = TeaRng::new(key, purpose, DEFAULT_ROUNDS);
                let expected = (0..=draw).map(|_| rng.next_bits()).last();
                assert_eq!(Some(lanes[lane]), expected);
                let mut late = TeaRng::starting_at(key, purpose, DEFAULT_ROUNDS, draw);
                assert_eq!(Some(late.next_bits()), expected);
            }
        }
    }

    #[test]
    fn implements_rand_core() {
        let mut rng = TeaRng::from_seed([5; 16]);
        let a = rng.next_u64();
        let b = rng.next_u32();
        let mut bytes = [0u8; 11];
        rng.fill_bytes(&mut bytes);
        assert_ne!(a, u64::from(b));
        assert!(bytes.iter().any(|&x| x != 0));
        let mut again = TeaRng::from_seed([5; 16]);
        assert_eq!(again.next_u64(), a);
    }

    #[test]
    fn uniforms_have_the_right_moments() {
        // Mean 1/2 and variance 1/12; 1e5 draws, 5-sigma bounds.
        let mut rng = TeaRng::new([9, 8, 7, 6], 0, DEFAULT_ROUNDS);
        let n = 100_000;
        let draws: Vec<f64> = (0..n).map(|_| rng.uniform()).collect();
        let mean = draws.iter().sum::<f64>() / n as f64;
        let variance = draws.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        assert!((mean - 0.5).abs() < 5.0 * (1.0 / 12.0 / n as f64).sqrt());
        assert!((variance - 1.0 / 12.0).abs() < 5.0 * (1.0 / 180.0 / n as f64).sqrt());
    }
}
