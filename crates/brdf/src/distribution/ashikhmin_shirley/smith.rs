//! Smith's Λ for Ashikhmin–Shirley: a table per roughness, built from the slope marginal.
//!
//! **Definition.** With μ = cot θ_o and P2 the density of the slope q along ω's azimuth φ_o
//! (the marginal of P22 = D cos⁴θ), Λ(ω) = (1/μ) ∫_μ^∞ (q − μ) P2(q) dq =: F(μ)/μ. There is no
//! closed form; the parent module derives the same Λ as a double integral over the half plane
//! facing ω, which the tests use as the reference.
//!
//! **The table.** Λ depends on the direction through a = ω_z/√((α_x ω_x)² + (α_y ω_y)²) (the
//! Beckmann-like scaled cotangent) and ϕ, the azimuth of (α_x ω_x, α_y ω_y) (the azimuth in
//! scaled slopes, where the lobe is nearly round: Λ varies slowly with ϕ), and on nothing else
//! but (α_x, α_y). The table holds G = Λ·(1 − u) at u = 1/(1 + a) on [`U_NODES`] uniform nodes
//! of [0, 1] (and one beyond 1, where F continues smoothly to μ < 0) and, for an anisotropic
//! lobe, ϕ on [`AZIMUTH_NODES`] uniform nodes of [0, π/2] (p is even in x and y, so Λ is even
//! in ϕ about 0 and π/2). G is bounded: Λ grows like E[q⁺]/μ at grazing angles, and 1 − u
//! cancels that. A lookup is Catmull–Rom in u on each of four rows, then in ϕ, and
//! Λ = G/(1 − u).
//!
//! **Building a row.** For the row's φ_o the nodes are μ_j = (1 − u_j)α(φ_o)/u_j, and
//! F(μ_j) = F(μ_{j−1}) + (μ_{j−1} − μ_j)·T0(μ_{j−1}) + ∫_{μ_j}^{μ_{j−1}} (q − μ_j)P2 dq with
//! T0(μ) = ∫_μ^∞ P2: every term positive, one 15-point rule per interval, each P2(q) an
//! adaptive rule across the azimuth.
//!
//! **Accuracy and cost** (`the_table_is_the_quadrature`, halfway between nodes against the
//! double integral): |ΔΛ|/(1 + Λ) ≤ 1.3e-7 for isotropic lobes and (α_x, α_y) = (0.1, 0.4),
//! 1.1e-6 for (1, 0.5), 2.6e-3 for the wedge (10⁻⁴, 1). A table takes 15–30 ms isotropic,
//! 0.4–0.8 s of CPU anisotropic (release build), once per roughness per process, its azimuth
//! rows on up to [`BUILD_THREADS`] cores (the ornaments scene at 32 × 18 pixels, whose one
//! anisotropic lobe's table is most of its run, takes 0.60–0.62 s instead of 0.85–0.93 on two
//! cores). One table is built at a time, and threads that need it wait for it rather than
//! build it again. [`REMEMBERED_TABLES`] are kept, and each thread holds the last it used, so
//! a lookup takes no lock.

use std::cell::RefCell;
use std::sync::{Arc, Mutex};

use glam::DVec3;

use super::{exponents, log_phong};
use crate::quadrature::{adaptive_gauss_kronrod, gauss_kronrod, kronrod_points};

/// The marginal density's quadrature across the azimuth stops at this relative error
/// estimate (the 15-point rule's actual error is far smaller than its estimate).
const MARGINAL_TOLERANCE: f64 = 1e-7;

/// At most this many pieces of 15 points per value of the marginal density.
const MARGINAL_MAX_PIECES: usize = 32;

/// Nodes of u = 1/(1 + a) on [0, 1].
pub(crate) const U_NODES: usize = 129;

/// Values per row: the nodes of u, and one beyond u = 1 (where F continues smoothly to μ < 0)
/// for the last interval's cubic.
const ROW: usize = U_NODES + 1;

/// Nodes of the azimuth on [0, π/2] for an anisotropic lobe (1 for an isotropic one).
pub(crate) const AZIMUTH_NODES: usize = 33;

/// The most tables the process keeps.
const REMEMBERED_TABLES: usize = 64;

/// A table's rows are built on at most this many threads.
const BUILD_THREADS: usize = 8;

/// G = Λ·(1 − u) on the nodes of one azimuth row (the module's doc): from F(μ) at
/// μ_j = (1 − u_j)α(φ_o)/u_j, G_j = Λ_j(1 − u_j) = t_j F(μ_j)(1 − u_j) = u_j F(μ_j)/α(φ_o).
fn row(alpha: (f64, f64), scaled_azimuth: f64) -> Vec<f64> {
    let (sin, cos) = scaled_azimuth.sin_cos();
    // The azimuth φ_o whose scaled direction (α_x cos φ_o, α_y sin φ_o) has angle ϕ.
    let azimuth = (alpha.0 * sin).atan2(alpha.1 * cos);
    let (sin, cos) = azimuth.sin_cos();
    let scaled = (alpha.0 * cos).hypot(alpha.1 * sin);
    let density = |q: f64| marginal(alpha, (cos, sin), q);
    let u = |j: usize| j as f64 / (U_NODES - 1) as f64;
    let mu = |j: usize| (1.0 - u(j)) * scaled / u(j);
    let mut values = vec![0.0; ROW];
    // The tail beyond μ_1, with q = μ_1/τ (P2 falls at least like q⁻³ there, so the integrand
    // (q − μ_1)P2(q)·μ_1/τ² stays bounded as τ → 0).
    let (mut above, mut excess) = (0.0, 0.0);
    let top = mu(1);
    for (tau, weight) in kronrod_points(0.0, 1.0) {
        let q = top / tau;
        let mass = weight * density(q) * top / (tau * tau);
        above += mass;
        excess += mass * (q - top);
    }
    values[1] = u(1) * excess / scaled;
    // F(μ_j) = F(μ_{j−1}) + (μ_{j−1} − μ_j)·T0(μ_{j−1}) + ∫_{μ_j}^{μ_{j−1}} (q − μ_j)P2(q) dq,
    // T0(μ) = ∫_μ^∞ P2: every term positive.
    for (j, value) in values.iter_mut().enumerate().skip(2) {
        let (low, high) = (mu(j), mu(j - 1));
        let (mut mass, mut piece) = (0.0, 0.0);
        for (q, weight) in kronrod_points(low, high - low) {
            let m = weight * density(q);
            mass += m;
            piece += m * (q - low);
        }
        excess += (high - low) * above + piece;
        above += mass;
        *value = u(j) * excess / scaled;
    }
    values
}

/// P22 = D cos⁴θ at slopes (x, y): C exp(−½(e_x x² + e_y y²)·ln(1 + r²)/r² − 2 ln(1 + r²)).
fn slope_density((e_x, e_y, c): (f64, f64, f64), x: f64, y: f64) -> f64 {
    let (x2, y2) = (x * x, y * y);
    c * (log_phong((e_x, e_y), x2, y2) - 2.0 * (x2 + y2).ln_1p()).exp()
}

/// P2(q), the density of the slope along the azimuth (cos φ_o, sin φ_o): P22 integrated across
/// it, s from −∞ to ∞, with s = w·tan β (w the lobe's width across, times √(1 + q²)).
fn marginal(alpha: (f64, f64), (cos, sin): (f64, f64), q: f64) -> f64 {
    let lobe = exponents(alpha);
    let width = (1.0 + q * q).sqrt() * (alpha.0 * sin).hypot(alpha.1 * cos);
    let across = |beta: f64| {
        let (sin_beta, cos_beta) = beta.sin_cos();
        let s = width * sin_beta / cos_beta;
        let density = slope_density(lobe, q * cos - s * sin, q * sin + s * cos);
        density * width / (cos_beta * cos_beta)
    };
    let rule = |start: f64, length: f64| gauss_kronrod(start, length, across);
    let eighth = std::f64::consts::FRAC_PI_4;
    let pieces = (-2..2)
        .map(|k| rule(f64::from(k) * eighth, eighth))
        .collect();
    adaptive_gauss_kronrod(pieces, MARGINAL_TOLERANCE, 0.0, MARGINAL_MAX_PIECES, rule).0
}

/// G = Λ·(1 − u) of one roughness on its nodes (the module's doc): the table a render reads,
/// and which the Dr.Jit lobe reads too (`glint.Material`'s `smith_table`).
#[derive(Clone, Debug, PartialEq)]
pub struct SmithTable {
    alpha: (f64, f64),
    azimuth_nodes: usize,
    /// Row-major: one row of [`U_NODES`] values and one beyond u = 1 per azimuth node.
    values: Vec<f64>,
}

/// The tables built in this process, the most recent last.
static TABLES: Mutex<Vec<Arc<SmithTable>>> = Mutex::new(Vec::new());

/// Held while a table is built.
static BUILDING: Mutex<()> = Mutex::new(());

thread_local! {
    /// The table this thread used last.
    static LAST: RefCell<Option<Arc<SmithTable>>> = const { RefCell::new(None) };
}

/// (u, ϕ) of a direction: u = 1/(1 + a), and ϕ the azimuth of (α_x ω_x, α_y ω_y) folded into
/// [0, π/2] (the azimuth in scaled slopes, where the lobe is nearly round: Λ varies slowly
/// with it, and for Beckmann not at all).
fn coordinates((alpha_x, alpha_y): (f64, f64), w: DVec3) -> (f64, f64) {
    let a = w.z / (alpha_x * w.x).hypot(alpha_y * w.y);
    (
        1.0 / (1.0 + a),
        (alpha_y * w.y).abs().atan2((alpha_x * w.x).abs()),
    )
}

impl SmithTable {
    /// Λ(ω) from the table of roughness `alpha` (built on first use), for a unit ω above the
    /// horizon, off the normal: the thread's last table is read in place, without a lock or a
    /// reference count.
    pub(crate) fn lambda_of(alpha: (f64, f64), w: DVec3) -> f64 {
        let cached = LAST.with(|last| {
            last.borrow()
                .as_ref()
                .filter(|table| table.alpha == alpha)
                .map(|table| table.lambda(w))
        });
        cached.unwrap_or_else(|| Self::of(alpha).lambda(w))
    }

    /// [`SmithTable::lambda_times_cos`] from the table of roughness `alpha`, read as
    /// [`SmithTable::lambda_of`] reads it.
    pub(crate) fn lambda_times_cos_of(alpha: (f64, f64), w: DVec3) -> f64 {
        let cached = LAST.with(|last| {
            last.borrow()
                .as_ref()
                .filter(|table| table.alpha == alpha)
                .map(|table| table.lambda_times_cos(w))
        });
        cached.unwrap_or_else(|| Self::of(alpha).lambda_times_cos(w))
    }

    /// The table of roughness `alpha`, built on first use.
    pub(crate) fn of(alpha: (f64, f64)) -> Arc<Self> {
        let same = |table: &Arc<Self>| table.alpha == alpha;
        if let Some(table) = LAST.with(|last| last.borrow().as_ref().filter(|t| same(t)).cloned()) {
            return table;
        }
        let lock = || TABLES.lock().unwrap_or_else(|e| e.into_inner());
        let known = lock().iter().find(|t| same(t)).cloned();
        let table = known.unwrap_or_else(|| {
            // One table is built at a time (on every core, `SmithTable::new`), outside the
            // lock on the tables that lookups take: the render threads that need the table
            // being built wait for it instead of each building it again.
            let _building = BUILDING.lock().unwrap_or_else(|e| e.into_inner());
            if let Some(built) = lock().iter().find(|t| same(t)) {
                return Arc::clone(built);
            }
            let built = Arc::new(Self::new(alpha));
            let mut tables = lock();
            if tables.len() == REMEMBERED_TABLES {
                tables.remove(0);
            }
            tables.push(Arc::clone(&built));
            built
        });
        LAST.with(|last| *last.borrow_mut() = Some(Arc::clone(&table)));
        table
    }

    /// The table of roughness `alpha`, by quadrature at every node: the azimuth rows are
    /// independent, so they are built on up to [`BUILD_THREADS`] threads, each every
    /// threads-th row, and assembled in order (the same values as one thread's).
    fn new(alpha: (f64, f64)) -> Self {
        let azimuth_nodes = if alpha.0 == alpha.1 { 1 } else { AZIMUTH_NODES };
        let row_at = |r: usize| {
            let azimuth = if azimuth_nodes == 1 {
                0.0
            } else {
                std::f64::consts::FRAC_PI_2 * r as f64 / (azimuth_nodes - 1) as f64
            };
            row(alpha, azimuth)
        };
        let threads = std::thread::available_parallelism()
            .map_or(1, |n| n.get())
            .min(BUILD_THREADS)
            .min(azimuth_nodes);
        let rows_of = |first: usize| -> Vec<(usize, Vec<f64>)> {
            (first..azimuth_nodes)
                .step_by(threads)
                .map(|r| (r, row_at(r)))
                .collect()
        };
        let mut rows: Vec<(usize, Vec<f64>)> = std::thread::scope(|scope| {
            // A thread the system refuses leaves its rows to this one.
            let handles: Vec<_> = (1..threads)
                .map(|first| {
                    let spawned = std::thread::Builder::new()
                        .spawn_scoped(scope, move || rows_of(first))
                        .ok();
                    (first, spawned)
                })
                .collect();
            let mut rows = rows_of(0);
            for (first, handle) in handles {
                match handle.map(|handle| handle.join()) {
                    Some(Ok(part)) => rows.extend(part),
                    Some(Err(panic)) => std::panic::resume_unwind(panic),
                    None => rows.extend(rows_of(first)),
                }
            }
            rows
        });
        rows.sort_by_key(|&(r, _)| r);
        Self {
            alpha,
            azimuth_nodes,
            values: rows.into_iter().flat_map(|(_, values)| values).collect(),
        }
    }

    /// Λ(ω) for a unit ω above the horizon, off the normal.
    #[must_use]
    pub fn lambda(&self, w: DVec3) -> f64 {
        let (u, azimuth) = coordinates(self.alpha, w);
        if u >= 1.0 {
            return f64::INFINITY;
        }
        (self.g_at(u, azimuth) / (1.0 - u)).max(0.0)
    }

    /// Λ(ω)·ω_z for a unit ω above the horizon, off the normal, finite down to the horizon:
    /// with a = ω_z/p, p = √((α_x ω_x)² + (α_y ω_y)²), 1 − u = a/(1 + a), so
    /// Λ·ω_z = G/(1 − u)·a·p = G·(1 + a)·p, without forming 1 − u (which is 0 where a is
    /// below the rounding of 1 + a).
    #[must_use]
    pub fn lambda_times_cos(&self, w: DVec3) -> f64 {
        let (u, azimuth) = coordinates(self.alpha, w);
        let projected = (self.alpha.0 * w.x).hypot(self.alpha.1 * w.y);
        let a = w.z / projected;
        (self.g_at(u.min(1.0), azimuth) * (1.0 + a) * projected).max(0.0)
    }

    /// G = Λ·(1 − u) at (u, ϕ), u ≤ 1: Catmull–Rom along u on four rows, then along ϕ.
    fn g_at(&self, u: f64, azimuth: f64) -> f64 {
        let row = |r: isize| -> f64 {
            // Even in φ_o about 0 and about π/2.
            let last = self.azimuth_nodes as isize - 1;
            let r = if r < 0 {
                -r
            } else if r > last {
                2 * last - r
            } else {
                r
            };
            let start = r as usize * ROW;
            along_u(&self.values[start..start + ROW], u)
        };
        if self.azimuth_nodes == 1 {
            row(0)
        } else {
            let y = azimuth / std::f64::consts::FRAC_PI_2 * (self.azimuth_nodes - 1) as f64;
            let i = (y.floor() as isize).clamp(0, self.azimuth_nodes as isize - 2);
            let f = y - i as f64;
            catmull_rom([row(i - 1), row(i), row(i + 1), row(i + 2)], f)
        }
    }

    /// The roughness (α_x, α_y).
    #[must_use]
    pub fn alpha(&self) -> (f64, f64) {
        self.alpha
    }

    /// The number of nodes of u on [0, 1] ([`U_NODES`]); each row has one more, at
    /// u = 1 + 1/(U_NODES − 1).
    #[must_use]
    pub fn u_nodes(&self) -> usize {
        U_NODES
    }

    /// The number of azimuth nodes: 1 for an isotropic lobe, [`AZIMUTH_NODES`] otherwise.
    #[must_use]
    pub fn azimuth_nodes(&self) -> usize {
        self.azimuth_nodes
    }

    /// G = Λ·(1 − u) on the nodes: per azimuth node, [`U_NODES`] values on u = 0, 1/128, …, 1
    /// and one at u = 1 + 1/128.
    #[must_use]
    pub fn values(&self) -> &[f64] {
        &self.values
    }
}

/// Catmull–Rom along one row at u ∈ [0, 1): even beyond u = 0 (G is flat there), the row's
/// own node beyond u = 1.
fn along_u(row: &[f64], u: f64) -> f64 {
    let x = u * (U_NODES - 1) as f64;
    let i = (x.floor() as usize).min(U_NODES - 2);
    let f = x - i as f64;
    let below = if i == 0 { row[1] } else { row[i - 1] };
    catmull_rom([below, row[i], row[i + 1], row[i + 2]], f)
}

/// The Catmull–Rom cubic through p1 (f = 0) and p2 (f = 1).
fn catmull_rom([p0, p1, p2, p3]: [f64; 4], f: f64) -> f64 {
    p1 + 0.5
        * f
        * (p2 - p0 + f * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3 + f * (3.0 * (p1 - p2) + p3 - p0)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Λ by quadrature of its definition over the half plane facing ω (the parent module's
    /// derivation), for t = tan θ_o > 0 and the azimuth φ_o: the reference.
    fn lambda_by_quadrature(alpha: (f64, f64), tan: f64, azimuth: f64) -> f64 {
        lambda_to(alpha, tan, azimuth, 1e-10)
    }

    /// [`lambda_by_quadrature`] to the tolerance `tolerance`.
    fn lambda_to(alpha: (f64, f64), tan: f64, azimuth: f64, tolerance: f64) -> f64 {
        let (e_x, e_y, c) = exponents(alpha);
        // J ≤ (1 + 1/c²)^{−K}·√(1 + c²)/K ≤ (1 + 1/t²)^{−K_min}√(1 + t²) (the integral of
        // e^{−v}·√(1 + c²)e^{v/2K} is at most 2√(1 + c²) for K ≥ 1), so Λ ≤ πC·that: below
        // 1e-17, Λ is 0 to double precision in 1 + Λ.
        let k_min = 0.5 * e_x.min(e_y) + 1.0;
        let log_bound = -k_min * (1.0 / (tan * tan)).ln_1p() + 0.5 * (tan * tan).ln_1p();
        if std::f64::consts::PI * c * log_bound.exp() < 1e-17 {
            return 0.0;
        }
        let half_plane = |psi: f64| {
            let cos = psi.cos();
            if cos <= 0.0 {
                return 0.0;
            }
            let (sin_phi, cos_phi) = (azimuth + psi).sin_cos();
            let k_minus_one = 0.5 * (e_x * cos_phi * cos_phi + e_y * sin_phi * sin_phi) + 1.0;
            radial_excess(tan * cos, k_minus_one, tolerance)
        };
        let rule = |start: f64, length: f64| gauss_kronrod(start, length, half_plane);
        let quarter = std::f64::consts::FRAC_PI_2;
        // Very anisotropic lobes are thin wedges about the axes (φ = kπ/2): cut the half plane
        // there and at geometric steps 10⁻¹, …, 10⁻⁸ on either side, so that no wedge falls
        // between the rule's points.
        let mut cuts = vec![-quarter, quarter];
        for k in -2..=2 {
            let axis = f64::from(k) * quarter - azimuth;
            let axis = axis - std::f64::consts::PI * (axis / std::f64::consts::PI).round();
            for step in (1..=8).map(|p| 10f64.powi(-p)) {
                cuts.extend([axis - step, axis, axis + step]);
            }
        }
        cuts.retain(|c| c.abs() <= quarter);
        cuts.sort_by(f64::total_cmp);
        cuts.dedup();
        let pieces = cuts.windows(2).map(|w| rule(w[0], w[1] - w[0])).collect();
        // Λ = C·∫: an error below 1e-10·(1 + Λ).
        let (integral, _) = adaptive_gauss_kronrod(pieces, tolerance, tolerance / c, 256, rule);
        c * integral
    }

    /// The radial part of Λ on one azimuth, J = ∫_{1/c}^∞ (1 + r²)^{−(K+1)}(c r − 1) r dr for c > 0,
    /// K ≥ 1, as (1 + 1/c²)^{−K}/(2K)·∫_0^∞ e^{−v} g(v) dv with g = √(1 + b·expm1(v/K)) − 1,
    /// b = 1 + c² (the parent module's derivation). g grows like √b·e^{v/2K}, so with
    /// v = −M ln(1 − σ), M = 4K/(2K − 1), the integrand M(1 − σ)^{M−1} g is about
    /// M√b·(1 − σ) near σ = 1: bounded and smooth there. g turns from linear to a square root
    /// near v = K/b: the first pieces end there and then grow by 4 to σ = 1/4.
    fn radial_excess(c: f64, k_minus_one: f64, tolerance: f64) -> f64 {
        let c2 = c * c;
        let log_prefactor = -k_minus_one * (1.0 / c2).ln_1p();
        if log_prefactor < -745.0 {
            return 0.0;
        }
        let b = 1.0 + c2;
        let m = 4.0 * k_minus_one / (2.0 * k_minus_one - 1.0);
        let integrand = |sigma: f64| {
            let v = -m * (-sigma).ln_1p();
            let grown = b * (v / k_minus_one).exp_m1();
            m * (-v * (m - 1.0) / m).exp() * grown / ((1.0 + grown).sqrt() + 1.0)
        };
        let rule = |start: f64, length: f64| gauss_kronrod(start, length, integrand);
        let turn = (-(k_minus_one / b) / m).exp_m1().abs().clamp(1e-15, 0.25);
        let mut pieces = vec![rule(0.0, turn)];
        let mut start = turn;
        while start < 0.25 {
            let end = (4.0 * start).min(0.25);
            pieces.push(rule(start, end - start));
            start = end;
        }
        pieces.push(rule(0.25, 0.75));
        let (integral, _) = adaptive_gauss_kronrod(pieces, tolerance, 0.0, 256, rule);
        log_prefactor.exp() / (2.0 * k_minus_one) * integral
    }

    /// The table against the quadrature halfway between nodes (where interpolation errs
    /// most), over directions from the normal to grazing, and the time a table takes.
    #[test]
    fn the_table_is_the_quadrature() {
        // (α, the largest error allowed): 10⁴ to 1 is the roughest case, a wedge in slope space.
        for (alpha, allowed) in [
            ((0.1, 0.4), 1e-6),
            ((0.3, 0.3), 1e-6),
            ((1.0, 0.5), 5e-6),
            ((0.02, 0.02), 1e-6),
            ((1e-4, 1.0), 5e-3),
        ] {
            let start = std::time::Instant::now();
            let table = SmithTable::new(alpha);
            let built = start.elapsed();
            let mut worst: f64 = 0.0;
            for k in 0..400 {
                let x = (k as f64 + 0.5) / 400.0;
                let azimuth = std::f64::consts::FRAC_PI_2 * ((k * 7) % 400) as f64 / 400.0;
                let (sin, cos) = azimuth.sin_cos();
                let scaled = (alpha.0 * cos).hypot(alpha.1 * sin);
                let u = 0.02 + 0.975 * x;
                let tan = u / ((1.0 - u) * scaled);
                let w = DVec3::new(tan * cos, tan * sin, 1.0).normalize();
                let exact = lambda_by_quadrature(alpha, tan, azimuth);
                let got = table.lambda(w);
                worst = worst.max((got - exact).abs() / (1.0 + exact));
            }
            println!("α {alpha:?}: built in {built:?}, worst |ΔΛ|/(1 + Λ) {worst:.1e}");
            assert!(worst < allowed, "α {alpha:?}: {worst}");
        }
    }
}
