//! The log-linear law of slopes within a lattice square: on the unit square t ∈ [0, 1]², the
//! density ∝ exp(g·t), a product of one law per axis. On one axis, with g the log-slope times
//! the square's side:
//!
//! ```text
//!   f(t) = g·e^(g·t)/(e^g − 1),   F(t) = (e^(g·t) − 1)/(e^g − 1),   F⁻¹(u) = ln(1 + u(e^g − 1))/g
//! ```
//!
//! (uniform as g → 0). For g > 700 these would overflow; there they are evaluated in the forms
//! multiplied through by e^(−g): f(t) = g·e^(g(t−1))/(1 − e^(−g)),
//! F(t) = (e^(g(t−1)) − e^(−g))/(1 − e^(−g)), F⁻¹(u) = 1 + ln(u + (1 − u)·e^(−g))/g.

use glam::DVec2;

/// Below this |g| the law is uniform to double precision in what the lattice needs.
const UNIFORM_BELOW: f64 = 1e-9;

/// Below this |g|, F's numerator is e^(g·t) − 1 by `exp_m1`; above, by `exp` less 1.
const EXP_M1_BELOW: f64 = 1e-3;

/// Above this g, e^g nears overflow: the forms multiplied through by e^(−g) are used.
const LARGE_TILT: f64 = 700.0;

/// The law on one axis, with what its functions need precomputed.
#[derive(Clone, Copy, Debug)]
pub(super) struct AxisTilt {
    g: f64,
    /// e^g − 1, or e^(−g) above [`LARGE_TILT`].
    precomputed: f64,
}

impl AxisTilt {
    pub(super) fn new(g: f64) -> Self {
        let precomputed = if g > LARGE_TILT {
            (-g).exp()
        } else {
            g.exp_m1()
        };
        Self { g, precomputed }
    }

    fn is_uniform(&self) -> bool {
        self.g.abs() < UNIFORM_BELOW
    }

    /// f(t), the density at t ∈ [0, 1].
    pub(super) fn density(&self, t: f64) -> f64 {
        let g = self.g;
        if self.is_uniform() {
            1.0
        } else if g > LARGE_TILT {
            g * (g * (t - 1.0)).exp() / (1.0 - self.precomputed)
        } else {
            g * (g * t).exp() / self.precomputed
        }
    }

    /// f(t + step)/f(t): the density's ratio over a step, for evenly spaced points; `None`
    /// where it exceeds e^20 either way (a product of such ratios would leave the doubles'
    /// range: evaluate f at each point).
    pub(super) fn density_ratio(&self, step: f64) -> Option<f64> {
        let exponent = self.g * step;
        (exponent.abs() <= 20.0).then(|| exponent.exp())
    }

    /// F(t), the mass of [0, t].
    pub(super) fn cdf(&self, t: f64) -> f64 {
        let g = self.g;
        if t <= 0.0 {
            0.0
        } else if t >= 1.0 {
            1.0
        } else if self.is_uniform() {
            t
        } else if g > LARGE_TILT {
            ((g * (t - 1.0)).exp() - self.precomputed) / (1.0 - self.precomputed)
        } else if g.abs() < EXP_M1_BELOW {
            (g * t).exp_m1() / self.precomputed
        } else {
            // e^(g·t) − 1 by exp: an absolute error in F of at most
            // 2⁻⁵²·(1 + e^(g·t))/|e^g − 1| ≲ 5·10⁻¹³ for |g| ≥ 10⁻³, at a third of exp_m1's cost.
            ((g * t).exp() - 1.0) / self.precomputed
        }
    }

    /// F⁻¹(u) for u ∈ [0, 1).
    #[inline]
    pub(super) fn quantile(&self, u: f64) -> f64 {
        let g = self.g;
        let t = if self.is_uniform() {
            u
        } else if g > LARGE_TILT {
            1.0 + (u + (1.0 - u) * self.precomputed).ln() / g
        } else {
            ln_1p(u * self.precomputed) / g
        };
        t.clamp(0.0, 1.0)
    }
}

/// ln(1 + v) for v > −1, within about 10⁻¹² (relative) of `f64::ln_1p` at a third of its
/// cost: 2·atanh(s) by its odd series, s = v/(2 + v) where |v| ≤ ¼ (|s| ≤ 0.143, terms to
/// s¹³), else ln 2 times the exponent of 1 + v plus 2·atanh((m − 1)/(m + 1)) of its mantissa m
/// taken in [1/√2, √2) (|s| ≤ 0.172, terms to s¹⁷). A point's slope takes two (the quantile
/// of its cell's law on each axis); `f64::ln_1p` where 1 + v is not a normal double.
#[inline]
fn ln_1p(v: f64) -> f64 {
    // 2·(s + s³/3 + … + s^(2k+1)/(2k+1)), in Horner form on s².
    let atanh_twice = |s: f64, terms: usize| {
        let s2 = s * s;
        let mut sum = 1.0 / (2 * terms + 1) as f64;
        for k in (0..terms).rev() {
            sum = sum * s2 + 1.0 / (2 * k + 1) as f64;
        }
        2.0 * s * sum
    };
    if v.abs() <= 0.25 {
        return atanh_twice(v / (2.0 + v), 6);
    }
    let x = 1.0 + v;
    if !(x >= f64::MIN_POSITIVE && x.is_finite()) {
        return v.ln_1p();
    }
    let bits = x.to_bits();
    let mut exponent = ((bits >> 52) & 0x7FF) as i64 - 1023;
    let mut m = f64::from_bits((bits & 0x000F_FFFF_FFFF_FFFF) | (1023 << 52));
    if m > std::f64::consts::SQRT_2 {
        m *= 0.5;
        exponent += 1;
    }
    exponent as f64 * std::f64::consts::LN_2 + atanh_twice((m - 1.0) / (m + 1.0), 8)
}

/// The law on the unit square: one [`AxisTilt`] per axis.
#[derive(Clone, Copy, Debug)]
pub(super) struct Tilt {
    pub(super) x: AxisTilt,
    pub(super) y: AxisTilt,
}

impl Tilt {
    /// The law ∝ exp(g·t).
    pub(super) fn new(g: DVec2) -> Self {
        Self {
            x: AxisTilt::new(g.x),
            y: AxisTilt::new(g.y),
        }
    }

    /// The point of the unit square whose coordinates have the quantiles `u`.
    #[inline]
    pub(super) fn quantile(&self, u: [f64; 2]) -> DVec2 {
        DVec2::new(self.x.quantile(u[0]), self.y.quantile(u[1]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// For g from −2000 to 2000: F is finite, rises from 0 to 1, is the integral of f
    /// (Simpson on 2000 panels, where f is resolved), F⁻¹ inverts it, and the density's ratio
    /// over a step is f's.
    #[test]
    fn the_law_is_finite_and_consistent_for_any_tilt() {
        for g in [
            -2000.0, -700.0, -30.0, -1.0, -2e-3, -1e-7, 0.0, 1e-12, 1e-7, 1e-3, 0.5, 3.0, 30.0,
            710.0, 2000.0,
        ] {
            let axis = AxisTilt::new(g);
            assert!(
                axis.cdf(0.0).abs() < 1e-15 && (axis.cdf(1.0) - 1.0).abs() < 1e-12,
                "{g}"
            );
            let mut last = 0.0;
            for i in 0..=100 {
                let t = f64::from(i) / 100.0;
                let f = axis.cdf(t);
                assert!(
                    f.is_finite() && f >= last - 1e-15 && f <= 1.0 + 1e-12,
                    "g {g}, t {t}: {f}"
                );
                last = f;
                let u = f.min(1.0 - 1e-16);
                let back = axis.quantile(u);
                assert!(
                    back.is_finite() && (0.0..=1.0).contains(&back),
                    "g {g}: {back}"
                );
                // Where F is not flat, F⁻¹(F(t)) = t.
                if axis.density(t) * 1e-9 > f64::EPSILON && (0.01..0.99).contains(&u) {
                    assert!((back - t).abs() < 1e-6, "g {g}, t {t}: {back}");
                }
            }
            if g.abs() <= 30.0 {
                let step = axis.density_ratio(0.25).expect("a moderate ratio");
                let ratio = axis.density(0.3) * step / axis.density(0.55);
                assert!((ratio - 1.0).abs() < 1e-12, "g {g}: {ratio}");
                let panels = 2000;
                let h = 1.0 / f64::from(panels);
                let mut integral = 0.0;
                for i in 0..panels {
                    let a = f64::from(i) * h;
                    integral += h / 6.0
                        * (axis.density(a) + 4.0 * axis.density(a + 0.5 * h) + axis.density(a + h));
                    let want = axis.cdf(a + h);
                    assert!(
                        (integral - want).abs() < 1e-9,
                        "g {g}: ∫f {integral} against F {want}"
                    );
                }
            }
        }
    }

    /// The fast ln(1 + v) is `f64::ln_1p` within 2·10⁻¹² (relative) from v = −1 + 10⁻³⁰⁰ to
    /// 10³⁰⁰, on both sides of its two forms' boundary.
    #[test]
    fn the_fast_logarithm_is_ln_1p() {
        let close = |w: f64| {
            let (fast, want) = (ln_1p(w), w.ln_1p());
            assert!(
                (fast - want).abs() <= 2e-12 * want.abs().max(f64::MIN_POSITIVE),
                "{w}: {fast} against {want}"
            );
        };
        let mut checked = 0;
        // From 1e-300 to 1e300 by factors of 1.37, and the same distances above −1.
        let mut v = 1e-300f64;
        while v < 1e300 {
            close(v);
            if v < 1.0 {
                close(-v);
            }
            // −1 + v is a double above −1 from v = 2⁻⁵³.
            if v < 1.0 && v > 1.2e-16 {
                close(-1.0 + v);
            }
            checked += 1;
            v *= 1.37;
        }
        for w in [
            0.25,
            -0.25,
            0.250_000_1,
            -0.250_000_1,
            0.0,
            1.0,
            3.0,
            -0.999_999,
        ] {
            close(w);
        }
        assert!(checked > 4000, "{checked}");
    }

    /// F by `exp` less 1 (from |g| = 10⁻³) is F by `exp_m1` within 10⁻¹² at every t.
    #[test]
    fn the_cheap_distribution_function_keeps_its_precision() {
        for g in [
            -40.0, -3.0, -0.2, -1.001e-3, 1.001e-3, 0.01, 0.7, 5.0, 60.0, 699.0,
        ] {
            let axis = AxisTilt::new(g);
            for i in 1..1000 {
                let t = f64::from(i) / 1000.0;
                let precise = (g * t).exp_m1() / g.exp_m1();
                assert!((axis.cdf(t) - precise).abs() < 1e-12, "g {g}, t {t}");
            }
        }
    }
}
