//! Spherical triangles: the directional extent of a count-tree node (Sec. 3.3, "Data structure").
//!
//! A [`SphericalTriangle`] is the region of S² bounded by the three great-circle arcs between its
//! vertices, always the smaller of the two candidates (less than a hemisphere). Vertices are
//! stored counter-clockwise as seen from outside the sphere, i.e. a·(b×c) > 0.

use glam::DVec3;

use crate::error::{SphereError, unit_direction};

/// A spherical triangle with unit vertices in counter-clockwise order (a·(b×c) > 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphericalTriangle {
    vertices: [DVec3; 3],
}

impl SphericalTriangle {
    /// Builds a triangle from three directions, normalizing them and putting them in
    /// counter-clockwise order.
    ///
    /// # Errors
    /// [`SphereError::NonFiniteDirection`] or [`SphereError::ZeroDirection`] for an unusable
    /// vertex, [`SphereError::DegenerateTriangle`] when the vertices lie on one great circle.
    pub fn new(a: DVec3, b: DVec3, c: DVec3) -> Result<Self, SphereError> {
        let a = unit_direction(a, "a")?;
        let b = unit_direction(b, "b")?;
        let c = unit_direction(c, "c")?;
        let orientation = a.dot((b - a).cross(c - a));
        if orientation > 0.0 {
            Ok(Self {
                vertices: [a, b, c],
            })
        } else if orientation < 0.0 {
            Ok(Self {
                vertices: [a, c, b],
            })
        } else {
            Err(SphereError::DegenerateTriangle)
        }
    }

    /// Builds a triangle from unit vertices already in counter-clockwise order, without checks
    /// beyond debug assertions. For callers that derive vertices from a checked triangle.
    #[must_use]
    pub fn from_unit_ccw(a: DVec3, b: DVec3, c: DVec3) -> Self {
        debug_assert!(a.is_normalized() && b.is_normalized() && c.is_normalized());
        debug_assert!(
            a.dot((b - a).cross(c - a)) > 0.0,
            "vertices must be counter-clockwise"
        );
        Self {
            vertices: [a, b, c],
        }
    }

    /// The four octant triangles that split the upper hemisphere (z ≥ 0): the root's first
    /// directional split in the count tree. Octant k spans azimuths [kπ/2, (k+1)π/2].
    #[must_use]
    pub fn upper_hemisphere_octants() -> [Self; 4] {
        let z = DVec3::Z;
        let e = [DVec3::X, DVec3::Y, DVec3::NEG_X, DVec3::NEG_Y];
        [0, 1, 2, 3].map(|k| Self {
            vertices: [e[k], e[(k + 1) % 4], z],
        })
    }

    /// The vertices, counter-clockwise.
    #[must_use]
    pub fn vertices(&self) -> [DVec3; 3] {
        self.vertices
    }

    /// The solid angle (steradians), by the formula of Van Oosterom and Strackee,
    /// tan(Ω/2) = a·(b×c) / (1 + a·b + b·c + c·a),
    /// with the triple product evaluated on edge vectors, a·((b−a)×(c−a)), so that it keeps full
    /// relative precision for triangles with edges of 1e-5 rad and below. Triangles below
    /// Ω ≈ 0.2 sr (most of the count tree's, t = tan(Ω/2) < 0.1) take the arctangent from its
    /// series ([`atan_series`]) instead of `atan2`, a libm call that costs about twice as much.
    #[must_use]
    pub fn solid_angle(&self) -> f64 {
        let [a, b, c] = self.vertices;
        let triple = a.dot((b - a).cross(c - a));
        let denominator = 1.0 + a.dot(b) + b.dot(c) + c.dot(a);
        if triple >= 0.0 && triple < 0.1 * denominator {
            return 2.0 * atan_series(triple / denominator);
        }
        2.0 * triple.atan2(denominator)
    }

    /// The solid angles of four triangles, each bit for bit [`SphericalTriangle::solid_angle`]'s
    /// (the same operations in the same order), computed side by side: the four chains of
    /// dependent operations (the series' Horner steps, the quotient) overlap, where four calls
    /// one after the other mostly wait on each other's latency.
    #[must_use]
    pub fn solid_angles_of(triangles: &[Self; 4]) -> [f64; 4] {
        let mut triples = [0.0; 4];
        let mut denominators = [0.0; 4];
        for (j, triangle) in triangles.iter().enumerate() {
            let [a, b, c] = triangle.vertices;
            triples[j] = a.dot((b - a).cross(c - a));
            denominators[j] = 1.0 + a.dot(b) + b.dot(c) + c.dot(a);
        }
        let mut quotients = [0.0; 4];
        for j in 0..4 {
            quotients[j] = triples[j] / denominators[j];
        }
        let series = atan_series_of(quotients);
        std::array::from_fn(|j| {
            let (triple, denominator) = (triples[j], denominators[j]);
            if triple >= 0.0 && triple < 0.1 * denominator {
                2.0 * series[j]
            } else {
                2.0 * triple.atan2(denominator)
            }
        })
    }

    /// The inward normals of the three great circles through the edges ab, bc, ca (not
    /// normalized). A direction p is inside when p has a non-negative dot product with all three.
    #[must_use]
    pub fn edge_normals(&self) -> [DVec3; 3] {
        let [a, b, c] = self.vertices;
        // a×b = a×(b−a): the difference keeps precision for short edges.
        [a.cross(b - a), b.cross(c - b), c.cross(a - c)]
    }

    /// Whether direction `p` (any length) lies in the triangle: three plane-side tests, one per
    /// edge plane through the sphere's centre. Points on an edge count as inside.
    #[must_use]
    pub fn contains(&self, p: DVec3) -> bool {
        self.edge_normals().iter().all(|n| n.dot(p) >= 0.0)
    }

    /// The four children of the standard subdivision by normalized edge midpoints: three corner
    /// triangles (at a, b, c, in that order) and the centre one. All are counter-clockwise, and
    /// their solid angles sum to the parent's.
    #[must_use]
    pub fn subdivide(&self) -> [Self; 4] {
        let [a, b, c] = self.vertices;
        let mab = (a + b).normalize();
        let mbc = (b + c).normalize();
        let mca = (c + a).normalize();
        [
            Self {
                vertices: [a, mab, mca],
            },
            Self {
                vertices: [mab, b, mbc],
            },
            Self {
                vertices: [mca, mbc, c],
            },
            Self {
                vertices: [mab, mbc, mca],
            },
        ]
    }

    /// The normalized vertex centroid, a direction inside the triangle.
    #[must_use]
    pub fn centroid(&self) -> DVec3 {
        let [a, b, c] = self.vertices;
        (a + b + c).normalize()
    }

    /// The longest edge's chord |b − a| (no trigonometry): the arc is 2·asin(chord/2).
    #[must_use]
    pub fn longest_chord(&self) -> f64 {
        let [a, b, c] = self.vertices;
        (b - a)
            .length_squared()
            .max((c - b).length_squared())
            .max((a - c).length_squared())
            .sqrt()
    }

    /// The longest edge's arc length (radians), 2·asin(|b−a|/2), accurate for tiny edges.
    #[must_use]
    pub fn longest_edge(&self) -> f64 {
        2.0 * (0.5 * self.longest_chord()).min(1.0).asin()
    }

    /// Maps barycentric-like weights (w0, w1, w2 ≥ 0, not all zero) to the direction
    /// normalize(w0·a + w1·b + w2·c), which lies in the triangle. Used by samplers in tests and
    /// validation; uniform weights on the planar triangle do *not* give uniform directions.
    #[must_use]
    pub fn direction_at(&self, w: [f64; 3]) -> DVec3 {
        let [a, b, c] = self.vertices;
        (w[0] * a + w[1] * b + w[2] * c).normalize()
    }
}

/// atan t for 0 ≤ t < 0.1 by its Maclaurin series to t¹⁵ (remainder < t¹⁷/17 < 6e-18·t),
/// in Horner form in x = t².
#[inline]
fn atan_series(t: f64) -> f64 {
    let x = t * t;
    let mut sum = -1.0 / 15.0;
    for coefficient in ATAN_COEFFICIENTS {
        sum = sum * x + coefficient;
    }
    t * sum
}

/// The coefficients of [`atan_series`]'s Horner steps after the first, −1/15.
const ATAN_COEFFICIENTS: [f64; 7] = [
    1.0 / 13.0,
    -1.0 / 11.0,
    1.0 / 9.0,
    -1.0 / 7.0,
    1.0 / 5.0,
    -1.0 / 3.0,
    1.0,
];

/// [`atan_series`] of four arguments, step by step side by side (each lane bit for bit
/// [`atan_series`]'s; meaningful only where 0 ≤ t < 0.1).
#[inline]
fn atan_series_of(t: [f64; 4]) -> [f64; 4] {
    let x = t.map(|t| t * t);
    let mut sum = [-1.0 / 15.0; 4];
    for coefficient in ATAN_COEFFICIENTS {
        for j in 0..4 {
            sum[j] = sum[j] * x[j] + coefficient;
        }
    }
    std::array::from_fn(|j| t[j] * sum[j])
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn octants_tile_the_upper_hemisphere() {
        let total: f64 = SphericalTriangle::upper_hemisphere_octants()
            .iter()
            .map(SphericalTriangle::solid_angle)
            .sum();
        assert!((total - 2.0 * PI).abs() < 1e-14, "{total}");
        for t in SphericalTriangle::upper_hemisphere_octants() {
            assert!((t.solid_angle() - PI / 2.0).abs() < 1e-15);
        }
    }

    #[test]
    fn new_orients_and_rejects() {
        let t = SphericalTriangle::new(DVec3::X, DVec3::Z, DVec3::Y).unwrap();
        assert!(t.solid_angle() > 0.0);
        assert_eq!(
            SphericalTriangle::new(DVec3::X, DVec3::Y, DVec3::new(1.0, 1.0, 0.0)),
            Err(SphereError::DegenerateTriangle)
        );
        assert_eq!(
            SphericalTriangle::new(DVec3::X, DVec3::ZERO, DVec3::Z),
            Err(SphereError::ZeroDirection { name: "b" })
        );
        assert_eq!(
            SphericalTriangle::new(DVec3::X, DVec3::Y, DVec3::new(0.0, f64::NAN, 1.0)),
            Err(SphereError::NonFiniteDirection { name: "c" })
        );
    }

    #[test]
    fn containment_of_vertices_centroid_and_antipode() {
        let t = SphericalTriangle::upper_hemisphere_octants()[0];
        assert!(t.contains(t.centroid()));
        assert!(!t.contains(-t.centroid()));
        for v in t.vertices() {
            assert!(t.contains(v));
        }
        assert!(!t.contains(DVec3::new(-1.0, 0.1, 0.1)));
    }

    /// `solid_angles_of` is `solid_angle` four times, bit for bit: triangles from octants to
    /// 10⁻⁶ rad across (the series and `atan2` branches), subdivided as the count tree does.
    #[test]
    fn four_solid_angles_side_by_side_are_each_solid_angle() {
        let mut level: Vec<SphericalTriangle> =
            SphericalTriangle::upper_hemisphere_octants().to_vec();
        level.push(
            SphericalTriangle::new(DVec3::X, DVec3::Y, DVec3::new(-1.0, -1.0, -0.1)).unwrap(),
        );
        let mut compared = 0;
        for _ in 0..20 {
            for quad in level.chunks_exact(4) {
                let quad: &[SphericalTriangle; 4] = quad.try_into().unwrap();
                let side_by_side = SphericalTriangle::solid_angles_of(quad);
                for (triangle, omega) in quad.iter().zip(side_by_side) {
                    assert_eq!(
                        omega.to_bits(),
                        triangle.solid_angle().to_bits(),
                        "{triangle:?}"
                    );
                    compared += 1;
                }
            }
            // Keep every level small: the first, a middle and the last triangle's children.
            let picks = [0, level.len() / 2, level.len() - 1];
            level = picks.iter().flat_map(|&k| level[k].subdivide()).collect();
        }
        assert!(compared > 200, "{compared}");
    }

    #[test]
    fn atan_series_matches_atan_below_its_threshold() {
        let mut worst: f64 = 0.0;
        for k in 0..=10_000 {
            let t = 0.1 * f64::from(k) / 10_000.0 * (1.0 - 1e-12);
            let exact = t.atan();
            if exact > 0.0 {
                worst = worst.max((atan_series(t) - exact).abs() / exact);
            }
        }
        assert!(worst < 4e-16, "relative error {worst:e}");
    }
}
