//! Checkers of counts under density maps (issue 31): test maps, ∫d over a square footprint
//! texel by texel from the values as given (independently of the map's own tables), and the
//! binomial sums of counts over footprints split by their mean density.

use std::f64::consts::PI;
use std::sync::Arc;

use glam::DVec2;
use glint_sphere::SphericalConic;
use glint_tree::{
    CountTree, CountTreeConfig, DenseCounts, DensityMap, Footprint, MapFilter, QueryScratch,
};

use crate::SplitMix64;
use crate::counts::{beckmann_density, conic_integral_by_sampling};
use crate::geometry::direction;

/// A test map: its name, width, height and values (row 0 at the top).
pub type TestMap = (&'static str, usize, usize, Vec<f64>);

/// An 8 × 8 checkerboard of 0.2 and 1, a 37 × 23 gradient in u (non-power-of-two texels that
/// no dyadic box edge matches), and a 16 × 16 disc of ones in zeros.
#[must_use]
pub fn test_maps() -> Vec<TestMap> {
    vec![
        ("checkerboard", 8, 8, checkerboard(8)),
        (
            "gradient",
            37,
            23,
            (0..37 * 23).map(|k| (k % 37) as f64 / 36.0).collect(),
        ),
        ("disc", 16, 16, disc(16)),
    ]
}

/// A count check's case: (name, width, height, values, N, γ in degrees).
pub type CountCase = (&'static str, usize, usize, Vec<f64>, u64, f64);

/// The count checks' cases: each test map with 2·10⁶ particles and a cone of 6°, and a sparse
/// 64 × 64 checkerboard with 10⁴ particles and 40° (its leaves span 4 × 4 texels and place
/// their particles by the map).
#[must_use]
pub fn count_cases() -> Vec<CountCase> {
    test_maps()
        .into_iter()
        .map(|(name, w, h, values)| (name, w, h, values, 2_000_000, 6.0))
        .chain([(
            "sparse checkerboard",
            64,
            64,
            checkerboard(64),
            10_000,
            40.0,
        )])
        .collect()
}

/// An n × n checkerboard of 0.2 and 1.
#[must_use]
pub fn checkerboard(n: usize) -> Vec<f64> {
    (0..n * n)
        .map(|k| {
            if (k % n + k / n).is_multiple_of(2) {
                0.2
            } else {
                1.0
            }
        })
        .collect()
}

/// An n × n map of ones inside a disc of radius 0.34 and zeros outside.
#[must_use]
pub fn disc(n: usize) -> Vec<f64> {
    (0..n * n)
        .map(|k| {
            let centre = 0.5 * (n as f64 - 1.0);
            let (x, y) = ((k % n) as f64 - centre, (k / n) as f64 - centre);
            if (x * x + y * y).sqrt() < 0.34 * n as f64 {
                1.0
            } else {
                0.0
            }
        })
        .collect()
}

/// The near-specular conic of the count checks, of radius `gamma_deg` degrees.
///
/// # Panics
/// Never for γ in (0, 180°).
#[must_use]
pub fn test_conic(gamma_deg: f64) -> SphericalConic {
    SphericalConic::new(
        direction(0.3, 0.2),
        direction(0.25, 0.2 + PI),
        gamma_deg.to_radians(),
    )
    .expect("a valid conic")
}

/// ∫d over an axis-aligned square footprint, wrapped across tiles, texel by texel from the
/// values as given (row 0 at the top).
#[must_use]
pub fn square_mass(values: &[f64], (w, h): (usize, usize), centre: DVec2, side: f64) -> f64 {
    let (x0, y0) = (centre.x - 0.5 * side, centre.y - 0.5 * side);
    let mut mass = 0.0;
    for tile_x in -1..=1 {
        for tile_y in -1..=1 {
            for j in 0..h {
                for i in 0..w {
                    let cx = [
                        (i as f64 / w as f64) + f64::from(tile_x),
                        ((i + 1) as f64 / w as f64) + f64::from(tile_x),
                    ];
                    let cy = [
                        (j as f64 / h as f64) + f64::from(tile_y),
                        ((j + 1) as f64 / h as f64) + f64::from(tile_y),
                    ];
                    let ox = (cx[1].min(x0 + side) - cx[0].max(x0)).max(0.0);
                    let oy = (cy[1].min(y0 + side) - cy[0].max(y0)).max(0.0);
                    mass += values[(h - 1 - j) * w + i] * ox * oy;
                }
            }
        }
    }
    mass
}

/// ∫d over an axis-aligned square footprint, wrapped across tiles, of the map reconstructed
/// from the values as given by `filter`: [`square_mass`], or for the bilinear map each texel's
/// value times the integrals of its tents (centred on the texel, one texel wide on each side,
/// in every neighbouring tile) over the square's sides, each tent integrated as its two linear
/// halves.
#[must_use]
pub fn filtered_square_mass(
    values: &[f64],
    (w, h): (usize, usize),
    filter: MapFilter,
    centre: DVec2,
    side: f64,
) -> f64 {
    if filter == MapFilter::Nearest {
        return square_mass(values, (w, h), centre, side);
    }
    // ∫ over [lo, hi] of the tent of half-width `half` centred at c.
    let tent = |c: f64, half: f64, lo: f64, hi: f64| {
        let linear = |a: f64, b: f64, value: &dyn Fn(f64) -> f64| {
            let (a, b) = (a.max(lo), b.min(hi));
            if b > a {
                (b - a) * 0.5 * (value(a) + value(b))
            } else {
                0.0
            }
        };
        linear(c - half, c, &|x| (x - c + half) / half)
            + linear(c, c + half, &|x| (c + half - x) / half)
    };
    let (x0, y0) = (centre.x - 0.5 * side, centre.y - 0.5 * side);
    let mut mass = 0.0;
    for tile_x in -2..=2 {
        for tile_y in -2..=2 {
            for j in 0..h {
                for i in 0..w {
                    let cx = (i as f64 + 0.5) / w as f64 + f64::from(tile_x);
                    let cy = (j as f64 + 0.5) / h as f64 + f64::from(tile_y);
                    let a = tent(cx, 1.0 / w as f64, x0, x0 + side);
                    let b = tent(cy, 1.0 / h as f64, y0, y0 + side);
                    mass += values[(h - 1 - j) * w + i] * a * b;
                }
            }
        }
    }
    mass
}

/// Sums of counts against their means over one half of the footprints.
#[derive(Clone, Copy, Debug, Default)]
pub struct CountSums {
    /// Σ counts.
    pub counts: f64,
    /// Σ N·∫_A d·∫p.
    pub means: f64,
    /// Σ (count − mean)².
    pub squares: f64,
    /// Σ mean·(1 − q), the binomial variances.
    pub variances: f64,
    /// The standard error of Σ counts: the binomial spread, each particle set's fluctuation
    /// over the footprints it shares, and the Monte Carlo error of ∫p.
    pub error: f64,
    /// Footprints where d = 0 everywhere (light half only).
    pub masked_footprints: usize,
    /// Particles those found: 0 when masks hold.
    pub masked_count: f64,
}

impl CountSums {
    /// (Σ counts − Σ means) / error.
    #[must_use]
    pub fn z(&self) -> f64 {
        (self.counts - self.means) / self.error
    }

    /// Σ (count − mean)² / Σ mean(1 − q): 1 for binomial counts.
    #[must_use]
    pub fn dispersion(&self) -> f64 {
        self.squares / self.variances
    }
}

/// Counts of square footprints of side 1.3 texels at random positions (straddling texel edges
/// and tiles) on `sets` particle sets (seeds) of `per_set` footprints each, under the map
/// `(w, h, values)` reconstructed by `filter`, with `particles` particles, ε = `epsilon` and a cone of `gamma_deg`
/// degrees: the sums over footprints of mean density ≥ ½ and < ½, [dense, light].
///
/// # Panics
/// If the map or the tree is invalid (a bug in the caller).
#[must_use]
pub fn mapped_count_sums(
    (w, h, values): (usize, usize, &[f64]),
    filter: MapFilter,
    particles: u64,
    gamma_deg: f64,
    epsilon: f64,
    (sets, per_set): (u64, usize),
) -> [CountSums; 2] {
    let conic = test_conic(gamma_deg);
    let density = beckmann_density(0.2, 0.2);
    let (integral, integral_error) =
        conic_integral_by_sampling(density.as_ref(), &conic, 400_000, &mut SplitMix64::new(4));
    let map = Arc::new(DensityMap::with_filter(w, h, values, filter).expect("a valid map"));
    let side = 1.3 / w.max(h) as f64;
    let mut rng = SplitMix64::new(17);
    let mut scratch = QueryScratch::new();
    let mut sums = [CountSums::default(); 2];
    for seed in 0..sets {
        let config = CountTreeConfig {
            particles,
            seed,
            epsilon,
            dense: DenseCounts::Exact,
            ..CountTreeConfig::default()
        };
        let tree = CountTree::with_density_map(config, density.clone(), Some(map.clone()))
            .expect("a valid tree");
        for _ in 0..per_set {
            let centre = DVec2::new(rng.uniform(), rng.uniform());
            let footprint = Footprint::new(centre, DVec2::new(side, 0.0), DVec2::new(0.0, side))
                .expect("a finite footprint");
            let count = tree.query(&footprint, &conic, &mut scratch).count;
            let mass = filtered_square_mass(values, (w, h), filter, centre, side);
            let q = mass * integral;
            let mean = particles as f64 * q;
            let sum = &mut sums[usize::from(mass < 0.5 * side * side)];
            if mass == 0.0 {
                sum.masked_footprints += 1;
                sum.masked_count += count;
            }
            sum.counts += count;
            sum.means += mean;
            sum.squares += (count - mean).powi(2);
            sum.variances += mean * (1.0 - q);
        }
    }
    for sum in &mut sums {
        let realization = sum.means * side * side * per_set as f64;
        sum.error = (sum.variances + realization).sqrt() + sum.means * integral_error / integral;
    }
    sums
}
