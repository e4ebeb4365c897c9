//! How many particles glint queries find, as a histogram: what a render reports beside the
//! mean so that a user choosing N sees the spread of what pixels see (docs/integration.md,
//! "Choosing N and γ"). Bins are a quarter octave wide (a factor 2^¼ ≈ 1.19), so a quantile is
//! known to within that factor; they merge by addition, across threads, tiles and machines.

/// Bins above the two for 0 and (0, 1): a quarter octave each from 1 to 2⁶⁴.
const OCTAVE_BINS: usize = 4 * 64;

/// The histogram of particles found per query (a count may be fractional where Eq. 10 stopped
/// early): bin 0 holds queries that found none, bin 1 those that found less than one, bin
/// k ≥ 2 those in [2^((k−2)/4), 2^((k−1)/4)); the last bin also holds the counts above 2⁶⁴
/// (footprints over very many tiles), which its edge, 2⁶⁴, then understates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParticleHistogram {
    bins: [u64; 2 + OCTAVE_BINS],
}

impl Default for ParticleHistogram {
    fn default() -> Self {
        Self {
            bins: [0; 2 + OCTAVE_BINS],
        }
    }
}

impl ParticleHistogram {
    /// The bin of a count (non-finite or negative counts, which queries never give, go to 0).
    fn bin(count: f64) -> usize {
        if !(count > 0.0) {
            0
        } else if count < 1.0 {
            1
        } else {
            let quarter_octaves = (4.0 * count.log2()).floor();
            2 + (quarter_octaves as usize).min(OCTAVE_BINS - 1)
        }
    }

    /// The upper edge of bin `k`: 0, then 1, then 2^((k−1)/4).
    fn upper_edge(k: usize) -> f64 {
        match k {
            0 => 0.0,
            1 => 1.0,
            k => ((k - 1) as f64 / 4.0).exp2(),
        }
    }

    /// Counts one query that found `count` particles.
    pub fn record(&mut self, count: f64) {
        self.bins[Self::bin(count)] += 1;
    }

    /// Adds another histogram.
    pub fn add(&mut self, other: &Self) {
        for (a, b) in self.bins.iter_mut().zip(&other.bins) {
            *a += b;
        }
    }

    /// The queries counted.
    #[must_use]
    pub fn total(&self) -> u64 {
        self.bins.iter().sum()
    }

    /// An upper bound, within a factor 2^¼, on the `q`-quantile of the counts (q in (0, 1]):
    /// the upper edge of the bin where the cumulative share reaches q (2⁶⁴ for a quantile
    /// beyond it); 0 without queries.
    #[must_use]
    pub fn quantile_bound(&self, q: f64) -> f64 {
        let total = self.total();
        let mut below = 0u64;
        for (k, &n) in self.bins.iter().enumerate() {
            below += n;
            if n > 0 && below as f64 >= q * total as f64 {
                return Self::upper_edge(k);
            }
        }
        0.0
    }

    /// The non-empty bins as (upper edge, queries) pairs, in order: what a render's JSON
    /// writes, so that renders of parts of a frame (tiles, machines) merge exactly.
    #[must_use]
    pub fn nonempty(&self) -> Vec<(f64, u64)> {
        self.bins
            .iter()
            .enumerate()
            .filter(|(_, n)| **n > 0)
            .map(|(k, &n)| (Self::upper_edge(k), n))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bins hold their counts (0, fractions, powers of 2^¼ on both sides of a bin edge, huge
    /// counts), quantile bounds are within 2^¼ above the exact quantile, and merged histograms
    /// are the histogram of all the counts.
    #[test]
    fn quantile_bounds_bracket_the_exact_quantiles() {
        let mut counts: Vec<f64> = vec![0.0, 0.0, 0.3, 1.0, 1.1892, 1.19, 2.0, 1e6, 1e19];
        counts.extend((0..1000).map(|i| f64::from(i) * 0.731));
        let (first, second) = counts.split_at(400);
        let (mut a, mut b, mut all) = Default::default();
        for &c in first {
            ParticleHistogram::record(&mut a, c);
        }
        for &c in second {
            ParticleHistogram::record(&mut b, c);
        }
        for &c in &counts {
            ParticleHistogram::record(&mut all, c);
        }
        let mut merged: ParticleHistogram = a;
        merged.add(&b);
        assert_eq!(merged, all);
        let mut sorted = counts.clone();
        sorted.sort_by(f64::total_cmp);
        for q in [0.01, 0.5, 0.9, 0.99, 1.0] {
            let exact = sorted[((q * sorted.len() as f64).ceil() as usize).max(1) - 1];
            let bound = all.quantile_bound(q);
            assert!(bound >= exact, "q = {q}: {bound} < {exact}");
            assert!(
                bound <= (exact * 2f64.powf(0.25)).max(1.0) * (1.0 + 1e-12),
                "q = {q}: {bound} vs {exact}"
            );
        }
        assert_eq!(ParticleHistogram::default().quantile_bound(0.99), 0.0);
        let total: u64 = all.nonempty().iter().map(|(_, n)| n).sum();
        assert_eq!(total, counts.len() as u64);
        // Counts past 2⁶⁴ fall in the last bin.
        all.record(1e30);
        assert_eq!(all.quantile_bound(1.0), 2f64.powi(64));
    }
}
