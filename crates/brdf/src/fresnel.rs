//! Fresnel reflectance: none (F = 1), conductors (complex index per RGB channel) and
//! dielectrics (the paper's flakes with η = 1.5), for unpolarized light.
//!
//! The accepted indices are [`Fresnel::MIN_ETA`] ≤ η ≤ [`Fresnel::MAX_ETA`] and
//! 0 ≤ k ≤ [`Fresnel::MAX_K`] ([`Fresnel::validated`]); every interface (eval JSON, Python, C,
//! scene files) inherits the range from here. [`Fresnel::evaluate`] gives F in [0, 1] for any
//! finite η > 0 and k ≥ 0, in and beyond that range: the conductor's terms are written as sums
//! of squares (no cancellation makes them negative) and evaluated in units of max(η, k, 1) (no
//! square overflows).

use glam::DVec3;

use crate::error::BrdfError;

/// The Fresnel term of a material, per RGB channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Fresnel {
    /// F = 1 (the paper's metallic flakes without Fresnel effects).
    None,
    /// A conductor with complex index η + ik per channel.
    Conductor {
        /// Real part η per channel.
        eta: DVec3,
        /// Imaginary part k per channel.
        k: DVec3,
    },
    /// A dielectric with relative index η (outside to inside).
    Dielectric {
        /// η.
        eta: f64,
    },
}

impl Fresnel {
    /// The smallest accepted η (conductor or dielectric): real conductors have η ≥ 0.03 in the
    /// visible (silver's is about 0.05), relative dielectric indices are above 0.2.
    pub const MIN_ETA: f64 = 1e-3;
    /// The largest accepted η: real materials have η ≤ 4 in the visible.
    pub const MAX_ETA: f64 = 1e3;
    /// The largest accepted k (the smallest is 0): real conductors have k ≤ 10 in the visible.
    pub const MAX_K: f64 = 1e3;

    /// Checks the parameters: η in [[`Self::MIN_ETA`], [`Self::MAX_ETA`]] and k in
    /// [0, [`Self::MAX_K`]], per channel.
    ///
    /// # Errors
    /// [`BrdfError::InvalidFresnel`] naming the first parameter out of range (NaN is).
    pub fn validated(self) -> Result<Self, BrdfError> {
        let eta_ok = |eta: f64| (Self::MIN_ETA..=Self::MAX_ETA).contains(&eta);
        let k_ok = |k: f64| (0.0..=Self::MAX_K).contains(&k);
        let channels = |v: DVec3| [v.x, v.y, v.z];
        let bad = match self {
            Self::None => None,
            Self::Conductor { eta, k } => channels(eta)
                .into_iter()
                .find(|x| !eta_ok(*x))
                .map(|value| ("eta", value))
                .or_else(|| {
                    channels(k)
                        .into_iter()
                        .find(|x| !k_ok(*x))
                        .map(|value| ("k", value))
                }),
            Self::Dielectric { eta } => (!eta_ok(eta)).then_some(("eta", eta)),
        };
        match bad {
            None => Ok(self),
            Some((parameter, value)) => Err(BrdfError::InvalidFresnel { parameter, value }),
        }
    }

    /// Whether F is the same in every channel (the BRDF is then gray).
    #[must_use]
    pub fn is_gray(&self) -> bool {
        match self {
            Self::None | Self::Dielectric { .. } => true,
            Self::Conductor { eta, k } => {
                eta.x == eta.y && eta.y == eta.z && k.x == k.y && k.y == k.z
            }
        }
    }

    /// F at the cosine `cos_theta` between the incident direction and the facet normal, in
    /// [0, 1] per channel for any finite η > 0 and k ≥ 0.
    #[must_use]
    pub fn evaluate(&self, cos_theta: f64) -> DVec3 {
        let c = cos_theta.clamp(0.0, 1.0);
        match *self {
            Self::None => DVec3::ONE,
            Self::Dielectric { eta } => DVec3::splat(dielectric(c, eta)),
            Self::Conductor { eta, k } => DVec3::new(
                conductor(c, eta.x, k.x),
                conductor(c, eta.y, k.y),
                conductor(c, eta.z, k.z),
            ),
        }
    }
}

/// Exact dielectric reflectance: Fresnel's equations for a real index, which are the
/// conductor's with k = 0 (total internal reflection, η < sin θ, gives a = 0 and R = 1).
fn dielectric(cos_i: f64, eta: f64) -> f64 {
    conductor(cos_i, eta, 0.0)
}

/// `numerator / denominator` for 0 ≤ numerator ≤ denominator, and 1 for 0/0 (the terms below
/// vanish together only at grazing incidence, where the reflectance tends to 1).
fn ratio(numerator: f64, denominator: f64) -> f64 {
    if denominator > 0.0 {
        numerator / denominator
    } else {
        1.0
    }
}

/// Exact conductor reflectance for unpolarized light and complex index n = η + ik.
///
/// With c = cos θ, s² = sin²θ and a + ib = √(n² − s²) (a, b ≥ 0: a² − b² = η² − k² − s²,
/// ab = ηk), the amplitudes' squared moduli are sums of squares,
///
/// ```text
///   R_s = ((a − c)² + b²) / ((a + c)² + b²),
///   R_p = R_s · ((ac − s²)² + (bc)²) / ((ac + s²)² + (bc)²),
/// ```
///
/// the textbook forms (a² + b² ∓ 2ac + c²)/… and (c²(a² + b²) ∓ 2acs² + s⁴)/… rewritten so
/// that no subtraction of nearly equal terms can make them negative by rounding.
/// Each numerator is at most its denominator (a, c ≥ 0), so F = ½(R_s + R_p) ∈ [0, 1]. Of a² and
/// b², the one computed from |w| + |Re w| (w = n² − s²) has no cancellation; the other follows
/// from ab = ηk. Everything is computed in units of r = max(η, k, 1) (a, b, c and s²/r scaled
/// by 1/r, which leaves both ratios unchanged), so no square overflows for any finite index.
/// Exact to rounding wherever c² is a normal double (c > 10⁻¹⁵⁴); below, c² rounds to 0 and F
/// is its grazing value 1 (which differs from the exact value only for n = 1 exactly, where
/// F = 0 for every c > 0).
fn conductor(cos_i: f64, eta: f64, k: f64) -> f64 {
    let r = eta.max(k).max(1.0);
    let unit = 1.0 / r;
    let (eta, k, c) = (eta * unit, k * unit, cos_i * unit);
    // s² = (1 − cos θ)(1 + cos θ), accurate near normal incidence.
    let s2_over_r = (1.0 - cos_i) * (1.0 + cos_i) * unit;
    // Re w = η² − k² − s² = (η² − 1) + (c² − k²), each difference a product of a difference
    // and a sum (exact to rounding): 1 − c² would round away c² at grazing incidence.
    let real = (eta - unit) * (eta + unit) + (c - k) * (c + k);
    let eta_k = eta * k;
    let modulus = real.hypot(2.0 * eta_k);
    let (a, b) = if real >= 0.0 {
        let a = (0.5 * (modulus + real)).sqrt();
        (a, if a > 0.0 { eta_k / a } else { 0.0 })
    } else {
        let b = (0.5 * (modulus - real)).sqrt();
        (eta_k / b, b)
    };
    let r_s = ratio((a - c) * (a - c) + b * b, (a + c) * (a + c) + b * b);
    let (ac, bc) = (a * cos_i, b * cos_i);
    let r_p = r_s
        * ratio(
            (ac - s2_over_r) * (ac - s2_over_r) + bc * bc,
            (ac + s2_over_r) * (ac + s2_over_r) + bc * bc,
        );
    0.5 * (r_s + r_p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn normal_incidence_matches_the_closed_forms() {
        // Dielectric: ((η − 1)/(η + 1))²; conductor: ((η − 1)² + k²)/((η + 1)² + k²).
        let f = Fresnel::Dielectric { eta: 1.5 }.evaluate(1.0);
        assert!((f.x - 0.04).abs() < 1e-12);
        let (eta, k) = (0.2, 3.0);
        let expected = ((eta - 1.0) * (eta - 1.0) + k * k) / ((eta + 1.0) * (eta + 1.0) + k * k);
        let f = Fresnel::Conductor {
            eta: DVec3::splat(eta),
            k: DVec3::splat(k),
        }
        .evaluate(1.0);
        assert!((f.x - expected).abs() < 1e-12);
        // A conductor with k = 0 is a dielectric.
        let f = Fresnel::Conductor {
            eta: DVec3::splat(1.5),
            k: DVec3::ZERO,
        }
        .evaluate(0.4);
        assert!((f.x - Fresnel::Dielectric { eta: 1.5 }.evaluate(0.4).x).abs() < 1e-12);
        // Grazing: 1; total internal reflection: 1.
        assert!((Fresnel::Dielectric { eta: 1.5 }.evaluate(0.0).x - 1.0).abs() < 1e-12);
        assert_eq!(Fresnel::Dielectric { eta: 1.0 / 1.5 }.evaluate(0.3).x, 1.0);
        assert!(Fresnel::Dielectric { eta: -1.0 }.validated().is_err());
    }

    /// A complex number, for the reference below.
    #[derive(Clone, Copy)]
    struct Complex(f64, f64);

    impl Complex {
        fn add(self, o: Self) -> Self {
            Self(self.0 + o.0, self.1 + o.1)
        }
        fn sub(self, o: Self) -> Self {
            Self(self.0 - o.0, self.1 - o.1)
        }
        fn mul(self, o: Self) -> Self {
            Self(self.0 * o.0 - self.1 * o.1, self.0 * o.1 + self.1 * o.0)
        }
        fn norm_squared(self) -> f64 {
            self.0 * self.0 + self.1 * self.1
        }
        /// The principal square root.
        fn sqrt(self) -> Self {
            let t = (0.5 * (self.0.hypot(self.1) + self.0.abs())).sqrt();
            if t == 0.0 {
                Self(0.0, 0.0)
            } else if self.0 >= 0.0 {
                Self(t, self.1 / (2.0 * t))
            } else {
                Self(self.1.abs() / (2.0 * t), t.copysign(self.1))
            }
        }
    }

    /// Fresnel's equations for a conductor as printed (Born and Wolf), by complex arithmetic:
    /// with n = η + ik and w = n cos θ_t = √(n² − sin²θ), r_s = (c − w)/(c + w) and
    /// r_p = (n²c − w)/(n²c + w); F = ½(|r_s|² + |r_p|²). Independent of the real-arithmetic
    /// form under test (the amplitudes, not their sums of squares), accurate in absolute terms
    /// within the accepted range.
    fn reference(c: f64, eta: f64, k: f64) -> f64 {
        if c == 0.0 {
            return 1.0; // grazing: r_s = r_p = −1 (0/0 only for n = 1, whose limit is 1 too)
        }
        let n = Complex(eta, k);
        let n2 = n.mul(n);
        // n² − sin²θ = (η² − 1) + (c² − k²) + 2iηk, without rounding 1 − c² at grazing.
        let w = Complex((eta - 1.0) * (eta + 1.0) + (c - k) * (c + k), 2.0 * eta * k).sqrt();
        let cc = Complex(c, 0.0);
        let r_s = cc.sub(w).norm_squared() / cc.add(w).norm_squared();
        let n2c = n2.mul(cc);
        let r_p = n2c.sub(w).norm_squared() / n2c.add(w).norm_squared();
        0.5 * (r_s + r_p)
    }

    fn conductor_f(c: f64, eta: f64, k: f64) -> f64 {
        Fresnel::Conductor {
            eta: DVec3::splat(eta),
            k: DVec3::splat(k),
        }
        .evaluate(c)
        .x
    }

    /// log-uniform in [lo, hi].
    fn log_uniform(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
        (lo.log10()..=hi.log10()).prop_map(move |e| 10f64.powf(e).clamp(lo, hi))
    }

    /// Cosines in [0, 1], with their ends, and down to `smallest` above 0.
    fn cosine(smallest: f64) -> impl Strategy<Value = f64> {
        prop_oneof![
            4 => 0.0..=1.0f64,
            1 => log_uniform(smallest, 1.0),
            1 => prop::sample::select(vec![0.0, 1.0, smallest, 1.0 - f64::EPSILON]),
        ]
    }

    fn accepted_eta() -> impl Strategy<Value = f64> {
        prop_oneof![
            6 => log_uniform(Fresnel::MIN_ETA, Fresnel::MAX_ETA),
            1 => prop::sample::select(vec![Fresnel::MIN_ETA, 1.0, Fresnel::MAX_ETA]),
        ]
    }

    fn accepted_k() -> impl Strategy<Value = f64> {
        prop_oneof![
            6 => log_uniform(1e-9, Fresnel::MAX_K),
            1 => prop::sample::select(vec![0.0, 1e-300, 1.0, Fresnel::MAX_K]),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            cases: 20_000,
            rng_seed: proptest::test_runner::RngSeed::Fixed(0x6672_6573),
            failure_persistence: None,
            ..ProptestConfig::default()
        })]

        /// Over the whole accepted range (η, k to their limits, every cosine whose square is
        /// a normal double), F is in [0, 1] and within 10⁻¹² of the complex-arithmetic
        /// reference; a dielectric with the same η is the conductor with k = 0.
        #[test]
        fn conductor_matches_the_reference_over_the_accepted_range(
            c in cosine(1e-150),
            eta in accepted_eta(),
            k in accepted_k(),
        ) {
            let f = conductor_f(c, eta, k);
            prop_assert!((0.0..=1.0).contains(&f), "F = {f} at c = {c}, η = {eta}, k = {k}");
            let expected = reference(c, eta, k);
            prop_assert!(
                (f - expected).abs() <= 1e-12,
                "F = {f}, reference {expected} at c = {c}, η = {eta}, k = {k}"
            );
            let dielectric = Fresnel::Dielectric { eta }.evaluate(c).x;
            prop_assert!((0.0..=1.0).contains(&dielectric));
            prop_assert_eq!(conductor_f(c, eta, 0.0), dielectric);
        }

        /// Beyond the accepted range, for any finite η > 0 and k ≥ 0 (the public `evaluate`
        /// of an unvalidated value), F is still in [0, 1].
        #[test]
        fn any_finite_index_gives_a_reflectance(
            c in cosine(f64::MIN_POSITIVE),
            eta in prop_oneof![log_uniform(1e-300, f64::MAX), Just(f64::MIN_POSITIVE), Just(f64::MAX)],
            k in prop_oneof![Just(0.0), log_uniform(1e-300, f64::MAX), Just(f64::MAX)],
        ) {
            let f = conductor_f(c, eta, k);
            prop_assert!((0.0..=1.0).contains(&f), "F = {f} at c = {c}, η = {eta}, k = {k}");
            let d = Fresnel::Dielectric { eta }.evaluate(c).x;
            prop_assert!((0.0..=1.0).contains(&d), "dielectric F = {d} at c = {c}, η = {eta}");
        }
    }

    /// The inputs that overflowed and went negative: η = k = 10³⁰⁰ and 10¹⁵⁴ (F → 1 as
    /// |n| → ∞), and η = 1, k = 0 (F = 0 off grazing, 1 at grazing).
    #[test]
    fn the_extremes_that_failed() {
        for x in [1e154, 1e300, f64::MAX] {
            for c in [0.0, 1e-6, 0.5, 1.0] {
                let f = conductor_f(c, x, x);
                assert!(f.is_finite() && f > 0.999_999 && f <= 1.0, "{x} {c}: {f}");
            }
        }
        for i in 0..=1000 {
            let c = f64::from(i) * 1e-3;
            let f = conductor_f(c, 1.0, 0.0);
            assert!((0.0..=1e-15).contains(&f) || c == 0.0, "c = {c}: {f}");
        }
        assert_eq!(conductor_f(0.0, 1.0, 0.0), 1.0);
    }

    /// The accepted range is the documented one: its ends are in, just past them is out, and
    /// the error names the parameter.
    #[test]
    fn validation_enforces_the_documented_range() {
        let conductor = |eta: f64, k: f64| {
            Fresnel::Conductor {
                eta: DVec3::new(1.0, eta, 1.0),
                k: DVec3::new(0.0, 0.0, k),
            }
            .validated()
        };
        assert!(conductor(Fresnel::MIN_ETA, 0.0).is_ok());
        assert!(conductor(Fresnel::MAX_ETA, Fresnel::MAX_K).is_ok());
        for (eta, k, parameter) in [
            (0.999e-3, 0.0, "eta"),
            (1.001e3, 0.0, "eta"),
            (f64::NAN, 0.0, "eta"),
            (1.0, -1e-300, "k"),
            (1.0, 1.001e3, "k"),
            (1.0, f64::INFINITY, "k"),
        ] {
            match conductor(eta, k) {
                Err(BrdfError::InvalidFresnel { parameter: p, .. }) => assert_eq!(p, parameter),
                other => panic!("η = {eta}, k = {k}: {other:?}"),
            }
        }
        assert!(Fresnel::Dielectric { eta: 1e3 }.validated().is_ok());
        assert!(Fresnel::Dielectric { eta: 1e300 }.validated().is_err());
        assert!(Fresnel::Dielectric { eta: 1e-4 }.validated().is_err());
    }
}
