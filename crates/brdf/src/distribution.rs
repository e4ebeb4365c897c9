//! Microfacet distributions: one table of kinds, one file per kind.
//!
//! A kind is a [`Model`] in a file of its own ([`beckmann`], [`ggx`], [`ashikhmin_shirley`])
//! and a row of [`DistributionKind`]'s table ([`DistributionKind::ALL`], its name, and the line
//! of [`with_model!`] that maps it to its model). Everything else takes the kinds from there:
//! eval's and the scene files' names, C's constants (checked against the table by a test),
//! Python, the tests' and `validate`'s loops. Adding a kind is described in
//! `ARCHITECTURE.md` ("Adding a distribution").
//!
//! All directions are in the local shading frame (n = +z); (α_x, α_y) are the roughnesses
//! along x and y. Every kind keeps the contract below, which the tests of this module and of
//! `tests/tests/brdf.rs` check for each row of the table:
//!
//! - p(m) = D(m)(m·n) integrates to 1 over the hemisphere: it is the density of particle
//!   normals the count tree uses ([`Microfacet::particle_density`]);
//! - p reads m_x and m_y only through their squares (a half turn about n leaves it unchanged
//!   bit for bit), and with α_x = α_y it treats them alike (a quarter turn too): the count
//!   tree's law excess walks one octant or two on that promise;
//! - Λ is Smith's for this D: (1 + Λ(ω)) cos θ = ∫ D(m) max(0, ω·m) dm;
//! - [`Microfacet::sample_normal`] draws from p, and the particle density bound holds;
//! - its name is lowercase ASCII letters and `_` (scene files, eval, C and Python use it);
//! - it states the settings its checks need beyond the suites' common ones
//!   ([`KindChecks`]: wide cones, an anisotropic lobe, convergence cases).
//!
//! Nothing else is asked of a kind: how α maps to its shape (D(n) = 1/(π α_x α_y) for the
//! three kinds here) is its own, checked in its own file. Every loop over the table reads
//! [`DistributionKind::ALL`]; the user docs' lists of names are checked against it by
//! `tests/tests/doc_lists.rs`, which names the file to update.
//!
//! G1(ω, m) = χ⁺(ω·m)/(1 + Λ(ω)); G(ω_i, ω_o, m) is the height-correlated form
//! χ⁺(ω_i·m)χ⁺(ω_o·m)/(1 + Λ(ω_i) + Λ(ω_o)) (Heitz 2014).

mod ashikhmin_shirley;
mod beckmann;
mod ggx;

use std::sync::Arc;

use glam::DVec3;

pub use ashikhmin_shirley::SmithTable;

use crate::error::BrdfError;

/// Which microfacet distribution: the table of kinds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DistributionKind {
    /// Beckmann (Gaussian slopes).
    Beckmann,
    /// GGX / Trowbridge–Reitz.
    Ggx,
    /// Ashikhmin and Shirley's anisotropic Phong (2000), exponents e = 2/α² − 2.
    AshikhminShirley,
}

/// Calls `$body` with `$model` standing for the [`Model`] of `$kind`: the one place that maps a
/// kind to its implementation.
macro_rules! with_model {
    ($kind:expr, $model:ident => $body:expr) => {
        match $kind {
            DistributionKind::Beckmann => {
                type $model = beckmann::Beckmann;
                $body
            }
            DistributionKind::Ggx => {
                type $model = ggx::Ggx;
                $body
            }
            DistributionKind::AshikhminShirley => {
                type $model = ashikhmin_shirley::AshikhminShirley;
                $body
            }
        }
    };
}

impl DistributionKind {
    /// Every kind, in the order of C's `GlintDistribution` constants (a kind's constant is its
    /// index here).
    pub const ALL: [DistributionKind; 3] = [
        DistributionKind::Beckmann,
        DistributionKind::Ggx,
        DistributionKind::AshikhminShirley,
    ];

    /// The kind's name in scene files, eval, Python and the Mitsuba plugins.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            DistributionKind::Beckmann => "beckmann",
            DistributionKind::Ggx => "ggx",
            DistributionKind::AshikhminShirley => "ashikhmin_shirley",
        }
    }

    /// The kind named `name` ([`DistributionKind::name`]), if any.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|kind| kind.name() == name)
    }

    /// The kind whose C constant is `code` (its index in [`DistributionKind::ALL`]), if any.
    #[must_use]
    pub fn from_code(code: u32) -> Option<Self> {
        Self::ALL.get(usize::try_from(code).ok()?).copied()
    }

    /// The kind's C constant: its index in [`DistributionKind::ALL`].
    #[must_use]
    pub fn code(self) -> u32 {
        Self::ALL
            .iter()
            .position(|kind| *kind == self)
            .and_then(|index| u32::try_from(index).ok())
            .unwrap_or(u32::MAX)
    }

    /// The names of all kinds, for error messages: "beckmann, ggx, …".
    #[must_use]
    pub fn names() -> String {
        Self::ALL.map(Self::name).join(", ")
    }

    /// Whether [`NormalSampling::Visible`] is available for this kind.
    #[must_use]
    pub fn samples_visible_normals(self) -> bool {
        with_model!(self, M => M::SAMPLES_VISIBLE_NORMALS)
    }

    /// The radial law of the kind's scaled slopes, if it has one.
    pub(crate) fn radial_law(self) -> Option<RadialLaw> {
        with_model!(self, M => M::RADIAL)
    }

    /// The settings the test suites check this kind at, beyond the settings they share
    /// ([`KindChecks`]).
    #[must_use]
    pub fn checks(self) -> KindChecks {
        with_model!(self, M => M::CHECKS)
    }
}

/// The settings where a kind's checks need more than the suites' common ones, stated in the
/// kind's own file so that every suite that loops over [`DistributionKind::ALL`] reads them
/// from there: the glint sampler's χ² test and `validate`'s samplers (`sampler_cones`), the
/// glint sampler's mean weight against the albedo (`albedo_cones`), and f̂'s mean against the
/// smooth BRDF (`convergence`). Cones should include one wide against the lobe (its pdf takes
/// the slope-space rule) and an anisotropic lobe; a new kind states its own.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KindChecks {
    /// The glint sampler's χ² cases where the cone is wide against the lobe or the lobe
    /// extremely anisotropic, at incidence from the normal to 85°.
    pub sampler_cones: &'static [ConeCheck],
    /// The glint sampler's smooth weight f·cos θ_o / pdf, whose mean is the albedo.
    pub albedo_cones: &'static [ConeCheck],
    /// The mean of f̂ over footprints against the smooth BRDF convolved with the cone.
    pub convergence: &'static [ConvergenceCheck],
}

/// A material and cone for a sampler check.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConeCheck {
    /// (α_x, α_y).
    pub alpha: (f64, f64),
    /// The cone's half-angle γ, in degrees.
    pub gamma_degrees: f64,
    /// For a lobe narrow against the χ² test's bins: the radius, in degrees, of the cap around
    /// the lobe that the test bins finely (`None`: the whole hemisphere).
    pub cap_degrees: Option<f64>,
}

impl ConeCheck {
    /// Roughness (α_x, α_y) under a cone of half-angle γ (degrees), binned over the whole
    /// hemisphere.
    #[must_use]
    pub const fn new(alpha: (f64, f64), gamma_degrees: f64) -> Self {
        Self {
            alpha,
            gamma_degrees,
            cap_degrees: None,
        }
    }

    /// The same, binned finely over a cap of `degrees` around the lobe.
    #[must_use]
    pub const fn capped(self, degrees: f64) -> Self {
        Self {
            cap_degrees: Some(degrees),
            ..self
        }
    }
}

/// A material, cone and pair of directions for the convergence check.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConvergenceCheck {
    /// (α_x, α_y).
    pub alpha: (f64, f64),
    /// The cone's half-angle γ, in degrees.
    pub gamma_degrees: f64,
    /// θ_i, θ_o and φ_o in radians (ω_i at φ = 0).
    pub angles: (f64, f64, f64),
}

impl ConvergenceCheck {
    /// Roughness (α_x, α_y), a cone of half-angle γ (degrees), and θ_i, θ_o, φ_o (radians).
    #[must_use]
    pub const fn new(alpha: (f64, f64), gamma_degrees: f64, angles: (f64, f64, f64)) -> Self {
        Self {
            alpha,
            gamma_degrees,
            angles,
        }
    }
}

impl std::fmt::Display for DistributionKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A lobe that is radial in scaled slopes (x/α_x, y/α_y), with density P(ρ) in the scaled
/// radius ρ: the glint sampler's slope-space pdf integrates its chords in closed form
/// (`slope_pdf/ellipse.rs`) and its rays by the tail T(ρ) = 2π∫_ρ^∞ P(r) r dr.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum RadialLaw {
    /// P(ρ) = e^(−ρ²)/π, T(ρ) = e^(−ρ²) (Beckmann).
    Gaussian,
    /// P(ρ) = 1/(π(1 + ρ²)²), T(ρ) = 1/(1 + ρ²) (GGX).
    Student,
}

/// What a microfacet distribution implements, in terms of its roughness (α_x, α_y). Arguments
/// are checked by [`Microfacet`] first: unit vectors above the horizon, and for Λ a direction
/// off the normal. See the module's contract.
pub(crate) trait Model {
    /// Its radial law in scaled slopes, for the slope-space pdf's closed forms; `None` takes
    /// [`Model::ray_mass`] along rays instead.
    const RADIAL: Option<RadialLaw>;
    /// Whether [`Model::sample_visible_normal`] is implemented.
    const SAMPLES_VISIBLE_NORMALS: bool;
    /// The settings the test suites check it at ([`KindChecks`]).
    const CHECKS: KindChecks;

    /// D(m) for a unit normal m with m_z > 0.
    fn d(alpha: (f64, f64), m: DVec3) -> f64;

    /// D(h)/|H|⁴ for h = H/|H|, H with H_z > 0 of any length.
    fn d_of_half_vector(alpha: (f64, f64), half: DVec3) -> f64 {
        let length2 = half.length_squared();
        Self::d(alpha, half / length2.sqrt()) / (length2 * length2)
    }

    /// Smith's Λ(ω) for a unit ω with ω_z > 0, off the normal.
    fn lambda(alpha: (f64, f64), w: DVec3) -> f64;

    /// Λ(ω)·ω_z for a unit ω with ω_z > 0, off the normal: finite down to the horizon, where
    /// Λ grows like 1/ω_z and overflows.
    fn lambda_times_cos(alpha: (f64, f64), w: DVec3) -> f64;

    /// An upper bound on p(m) = D(m)(m·n) over the unit normals with tan²θ in
    /// [t_near, t_far] (t_near ≤ t_far, t_far may be +∞).
    fn particle_density_bound(alpha: (f64, f64), t_near: f64, t_far: f64) -> f64;

    /// A normal drawn from p(m) = D(m)(m·n), from two uniforms.
    fn sample_normal(alpha: (f64, f64), u: [f64; 2]) -> DVec3;

    /// A normal drawn from the visible normals seen from ω_i, whose density is
    /// G1(ω_i, m)·max(0, ω_i·m)·D(m)/ω_i.z. Only called where
    /// [`Model::SAMPLES_VISIBLE_NORMALS`]; the default draws from p.
    fn sample_visible_normal(alpha: (f64, f64), _wi: DVec3, u: [f64; 2]) -> DVec3 {
        Self::sample_normal(alpha, u)
    }

    /// The table Λ is read from, for kinds that tabulate it.
    fn smith_table(_alpha: (f64, f64)) -> Option<Arc<SmithTable>> {
        None
    }

    /// 2π times the mass of p per unit ψ along the ray H = (α_x ρ cos ψ, α_y ρ sin ψ, 1) of
    /// scaled slopes for ρ in [a, b] (a ≤ b, b may be +∞), from the ray's direction
    /// (cos ψ, sin ψ): for a radial law, T(a) − T(b) whatever the direction (the default).
    fn ray_mass(_alpha: (f64, f64), _direction: (f64, f64), a: f64, b: f64) -> f64 {
        match Self::RADIAL {
            Some(law) => law.tail_difference(a, b),
            None => unreachable!("a kind without a radial law implements its ray mass"),
        }
    }
}

impl RadialLaw {
    /// T(a) − T(b) for a ≤ b, without cancellation when they are close.
    pub(crate) fn tail_difference(self, a: f64, b: f64) -> f64 {
        match self {
            // e^(−a²) − e^(−b²) = e^(−a²)(1 − e^(−(b − a)(b + a))).
            RadialLaw::Gaussian => {
                if b.is_infinite() {
                    (-a * a).exp()
                } else {
                    -(-a * a).exp() * (-(b - a) * (b + a)).exp_m1()
                }
            }
            // 1/(1 + a²) − 1/(1 + b²) = (b − a)(b + a)/((1 + a²)(1 + b²)).
            RadialLaw::Student => {
                if b.is_infinite() {
                    return 1.0 / (1.0 + a * a);
                }
                let denominator = (1.0 + a * a) * (1.0 + b * b);
                if denominator.is_finite() {
                    (b - a) * (b + a) / denominator
                } else {
                    // Beyond a scaled slope of about 1e154 (grazing directions) the squares
                    // overflow (∞/∞): the same product factor by factor, each finite.
                    let (near, far) = (1.0 / (1.0 + a * a), 1.0 / (1.0 + b * b));
                    (b - a) * near * (2.0 * ((0.5 * a + 0.5 * b) * far))
                }
            }
        }
    }
}

/// How normals are sampled.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum NormalSampling {
    /// From p(m) = D(m)(m·n), the standard method (Walter et al. 2007).
    #[default]
    Distribution,
    /// From the distribution of normals visible from ω_i (Heitz 2018 for GGX, Heitz and
    /// d'Eon 2014 for Beckmann); kinds without it refuse it
    /// ([`DistributionKind::samples_visible_normals`]).
    Visible,
}

/// A microfacet distribution with its roughness (α_x, α_y).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Microfacet {
    kind: DistributionKind,
    alpha_x: f64,
    alpha_y: f64,
}

/// The smallest roughness accepted; below it the distributions are numerically a delta.
pub const MIN_ALPHA: f64 = 1e-4;

impl Microfacet {
    /// A distribution with roughness (α_x, α_y) in [1e-4, 1] (α_x = α_y is isotropic).
    ///
    /// # Errors
    /// [`BrdfError::InvalidRoughness`] for α outside [1e-4, 1] or not finite.
    pub fn new(kind: DistributionKind, alpha_x: f64, alpha_y: f64) -> Result<Self, BrdfError> {
        for alpha in [alpha_x, alpha_y] {
            if !(MIN_ALPHA..=1.0).contains(&alpha) {
                return Err(BrdfError::InvalidRoughness { alpha });
            }
        }
        Ok(Self {
            kind,
            alpha_x,
            alpha_y,
        })
    }

    /// The distribution kind.
    #[must_use]
    pub fn kind(&self) -> DistributionKind {
        self.kind
    }

    /// (α_x, α_y).
    #[must_use]
    pub fn alpha(&self) -> (f64, f64) {
        (self.alpha_x, self.alpha_y)
    }

    /// The same distribution with both roughnesses scaled by `factor`, clamped to [1e-4, 1]
    /// (the widened sampling distribution of Sec. 3.4).
    #[must_use]
    pub fn scaled(&self, factor: f64) -> Self {
        Self {
            kind: self.kind,
            alpha_x: (self.alpha_x * factor).clamp(MIN_ALPHA, 1.0),
            alpha_y: (self.alpha_y * factor).clamp(MIN_ALPHA, 1.0),
        }
    }

    /// D(m) for a unit normal m (0 below the horizon).
    #[must_use]
    pub fn d(&self, m: DVec3) -> f64 {
        if m.z <= 0.0 {
            return 0.0;
        }
        with_model!(self.kind, M => M::d(self.alpha(), m))
    }

    /// D(h)(h·n)/(4 ω_i·h), the density of ω_o = reflect(ω_i, h) for normals h drawn from
    /// D(h)(h·n), from the unnormalized half vector H = ω_i + ω_o (0 unless H.z > 0 and
    /// ω_i·H > 0). With D(h)/|H|⁴ from the kind ([`Model::d_of_half_vector`], no square root
    /// for kinds whose formula is homogeneous) and (h·n)/(ω_i·h) = H_z/(ω_i·H).
    #[inline]
    #[must_use]
    pub fn reflected_density(&self, wi: DVec3, half: DVec3) -> f64 {
        let cos = wi.dot(half);
        if !(half.z > 0.0 && cos > 0.0) {
            return 0.0;
        }
        let length2 = half.length_squared();
        let d = with_model!(self.kind, M => M::d_of_half_vector(self.alpha(), half));
        d * length2 * length2 * half.z / (4.0 * cos)
    }

    /// p(m) = D(m)(m·n): the density of particle normals, which integrates to 1.
    #[must_use]
    pub fn particle_density(&self, m: DVec3) -> f64 {
        self.d(m) * m.z.max(0.0)
    }

    /// An upper bound on p(m) = D(m)(m·n) over the unit normals whose angle θ from n lies
    /// between the angles of `cos_near` and `cos_far` (cos_near ≥ cos_far; cos_far ≤ 0 reaches
    /// the horizon). For the negligible-query test of [`crate::DiscreteBrdf`]. Each kind bounds
    /// p on tan²θ in [t_near, t_far] ([`Model::particle_density_bound`]).
    #[must_use]
    pub fn particle_density_bound(&self, cos_near: f64, cos_far: f64) -> f64 {
        let tan2 = |c: f64| {
            if c <= 0.0 {
                f64::INFINITY
            } else {
                (1.0 - c * c).max(0.0) / (c * c)
            }
        };
        let (t_near, t_far) = (tan2(cos_near.min(1.0)), tan2(cos_far));
        if !t_near.is_finite() {
            return 0.0;
        }
        with_model!(self.kind, M => M::particle_density_bound(self.alpha(), t_near, t_far.max(t_near)))
    }

    /// Smith's Λ(ω) for a unit direction ω above the horizon.
    #[must_use]
    pub fn lambda(&self, w: DVec3) -> f64 {
        if w.z <= 0.0 {
            return f64::INFINITY;
        }
        if w.x == 0.0 && w.y == 0.0 {
            return 0.0;
        }
        with_model!(self.kind, M => M::lambda(self.alpha(), w))
    }

    /// Λ(ω)·ω_z for a unit direction ω above the horizon: finite down to the horizon, where Λ
    /// grows like 1/ω_z (and overflows below about 1e-300).
    #[must_use]
    pub fn lambda_times_cos(&self, w: DVec3) -> f64 {
        if w.z <= 0.0 || (w.x == 0.0 && w.y == 0.0) {
            return 0.0;
        }
        with_model!(self.kind, M => M::lambda_times_cos(self.alpha(), w))
    }

    /// G(ω_i, ω_o, m)/(4 cos θ_i cos θ_o), the shadowing and cosine factor of Eq. 3, finite for
    /// directions at any height above the horizon. Where 4 cos θ_i cos θ_o underflows or a Λ
    /// overflows (heights below about 1e-150), the quotient G/(4 cos θ_i cos θ_o) is 0/0 (or
    /// 1/0) term by term; it is then 1/(4(cos θ_i cos θ_o + (Λ_i cos θ_i) cos θ_o +
    /// (Λ_o cos θ_o) cos θ_i)) with [`Microfacet::lambda_times_cos`], which stay finite
    /// (clamped to the largest finite number where the true value exceeds it). Elsewhere it is
    /// G/(4 cos θ_i cos θ_o) as written.
    #[must_use]
    pub fn g_over_cosines(&self, wi: DVec3, wo: DVec3, m: DVec3) -> f64 {
        let g = self.g(wi, wo, m);
        let cosines = 4.0 * wi.z * wo.z;
        if g > 0.0 && cosines >= f64::MIN_POSITIVE {
            return g / cosines;
        }
        if wi.dot(m) <= 0.0 || wo.dot(m) <= 0.0 || wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        let product =
            wi.z * wo.z + self.lambda_times_cos(wi) * wo.z + self.lambda_times_cos(wo) * wi.z;
        (0.25 / product).min(f64::MAX)
    }

    /// G1(ω, m) = χ⁺(ω·m)/(1 + Λ(ω)).
    #[must_use]
    pub fn g1(&self, w: DVec3, m: DVec3) -> f64 {
        if w.dot(m) <= 0.0 || w.z <= 0.0 {
            return 0.0;
        }
        1.0 / (1.0 + self.lambda(w))
    }

    /// The height-correlated G(ω_i, ω_o, m).
    #[must_use]
    pub fn g(&self, wi: DVec3, wo: DVec3, m: DVec3) -> f64 {
        if wi.dot(m) <= 0.0 || wo.dot(m) <= 0.0 || wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        1.0 / (1.0 + self.lambda(wi) + self.lambda(wo))
    }

    /// A normal drawn from p(m) = D(m)(m·n), from two uniforms (each kind's file says how).
    #[must_use]
    pub fn sample_normal(&self, u: [f64; 2]) -> DVec3 {
        with_model!(self.kind, M => M::sample_normal(self.alpha(), u))
    }

    /// The density of [`Microfacet::sample_normal`] in solid angle: D(m)(m·n).
    #[must_use]
    pub fn normal_pdf(&self, m: DVec3) -> f64 {
        self.particle_density(m)
    }

    /// A normal drawn from the visible normals seen from ω_i, for kinds that
    /// [sample them](DistributionKind::samples_visible_normals) (each kind's file says how);
    /// for the others, a normal from p (whose density [`Microfacet::visible_normal_pdf`] is not).
    #[must_use]
    pub fn sample_visible_normal(&self, wi: DVec3, u: [f64; 2]) -> DVec3 {
        with_model!(self.kind, M => M::sample_visible_normal(self.alpha(), wi, u))
    }

    /// The density of [`Microfacet::sample_visible_normal`]: G1(ω_i, m)·max(0, ω_i·m)·D(m)/ω_i.z.
    #[must_use]
    pub fn visible_normal_pdf(&self, wi: DVec3, m: DVec3) -> f64 {
        if wi.z <= 0.0 {
            return 0.0;
        }
        let g1 = self.g1(wi, m);
        if g1 > 0.0 {
            return g1 * wi.dot(m).max(0.0) * self.d(m) / wi.z;
        }
        if wi.dot(m) <= 0.0 {
            return 0.0;
        }
        // Λ(ω_i) overflowed (ω_i within about 1e-300 of the horizon): G1/ω_i.z =
        // 1/(ω_i.z + Λ(ω_i)ω_i.z).
        let g1_over_cos = (1.0 / (wi.z + self.lambda_times_cos(wi))).min(f64::MAX);
        (g1_over_cos * wi.dot(m) * self.d(m)).min(f64::MAX)
    }

    /// The table this distribution reads Λ from, if its kind tabulates Λ (Ashikhmin–Shirley:
    /// built on first use, then shared): what a port of the lobe (the Dr.Jit plugin's)
    /// interpolates to give the same Λ.
    #[must_use]
    pub fn smith_table(&self) -> Option<Arc<SmithTable>> {
        with_model!(self.kind, M => M::smith_table(self.alpha()))
    }

    /// 2π times the mass of p per unit ψ along a ray of scaled slopes for ρ in [a, b]
    /// ([`Model::ray_mass`]).
    pub(crate) fn ray_mass(&self, direction: (f64, f64), a: f64, b: f64) -> f64 {
        with_model!(self.kind, M => M::ray_mass(self.alpha(), direction, a, b))
    }
}

/// (x²/α_x² + y²/α_y²)/z² for m = (x, y, z): the squared scaled slope of radial kinds.
pub(crate) fn scaled_slope2((alpha_x, alpha_y): (f64, f64), m: DVec3) -> f64 {
    (m.x * m.x / (alpha_x * alpha_x) + m.y * m.y / (alpha_y * alpha_y)) / (m.z * m.z)
}

/// The unit normal normalize(−s_x, −s_y, 1) of the slopes s = (α_x ρ cos φ, α_y ρ sin φ),
/// φ = 2πu: a radial kind's sample from its scaled radius ρ.
pub(crate) fn normal_from_scaled_slope(
    (alpha_x, alpha_y): (f64, f64),
    radius: f64,
    u: f64,
) -> DVec3 {
    let phi = 2.0 * std::f64::consts::PI * u;
    DVec3::new(
        -alpha_x * radius * phi.cos(),
        -alpha_y * radius * phi.sin(),
        1.0,
    )
    .normalize()
}

/// The root of increasing `f` in [lo, hi] by bisection to double precision.
pub(crate) fn bisect(f: impl Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> f64 {
    for _ in 0..64 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if f(mid) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The error function, to ~1e-15: for |x| < 2.5 the series
/// erf(x) = 2/√π·e^(−x²)·Σ 2ⁿx^(2n+1)/(1·3·…·(2n+1)) (positive terms, no cancellation), beyond
/// 1 − erfc(x) with erfc's continued fraction e^(−x²)/√π · 1/(x + ½/(x + 1/(x + (3/2)/(x + …)))),
/// truncated at ⌈200/x²⌉ levels.
#[must_use]
pub fn erf(x: f64) -> f64 {
    let a = x.abs();
    let value = if a < 2.5 {
        let two_x2 = 2.0 * a * a;
        let mut term = a;
        let mut sum = a;
        let mut n = 0.0;
        while term > 1e-17 * sum {
            n += 1.0;
            term *= two_x2 / (2.0 * n + 1.0);
            sum += term;
        }
        2.0 / std::f64::consts::PI.sqrt() * (-a * a).exp() * sum
    } else {
        // ⌈200/x²⌉ levels reach 2e-17 absolute on erfc for x ≥ 2.5 (29 levels at 2.5, 3 at 5;
        // checked against a 40-digit evaluation).
        1.0 - erfc_continued_fraction(a, (200.0 / (a * a)).ceil().min(80.0) as u32)
    };
    value.copysign(x)
}

/// erfc(x) for x ≥ 2.5 by its continued fraction e^(−x²)/√π · 1/(x + ½/(x + 1/(x + (3/2)/(x +
/// …)))) truncated at `levels` levels: [`erf`]'s tail, and with 60 levels a reference to a
/// relative 1e-15 for faster approximations.
pub(crate) fn erfc_continued_fraction(x: f64, levels: u32) -> f64 {
    let mut fraction = x;
    for k in (1..=levels).rev() {
        fraction = x + (f64::from(k) * 0.5) / fraction;
    }
    (-x * x).exp() / (std::f64::consts::PI.sqrt() * fraction)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn erf_matches_reference_values() {
        for (x, expected) in [
            (0.0, 0.0),
            (0.1, 0.112_462_916_018_284_9),
            (1.0, 0.842_700_792_949_714_9),
            (2.0, 0.995_322_265_018_952_7),
            (2.49, 0.999_570_712_132_266_1),
            (2.51, 0.999_614_294_518_275_8),
            (3.5, 0.999_999_256_901_627_6),
            (-1.5, -0.966_105_146_475_310_8),
            (2.6, 0.999_763_965_583_470_7),
            (2.75, 0.999_899_378_077_880_3),
            (3.2, 0.999_993_974_238_848_3),
            (4.5, 0.999_999_999_803_383_9),
            (5.5, 0.999_999_999_999_992_7),
        ] {
            let got = erf(x);
            assert!(
                (got - expected).abs() < 2e-15,
                "erf({x}) = {got}, expected {expected}"
            );
        }
    }

    /// Every kind states the settings its checks need (`KindChecks`): a sampler cone wide
    /// against the lobe (γ > 4α at normal incidence, beyond the cone rules' reach, so the
    /// slope-space rule answers), an anisotropic lobe, an albedo cone and a convergence case,
    /// each a valid material.
    #[test]
    fn every_kind_states_the_settings_its_checks_need() {
        for kind in DistributionKind::ALL {
            let checks = kind.checks();
            let wide =
                |c: &ConeCheck| c.gamma_degrees.to_radians() > 4.0 * c.alpha.0.max(c.alpha.1);
            assert!(
                checks.sampler_cones.iter().any(wide),
                "{kind:?}: no wide cone"
            );
            let anisotropic = checks
                .sampler_cones
                .iter()
                .map(|c| c.alpha)
                .chain(checks.convergence.iter().map(|c| c.alpha))
                .any(|(ax, ay)| ax != ay);
            assert!(anisotropic, "{kind:?}: no anisotropic lobe");
            assert!(!checks.albedo_cones.is_empty() && !checks.convergence.is_empty());
            let alphas = (checks.sampler_cones.iter().chain(checks.albedo_cones))
                .map(|c| c.alpha)
                .chain(checks.convergence.iter().map(|c| c.alpha));
            for (ax, ay) in alphas {
                assert!(
                    Microfacet::new(kind, ax, ay).is_ok(),
                    "{kind:?} ({ax}, {ay})"
                );
            }
        }
    }

    #[test]
    fn the_table_names_every_kind_once() {
        for (index, kind) in DistributionKind::ALL.into_iter().enumerate() {
            assert_eq!(DistributionKind::from_name(kind.name()), Some(kind));
            assert_eq!(kind.code() as usize, index);
            assert_eq!(DistributionKind::from_code(kind.code()), Some(kind));
            assert_eq!(kind.to_string(), kind.name());
            assert!(
                kind.name()
                    .chars()
                    .all(|c| c.is_ascii_lowercase() || c == '_')
            );
        }
        assert_eq!(DistributionKind::from_name("Beckmann"), None);
        // The list errors name: every kind once, in the table's order.
        let listed: Vec<String> = DistributionKind::names()
            .split(", ")
            .map(str::to_owned)
            .collect();
        let table: Vec<String> = DistributionKind::ALL
            .iter()
            .map(|kind| kind.name().to_owned())
            .collect();
        assert_eq!(listed, table);
    }

    /// The contract's symmetries, bit for bit: p is even in m_x and in m_y, and with
    /// α_x = α_y a quarter turn about n leaves it unchanged (the count tree's law excess walks
    /// one octant on that promise).
    #[test]
    fn every_kind_keeps_the_symmetries_the_count_tree_relies_on() {
        for kind in DistributionKind::ALL {
            for (ax, ay) in [(0.3, 0.1), (0.2, 0.2), (1e-4, 1.0), (0.05, 0.05)] {
                let d = Microfacet::new(kind, ax, ay).unwrap();
                for k in 0..200 {
                    let t = f64::from(k) * 0.618_033_988_749_895;
                    let (sin, cos) = (std::f64::consts::TAU * t.fract()).sin_cos();
                    let tan = 3.0 * (0.37 * f64::from(k)).fract();
                    let m = DVec3::new(tan * cos, tan * sin, 1.0).normalize();
                    let p = d.particle_density(m);
                    let mirrored_x = DVec3::new(-m.x, m.y, m.z);
                    let mirrored_y = DVec3::new(m.x, -m.y, m.z);
                    assert_eq!(
                        p.to_bits(),
                        d.particle_density(mirrored_x).to_bits(),
                        "{kind}"
                    );
                    assert_eq!(
                        p.to_bits(),
                        d.particle_density(mirrored_y).to_bits(),
                        "{kind}"
                    );
                    if ax == ay {
                        let turned = DVec3::new(-m.y, m.x, m.z);
                        assert_eq!(p.to_bits(), d.particle_density(turned).to_bits(), "{kind}");
                    }
                }
            }
        }
    }

    #[test]
    fn known_values() {
        for kind in DistributionKind::ALL {
            let d = Microfacet::new(kind, 0.3, 0.1).unwrap();
            assert_eq!(d.lambda(DVec3::Z), 0.0);
            assert_eq!(d.d(DVec3::new(0.0, 0.6, -0.8)), 0.0);
        }
        assert!(Microfacet::new(DistributionKind::Ggx, 0.0, 0.1).is_err());
        assert!(Microfacet::new(DistributionKind::Ggx, 0.1, f64::NAN).is_err());
        assert!(Microfacet::new(DistributionKind::Beckmann, 1.5, 0.1).is_err());
    }

    /// The square-root-free density against its definition with the normalized half vector,
    /// for any length of H.
    #[test]
    fn reflected_density_is_d_times_the_jacobian() {
        for kind in DistributionKind::ALL {
            let d = Microfacet::new(kind, 0.3, 0.1).unwrap();
            for (wi, wo) in [
                (DVec3::new(0.2, -0.1, 0.9), DVec3::new(-0.3, 0.2, 0.8)),
                (DVec3::new(0.9, 0.1, 0.05), DVec3::new(-0.5, 0.4, 0.3)),
                (DVec3::Z, DVec3::new(0.1, 0.0, 1.0)),
            ] {
                let (wi, wo) = (wi.normalize(), wo.normalize());
                let h = (wi + wo).normalize();
                let expected = d.d(h) * h.z / (4.0 * wi.dot(h));
                for scale in [1.0, 1e-3, 7.0] {
                    let got = d.reflected_density(wi, scale * (wi + wo));
                    assert!(
                        (got - expected).abs() <= 1e-13 * expected,
                        "{kind:?}: {got} against {expected}"
                    );
                }
            }
            // Below the horizon, and facing away from ω_i: 0.
            assert_eq!(
                d.reflected_density(DVec3::Z, DVec3::new(0.3, 0.0, -0.1)),
                0.0
            );
            let wi = DVec3::new(0.8, 0.0, 0.6);
            assert_eq!(d.reflected_density(wi, DVec3::new(-0.9, 0.0, 0.1)), 0.0);
        }
    }
}
