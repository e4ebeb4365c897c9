//! Piecewise-constant distributions in one and two dimensions (pbrt-v4, "Sampling Functions"):
//! environment-map importance sampling and tabulated pixel-filter sampling.

/// A piecewise-constant density on [0, 1) with `n` equal bins.
#[derive(Clone, Debug, PartialEq)]
pub struct Distribution1D {
    /// The function values (non-negative).
    function: Vec<f64>,
    /// The running integral, cdf[0] = 0, cdf[n] = 1.
    cdf: Vec<f64>,
    /// ∫ f over [0, 1).
    integral: f64,
}

impl Distribution1D {
    /// The distribution proportional to `function` (negative or non-finite values count as 0);
    /// a function that is zero everywhere gives the uniform distribution.
    #[must_use]
    pub fn new(function: &[f64]) -> Self {
        let n = function.len().max(1);
        let function: Vec<f64> = (0..n)
            .map(|i| {
                let f = function.get(i).copied().unwrap_or(0.0);
                if f.is_finite() && f > 0.0 { f } else { 0.0 }
            })
            .collect();
        let mut cdf = vec![0.0; n + 1];
        for i in 0..n {
            cdf[i + 1] = cdf[i] + function[i] / n as f64;
        }
        let integral = cdf[n];
        if integral > 0.0 {
            for c in &mut cdf {
                *c /= integral;
            }
        } else {
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f64 / n as f64;
            }
        }
        cdf[n] = 1.0;
        Self {
            function,
            cdf,
            integral,
        }
    }

    /// The number of bins.
    #[must_use]
    pub fn len(&self) -> usize {
        self.function.len()
    }

    /// Whether there are no bins (never: a distribution has at least one).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.function.is_empty()
    }

    /// ∫ f over [0, 1).
    #[must_use]
    pub fn integral(&self) -> f64 {
        self.integral
    }

    /// A point x ∈ [0, 1) from the uniform `u`, with its density and bin.
    #[must_use]
    pub fn sample(&self, u: f64) -> (f64, f64, usize) {
        let n = self.function.len();
        // The last bin with cdf ≤ u.
        let bin = self
            .cdf
            .partition_point(|&c| c <= u)
            .saturating_sub(1)
            .min(n - 1);
        let width = self.cdf[bin + 1] - self.cdf[bin];
        let offset = if width > 0.0 {
            ((u - self.cdf[bin]) / width).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let x = ((bin as f64 + offset) / n as f64).min(1.0 - f64::EPSILON);
        (x, self.pdf_bin(bin), bin)
    }

    /// The density of bin `bin`.
    #[must_use]
    pub fn pdf_bin(&self, bin: usize) -> f64 {
        if self.integral > 0.0 {
            self.function[bin] / self.integral
        } else {
            1.0
        }
    }

    /// The density at x ∈ [0, 1).
    #[must_use]
    pub fn pdf(&self, x: f64) -> f64 {
        let n = self.function.len();
        let bin = ((x * n as f64) as usize).min(n - 1);
        self.pdf_bin(bin)
    }
}

/// A piecewise-constant density on [0, 1)², sampled as a marginal in v and a conditional in u.
#[derive(Clone, Debug, PartialEq)]
pub struct Distribution2D {
    conditionals: Vec<Distribution1D>,
    marginal: Distribution1D,
}

impl Distribution2D {
    /// The density proportional to `function`, given row by row (`width` values per row).
    #[must_use]
    pub fn new(function: &[f64], width: usize) -> Self {
        let width = width.max(1);
        let conditionals: Vec<Distribution1D> =
            function.chunks(width).map(Distribution1D::new).collect();
        let marginal = Distribution1D::new(
            &conditionals
                .iter()
                .map(Distribution1D::integral)
                .collect::<Vec<_>>(),
        );
        Self {
            conditionals,
            marginal,
        }
    }

    /// A point (u, v) from two uniforms, with its density.
    #[must_use]
    pub fn sample(&self, u: [f64; 2]) -> ([f64; 2], f64) {
        let (v, pdf_v, row) = self.marginal.sample(u[1]);
        let (x, pdf_u, _) = self.conditionals[row].sample(u[0]);
        ([x, v], pdf_u * pdf_v)
    }

    /// The density at (u, v).
    #[must_use]
    pub fn pdf(&self, p: [f64; 2]) -> f64 {
        let rows = self.conditionals.len();
        let row = ((p[1] * rows as f64) as usize).min(rows - 1);
        self.marginal.pdf_bin(row) * self.conditionals[row].pdf(p[0])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_dimensional_sampling_inverts_the_cdf() {
        let d = Distribution1D::new(&[1.0, 0.0, 3.0, 4.0]);
        assert!((d.integral() - 2.0).abs() < 1e-15);
        let mut counts = [0usize; 4];
        let n = 100_000;
        for i in 0..n {
            let (x, pdf, bin) = d.sample((i as f64 + 0.5) / n as f64);
            assert_eq!(bin, (x * 4.0) as usize);
            assert!((pdf - d.pdf(x)).abs() < 1e-12);
            counts[bin] += 1;
        }
        // Stratified uniforms: each bin gets its probability to within a count or two.
        for (c, p) in counts.iter().zip([0.125, 0.0, 0.375, 0.5]) {
            assert!((*c as f64 - p * n as f64).abs() <= 2.0, "{counts:?}");
        }
        let zero = Distribution1D::new(&[0.0, f64::NAN]);
        assert_eq!(zero.pdf(0.7), 1.0);
    }

    #[test]
    fn two_dimensional_density_integrates_to_one_and_matches_samples() {
        let (w, h) = (8, 5);
        let f: Vec<f64> = (0..w * h).map(|i| ((i * 7919) % 13) as f64).collect();
        let d = Distribution2D::new(&f, w);
        let mut integral = 0.0;
        for y in 0..h {
            for x in 0..w {
                integral += d.pdf([(x as f64 + 0.5) / w as f64, (y as f64 + 0.5) / h as f64])
                    / (w * h) as f64;
            }
        }
        assert!((integral - 1.0).abs() < 1e-12);
        for i in 0..1000 {
            let u = [(i as f64 * 0.618_034) % 1.0, (i as f64 + 0.5) / 1000.0];
            let (p, pdf) = d.sample(u);
            assert!((pdf - d.pdf(p)).abs() < 1e-9 * pdf.max(1.0));
            assert!(pdf > 0.0);
        }
    }
}
