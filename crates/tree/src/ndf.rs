//! Memoized quadrature of the particle normal density over the directional hierarchy (Alg. 2).
//!
//! The probabilities of a directional split are the integrals of p(m) = D(m)(m·n) over the four
//! child triangles, renormalized to sum to one (Sec. 3.4). Before rendering, Alg. 2 integrates p
//! over the four octants, comparing a midpoint rule (Ω·p(centre)) with a corner rule
//! (Ω/3·Σ p(vertex)); where they disagree by more than δ_abs, and relatively by more than δ_rel,
//! it recurses into the four children and stores the sum in a table. At query time a triangle
//! with a table entry uses it; any other triangle is one where p is close to uniform, and the
//! one-point rule Ω·p(centre) serves. The same "no entry" condition gates the error criterion
//! (Eq. 10) of the traversal.
//!
//! **The refinement below the table (the law in the lobe's tail).** δ_abs = 10⁻⁵ is an absolute
//! error in probability: it accepts a whole octant's worth of tail where p falls by orders of
//! magnitude across one cell, and a split's one-point rule then gives that cell the mass of its
//! centre (Beckmann α = 0.1: 8% too much at θ = 15°, 24× too little at 21°). At N = 10¹² that
//! is millions of particles per unit area in the wrong places, and exact counts are no longer
//! Binomial(N, q) with q = A·∫p. So Alg. 2's acceptance also asks that the one-point rule's
//! error be small against the Poisson spread of the cell's own particles: for a locally
//! quadratic p on a flat triangle the exact integral is (3·midpoint + corner)/4, so the
//! midpoint rule misses it by |midpoint − corner|/4, and the cell is accepted only when
//! N′·|midpoint − corner|/4 ≤ [`LAW_BIAS`]·√(N′·I), I = max(midpoint, corner) and
//! N′ = min(N, [`LAW_PARTICLES`]): in a footprint of N′ particles the rule misplaces at most
//! [`LAW_BIAS`] = 0.02 standard deviations of the cell's number (a cone over K such cells sees
//! up to 0.02·√K of its own: `exact_counts_follow_p_in_the_lobe_tail` measures 0.8–4.1 at
//! N·A = 10⁹). Where that test refines a cell the paper's test accepted, the sums below it go
//! to a second map, the *refinement*: it sets the integrals of splits (and so the particle
//! set), while the table alone keeps Alg. 2's role of gating Eq. 10 and of the splits the tree
//! caches. Its size, by `NdfQuadrature::heap_bytes` with the table (Beckmann): α = 0.1, 1 640
//! entries at N = 10⁶, 25 272 from N′ = 2³⁰ up (0.6 MB, 11 ms to build); α = 1, 30 268
//! (1.1 MB); α = (10⁻³, 0.3), whose table already holds 13 380, 1.1·10⁶ (36 MB, 0.7 s).
//!
//! Directional cells are identified by the paper's labels restricted to directional splits:
//! the hemisphere is 1, octant j (0-based) is 3 + j, child j of cell i is 4i + j − 1.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};
use std::time::{Duration, Instant};

use glam::DVec3;
use glint_sphere::SphericalTriangle;

use crate::error::TreeError;

/// The particle normal density p(m) = D(m)(m·n) over the upper hemisphere, as a function of a
/// unit normal in the local frame. It integrates to 1 over the hemisphere. The tree evaluates it
/// only where m·n > 0 and takes p = 0 on the horizon (where m·n = 0).
pub type NormalDensity = dyn Fn(DVec3) -> f64 + Send + Sync;

/// A directional cell: the hemisphere (the root) or a spherical triangle of the hierarchy.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectionalCell {
    /// `None` for the whole upper hemisphere.
    pub triangle: Option<SphericalTriangle>,
    /// The directional label (see the module docs).
    pub label: u64,
    /// Directional splits from the hemisphere.
    pub depth: u32,
}

impl DirectionalCell {
    /// The upper hemisphere.
    pub const HEMISPHERE: Self = Self {
        triangle: None,
        label: 1,
        depth: 0,
    };

    /// Labels stay exact in 64 bits to this depth.
    pub const MAX_LABELLED_DEPTH: u32 = 30;

    /// The four children: the octants of the hemisphere, or the triangle's subdivision.
    #[must_use]
    pub fn children(&self) -> [Self; 4] {
        let triangles = match &self.triangle {
            None => SphericalTriangle::upper_hemisphere_octants(),
            Some(t) => t.subdivide(),
        };
        let label = |j: usize| {
            if self.depth < Self::MAX_LABELLED_DEPTH {
                4 * self.label + j as u64 - 1
            } else {
                // Beyond the memo's reach labels are never looked up; keep them saturated.
                u64::MAX
            }
        };
        [0, 1, 2, 3].map(|j| Self {
            triangle: Some(triangles[j]),
            label: label(j),
            depth: self.depth + 1,
        })
    }

    /// The solid angle: 2π for the hemisphere.
    #[must_use]
    pub fn solid_angle(&self) -> f64 {
        self.triangle
            .map_or(2.0 * std::f64::consts::PI, |t| t.solid_angle())
    }
}

/// The tolerances of Alg. 2 (defaults: δ_abs = δ_rel = 1e-5, the paper's).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuadratureTolerance {
    /// δ_abs: accept a triangle when |rule1 − rule2| < δ_abs.
    pub absolute: f64,
    /// δ_rel: accept a triangle when |rule1 − rule2| / rule2 < δ_rel.
    pub relative: f64,
    /// Deepest directional level that may receive a table entry.
    pub max_depth: u32,
}

impl Default for QuadratureTolerance {
    fn default() -> Self {
        Self {
            absolute: 1e-5,
            relative: 1e-5,
            max_depth: 18,
        }
    }
}

/// A hasher for the table's keys, which are already well-spread labels after one mix.
#[derive(Default)]
pub(crate) struct LabelHasher(u64);

impl Hasher for LabelHasher {
    fn finish(&self) -> u64 {
        crate::node::mix64(self.0)
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 << 8 | u64::from(b)).rotate_left(5);
        }
    }

    fn write_u64(&mut self, value: u64) {
        self.0 = value;
    }
}

/// How far the one-point rule may misplace the particles of a cell the quadrature accepts, in
/// standard deviations of their number in a footprint of [`LAW_PARTICLES`] (see the module
/// docs).
pub const LAW_BIAS: f64 = 0.02;

/// The most particles a footprint may hold for [`LAW_BIAS`] to bound the law's error in its
/// counts (2³⁰: a 10⁻³ footprint at N = 10¹²); a footprint of N·A = k·2³⁰ sees up to
/// √k·[`LAW_BIAS`] standard deviations. Materials of fewer particles are refined for N.
pub const LAW_PARTICLES: u64 = 1 << 30;

/// The memo table of Alg. 2 for one density, and its refinement for N particles.
#[derive(Clone, Debug)]
pub struct NdfQuadrature {
    table: HashMap<u64, f64, BuildHasherDefault<LabelHasher>>,
    /// The sums of the cells Alg. 2 accepts (or that lie below one it accepts) and the law's
    /// test refines, by label.
    refinement: HashMap<u64, f64, BuildHasherDefault<LabelHasher>>,
    /// min(N, [`LAW_PARTICLES`]), the particles whose spread the law's test measures errors
    /// against.
    particles: f64,
    tolerance: QuadratureTolerance,
    build_time: Duration,
    hemisphere_integral: f64,
}

impl NdfQuadrature {
    /// Runs Alg. 2 on the four octants of the upper hemisphere, refined for a material of
    /// `particles` particles in the unit square (see the module docs).
    ///
    /// # Errors
    /// [`TreeError::InvalidTolerance`] for negative or non-finite tolerances, or a maximum
    /// depth of 30 or more (labels are exact only above it);
    /// [`TreeError::InvalidDensity`] if the density is negative or not finite at a quadrature
    /// point, or integrates to zero.
    pub fn build(
        density: &NormalDensity,
        tolerance: QuadratureTolerance,
        particles: u64,
    ) -> Result<Self, TreeError> {
        let valid = |x: f64| x >= 0.0 && x.is_finite();
        // Table keys are labels, exact only to MAX_LABELLED_DEPTH.
        if !(valid(tolerance.absolute)
            && valid(tolerance.relative)
            && tolerance.max_depth < DirectionalCell::MAX_LABELLED_DEPTH)
        {
            return Err(TreeError::InvalidTolerance);
        }
        let started = Instant::now();
        let mut quadrature = Self {
            table: HashMap::default(),
            refinement: HashMap::default(),
            particles: particles.min(LAW_PARTICLES) as f64,
            tolerance,
            build_time: Duration::ZERO,
            hemisphere_integral: 0.0,
        };
        let mut total = 0.0;
        for octant in DirectionalCell::HEMISPHERE.children() {
            total += quadrature.integrate(&octant, density, false)?;
        }
        if !(total > 0.0 && total.is_finite()) {
            return Err(TreeError::InvalidDensity);
        }
        quadrature.hemisphere_integral = total;
        quadrature.build_time = started.elapsed();
        Ok(quadrature)
    }

    /// Alg. 2 for one cell: the corner rule where it agrees with the midpoint rule, else the
    /// sum over the children, memoized in the table, or in the refinement where the paper's
    /// test accepts the cell (or one above it, `refining`) and the law's does not.
    fn integrate(
        &mut self,
        cell: &DirectionalCell,
        density: &NormalDensity,
        refining: bool,
    ) -> Result<f64, TreeError> {
        let triangle = cell.triangle.expect("Alg. 2 runs below the hemisphere");
        let area = triangle.solid_angle();
        let evaluate = |m: DVec3| {
            let value = if m.z > 0.0 { density(m) } else { 0.0 };
            if value >= 0.0 && value.is_finite() {
                Ok(value)
            } else {
                Err(TreeError::InvalidDensity)
            }
        };
        let [a, b, c] = triangle.vertices();
        let midpoint_rule = area * evaluate(triangle.centroid())?;
        let corner_rule = area / 3.0 * (evaluate(a)? + evaluate(b)? + evaluate(c)?);
        let difference = (midpoint_rule - corner_rule).abs();
        let deepest = cell.depth >= self.tolerance.max_depth;
        let paper_accepts = refining
            || difference < self.tolerance.absolute
            || difference < self.tolerance.relative * corner_rule;
        // N·|midpoint − corner|/4 ≤ LAW_BIAS·√(N·I), squared.
        let misplaced = self.particles * difference / 4.0;
        let law_accepts = misplaced * misplaced
            <= LAW_BIAS * LAW_BIAS * self.particles * midpoint_rule.max(corner_rule);
        if deepest || (paper_accepts && law_accepts) {
            return Ok(corner_rule);
        }
        let mut sum = 0.0;
        for child in cell.children() {
            sum += self.integrate(&child, density, paper_accepts)?;
        }
        if paper_accepts {
            self.refinement.insert(cell.label, sum);
        } else {
            self.table.insert(cell.label, sum);
        }
        Ok(sum)
    }

    /// Whether `cell` has a table entry: p is not close to uniform on it, so the traversal may
    /// not stop early there (Eq. 10) and its integral comes from the table.
    #[inline]
    #[must_use]
    pub fn has_entry(&self, cell: &DirectionalCell) -> bool {
        cell.triangle.is_none()
            || (cell.depth <= self.tolerance.max_depth && self.table.contains_key(&cell.label))
    }

    /// Whether `cell`'s integral is the sum of its children's (a table or refinement entry):
    /// a particle's normal that reaches it descends further.
    #[inline]
    #[must_use]
    pub fn is_refined(&self, cell: &DirectionalCell) -> bool {
        self.has_entry(cell)
            || (cell.depth <= self.tolerance.max_depth
                && !self.refinement.is_empty()
                && self.refinement.contains_key(&cell.label))
    }

    /// ∫ p over `cell`: the table or refinement entry if there is one, else the one-point rule
    /// Ω·p(centre) (the solid angle is computed only then).
    #[inline]
    #[must_use]
    pub fn integral(&self, cell: &DirectionalCell, density: &NormalDensity) -> f64 {
        match &cell.triangle {
            None => self.hemisphere_integral,
            Some(triangle) => self
                .table_entry(cell)
                .unwrap_or_else(|| one_point_rule(triangle, triangle.solid_angle(), density)),
        }
    }

    /// [`NdfQuadrature::integral`] for a cell whose solid angle the caller already has.
    #[inline]
    #[must_use]
    pub fn integral_with_solid_angle(
        &self,
        cell: &DirectionalCell,
        solid_angle: f64,
        density: &NormalDensity,
    ) -> f64 {
        match &cell.triangle {
            None => self.hemisphere_integral,
            Some(triangle) => self
                .table_entry(cell)
                .unwrap_or_else(|| one_point_rule(triangle, solid_angle, density)),
        }
    }

    fn table_entry(&self, cell: &DirectionalCell) -> Option<f64> {
        if cell.depth > self.tolerance.max_depth {
            return None;
        }
        let entry = self.table.get(&cell.label).copied();
        if entry.is_some() || self.refinement.is_empty() {
            return entry;
        }
        self.refinement.get(&cell.label).copied()
    }

    /// The probabilities of a directional split into `children` (with solid angles
    /// `solid_angles`): their integrals, renormalized to sum to 1 (Sec. 3.4). Where p vanishes
    /// on all four, the split follows solid angle, so that particles still land somewhere.
    #[must_use]
    pub fn split_probabilities(
        &self,
        children: &[DirectionalCell; 4],
        solid_angles: &[f64; 4],
        density: &NormalDensity,
    ) -> [f64; 4] {
        let integrals: [f64; 4] = std::array::from_fn(|j| {
            self.integral_with_solid_angle(&children[j], solid_angles[j], density)
        });
        normalized_split(integrals, solid_angles)
    }

    /// The number of table entries (the paper reports 500–1000 for its scenes).
    #[must_use]
    pub fn len(&self) -> usize {
        self.table.len()
    }

    /// The number of refinement entries (see the module docs).
    #[must_use]
    pub fn refinement_len(&self) -> usize {
        self.refinement.len()
    }

    /// The bytes the table and the refinement hold: 8 for a key, 8 for a value and one control
    /// byte per bucket of their hash maps, whose buckets are at least 8/7 of their capacity.
    #[must_use]
    pub fn heap_bytes(&self) -> usize {
        (self.table.capacity() + self.refinement.capacity()) * 17 * 8 / 7
    }

    /// Whether the table is empty (p close to uniform on every octant).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.table.is_empty()
    }

    /// The time `build` took.
    #[must_use]
    pub fn build_time(&self) -> Duration {
        self.build_time
    }

    /// ∫ p over the hemisphere by this quadrature (1 for a normalized density, up to δ).
    #[must_use]
    pub fn hemisphere_integral(&self) -> f64 {
        self.hemisphere_integral
    }

    /// The tolerances the table was built with.
    #[must_use]
    pub fn tolerance(&self) -> QuadratureTolerance {
        self.tolerance
    }
}
/// One directional split: the four child cells, their solid angles and the split
/// probabilities ([`NdfQuadrature::split_probabilities`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct DirectionalSplit {
    pub(crate) children: [DirectionalCell; 4],
    pub(crate) solid_angles: [f64; 4],
    pub(crate) probabilities: [f64; 4],
}

impl DirectionalSplit {
    pub(crate) fn of(
        cell: &DirectionalCell,
        quadrature: &NdfQuadrature,
        density: &NormalDensity,
    ) -> Self {
        let children = cell.children();
        let triangles = children.map(|c| c.triangle.expect("every child is a triangle"));
        let solid_angles = SphericalTriangle::solid_angles_of(&triangles);
        let probabilities = quadrature.split_probabilities(&children, &solid_angles, density);
        Self {
            children,
            solid_angles,
            probabilities,
        }
    }
}

/// The directional splits that recur in most queries, computed once per material: those of
/// every cell above a depth (every spatial box shares the same directional hierarchy, and the
/// coarse cells' solid angles take `atan2`), and below it those of the cells with a table
/// entry (where a peaked p sends the queries and the leaf particles' normals, and a split
/// costs four table look-ups). The coarse ones are indexed by depth, then by label within the
/// depth (labels of depth d are the consecutive (2·4ᵈ + 1)/3, …).
#[derive(Clone, Debug, Default)]
pub(crate) struct DirectionalSplits {
    levels: u32,
    /// The coarse splits (by depth, then label), then those of the deeper cells with a table
    /// entry.
    splits: Vec<DirectionalSplit>,
    /// The coarse splits' number: those of every cell of depths 0 to `levels` − 1.
    coarse: usize,
    /// The index in `splits` of each deeper cell's split, by the cell's label.
    non_uniform: HashMap<u64, u32, BuildHasherDefault<LabelHasher>>,
}

impl DirectionalSplits {
    /// The splits of the cells of depths 0 to `levels` − 1 and of the deeper cells with a
    /// table entry (about 450 bytes each).
    pub(crate) fn build(quadrature: &NdfQuadrature, density: &NormalDensity, levels: u32) -> Self {
        // The coarse splits, and at most one per table entry below them, allocated once.
        let coarse = ((1usize << (2 * levels)) - 1) / 3;
        let mut splits = Vec::with_capacity(coarse + quadrature.len());
        let mut level = vec![DirectionalCell::HEMISPHERE];
        for _ in 0..levels {
            let mut next = Vec::with_capacity(4 * level.len());
            for cell in &level {
                let split = DirectionalSplit::of(cell, quadrature, density);
                next.extend_from_slice(&split.children);
                splits.push(split);
            }
            level = next;
        }
        debug_assert_eq!(coarse, splits.len());
        // A cell has a table entry only if its parent has one (Alg. 2 recurses from there).
        let mut non_uniform = HashMap::default();
        let mut pending = level;
        while let Some(cell) = pending.pop() {
            if cell.depth >= DirectionalCell::MAX_LABELLED_DEPTH || !quadrature.has_entry(&cell) {
                continue;
            }
            let split = DirectionalSplit::of(&cell, quadrature, density);
            pending.extend_from_slice(&split.children);
            let index = u32::try_from(splits.len()).expect("fewer than 2³² table entries");
            non_uniform.insert(cell.label, index);
            splits.push(split);
        }
        Self {
            levels,
            splits,
            coarse,
            non_uniform,
        }
    }

    /// The index of the split of `cell` ([`Self::at`]), if it is in the table.
    #[inline]
    pub(crate) fn index_of(&self, cell: &DirectionalCell) -> Option<usize> {
        if cell.depth >= self.levels {
            if cell.depth >= DirectionalCell::MAX_LABELLED_DEPTH || self.non_uniform.is_empty() {
                return None;
            }
            return self.non_uniform.get(&cell.label).map(|&i| i as usize);
        }
        let power = 1u64 << (2 * cell.depth);
        let first_label = (2 * power + 1) / 3;
        let before = (power - 1) / 3;
        let index = (before + cell.label - first_label) as usize;
        (index < self.coarse).then_some(index)
    }

    /// The split of `cell`, if it is in the table.
    #[inline]
    pub(crate) fn get(&self, cell: &DirectionalCell) -> Option<&DirectionalSplit> {
        self.index_of(cell).map(|i| &self.splits[i])
    }

    /// The split at `index` (below [`Self::len`]).
    #[inline]
    pub(crate) fn at(&self, index: usize) -> &DirectionalSplit {
        &self.splits[index]
    }

    /// The number of splits held.
    pub(crate) fn len(&self) -> usize {
        self.splits.len()
    }
}

/// A split's probabilities from its children's integrals: renormalized to sum to 1, or by
/// solid angle where p vanishes on all four ([`NdfQuadrature::split_probabilities`]).
#[inline]
pub(crate) fn normalized_split(integrals: [f64; 4], solid_angles: &[f64; 4]) -> [f64; 4] {
    let total: f64 = integrals.iter().sum();
    if total > 0.0 && total.is_finite() {
        integrals.map(|i| i / total)
    } else {
        let sum: f64 = solid_angles.iter().sum();
        solid_angles.map(|o| o / sum)
    }
}

/// Ω·p(centre), the one-point rule (p = 0 below the horizon).
#[inline]
fn one_point_rule(triangle: &SphericalTriangle, solid_angle: f64, density: &NormalDensity) -> f64 {
    one_point_rule_at(triangle.centroid(), solid_angle, density)
}

/// [`one_point_rule`] for a triangle whose centroid ([`SphericalTriangle::centroid`]) the
/// caller already has.
#[inline]
pub(crate) fn one_point_rule_at(centre: DVec3, solid_angle: f64, density: &NormalDensity) -> f64 {
    if centre.z > 0.0 {
        solid_angle * density(centre)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn beckmann(alpha: f64) -> impl Fn(DVec3) -> f64 {
        move |m: DVec3| {
            let cos2 = m.z * m.z;
            let tan2 = (1.0 - cos2) / cos2;
            (-tan2 / (alpha * alpha)).exp() / (std::f64::consts::PI * alpha * alpha * cos2)
        }
    }

    #[test]
    fn cached_splits_are_the_splits_of_the_cells_asked_for() {
        let density = beckmann(0.02);
        let quadrature = NdfQuadrature::build(&density, QuadratureTolerance::default(), 1_000_000)
            .expect("valid");
        let splits = DirectionalSplits::build(&quadrature, &density, 4);
        // Every cell above depth 4, and every deeper cell with an entry (and its children).
        let mut level = vec![DirectionalCell::HEMISPHERE];
        let mut deep_entries = 0;
        for depth in 0.. {
            if level.is_empty() {
                break;
            }
            for cell in &level {
                let cached = splits.get(cell);
                if depth < 4 || quadrature.has_entry(cell) {
                    let cached = cached.expect("cached");
                    let computed = DirectionalSplit::of(cell, &quadrature, &density);
                    assert_eq!(cached.children, computed.children, "depth {depth}");
                    assert_eq!(cached.probabilities, computed.probabilities);
                    deep_entries += usize::from(depth >= 4);
                } else {
                    assert!(cached.is_none(), "depth {depth}: a cell without an entry");
                }
            }
            level = level.iter().flat_map(DirectionalCell::children).collect();
            level.retain(|c| c.depth < 5 || quadrature.has_entry(c));
        }
        assert!(deep_entries > 10, "{deep_entries} deep cells with entries");
        assert_eq!(splits.len(), (4usize.pow(4) - 1) / 3 + deep_entries);
    }

    #[test]
    fn labels_past_their_exact_depth_are_refused() {
        let density = beckmann(0.1);
        let tolerance = QuadratureTolerance {
            max_depth: DirectionalCell::MAX_LABELLED_DEPTH,
            ..QuadratureTolerance::default()
        };
        assert!(matches!(
            NdfQuadrature::build(&density, tolerance, 1_000_000),
            Err(TreeError::InvalidTolerance)
        ));
    }
}
