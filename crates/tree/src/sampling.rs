//! Random variates for the count tree: binomial, multinomial (exact and the paper's normal
//! approximation), normal, gamma and Dirichlet, all driven by a node's [`TeaRng`] stream.
//!
//! # Exact binomial sampling for any n
//! - n·min(p, 1−p) < 10: inversion by sequential search from 0, with the pmf recursion
//!   f(k) = f(k−1)·((n+1)/k − 1)·p/q and f(0) = qⁿ = exp(n·ln(1−p)) (no underflow: qⁿ ≥ e⁻¹⁵).
//! - Otherwise BTRD, the transformed rejection method with decomposition of Hörmann (1993),
//!   "The generation of binomial random variates", J. Statist. Comput. Simul. 46. It is exact
//!   (the acceptance test compares against the true pmf through Stirling's series with the
//!   tabulated corrections fc(k)) and takes O(1) expected time for any n up to 2⁵³.
//!
//! # Multinomial splits (Sec. 3.4, "Optimizations")
//! [`MultinomialMode::Exact`] draws n ≤ 8 particles one by one (categorical draws) and larger n
//! as a binary tree of conditional binomials: X₀ + X₁ ~ Bin(n, p₀ + p₁), then
//! X₀ ~ Bin(X₀ + X₁, p₀/(p₀ + p₁)) and X₂ ~ Bin(n − X₀ − X₁, p₂/(p₂ + p₃)). The two
//! second-level draws are independent given the totals: the processor overlaps them, and the
//! count tree draws only the pairs a query needs.
//! [`MultinomialMode::Normal`] is the paper's approximation for n > 8: the normal distribution
//! with mean n·p and covariance n(diag p − ppᵀ), sampled by sequential conditioning
//! (X₀ ~ N(np₀, np₀(1−p₀)), then X₁ | X₀ ~ N((n−X₀)p₁/(1−p₀), np₁(1−p₀−p₁)/(1−p₀)), …, which
//! is exactly that Gaussian), rounded to non-negative integers, then fixed up by adding or
//! removing single particles in component i with probability pᵢ until the sum is n.
//! Both modes return counts that sum to n, always.
//!
//! # Spatial splits
//! A box splits into four equal quarters, each particle equally likely in each:
//! [`multinomial4_equal`] gives each particle two random bits (32 particles per 64-bit draw),
//! the exact multinomial at a fraction of three binomials' cost, up to
//! [`EQUAL_SPLIT_BY_BITS`] particles (exact mode; 8 in normal mode), and hands larger splits to
//! [`multinomial4`].

use crate::tea::TeaRng;

/// How a node's particles are divided among its four children.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum MultinomialMode {
    /// Exact multinomial sampling (categorical for n ≤ 8, conditional exact binomials above).
    #[default]
    Exact,
    /// The paper's normal approximation for n > 8 (exact categorical draws below).
    Normal,
}

/// ln(k!) − [(k + ½)·ln(k + 1) − (k + 1) + ½·ln(2π)] for k = 0..=9 (Stirling's correction).
const STIRLING_CORRECTION: [f64; 10] = [
    0.081_061_466_795_327_26,
    0.041_340_695_955_409_3,
    0.027_677_925_684_998_34,
    0.020_790_672_103_765_093,
    0.016_644_691_189_821_193,
    0.013_876_128_823_070_748,
    0.011_896_709_945_891_77,
    0.010_411_265_261_972_096,
    0.009_255_462_182_712_733,
    0.008_330_563_433_362_87,
];

/// Stirling's correction fc(k); the series 1/12 − 1/360 + 1/1260 in 1/(k+1) beyond the table.
fn stirling_correction(k: f64) -> f64 {
    if k < 10.0 {
        return STIRLING_CORRECTION[k as usize];
    }
    let r = 1.0 / (k + 1.0);
    let r2 = r * r;
    (1.0 / 12.0 - (1.0 / 360.0 - 1.0 / 1260.0 * r2) * r2) * r
}

/// An exact Bin(n, p) variate. `n` up to 2⁵³ (counts of the tree never exceed that).
pub fn binomial(n: u64, p: f64, rng: &mut TeaRng) -> u64 {
    if n == 0 || !(p > 0.0) {
        return 0;
    }
    if p >= 1.0 {
        return n;
    }
    if p > 0.5 {
        return n - binomial(n, 1.0 - p, rng);
    }
    if (n as f64) * p < 10.0 {
        binomial_inversion(n, p, rng)
    } else {
        binomial_btrd(n, p, rng)
    }
}

/// Sequential-search inversion, for n·p < 10 and p ≤ ½.
fn binomial_inversion(n: u64, p: f64, rng: &mut TeaRng) -> u64 {
    let q = 1.0 - p;
    let ratio = p / q;
    let scaled = (n as f64 + 1.0) * ratio;
    // f(0) = qⁿ: by repeated squaring for the small n of most splits (relative error about
    // 1e-14, exact for the spatial splits' q = ½), through exp and ln_1p beyond.
    let f0 = if n <= 64 {
        power(q, n)
    } else {
        ((n as f64) * (-p).ln_1p()).exp()
    };
    loop {
        let mut u = rng.uniform();
        let mut f = f0;
        let mut k = 0u64;
        // n·p < 10: the search ends within ~10 + a few·√10 steps except with negligible
        // probability; the bound only guards against rounding leaving u > 0 forever.
        while k <= n && k < 200 {
            if u < f {
                return k;
            }
            u -= f;
            k += 1;
            f *= scaled / k as f64 - ratio;
        }
    }
}

/// xⁿ by square-and-multiply: IEEE products only, so the same value on every platform (unlike
/// `powi`, whose precision Rust leaves unspecified).
fn power(x: f64, mut n: u64) -> f64 {
    let (mut result, mut square) = (1.0, x);
    while n > 0 {
        if n & 1 == 1 {
            result *= square;
        }
        square *= square;
        n >>= 1;
    }
    result
}

/// ⌊x⌋ for x ≥ 0 by truncation (`f64::floor` is a libm call on x86-64's baseline); values past
/// 2⁶⁴ saturate, which the callers' comparisons with n ≤ 2⁵³ treat alike.
#[inline]
fn floor_non_negative(x: f64) -> f64 {
    debug_assert!(x >= 0.0);
    x as u64 as f64
}

/// Hörmann's BTRD, for n·p ≥ 10 and p ≤ ½.
fn binomial_btrd(n: u64, p: f64, rng: &mut TeaRng) -> u64 {
    let nf = n as f64;
    let q = 1.0 - p;
    let npq = nf * p * q;
    let spq = npq.sqrt();
    let b = 1.15 + 2.53 * spq;
    let a = -0.0873 + 0.0248 * b + 0.01 * p;
    let c = nf * p + 0.5;
    let v_r = 0.92 - 4.2 / b;
    let u_r_v_r = 0.86 * v_r;
    // Step 1: the region of immediate acceptance (the value is positive, so truncation is
    // ⌊·⌋; `as` saturates anything else to 0, as ⌊·⌋ as u64 would). v/v_r is computed as
    // v·b/(0.92·b − 4.2), one division after b instead of two in a row.
    let v_r_times_b = 0.92 * b - 4.2;
    let immediate = |v: f64| {
        let u = v * b / v_r_times_b - 0.43;
        ((2.0 * a / (0.5 - u.abs()) + b) * u + c) as u64
    };
    // About 80% of draws end in step 1: the constants only the later steps use come after it.
    let first = rng.uniform();
    if first <= u_r_v_r {
        return immediate(first);
    }
    let mode = floor_non_negative((nf + 1.0) * p);
    let r = p / q;
    let nr = (nf + 1.0) * r;
    let alpha = (2.83 + 5.1 / b) * spq;
    let mut pending = Some(first);
    loop {
        let mut v = pending.take().unwrap_or_else(|| rng.uniform());
        if v <= u_r_v_r {
            return immediate(v);
        }
        // Step 2: generate u and v for the rejection test.
        let u = if v >= v_r {
            rng.uniform() - 0.5
        } else {
            let w = v / v_r - 0.93;
            v = rng.uniform() * v_r;
            0.5_f64.copysign(w) - w
        };
        // Step 3.0: the candidate.
        let us = 0.5 - u.abs();
        let candidate = (2.0 * a / us + b) * u + c;
        if !(candidate >= 0.0) {
            continue;
        }
        let k = floor_non_negative(candidate);
        if k > nf {
            continue;
        }
        v *= alpha / (a / (us * us) + b);
        let km = (k - mode).abs();
        if km <= 15.0 {
            // Step 3.1: f(k)/f(mode) by the pmf recursion.
            let mut f = 1.0;
            if mode < k {
                let mut i = mode;
                while i < k {
                    i += 1.0;
                    f *= nr / i - r;
                }
            } else if mode > k {
                let mut i = k;
                while i < mode {
                    i += 1.0;
                    v *= nr / i - r;
                }
            }
            if v <= f {
                return k as u64;
            }
            continue;
        }
        // Step 3.2: squeeze with the normal approximation of ln f(k)/f(mode).
        let v = v.ln();
        let rho = (km / npq) * (((km / 3.0 + 0.625) * km + 1.0 / 6.0) / npq + 0.5);
        let t = -km * km / (2.0 * npq);
        if v < t - rho {
            return k as u64;
        }
        if v > t + rho {
            continue;
        }
        // Steps 3.3–3.4: the final acceptance test, ln f(k)/f(mode) through Stirling's series.
        let nm = nf - mode + 1.0;
        let h = (mode + 0.5) * ((mode + 1.0) / (r * nm)).ln()
            + stirling_correction(mode)
            + stirling_correction(nf - mode);
        let nk = nf - k + 1.0;
        let bound = h + (nf + 1.0) * (nm / nk).ln() + (k + 0.5) * (nk * r / (k + 1.0)).ln()
            - stirling_correction(k)
            - stirling_correction(nf - k);
        if v <= bound {
            return k as u64;
        }
    }
}

/// The largest split [`multinomial4`] draws particle by particle (categorical draws), in both
/// modes, as the paper does.
pub const CATEGORICAL_PARTICLES: u64 = 8;

/// Splits `n` particles among four children with probabilities `p` (non-negative, summing to
/// 1 up to rounding). The result always sums to `n`.
///
/// Both modes draw n ≤ 8 particles one by one (categorical draws, four uniforms per 4-lane TEA
/// call), as the paper does; above 8 the mode decides.
pub fn multinomial4(n: u64, p: [f64; 4], mode: MultinomialMode, rng: &mut TeaRng) -> [u64; 4] {
    if n <= CATEGORICAL_PARTICLES {
        // One categorical draw per particle, four uniforms per 4-lane TEA call.
        let mut counts = [0u64; 4];
        let mut remaining = n as usize;
        while remaining > 0 {
            let uniforms = rng.uniform_x4();
            for &u in uniforms.iter().take(remaining) {
                counts[categorical(p, u)] += 1;
            }
            remaining = remaining.saturating_sub(4);
        }
        return counts;
    }
    match mode {
        MultinomialMode::Normal => multinomial4_normal(n, p, rng),
        MultinomialMode::Exact => multinomial4_conditional(n, p, rng),
    }
}

/// The largest split that [`multinomial4_equal`] draws two bits per particle for in
/// [`MultinomialMode::Exact`]: up to this size its draws (at most twelve 64-bit ones, three
/// 4-lane TEA calls) cost less than the three conditional binomials they replace.
pub const EQUAL_SPLIT_BY_BITS: u64 = 384;

/// Splits `n` particles among four equally likely children (a spatial split of a box into its
/// quarters). Each particle's child is two random bits, 32 particles per 64-bit draw: the
/// exact multinomial, for n ≤ [`EQUAL_SPLIT_BY_BITS`] in [`MultinomialMode::Exact`] and n ≤ 8
/// in [`MultinomialMode::Normal`] (the paper draws particles one by one up to 8). Larger n go
/// to [`multinomial4`] with p = ¼. The result always sums to `n`.
pub fn multinomial4_equal(n: u64, mode: MultinomialMode, rng: &mut TeaRng) -> [u64; 4] {
    if n > drawn_particle_by_particle(true, mode) {
        return multinomial4(n, [0.25; 4], mode, rng);
    }
    multinomial4_equal_by_bits(n, rng)
}

/// The largest split that [`multinomial4_equal`] (`equal`) or [`multinomial4`] draws particle
/// by particle (two bits or one categorical draw each); larger ones are drawn as `mode` says.
fn drawn_particle_by_particle(equal: bool, mode: MultinomialMode) -> u64 {
    if equal && mode == MultinomialMode::Exact {
        EQUAL_SPLIT_BY_BITS
    } else {
        CATEGORICAL_PARTICLES
    }
}

/// Whether [`multinomial4_equal`] (`equal`) or [`multinomial4`] splits `n` particles as the
/// binary tree of binomials ([`pair_totals`], then [`divide_pair`]) rather than particle by
/// particle or by the normal approximation: a caller that draws the pairs itself, from
/// streams of its own, asks this so that it agrees with those functions on every other split.
#[must_use]
pub fn splits_by_pairs(n: u64, equal: bool, mode: MultinomialMode) -> bool {
    mode == MultinomialMode::Exact && n > drawn_particle_by_particle(equal, mode)
}

/// The exact multinomial split of `n` particles among four equally likely children by two
/// random bits per particle, for any n (its cost grows linearly: [`multinomial4_equal`] uses
/// it up to [`EQUAL_SPLIT_BY_BITS`]).
pub fn multinomial4_equal_by_bits(n: u64, rng: &mut TeaRng) -> [u64; 4] {
    // Particle i of a draw takes bits 2i (low) and 2i + 1 (high): child low + 2·high.
    const PAIR_LOW_BITS: u64 = 0x5555_5555_5555_5555;
    let mut counts = [0u64; 4];
    let mut remaining = n;
    while remaining > 0 {
        let particles = remaining.min(32);
        let used = if particles == 32 {
            PAIR_LOW_BITS
        } else {
            PAIR_LOW_BITS & ((1u64 << (2 * particles)) - 1)
        };
        let bits = rng.next_bits();
        let low = bits & used;
        let high = (bits >> 1) & used;
        counts[1] += u64::from((low & !high).count_ones());
        counts[2] += u64::from((high & !low).count_ones());
        counts[3] += u64::from((low & high).count_ones());
        remaining -= particles;
    }
    counts[0] = n - counts[1] - counts[2] - counts[3];
    counts
}

/// Exact, as a binary tree of conditional binomials ([`pair_totals`], then [`divide_pair`]
/// for each pair), all from one stream.
fn multinomial4_conditional(n: u64, p: [f64; 4], rng: &mut TeaRng) -> [u64; 4] {
    let totals = pair_totals(n, p, rng);
    let [first, second] = divide_pair(totals[0], p, 0, rng);
    let [third, fourth] = divide_pair(totals[1], p, 1, rng);
    [first, second, third, fourth]
}

/// The first level of an exact split's binary tree: the totals of the pairs (0, 1) and
/// (2, 3), X₀ + X₁ ~ Bin(n, p₀ + p₁) and the rest.
pub fn pair_totals(n: u64, p: [f64; 4], rng: &mut TeaRng) -> [u64; 2] {
    let left = binomial(n, share(p[0] + p[1], p[0] + p[1] + p[2] + p[3]), rng);
    [left, n - left]
}

/// The second level of an exact split's binary tree: pair `pair` ((0, 1) or (2, 3)), holding
/// `total` particles, divided between its two children, X₂ᵢ ~ Bin(total, p₂ᵢ/(p₂ᵢ + p₂ᵢ₊₁)).
/// The two pairs' divisions are independent given the totals: a caller may draw only the
/// pair it needs, from a stream of its own.
pub fn divide_pair(total: u64, p: [f64; 4], pair: usize, rng: &mut TeaRng) -> [u64; 2] {
    let (a, b) = (p[2 * pair], p[2 * pair + 1]);
    let first = binomial(total, share(a, a + b), rng);
    [first, total - first]
}

/// part/total, clamped to 1 against rounding; 0 when the total is 0.
fn share(part: f64, total: f64) -> f64 {
    if total > 0.0 {
        (part / total).min(1.0)
    } else {
        0.0
    }
}

/// The category of uniform `u` under probabilities `p` (robust to p not summing to 1 exactly).
fn categorical(p: [f64; 4], u: f64) -> usize {
    let total = p[0] + p[1] + p[2] + p[3];
    let mut threshold = u * total;
    for (i, &pi) in p.iter().enumerate().take(3) {
        if threshold < pi {
            return i;
        }
        threshold -= pi;
    }
    // Rounding can leave a sliver past the third category: give it to the last positive one.
    (0..4).rev().find(|&i| p[i] > 0.0).unwrap_or(3)
}

/// The paper's normal approximation (see the module docs).
fn multinomial4_normal(n: u64, p: [f64; 4], rng: &mut TeaRng) -> [u64; 4] {
    let nf = n as f64;
    let mut real = [0.0f64; 4];
    let mut drawn = 0.0;
    for i in 0..3 {
        let rest: f64 = p[i..].iter().sum();
        if !(rest > 0.0) || !(p[i] > 0.0) {
            continue;
        }
        let share = (p[i] / rest).min(1.0);
        let remaining = (nf - drawn).max(0.0);
        let mean = remaining * share;
        // Var(X_i | earlier) of the Gaussian: n·p_i·(rest − p_i)/rest.
        let variance = nf * p[i] * (rest - p[i]) / rest;
        real[i] = mean + variance.max(0.0).sqrt() * standard_normal(rng);
        drawn += real[i];
    }
    real[3] = nf - drawn;
    let mut counts = real.map(|x| x.round().max(0.0) as u64);
    for i in 0..4 {
        if !(p[i] > 0.0) {
            counts[i] = 0;
        }
    }
    let mut sum: u64 = counts.iter().sum();
    while sum != n {
        let i = categorical(p, rng.uniform());
        if sum < n {
            counts[i] += 1;
            sum += 1;
        } else if counts[i] > 0 {
            counts[i] -= 1;
            sum -= 1;
        }
    }
    counts
}

/// A standard normal variate by Marsaglia's polar method (no trigonometry).
pub fn standard_normal(rng: &mut TeaRng) -> f64 {
    loop {
        let x = 2.0 * rng.uniform() - 1.0;
        let y = 2.0 * rng.uniform() - 1.0;
        let s = x * x + y * y;
        if s > 0.0 && s < 1.0 {
            return x * (-2.0 * s.ln() / s).sqrt();
        }
    }
}

/// A Gamma(shape, 1) variate for shape ≥ 1, by Marsaglia and Tsang (2000).
pub fn gamma(shape: f64, rng: &mut TeaRng) -> f64 {
    debug_assert!(shape >= 1.0);
    let d = shape - 1.0 / 3.0;
    let c = 1.0 / (9.0 * d).sqrt();
    loop {
        let x = standard_normal(rng);
        let v = 1.0 + c * x;
        if v <= 0.0 {
            continue;
        }
        let v = v * v * v;
        let u = rng.uniform();
        let x2 = x * x;
        if u < 1.0 - 0.0331 * x2 * x2 || u.ln() < 0.5 * x2 + d * (1.0 - v + v.ln()) {
            return d * v;
        }
    }
}

/// Splits a total of 1 among four parts as Dirichlet(n₀, n₁, n₂, n₃) (parts with nᵢ = 0 get 0):
/// the areas of four groups of particles whose individual areas are Dirichlet(1, …, 1) over all
/// particles (Sec. 3.4, "Additional state", by the aggregation property).
pub fn dirichlet4(counts: [u64; 4], rng: &mut TeaRng) -> [f64; 4] {
    let draws = counts.map(|n| if n == 0 { 0.0 } else { gamma(n as f64, rng) });
    let total: f64 = draws.iter().sum();
    if total > 0.0 {
        draws.map(|g| g / total)
    } else {
        [0.0; 4]
    }
}

/// An Exp(1) = Gamma(1) variate: the unnormalized share of one particle.
pub fn exponential(rng: &mut TeaRng) -> f64 {
    -(1.0 - rng.uniform()).ln()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rng(purpose: u32) -> TeaRng {
        TeaRng::new([11, 22, 33, 44], purpose, crate::tea::DEFAULT_ROUNDS)
    }

    #[test]
    fn stirling_table_continues_into_the_series() {
        // The series at k = 9 agrees with the table to its truncation error.
        let r = 1.0 / 10.0_f64;
        let series = (1.0 / 12.0 - (1.0 / 360.0 - 1.0 / 1260.0 * r * r) * r * r) * r;
        assert!((series - STIRLING_CORRECTION[9]).abs() < 1e-9);
    }

    #[test]
    fn floor_by_truncation_is_floor() {
        for x in [
            0.0_f64,
            0.5,
            1.0,
            1.5,
            2.0 - 1e-15,
            1e15 + 0.5,
            9.007_199_254_740_991e15,
            1e300,
        ] {
            let expected = if x < 1.8e19 {
                x.floor()
            } else {
                u64::MAX as f64
            };
            assert_eq!(floor_non_negative(x), expected, "{x}");
        }
    }

    #[test]
    fn power_matches_powf() {
        for x in [0.5_f64, 0.75, 2.0 / 3.0, 0.999_999, 1e-3] {
            for n in 0..=64u64 {
                let exact = x.powf(n as f64);
                assert!((power(x, n) - exact).abs() <= 2e-14 * exact, "{x}^{n}");
            }
        }
        assert_eq!(power(0.5, 40), 2f64.powi(-40));
    }

    #[test]
    fn binomial_extremes() {
        let mut r = rng(1);
        assert_eq!(binomial(0, 0.3, &mut r), 0);
        assert_eq!(binomial(10, 0.0, &mut r), 0);
        assert_eq!(binomial(10, 1.0, &mut r), 10);
        assert_eq!(binomial(10, f64::NAN, &mut r), 0);
        for _ in 0..1000 {
            assert!(binomial(1_000_000_000_000_000, 0.5, &mut r) <= 1_000_000_000_000_000);
            assert!(binomial(1_000_000_000_000_000, 1e-15, &mut r) < 100);
        }
    }

    #[test]
    fn multinomial_sums_to_n_in_both_modes() {
        let mut r = rng(2);
        for mode in [MultinomialMode::Exact, MultinomialMode::Normal] {
            for n in [0, 1, 7, 8, 9, 10, 1000, 123_456_789, 1_000_000_000_000_000] {
                for p in [
                    [0.25; 4],
                    [1.0, 0.0, 0.0, 0.0],
                    [0.0, 0.0, 0.0, 1.0],
                    [0.7, 0.2, 0.1, 0.0],
                    [1e-12, 0.5, 0.5 - 1e-12, 0.0],
                ] {
                    let c = multinomial4(n, p, mode, &mut r);
                    assert_eq!(c.iter().sum::<u64>(), n, "{mode:?} {n} {p:?}");
                    for i in 0..4 {
                        if p[i] == 0.0 {
                            assert_eq!(c[i], 0);
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn equal_splits_sum_to_n_and_hand_large_ones_on() {
        for mode in [MultinomialMode::Exact, MultinomialMode::Normal] {
            for n in [
                0u64,
                1,
                7,
                8,
                9,
                31,
                32,
                33,
                64,
                127,
                128,
                129,
                1000,
                1 << 40,
            ] {
                for trial in 0..20 {
                    let counts = multinomial4_equal(n, mode, &mut rng(trial));
                    assert_eq!(counts.iter().sum::<u64>(), n, "{mode:?} n = {n}");
                    let by_bits = match mode {
                        MultinomialMode::Exact => EQUAL_SPLIT_BY_BITS,
                        MultinomialMode::Normal => 8,
                    };
                    if n > by_bits {
                        let general = multinomial4(n, [0.25; 4], mode, &mut rng(trial));
                        assert_eq!(counts, general, "{mode:?} n = {n}");
                    }
                }
            }
        }
        // Every child gets particles: the bit pairs are not stuck.
        let totals = (0..200).fold([0u64; 4], |mut totals, trial| {
            let counts = multinomial4_equal(100, MultinomialMode::Exact, &mut rng(trial));
            for (total, count) in totals.iter_mut().zip(counts) {
                *total += count;
            }
            totals
        });
        for total in totals {
            assert!((4500..5500).contains(&total), "{totals:?}");
        }
    }

    #[test]
    fn dirichlet_parts_sum_to_one() {
        let mut r = rng(3);
        let parts = dirichlet4([3, 0, 1_000_000, 1], &mut r);
        assert!((parts.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert_eq!(parts[1], 0.0);
        assert_eq!(dirichlet4([0; 4], &mut r), [0.0; 4]);
    }
}
