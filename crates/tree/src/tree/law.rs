//! The law the particle set follows, and the expectations it gives: [`CountTree::expected_count`],
//! N·A·∫p over the conic (N·∫_A d·∫p under a density map) by the tree's own quadrature (Alg. 2's table, the one-point rule
//! elsewhere), which is what a count converges to and the scale of Eq. 10 in long queries; and
//! [`CountTree::directional_law_excess`], how far the directional law of leaf particles (the
//! split probabilities down to the final cells) exceeds a bound on p, which Alg. 2's δ_abs
//! allows in the far tails. These read the material's tables; they draw no random numbers.

use glam::DVec3;
use glint_sphere::{
    Classification, OverlapMethod, SphericalConic, SphericalTriangle,
    overlap_share_with_linear_density, overlap_solid_angle,
};

use super::scratch::QueryMemo;
use super::{CountTree, QueryScratch};
use crate::footprint::Footprint;
use crate::ndf::DirectionalCell;

/// How far the tree's directional law exceeds a bound on the density p it approximates
/// ([`CountTree::directional_law_excess`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectionalLawExcess {
    /// W = max over final cells L of P(L) / (σ(L)·B_L), B_L the given bound on p over L
    /// (over cells with B_L > 0): the tree's normal density is at most W·B_L on L.
    pub ratio: f64,
    /// Σ P(L) over the final cells whose bound B_L is 0 (p underflows there while the split
    /// law, falling back to solid angles, still gives them mass).
    pub unbounded_mass: f64,
    /// The final cells enumerated.
    pub cells: usize,
}

impl CountTree {
    /// The tree's directional law against the density it approximates. A particle's normal
    /// descends the directional hierarchy with the split probabilities (table integrals, the
    /// one-point rule elsewhere) to a *final cell* L (edges ≤ [`LEAF_CELL_ARC`], no Alg. 2
    /// entry) and lands uniformly in it, so its density on L is P(L)/σ(L), P(L) the product of
    /// the split probabilities along the path. Where Alg. 2 accepted a cell by δ_abs (the far
    /// tails) that density can exceed p by large factors. This enumerates every final cell
    /// with positive probability (hundreds of thousands for a wide p) and compares P(L)/σ(L)
    /// with `density_bound(cos θ_near, cos θ_far)`, an upper bound on p over the directions
    /// whose angle from n lies between those of L's circumscribed cap.
    ///
    /// [`LEAF_CELL_ARC`]: crate::LEAF_CELL_ARC
    #[must_use]
    pub fn directional_law_excess(
        &self,
        density_bound: &dyn Fn(f64, f64) -> f64,
    ) -> DirectionalLawExcess {
        let mut excess = DirectionalLawExcess {
            ratio: 0.0,
            unbounded_mass: 0.0,
            cells: 0,
        };
        let mut stack = vec![(DirectionalCell::HEMISPHERE, 1.0_f64)];
        while let Some((cell, probability)) = stack.pop() {
            if !(probability > 0.0) {
                continue;
            }
            if let Some(triangle) = self.final_cell(&cell) {
                // L lies within its circumscribed cap: centre c (the centroid's direction),
                // radius r (the farthest vertex), so θ over L is within [θ_c − r, θ_c + r].
                // Their cosines without an angle: cos(θ_c ∓ r) = cos θ_c cos r ± sin θ_c sin r,
                // and θ_c − r < 0 exactly when cos r < cos θ_c (both angles in [0, π]).
                let centre = triangle.centroid().normalize();
                let cos_radius = triangle
                    .vertices()
                    .iter()
                    .map(|v| centre.dot(*v).clamp(-1.0, 1.0))
                    .fold(1.0, f64::min);
                let sin_radius = (1.0 - cos_radius * cos_radius).max(0.0).sqrt();
                let cos_theta = centre.z.clamp(-1.0, 1.0);
                let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
                let cos_near = if cos_radius < cos_theta {
                    1.0
                } else {
                    (cos_theta * cos_radius + sin_theta * sin_radius).min(1.0)
                };
                let cos_far = (cos_theta * cos_radius - sin_theta * sin_radius).max(-1.0);
                let bound = density_bound(cos_near, cos_far);
                if bound > 0.0 {
                    let ratio = probability / (triangle.solid_angle() * bound);
                    excess.ratio = excess.ratio.max(ratio);
                } else {
                    excess.unbounded_mass += probability;
                }
                excess.cells += 1;
                continue;
            }
            let split = self.directional_split(&cell);
            for (child, p) in split.children.iter().zip(split.probabilities) {
                stack.push((*child, probability * p));
            }
        }
        excess
    }

    /// N·area(A)·∫_{Ω_h} p(m) dm: the expected count of a query, with ∫p over the conic by the
    /// tree's own quadrature (table entries, one-point rule and overlap fractions elsewhere).
    /// Under a density map, area(A) is ∫_A d ([`crate::DensityMap::mass_in`]).
    #[must_use]
    pub fn expected_count(
        &self,
        footprint: &Footprint,
        conic: &SphericalConic,
        scratch: &mut QueryScratch,
    ) -> f64 {
        self.expected_count_by(footprint, conic, OverlapMethod::Precise, &mut scratch.cells)
    }

    /// N·area·∫p over the conic, with partial near-uniform cells measured by `method`.
    pub(super) fn expected_count_by(
        &self,
        footprint: &Footprint,
        conic: &SphericalConic,
        method: OverlapMethod,
        cells: &mut Vec<DirectionalCell>,
    ) -> f64 {
        if footprint.is_degenerate() {
            return 0.0;
        }
        let integral = self.integral_over_conic_within(
            &DirectionalCell::HEMISPHERE,
            conic,
            LeafShare::SolidAngle(method),
            cells,
            None,
        );
        let area = match self.density_map.as_deref() {
            Some(map) => map.mass_in(footprint),
            None => footprint.area(),
        };
        self.config.particles as f64 * area * integral / self.quadrature.hemisphere_integral()
    }

    /// ∫ p over cell ∩ conic: descend the cells that have table entries; elsewhere take the
    /// cell's integral times its overlap share by `leaf` (Alg. 2's leaves are cells where the
    /// midpoint and corner rules agree: p is close to linear there, though not to constant).
    /// Within a query, its `memo` remembers the cells' classifications (the query's splits meet
    /// the same cells).
    pub(super) fn integral_over_conic_within(
        &self,
        start: &DirectionalCell,
        conic: &SphericalConic,
        leaf: LeafShare,
        stack: &mut Vec<DirectionalCell>,
        mut memo: Option<&mut QueryMemo>,
    ) -> f64 {
        stack.clear();
        stack.push(*start);
        let mut total = 0.0;
        let density = self.density.as_ref();
        while let Some(cell) = stack.pop() {
            let Some(triangle) = cell.triangle else {
                stack.extend(cell.children());
                continue;
            };
            let classification = match memo.as_deref_mut() {
                Some(memo) => memo.classify(&cell, conic),
                None => conic.classify(&triangle),
            };
            match classification {
                Classification::Disjoint => {}
                Classification::TriangleInsideConic => {
                    total += self.quadrature.integral(&cell, density)
                }
                _ if self.quadrature.has_entry(&cell) && !self.linear_enough(&triangle, leaf) => {
                    stack.extend(cell.children())
                }
                _ => {
                    let fraction = self.leaf_share(&triangle, cell.solid_angle(), conic, leaf);
                    total += self.quadrature.integral(&cell, density) * fraction;
                }
            }
        }
        total
    }

    /// Whether `leaf`'s rule may take a cell with a table entry as it is: for the linear rule,
    /// where p's midpoint and corner rules agree within [`LINEAR_ENOUGH`] (the linear
    /// interpolant then misses at most about that share of the cell's mass); the constant rule
    /// always descends to the table's leaves.
    fn linear_enough(&self, triangle: &SphericalTriangle, leaf: LeafShare) -> bool {
        if leaf != LeafShare::LinearDensity {
            return false;
        }
        let density = self.density.as_ref();
        let at = |m: DVec3| if m.z > 0.0 { density(m) } else { 0.0 };
        let corners: f64 = triangle.vertices().iter().map(|&m| at(m)).sum::<f64>() / 3.0;
        let middle = at(triangle.centroid());
        (middle - corners).abs() <= LINEAR_ENOUGH * corners.max(middle)
    }

    /// The share of a cell's particles whose normals lie in `conic`, by `leaf`'s rule.
    pub(super) fn leaf_share(
        &self,
        triangle: &SphericalTriangle,
        solid_angle: f64,
        conic: &SphericalConic,
        leaf: LeafShare,
    ) -> f64 {
        match leaf {
            LeafShare::SolidAngle(method) => {
                overlap_solid_angle(triangle, conic, method) / solid_angle
            }
            LeafShare::LinearDensity => {
                let density = self.density.as_ref();
                let vertex_densities = triangle
                    .vertices()
                    .map(|m| if m.z > 0.0 { density(m) } else { 0.0 });
                overlap_share_with_linear_density(triangle, conic, vertex_densities)
            }
        }
    }
}

/// The relative disagreement of p's midpoint and corner rules below which the linear rule takes
/// a cell with a table entry as linear (Alg. 2 refines to 10⁻⁵; the dense regime's shares need
/// about 10⁻³ of the mean count).
const LINEAR_ENOUGH: f64 = 1e-2;

/// How a cell of Alg. 2's table leaves that the conic cuts gives its share of ∫p.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum LeafShare {
    /// The overlap's share of the cell's solid angle (p taken as constant over the cell: the
    /// paper's overlap fraction, for Eq. 10 and the expected count).
    SolidAngle(OverlapMethod),
    /// The overlap's share of p interpolated linearly from its values at the cell's vertices
    /// (the dense regime's samples: on a lobe's flank p varies by a third across a 1° cell,
    /// and shares by solid angle made the mean count 4% low).
    LinearDensity,
}
