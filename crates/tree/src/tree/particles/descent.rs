//! A leaf particle's normal (Sec. 3.4).
//!
//! The directional law of the tree below a leaf, for one particle: descend the directional
//! hierarchy with the split probabilities of [`NdfQuadrature::split_probabilities`] (the law
//! of the multinomial splits, one particle at a time) until the cell has no entry (Alg. 2's table or its refinement) and
//! its longest edge is below [`LEAF_CELL_ARC`], then sample the flat triangle uniformly and
//! project (the projection's non-uniformity there is below 1e-4 relative).
//!
//! The descent is by inversion ([`NormalDescent`]), and the particles of a leaf descend
//! together ([`CountTree::normals_in_conic`]) with the draws each would take alone. The final
//! cells and the draws are value-stable: see `super`.
//!
//! [`NdfQuadrature::split_probabilities`]: crate::ndf::NdfQuadrature::split_probabilities

use glam::DVec3;
use glint_sphere::{Classification, SphericalConic, SphericalTriangle};

use super::leaf::{LeafParticle, LeafStream};
use crate::ndf::DirectionalCell;
use crate::tea::{draw_at, unit_f64};
use crate::tree::CountTree;
use crate::tree::scratch::QueryMemo;

/// Leaf particles' normals descend the directional hierarchy until the cell's longest edge is
/// below this arc (radians), then land uniformly in the cell: a particle's normal is within
/// this angle of every direction of the last cell it reached.
pub const LEAF_CELL_ARC: f64 = 0.01;

/// The chord of [`LEAF_CELL_ARC`], 2·sin(0.005).
pub(in crate::tree) const LEAF_CELL_CHORD: f64 = 0.009_999_958_333_385_416;

impl CountTree {
    /// The triangle of `cell` if it is a *final cell* of the directional law: its longest edge
    /// is below [`LEAF_CELL_ARC`] and Alg. 2 has no entry for it, so a leaf particle's normal
    /// that reaches it lands uniformly in it.
    pub(in crate::tree) fn final_cell<'a>(
        &self,
        cell: &'a DirectionalCell,
    ) -> Option<&'a SphericalTriangle> {
        cell.triangle.as_ref().filter(|triangle| {
            triangle.longest_chord() <= LEAF_CELL_CHORD && !self.quadrature.is_refined(cell)
        })
    }

    /// The splits of the material's table ([`DirectionalSplits`]) as one particle's descent
    /// walks them, index for index (see [`DescentStep`]).
    ///
    /// [`DirectionalSplits`]: crate::ndf::DirectionalSplits
    pub(in crate::tree) fn descent_steps(&self) -> Vec<DescentStep> {
        let splits = &self.directional_splits;
        (0..splits.len())
            .map(|index| {
                let split = splits.at(index);
                DescentStep {
                    probabilities: split.probabilities,
                    next: std::array::from_fn(|j| {
                        let child = &split.children[j];
                        match splits.index_of(child) {
                            Some(next) if self.final_cell(child).is_none() => next as u32,
                            _ => LEAVES_TABLE,
                        }
                    }),
                }
            })
            .collect()
    }

    /// Which of the leaf particles `members` (bits indexing `particles`, each descending the
    /// law above with its own stream, all now in `cell`, which the conic classifies as
    /// `classification`) have normals in the conic; the answer has their bits set.
    ///
    /// The particles descend together: a cell's split and its children's classifications are
    /// computed once for all the particles in it. Each particle still takes its own draws in
    /// its own order, so the answer is that of descending them one at a time. A descent stops
    /// as soon as its cell is inside the conic or disjoint from it: the classification is
    /// never wrong there, so the answer is that of the normals the full descent would reach.
    ///
    /// The descents that go down to their final cells leave their normals in the particles'
    /// `descended` and their bits in `reached`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn normals_in_conic(
        &self,
        cell: &DirectionalCell,
        classification: Classification,
        conic: &SphericalConic,
        memo: &mut QueryMemo,
        (stream, particles): (&LeafStream, &mut [LeafParticle]),
        members: u64,
        reached: &mut u64,
    ) -> u64 {
        match classification {
            Classification::Disjoint => return 0,
            Classification::TriangleInsideConic => return members,
            Classification::ConicInsideTriangle | Classification::Partial => {}
        }
        if members.is_power_of_two() {
            // Most groups are one particle a few levels below a leaf: no split of the group.
            let k = members.trailing_zeros() as usize;
            let (inside, reached_final) =
                self.normal_in_conic(cell, conic, memo, stream, &mut particles[k]);
            *reached |= u64::from(reached_final) << k;
            return u64::from(inside) << k;
        }
        if let Some(triangle) = self.final_cell(cell) {
            let mut inside = 0;
            for k in self::members(members) {
                let normal = particles[k].normal.point_in(triangle, stream);
                particles[k].descended = Some(normal);
                inside |= u64::from(conic.contains(normal)) << k;
            }
            *reached |= members;
            return inside;
        }
        self.with_split(cell, memo, |memo, children, probabilities| {
            let mut by_child = [0u64; 4];
            for k in self::members(members) {
                by_child[particles[k].normal.step(&probabilities, stream)] |= 1 << k;
            }
            let mut inside = 0;
            for (child, group) in children.iter().zip(by_child) {
                if group != 0 {
                    let classification = memo.classify(child, conic);
                    inside |= self.normals_in_conic(
                        child,
                        classification,
                        conic,
                        memo,
                        (stream, particles),
                        group,
                        reached,
                    );
                }
            }
            inside
        })
    }

    /// [`Self::normals_in_conic`] for one particle in `cell`, which the conic neither holds
    /// nor misses: whether its normal is in the conic, and whether its descent reached its
    /// normal (then left in its `descended`). The same steps and classifications, one level
    /// at a time: through the table by its [`DescentStep`]s while the cells have splits there.
    fn normal_in_conic(
        &self,
        cell: &DirectionalCell,
        conic: &SphericalConic,
        memo: &mut QueryMemo,
        stream: &LeafStream,
        particle: &mut LeafParticle,
    ) -> (bool, bool) {
        let mut cell = *cell;
        loop {
            if let Some(triangle) = self.final_cell(&cell) {
                let normal = particle.normal.point_in(triangle, stream);
                particle.descended = Some(normal);
                return (conic.contains(normal), true);
            }
            cell = match self.directional_splits.index_of(&cell) {
                // Through the table, one array look-up per level, until the descent leaves it.
                Some(mut index) => loop {
                    let step = &self.descent_steps[index];
                    let j = particle.normal.step(&step.probabilities, stream);
                    let child = &self.directional_splits.at(index).children[j];
                    if let Some(inside) = settled(memo.classify(child, conic)) {
                        return (inside, false);
                    }
                    match step.next[j] {
                        LEAVES_TABLE => break *child,
                        next => index = next as usize,
                    }
                },
                None => {
                    let (children, probabilities) = self.computed_split(&cell, memo);
                    let child = children[particle.normal.step(&probabilities, stream)];
                    if let Some(inside) = settled(memo.classify(&child, conic)) {
                        return (inside, false);
                    }
                    child
                }
            };
        }
    }

    /// [`Self::descend_normals`] for one particle in `cell`: its normal, left in its
    /// `descended`. Through the table by its [`DescentStep`]s while the cells have splits
    /// there, then one split at a time.
    fn descend_normal(
        &self,
        cell: &DirectionalCell,
        memo: &mut QueryMemo,
        stream: &LeafStream,
        particle: &mut LeafParticle,
    ) {
        let mut cell = *cell;
        loop {
            if let Some(triangle) = self.final_cell(&cell) {
                particle.descended = Some(particle.normal.point_in(triangle, stream));
                return;
            }
            cell = match self.directional_splits.index_of(&cell) {
                // Through the table, one array look-up per level, until the descent leaves it.
                Some(mut index) => loop {
                    let step = &self.descent_steps[index];
                    let j = particle.normal.step(&step.probabilities, stream);
                    match step.next[j] {
                        LEAVES_TABLE => break self.directional_splits.at(index).children[j],
                        next => index = next as usize,
                    }
                },
                None => {
                    let (children, probabilities) = self.computed_split(&cell, memo);
                    children[particle.normal.step(&probabilities, stream)]
                }
            };
        }
    }

    /// Which of the leaf particles `particles` (up to 64, each descending the law above with
    /// its own stream, all now in `cell`, which the conic classifies as `classification`) have
    /// normals in the conic, as [`Self::normals_in_conic`] answers, and which of them this call
    /// descended to their normals (left in their `descended`).
    /// A particle whose normal an earlier query reached ([`LeafParticle::descended`]) is
    /// tested directly. The others descend: all the way when `in_full`, so that every normal
    /// is reached, else until the conic decides them.
    pub(super) fn leaf_normals_in_conic(
        &self,
        (cell, classification): (&DirectionalCell, Classification),
        conic: &SphericalConic,
        memo: &mut QueryMemo,
        (stream, particles): (&LeafStream, &mut [LeafParticle]),
        in_full: bool,
    ) -> (u64, u64) {
        let everyone = u64::MAX >> (64 - particles.len());
        let mut reached = 0;
        let inside = match classification {
            Classification::Disjoint => 0,
            Classification::TriangleInsideConic => everyone,
            Classification::ConicInsideTriangle | Classification::Partial => {
                let mut to_descend = 0;
                let mut inside = 0;
                for (k, particle) in particles.iter().enumerate() {
                    match particle.descended {
                        Some(normal) => inside |= u64::from(conic.contains(normal)) << k,
                        None => to_descend |= 1 << k,
                    }
                }
                if to_descend == 0 {
                    inside
                } else if in_full {
                    self.descend_normals(cell, memo, (stream, particles), to_descend, &mut reached);
                    members(to_descend).fold(inside, |inside, k| {
                        let normal = particles[k].descended.unwrap_or(DVec3::ZERO);
                        inside | u64::from(conic.contains(normal)) << k
                    })
                } else {
                    inside
                        | self.normals_in_conic(
                            cell,
                            classification,
                            conic,
                            memo,
                            (stream, particles),
                            to_descend,
                            &mut reached,
                        )
                }
            }
        };
        (inside, reached)
    }

    /// The normals of the leaf particles `members` (bits indexing `particles`, each descending
    /// the law above with its own stream, all now in `cell`), left in their `descended` (their
    /// bits set in `reached`): each
    /// descent goes all the way to its final cell and the normal's point in it. The particles
    /// descend together as in [`Self::normals_in_conic`], with the same draws, so a normal is
    /// in a conic exactly when that descent answers that it is (it stops only in a cell the
    /// conic holds or misses, and is never wrong there).
    pub(super) fn descend_normals(
        &self,
        cell: &DirectionalCell,
        memo: &mut QueryMemo,
        (stream, particles): (&LeafStream, &mut [LeafParticle]),
        members: u64,
        reached: &mut u64,
    ) {
        if members.is_power_of_two() {
            let k = members.trailing_zeros() as usize;
            self.descend_normal(cell, memo, stream, &mut particles[k]);
            *reached |= members;
            return;
        }
        if let Some(triangle) = self.final_cell(cell) {
            for k in self::members(members) {
                particles[k].descended = Some(particles[k].normal.point_in(triangle, stream));
            }
            *reached |= members;
            return;
        }
        self.with_split(cell, memo, |memo, children, probabilities| {
            let mut by_child = [0u64; 4];
            for k in self::members(members) {
                by_child[particles[k].normal.step(&probabilities, stream)] |= 1 << k;
            }
            for (child, group) in children.iter().zip(by_child) {
                if group != 0 {
                    self.descend_normals(child, memo, (stream, particles), group, reached);
                }
            }
        });
    }

    /// Calls `f` with `cell`'s children and split probabilities: from the tree's table of
    /// splits, else computed (the probabilities remembered in `memo`).
    fn with_split<R>(
        &self,
        cell: &DirectionalCell,
        memo: &mut QueryMemo,
        f: impl FnOnce(&mut QueryMemo, &[DirectionalCell; 4], [f64; 4]) -> R,
    ) -> R {
        match self.directional_splits.get(cell) {
            Some(split) => f(memo, &split.children, split.probabilities),
            None => {
                let (children, probabilities) = self.computed_split(cell, memo);
                f(memo, &children, probabilities)
            }
        }
    }

    /// The children and split probabilities of `cell`, whose split is not in the tree's table:
    /// computed (the probabilities remembered in `memo`).
    #[inline]
    fn computed_split(
        &self,
        cell: &DirectionalCell,
        memo: &mut QueryMemo,
    ) -> ([DirectionalCell; 4], [f64; 4]) {
        let children = cell.children();
        let probabilities = memo.split_probabilities(self, cell, &children);
        (children, probabilities)
    }
}

/// A split of the material's table of directional splits as a single particle's descent walks
/// it: the split probabilities, and for each child the index of the child's own split in the
/// table, or [`LEAVES_TABLE`] when the child is a final cell or its split is not in the table.
/// A descent in the table thus takes one array look-up per level, instead of a hash look-up
/// of the cell's split and a final-cell test; where it leaves the table it goes on as before,
/// so it reaches the same cells with the same draws. The probabilities are copied from the
/// split so that the walk reads 48 bytes per level, not the split's 450.
#[derive(Clone, Copy, Debug)]
pub(in crate::tree) struct DescentStep {
    probabilities: [f64; 4],
    next: [u32; 4],
}

/// [`DescentStep::next`] for a child where the descent leaves the table.
const LEAVES_TABLE: u32 = u32::MAX;

/// A leaf particle's normal on its way down the directional hierarchy, by inversion: one
/// uniform number u picks the child whose interval [p₀ + … + p_{j−1}, p₀ + … + p_j) holds it,
/// and u rescaled to that interval, (u − p₀ − … − p_{j−1})/p_j, is again uniform and picks
/// the next level's child. The path then has the law of one categorical draw per level with
/// the split probabilities. Rescaling spends log₂(1/p_j) of u's 53 bits per level; once the
/// interval's width (the product of the p_j taken) is below 2⁻²¹, fewer than 32 bits would be
/// left (the resolution of the particle's position), and u is replaced by the stream's next
/// draw. Most descents thus take one draw until their final cell (a particle that reaches
/// one takes two more for its point in it), and a 4-lane TEA call computes the first draws of
/// four particles at once.
#[derive(Clone, Debug)]
pub(super) struct NormalDescent {
    /// The particle's stream: (leaf key, purpose).
    pub(super) purpose: u32,
    /// The stream's next unused draw.
    next_draw: u32,
    /// The current uniform number in [0, 1).
    pub(super) uniform: f64,
    /// The width of the interval of the number drawn that `uniform` now spans.
    width: f64,
}

/// Below this interval width a descent takes a fresh draw (see [`NormalDescent`]).
const DESCENT_MIN_WIDTH: f64 = 1.0 / (1u64 << 21) as f64;

/// The largest double below 1.
const ONE_BELOW: f64 = 1.0 - f64::EPSILON / 2.0;

impl NormalDescent {
    /// The descent of the particle with stream `purpose`, whose draws from `next_draw` on are
    /// unused; `uniform` is set by the caller (draw `leaf::DRAW_DESCENT`).
    pub(super) fn new(purpose: u32, next_draw: u32) -> Self {
        Self {
            purpose,
            next_draw,
            uniform: 0.0,
            width: 1.0,
        }
    }

    /// The stream's next draw as a uniform number in [0, 1).
    fn fresh_uniform(&mut self, stream: &LeafStream) -> f64 {
        let bits = draw_at(stream.key, self.purpose, self.next_draw, stream.rounds);
        self.next_draw += 1;
        unit_f64(bits)
    }

    /// The child (0–3) the descent takes under split `probabilities` (summing to 1 up to
    /// rounding; the last child takes any remainder), after which `self` is the descent in it.
    #[inline]
    fn step(&mut self, probabilities: &[f64; 4], stream: &LeafStream) -> usize {
        let [p0, p1, p2, p3] = *probabilities;
        let u = self.uniform;
        let (r1, r2) = (u - p0, u - p0 - p1);
        let r3 = r2 - p2;
        // The first j with u − p₀ − … − p_{j−1} < p_j, without branches (the child is random,
        // so a branch per comparison would be mispredicted often).
        let child =
            usize::from(u >= p0) * (1 + usize::from(r1 >= p1) * (1 + usize::from(r2 >= p2)));
        let (remainder, p) = [(u, p0), (r1, p1), (r2, p2), (r3, p3)][child];
        self.width *= p;
        self.uniform = if self.width < DESCENT_MIN_WIDTH {
            self.width = 1.0;
            self.fresh_uniform(stream)
        } else {
            (remainder / p).clamp(0.0, ONE_BELOW)
        };
        child
    }

    /// The particle's normal, uniform in the flat `triangle` of its final cell (projected):
    /// two fresh draws.
    fn point_in(&mut self, triangle: &SphericalTriangle, stream: &LeafStream) -> DVec3 {
        let root = self.fresh_uniform(stream).sqrt();
        let v = self.fresh_uniform(stream);
        triangle.direction_at([1.0 - root, root * (1.0 - v), root * v])
    }
}

/// Whether a descent's normal is in the conic, if the conic's `classification` of its cell
/// settles it (the cell inside the conic, or disjoint from it).
#[inline]
fn settled(classification: Classification) -> Option<bool> {
    match classification {
        Classification::Disjoint => Some(false),
        Classification::TriangleInsideConic => Some(true),
        Classification::ConicInsideTriangle | Classification::Partial => None,
    }
}

/// The indices of the set bits of `bits`, in increasing order.
pub(super) fn members(mut bits: u64) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (bits != 0).then(|| {
            let k = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            k
        })
    })
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::tea::TeaRng;
    use crate::tree::CountTreeConfig;
    use crate::tree::test_support::classify_cell;

    /// The descent of one leaf particle at a time: the reference for the grouped descent.
    fn normal_in_conic_alone(
        tree: &CountTree,
        cell: &DirectionalCell,
        classification: Classification,
        conic: &SphericalConic,
        stream: &LeafStream,
        normal: &mut NormalDescent,
    ) -> bool {
        let (mut cell, mut classification) = (*cell, classification);
        loop {
            match classification {
                Classification::Disjoint => return false,
                Classification::TriangleInsideConic => return true,
                Classification::ConicInsideTriangle | Classification::Partial => {}
            }
            if let Some(triangle) = tree.final_cell(&cell) {
                return conic.contains(normal.point_in(triangle, stream));
            }
            let split = tree.directional_split(&cell);
            cell = split.children[normal.step(&split.probabilities, stream)];
            classification = classify_cell(&cell, conic);
        }
    }

    /// A descent by inversion has the law of independent categorical draws per level: the
    /// children taken at consecutive levels are independent, each with the split's
    /// probabilities, across the fresh draws that replace a spent number (chi-square, 15
    /// degrees of freedom, α = 1e-6 per level pair).
    #[test]
    fn descents_by_inversion_take_independent_categorical_steps() {
        let p = [0.05, 0.15, 0.3, 0.5];
        let (particles, levels) = (40_000u32, 30);
        let stream = LeafStream {
            key: [5, 6, 7, 8],
            rounds: 8,
        };
        let mut pairs = vec![[[0u32; 4]; 4]; levels - 1];
        let mut fresh_draws = 0;
        for purpose in 0..particles {
            let mut descent = NormalDescent::new(purpose, 1);
            descent.uniform = descent.fresh_uniform(&stream);
            let mut previous = descent.step(&p, &stream);
            for pair in &mut pairs {
                let child = descent.step(&p, &stream);
                pair[previous][child] += 1;
                previous = child;
            }
            fresh_draws += descent.next_draw - 2;
        }
        // About one fresh draw per 13 levels (−Σ p ln p = 1.14 nats per level, 2⁻²¹ = e^−14.6).
        assert!(
            fresh_draws > particles,
            "{fresh_draws} fresh draws for {particles} descents"
        );
        for (level, pair) in pairs.iter().enumerate() {
            let mut chi_square = 0.0;
            for (a, row) in pair.iter().enumerate() {
                for (b, &observed) in row.iter().enumerate() {
                    let expected = f64::from(particles) * p[a] * p[b];
                    chi_square += (f64::from(observed) - expected).powi(2) / expected;
                }
            }
            assert!(
                chi_square < 57.4,
                "levels {level}, {}: χ² = {chi_square}",
                level + 1
            );
        }
    }

    #[test]
    fn grouped_leaf_descent_is_the_descent_one_particle_at_a_time() {
        let alpha: f64 = 0.02;
        let density = Arc::new(move |m: DVec3| {
            let cos2 = m.z * m.z;
            let tan2 = (1.0 - cos2) / cos2;
            (-tan2 / (alpha * alpha)).exp() / (std::f64::consts::PI * alpha * alpha * cos2 * m.z)
        });
        let tree = CountTree::new(CountTreeConfig::default(), density).expect("valid");
        let centroid = |cell: &DirectionalCell| cell.triangle.map_or(DVec3::Z, |t| t.centroid());
        let mut draws = TeaRng::new([1, 2, 3, 4], 0, 8);
        let (mut partial_answers, mut found, mut reached_final) = (0, 0, 0);
        // One memo for all trials, as one scratch serves many queries.
        let mut memo = QueryMemo::default();
        for trial in 0..300 {
            // A cell 0–9 levels deep, towards the normal for most trials (where the table is).
            let mut cell = DirectionalCell::HEMISPHERE;
            for _ in 0..trial % 10 {
                let children = cell.children();
                let toward_normal = children
                    .iter()
                    .max_by(|a, b| centroid(a).z.total_cmp(&centroid(b).z))
                    .copied()
                    .expect("four children");
                cell = if draws.uniform() < 0.7 {
                    toward_normal
                } else {
                    children[(draws.uniform() * 4.0) as usize % 4]
                };
            }
            // A conic of half-vectors around a point near the cell's centroid.
            let h = (centroid(&cell)
                + 0.01 * DVec3::new(draws.uniform() - 0.5, draws.uniform() - 0.5, 0.0))
            .normalize();
            let wi = DVec3::new(0.3, -0.2, 1.0).normalize();
            let wo = 2.0 * wi.dot(h) * h - wi;
            let gamma = 0.002 + 0.1 * draws.uniform();
            let Ok(conic) = SphericalConic::new(wi, wo, gamma) else {
                continue;
            };
            let classification = classify_cell(&cell, &conic);
            let count = 1 + (trial % 64);
            let stream = LeafStream {
                key: [trial, 7, 8, 9],
                rounds: 8,
            };
            let mut particles: Vec<LeafParticle> = (0..count)
                .map(|k| {
                    let mut normal = NormalDescent::new(k, 2 + k % 3);
                    normal.uniform = draws.uniform();
                    LeafParticle {
                        normal,
                        multiplicity: 1,
                        descended: None,
                    }
                })
                .collect();
            let mut alone: Vec<NormalDescent> =
                particles.iter().map(|p| p.normal.clone()).collect();
            let mut in_full = particles.clone();
            let everyone = u64::MAX >> (64 - count);
            memo.begin_query();
            let mut reached = 0;
            let grouped = tree.normals_in_conic(
                &cell,
                classification,
                &conic,
                &mut memo,
                (&stream, &mut particles),
                everyone,
                &mut reached,
            );
            // The full descents reach normals in the conic exactly where the descents that
            // stop early answer so, and the normals those reached.
            let mut full = 0;
            tree.descend_normals(
                &cell,
                &mut memo,
                (&stream, &mut in_full),
                everyone,
                &mut full,
            );
            assert_eq!(full, everyone);
            for k in 0..count as usize {
                let normal = in_full[k].descended.expect("descended in full");
                assert_eq!(
                    conic.contains(normal),
                    grouped >> k & 1 == 1,
                    "trial {trial} particle {k}: the full descent"
                );
                let early = particles[k].descended;
                assert_eq!(early.is_some(), reached >> k & 1 == 1, "trial {trial}");
                if let Some(early) = early {
                    assert_eq!(early, normal, "trial {trial} particle {k}");
                }
            }
            reached_final += reached.count_ones();
            for (k, normal) in alone.iter_mut().enumerate() {
                let expected =
                    normal_in_conic_alone(&tree, &cell, classification, &conic, &stream, normal);
                assert_eq!(
                    grouped >> k & 1 == 1,
                    expected,
                    "trial {trial} particle {k}"
                );
                // Each particle took the same draws as alone.
                let grouped = &particles[k].normal;
                assert_eq!(
                    (grouped.uniform, grouped.next_draw),
                    (normal.uniform, normal.next_draw),
                    "trial {trial}"
                );
            }
            partial_answers += u32::from(grouped != 0 && grouped != everyone);
            found += grouped.count_ones();
        }
        // The trials exercise descents that split their particles, and descents that go down
        // to their final cells.
        assert!(
            partial_answers > 30 && found > 300 && reached_final > 100,
            "{partial_answers} {found} {reached_final}"
        );
    }
}
