//! Per-pixel seeded sample streams: Owen-scrambled Sobol points (Burley 2020), so that a pixel's
//! samples depend only on (scene seed, frame, pixel, sample index) and never on which thread
//! renders it or in what order.

/// Dimensions served by the Sobol sequence; later dimensions fall back to a hash.
const SOBOL_DIMENSIONS: u32 = sobol_burley::NUM_DIMENSIONS;

/// The largest number of samples per pixel the Sobol sequence supports.
pub const MAX_SAMPLES_PER_PIXEL: u32 = 1 << 16;

/// A stream of uniform numbers in [0, 1) for one pixel sample.
#[derive(Clone, Debug)]
pub struct PixelSampler {
    seed: u32,
    index: u32,
    /// hash32(index), the part of every dimension's jitter hash that the stream shares.
    index_hash: u32,
    dimension: u32,
    /// Sobol dimensions 4·set … 4·set + 3 of this sample (`set` = [`NO_SET`] before the
    /// first), computed together by `sobol_burley::sample_4d` (identical to four `sample`
    /// calls, about 4× cheaper).
    set: u32,
    values: [f32; 4],
}

/// [`PixelSampler::set`] before any set is computed.
const NO_SET: u32 = u32::MAX;

/// One of `count` (> 0) choices, uniformly, from a uniform number `u` in [0, 1).
#[inline]
#[must_use]
pub fn uniform_index(u: f64, count: usize) -> usize {
    ((u * count as f64) as usize).min(count - 1)
}

/// A 32-bit integer hash (Wellons' lowbias32).
#[must_use]
pub fn hash32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

impl PixelSampler {
    /// The stream of sample `index` of pixel (`x`, `y`) under `seed`.
    #[must_use]
    pub fn new(seed: u64, x: u32, y: u32, index: u32) -> Self {
        let pixel_seed = hash32(
            hash32(x ^ hash32(y.wrapping_add(0x9e37_79b9)))
                ^ (seed as u32)
                ^ hash32((seed >> 32) as u32),
        );
        let index = index.min(MAX_SAMPLES_PER_PIXEL - 1);
        Self {
            seed: pixel_seed,
            index,
            index_hash: hash32(index),
            dimension: 0,
            set: NO_SET,
            values: [0.0; 4],
        }
    }

    /// The next uniform number in [0, 1), with full double precision: the Sobol point fixes the
    /// top 24 bits (its stratum), a hash fills the bits below.
    pub fn next_1d(&mut self) -> f64 {
        let d = self.dimension;
        self.dimension += 1;
        let jitter = f64::from(hash32(self.seed ^ hash32(d ^ self.index_hash))) / 4_294_967_296.0;
        if d < SOBOL_DIMENSIONS {
            let set = d / 4;
            if set != self.set {
                self.values = sobol_burley::sample_4d(self.index, set, self.seed);
                self.set = set;
            }
            let stratum = f64::from(self.values[(d % 4) as usize]);
            (stratum + jitter * f64::from(f32::EPSILON) * 0.5).min(1.0 - f64::EPSILON)
        } else {
            jitter
        }
    }

    /// Two uniform numbers.
    pub fn next_2d(&mut self) -> [f64; 2] {
        [self.next_1d(), self.next_1d()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn four_dimensions_at_a_time_match_one_at_a_time() {
        for index in [0, 1, 77, 4095] {
            let mut sampler = PixelSampler::new(9, 3, 5, index);
            for d in 0..SOBOL_DIMENSIONS + 3 {
                let u = sampler.next_1d();
                if d < SOBOL_DIMENSIONS {
                    let stratum = f64::from(sobol_burley::sample(index, d, sampler.seed));
                    assert!(u >= stratum && u < stratum + f64::from(f32::EPSILON), "{d}");
                }
            }
        }
    }

    #[test]
    fn streams_are_uniform_and_repeatable() {
        let mut sum = 0.0;
        let mut bins = [0u32; 16];
        for i in 0..4096 {
            let mut s = PixelSampler::new(3, 7, 11, i);
            let mut t = PixelSampler::new(3, 7, 11, i);
            for _ in 0..300 {
                let u = s.next_1d();
                assert_eq!(u.to_bits(), t.next_1d().to_bits());
                assert!((0.0..1.0).contains(&u));
                sum += u;
                bins[(u * 16.0) as usize] += 1;
            }
        }
        let n = 4096.0 * 300.0;
        assert!((sum / n - 0.5).abs() < 3e-3, "mean {}", sum / n);
        for b in bins {
            // Expected n/16 = 76800 per bin, σ ≈ 268: 5σ.
            assert!((f64::from(b) - n / 16.0).abs() < 1400.0, "{bins:?}");
        }
    }

    #[test]
    fn pixels_get_different_streams() {
        let a = PixelSampler::new(0, 1, 2, 0).next_1d();
        let b = PixelSampler::new(0, 2, 1, 0).next_1d();
        let c = PixelSampler::new(1, 1, 2, 0).next_1d();
        assert!(a != b && a != c && b != c);
    }
}
