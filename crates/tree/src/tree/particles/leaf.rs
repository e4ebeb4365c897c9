//! A leaf's particles (Sec. 3.4): a node with at most [`LEAF_PARTICLES`] particles, or at the
//! depth guard, places them explicitly, each from its own stream: in a sub-box of the leaf's
//! box picked by four bits of the leaf's stream, uniformly within it (or, under a density map
//! that varies over the box, by the map's inverse distribution there), with area shares per
//! colour channel, and a normal by the descent of `super::descent`. A leaf is counted against
//! the query here, drawing only what the footprint needs: positions for the sub-boxes that may
//! meet it, normals and area shares for the particles inside it. Which draw defines what is
//! value-stable: see `super`.

use glam::{DVec2, DVec3};
use glint_sphere::{Classification, SphericalConic};

use super::descent::{LEAF_CELL_ARC, NormalDescent, members};
use super::{Node, PURPOSE_LEAF, PURPOSE_LEAF_SUB_BOXES};
use crate::density_map::DensityMap;
use crate::footprint::Footprint;
use crate::sampling::exponential;
use crate::tea::{TeaRng, draws_x4, unit_f64, unit_pair};
use crate::tree::CountTree;
use crate::tree::scratch::QueryMemo;

/// Nodes with at most this many particles place them explicitly (leaves): up to this size a
/// leaf's per-particle work (one 4-lane TEA call per four positions, a normal only for the
/// particles in the footprint) costs less than splitting on (a multinomial and four child
/// tests per level).
pub const LEAF_PARTICLES: u64 = 32;

/// The particles of a remembered leaf that queries meet again descend in full (their normals
/// remembered) for cones of radius γ up to this (radians, 4.58°): conics whose narrow
/// half-width, γ/2 for every conic (the ŷ axis of Eq. 9's standard form: tan²θ = s/k2 =
/// tan²(γ/2)), is at most four final cells (`LEAF_CELL_ARC`). A descent that stops early
/// goes down to cells about that width wherever the conic is near, however long the conic
/// is. Measured by the instructions glint adds to a render: stained_glass (γ = 1°, conics up
/// to eight final cells long at grazing angles) 4% fewer than deciding by the conic's length;
/// ornaments (γ = 5°) 14% more if all its conics descended in full.
const FULL_DESCENT_MAX_GAMMA: f64 = 8.0 * LEAF_CELL_ARC;

/// A leaf's box is divided into this many sub-boxes per side for placing its particles (16:
/// four bits per particle).
const LEAF_SUB_BOXES_PER_SIDE: usize = 4;

/// The column and row of a leaf's sub-box from its four-bit code.
#[inline]
fn sub_box_column_and_row(code: usize) -> (usize, usize) {
    (
        code % LEAF_SUB_BOXES_PER_SIDE,
        code / LEAF_SUB_BOXES_PER_SIDE,
    )
}

/// A leaf particle's stream is (the leaf's key, its purpose): draw 0 is its position in the
/// box, draw 1 the first uniform number of its normal's descent, draws 2… its area shares
/// (one per colour channel), and the draws after those its descent's further numbers.
const DRAW_DESCENT: u32 = 1;
/// The first area-share draw of a leaf particle's stream (see [`DRAW_DESCENT`]).
const DRAW_AREAS: u32 = 2;

/// A leaf particle in the footprint, between its position and its normal: its normal's
/// descent, how many footprint translates hold it, and its exponential area draws per channel.
#[derive(Clone, Debug)]
pub(in crate::tree) struct LeafParticle {
    pub(super) normal: NormalDescent,
    pub(super) multiplicity: u64,
    /// Its normal, once known: remembered with its leaf from an earlier query, or reached by
    /// this query's descent.
    pub(super) descended: Option<DVec3>,
}

/// The key and TEA rounds of a leaf's particles' streams.
pub(super) struct LeafStream {
    pub(super) key: [u32; 4],
    pub(super) rounds: u32,
}

/// The sub-box codes of up to [`Self::CAPACITY`] particles of a leaf (four bits each, in
/// order, as the leaf's stream draws them: sixteen per draw), the positions drawn so far, and
/// the normals descended so far: what queries have drawn of a leaf's particles.
#[derive(Clone, Copy, Debug)]
pub(in crate::tree) struct LeafDraws {
    codes: [u64; 2],
    /// Bit i is set when `positions[i]` holds particle i's position.
    drawn: u32,
    /// Bit i is set when `normals[i]` holds particle i's normal.
    descended: u32,
    /// Whether a query has met the leaf since these were first drawn: its particles' normals
    /// are then worth descending in full (see [`CountTree::count_leaf`]).
    pub(in crate::tree) met_again: bool,
    positions: [DVec2; LeafDraws::CAPACITY],
    normals: [DVec3; LeafDraws::CAPACITY],
}

impl LeafDraws {
    /// The particles a set of positions holds: [`LEAF_PARTICLES`], a whole leaf.
    pub(in crate::tree) const CAPACITY: usize = LEAF_PARTICLES as usize;

    /// The codes of the next `particles` (at most [`Self::CAPACITY`]) particles from the
    /// leaf's sub-box stream, no position drawn.
    #[cfg(test)]
    fn with_codes(sub_boxes: &mut TeaRng, particles: usize) -> Self {
        let mut draws = Self::EMPTY;
        draws.start_over(sub_boxes, particles);
        draws
    }

    /// Nothing drawn, for no leaf.
    pub(in crate::tree) const EMPTY: Self = Self {
        codes: [0; 2],
        drawn: 0,
        descended: 0,
        met_again: false,
        positions: [DVec2::ZERO; Self::CAPACITY],
        normals: [DVec3::ZERO; Self::CAPACITY],
    };

    /// Forgets what was drawn and takes the codes of the next `particles` (at most
    /// [`Self::CAPACITY`]) particles from a leaf's sub-box stream, in place: the positions and
    /// normals (1.3 KB) are neither cleared nor copied, `drawn` and `descended` say which
    /// hold values.
    pub(in crate::tree) fn start_over(&mut self, sub_boxes: &mut TeaRng, particles: usize) {
        debug_assert!(particles <= Self::CAPACITY);
        self.codes = [0; 2];
        for code in self.codes.iter_mut().take(particles.div_ceil(16)) {
            *code = sub_boxes.next_bits();
        }
        self.drawn = 0;
        self.descended = 0;
        self.met_again = false;
    }

    /// Forgets what was drawn and takes the given positions of a leaf's next particles (at
    /// most [`Self::CAPACITY`]), placed by a density map: all drawn, their sub-box codes (of
    /// the box at `box_min`, sub-boxes of side `sub_size`) read from them.
    fn start_over_placed(&mut self, positions: &[DVec2], box_min: DVec2, sub_size: f64) {
        debug_assert!(positions.len() <= Self::CAPACITY);
        self.codes = [0; 2];
        let last = LEAF_SUB_BOXES_PER_SIDE - 1;
        for (i, &position) in positions.iter().enumerate() {
            let cell = ((position - box_min) / sub_size).floor().max(DVec2::ZERO);
            let (column, row) = ((cell.x as usize).min(last), (cell.y as usize).min(last));
            let code = (column + LEAF_SUB_BOXES_PER_SIDE * row) as u64;
            self.codes[i / 16] |= code << (4 * (i % 16));
            self.positions[i] = position;
        }
        self.drawn = u32::try_from((1u64 << positions.len()) - 1).unwrap_or(u32::MAX);
        self.descended = 0;
        self.met_again = false;
    }

    /// Particle i's normal, if a query has descended it.
    pub(in crate::tree) fn normal(&self, i: usize) -> Option<DVec3> {
        (self.descended >> i & 1 == 1).then(|| self.normals[i])
    }

    /// Remembers particle i's `normal`.
    pub(in crate::tree) fn remember_normal(&mut self, i: usize, normal: DVec3) {
        self.normals[i] = normal;
        self.descended |= 1 << i;
    }

    /// Particle i's sub-box code.
    fn code(&self, i: usize) -> usize {
        (self.codes[i / 16] >> (4 * (i % 16)) & 15) as usize
    }

    /// The first `particles` particles whose sub-boxes are in a column of `columns` and a row of
    /// `rows` (bit c for column or row c), bit i for particle i.
    fn in_sub_boxes(&self, [columns, rows]: [u32; 2], particles: usize) -> u32 {
        // Sixteen codes per word, compared all at once: no branch or shift per particle.
        let mut found = 0u64;
        for (word, &codes) in self.codes.iter().enumerate() {
            let meeting =
                nibbles_with_field_in(codes, 0, columns) & nibbles_with_field_in(codes, 2, rows);
            found |= u64::from(compress_nibble_flags(meeting)) << (16 * word);
        }
        debug_assert!(particles <= LeafDraws::CAPACITY);
        (found & ((1u64 << particles) - 1)) as u32
    }
}

/// Bit 4k of a word of sixteen four-bit codes (`LeafDraws::codes`).
const NIBBLE_LOW_BITS: u64 = 0x1111_1111_1111_1111;

/// Bit 4k set (k < 16) where code k's two-bit field at `shift` (0: its column, 2: its row) is
/// one of the values in the four-bit set `values`.
fn nibbles_with_field_in(codes: u64, shift: u32, values: u32) -> u64 {
    let fields = codes >> shift;
    members(u64::from(values & 15)).fold(0, |hits, value| {
        // Field k of `differs` is zero exactly where field k equals `value`.
        let differs = fields ^ (value as u64 * NIBBLE_LOW_BITS);
        hits | !(differs | differs >> 1) & NIBBLE_LOW_BITS
    })
}

/// Bit k set where bit 4k of `flags` is (k < 16; the other bits of `flags` are clear).
fn compress_nibble_flags(flags: u64) -> u32 {
    let pairs = (flags | flags >> 3) & 0x0303_0303_0303_0303;
    let fours = (pairs | pairs >> 6) & 0x000F_000F_000F_000F;
    let eights = (fours | fours >> 12) & 0x0000_00FF_0000_00FF;
    ((eights | eights >> 24) & 0xFFFF) as u32
}

impl CountTree {
    /// The positions of a leaf's particles `first`, …, `first + particles − 1` (at most
    /// [`LeafDraws::CAPACITY`]) under a density map that varies over its box: draw 0 of each
    /// particle's stream, the two uniform numbers that place it uniformly without a map,
    /// through the inverse of the map's distribution over the box ([`DensityMap::place_each`]).
    fn positions_by_map(
        &self,
        map: &DensityMap,
        node: &Node,
        first: u64,
        particles: usize,
    ) -> [DVec2; LeafDraws::CAPACITY] {
        let key = node.id.key(self.config.seed);
        let mut uniforms = [[0.0; 2]; LeafDraws::CAPACITY];
        for start in (0..particles).step_by(4) {
            let purposes = std::array::from_fn(|k| {
                let i = (start + k).min(particles - 1);
                PURPOSE_LEAF + (first as usize + i) as u32
            });
            let draws = draws_x4(key, purposes, 0, self.config.tea_rounds);
            for (k, draw) in draws.into_iter().enumerate().take(particles - start) {
                uniforms[start + k] = unit_pair(draw);
            }
        }
        let mut positions = [DVec2::ZERO; LeafDraws::CAPACITY];
        map.place_each(
            node.box_min,
            node.box_size(),
            &uniforms[..particles],
            &mut positions[..particles],
        );
        positions
    }

    /// Counts a leaf's particles (positions one by one, normals by [`Self::normals_in_conic`]);
    /// returns (count, area sums). `directional` is the conic's classification of the leaf's
    /// cell; `channels` the colour channels whose particle areas are summed (the material's,
    /// or 0 for a dense node's virtual sample, whose areas are not drawn); `in_footprint` is
    /// reused working memory.
    #[allow(clippy::too_many_arguments)]
    pub(in crate::tree) fn count_leaf(
        &self,
        node: &Node,
        directional: Classification,
        footprint: &Footprint,
        conic: &SphericalConic,
        memo: &mut QueryMemo,
        in_footprint: &mut Vec<LeafParticle>,
        channels: usize,
    ) -> (f64, [f64; 3]) {
        let box_size = node.box_size();
        let key = node.id.key(self.config.seed);
        let rounds = self.config.tea_rounds;
        // Each particle's share of the node's area, per channel: Dirichlet(1, …, 1) as
        // normalized exponentials, drawn from the particle's own stream. Only the particles
        // found need their shares, but the normalization needs every particle's draws: both
        // are drawn once the first particle is found (most leaves a query reaches hold none).
        let shares_of = |purpose: u32| {
            let mut shares = [0.0; 3];
            let mut rng = TeaRng::starting_at(key, purpose, rounds, DRAW_AREAS);
            for share in shares.iter_mut().take(channels) {
                *share = exponential(&mut rng);
            }
            shares
        };
        let mut exponential_sums: Option<[f64; 3]> = None;
        let mut node_areas: Option<[f64; 3]> = None;
        // Particle k lies in one of the box's 4×4 sub-boxes, four random bits of the leaf's
        // own stream (sixteen particles per draw), and uniformly in it: its position is draw 0
        // of its stream (x from the high 32 bits, y from the low ones). That is uniform in the
        // box, and only the particles of sub-boxes whose translates may meet the footprint
        // need their positions (four per 4-lane TEA call). A particle's later draws (its
        // normal's, its areas': see `DRAW_DESCENT`) are drawn only if the footprint holds it.
        in_footprint.clear();
        let multiplicity_at = footprint.multiplicity_in_box(node.box_min, box_size);
        let sub_size = box_size / LEAF_SUB_BOXES_PER_SIDE as f64;
        let sub_box_min = |code: usize| {
            let (column, row) = sub_box_column_and_row(code);
            node.box_min + sub_size * DVec2::new(column as f64, row as f64)
        };
        let meeting = multiplicity_at
            .meeting_columns_and_rows::<LEAF_SUB_BOXES_PER_SIDE>(node.box_min, box_size);
        // A leaf of at most `LeafDraws::CAPACITY` particles keeps its sub-box codes, the
        // positions drawn so far and the normals reached in the memo: a pixel's samples, and
        // its neighbours', meet the same leaves. Larger leaves (only at the depth guard) draw
        // them afresh.
        let mut sub_boxes = self.stream(node.id, PURPOSE_LEAF_SUB_BOXES);
        let map = self
            .density_map
            .as_deref()
            .filter(|map| !map.is_constant_over(node.box_min, box_size));
        let mut unremembered;
        let remembered = node.count <= LeafDraws::CAPACITY as u64;
        let mut met_again = false;
        for first in (0..node.count).step_by(LeafDraws::CAPACITY) {
            let particles = (node.count - first).min(LeafDraws::CAPACITY as u64) as usize;
            // Under a density map that varies over the box, every position is drawn at once
            // (by the map) and the sub-box codes are read from them.
            let mut placed = |draws: &mut LeafDraws| match map {
                Some(map) => {
                    let positions = self.positions_by_map(map, node, first, particles);
                    draws.start_over_placed(&positions[..particles], node.box_min, sub_size);
                }
                None => draws.start_over(&mut sub_boxes, particles),
            };
            let leaf = if remembered {
                memo.leaf_draws(self, node, placed)
            } else {
                unremembered = LeafDraws::EMPTY;
                placed(&mut unremembered);
                &mut unremembered
            };
            met_again = leaf.met_again;
            // The particles whose sub-boxes may meet the footprint (bit i for particle
            // first + i), and those of them whose positions are still to be drawn.
            let candidates = leaf.in_sub_boxes(meeting, particles);
            let mut to_draw = candidates & !leaf.drawn;
            while to_draw != 0 {
                // Four positions per 4-lane TEA call.
                let mut four = [None; 4];
                for slot in &mut four {
                    if to_draw != 0 {
                        *slot = Some(to_draw.trailing_zeros() as usize);
                        to_draw &= to_draw - 1;
                    }
                }
                let purpose = |i: usize| PURPOSE_LEAF + (first as usize + i) as u32;
                let purposes = four.map(|i| i.map_or(0, purpose));
                let draws = draws_x4(key, purposes, 0, rounds);
                for (i, draw) in four.into_iter().zip(draws) {
                    if let Some(i) = i {
                        leaf.positions[i] =
                            sub_box_min(leaf.code(i)) + sub_size * DVec2::from(unit_pair(draw));
                        leaf.drawn |= 1 << i;
                    }
                }
            }
            for i in members(u64::from(candidates)) {
                let multiplicity = multiplicity_at.at(leaf.positions[i]);
                if multiplicity == 0 {
                    continue;
                }
                in_footprint.push(LeafParticle {
                    normal: NormalDescent::new(
                        PURPOSE_LEAF + (first as usize + i) as u32,
                        DRAW_AREAS + channels as u32,
                    ),
                    multiplicity,
                    descended: leaf.normal(i),
                });
            }
        }
        // The first uniform number of each descent still to take, four particles per 4-lane
        // TEA call.
        let mut descending = in_footprint.iter_mut().filter(|p| p.descended.is_none());
        loop {
            let four: [Option<&mut LeafParticle>; 4] = std::array::from_fn(|_| descending.next());
            if four[0].is_none() {
                break;
            }
            let purposes = four
                .each_ref()
                .map(|p| p.as_ref().map_or(0, |p| p.normal.purpose));
            let draws = draws_x4(key, purposes, DRAW_DESCENT, rounds);
            for (particle, draw) in four.into_iter().zip(draws) {
                if let Some(particle) = particle {
                    particle.normal.uniform = unit_f64(draw);
                }
            }
        }
        // The normals of the particles in the footprint, 64 at a time (a bit each): tested
        // against the conic where an earlier query's descent reached them, else descended
        // until the conic decides them. The normals a remembered leaf's descents reach are
        // remembered. A descent that stops early stops in a cell about the conic's width: when
        // the conic is a few final cells wide, it goes most of the way anyway, and the
        // particles of a leaf that queries meet again descend in full.
        let descend_in_full = remembered && met_again && conic.gamma() <= FULL_DESCENT_MAX_GAMMA;
        let stream = LeafStream { key, rounds };
        let mut found = 0.0;
        let mut areas = [0.0; 3];
        for group in in_footprint.chunks_mut(64) {
            let (inside, reached) = self.leaf_normals_in_conic(
                (&node.cell, directional),
                conic,
                memo,
                (&stream, group),
                descend_in_full,
            );
            if remembered
                && reached != 0
                && let Some(leaf) = memo.remembered_leaf(self, node)
            {
                for k in members(reached) {
                    let i = (group[k].normal.purpose - PURPOSE_LEAF) as usize;
                    leaf.remember_normal(i, group[k].descended.unwrap_or(DVec3::ZERO));
                }
            }
            for particle in members(inside).map(|k| &group[k]) {
                let multiplicity = particle.multiplicity as f64;
                found += multiplicity;
                if channels == 0 {
                    continue;
                }
                let sums = *exponential_sums.get_or_insert_with(|| {
                    let mut sums = [0.0; 3];
                    for k in 0..node.count {
                        let shares = shares_of(PURPOSE_LEAF + k as u32);
                        for (sum, share) in sums.iter_mut().zip(shares).take(channels) {
                            *sum += share;
                        }
                    }
                    sums
                });
                let shares = shares_of(particle.normal.purpose);
                let node_areas =
                    *node_areas.get_or_insert_with(|| self.with_areas(node, memo).areas);
                for c in 0..channels {
                    if sums[c] > 0.0 {
                        areas[c] += multiplicity * node_areas[c] * shares[c] / sums[c];
                    }
                }
            }
        }
        (found, areas)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The word-at-a-time sub-box test answers as testing each particle's column and row.
    #[test]
    fn particles_in_sub_boxes_are_those_in_a_meeting_column_and_row() {
        let mut rng = TeaRng::new([3, 1, 4, 1], 5, 8);
        for trial in 0..2000 {
            let particles = 1 + trial % LeafDraws::CAPACITY;
            let leaf = LeafDraws::with_codes(&mut rng, particles);
            let bits = rng.next_bits();
            // Every column and row set, and the "all" answer of many-tile footprints.
            let (columns, rows) = match trial % 7 {
                0 => (u32::MAX, u32::MAX),
                _ => ((bits & 15) as u32, (bits >> 4 & 15) as u32),
            };
            let expected = (0..particles).fold(0u32, |mask, i| {
                let (column, row) = sub_box_column_and_row(leaf.code(i));
                mask | (columns >> column & rows >> row & 1) << i
            });
            assert_eq!(
                leaf.in_sub_boxes([columns, rows], particles),
                expected,
                "trial {trial}: {particles} particles, columns {columns:b}, rows {rows:b}"
            );
        }
    }
}
