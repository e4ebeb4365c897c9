//! The acceleration structure: an `obvhs` compressed wide BVH (CWBVH) over the bounds of every
//! primitive. Traversal is obvhs's (single precision boxes, padded so that flat primitives are
//! never missed); each primitive is intersected in double precision.
//!
//! The boxes are built in normalized coordinates: world coordinates times 2⁻ᵏ, with k the
//! integer that brings the largest bound into (½, 1]. obvhs 0.4 computes surface-area costs in
//! single precision (half areas times primitive counts, summed over the tree): in world units a
//! box wider than about 10¹⁹ overflowed them to infinity and the build indexed out of bounds.
//! Normalized, a half area is at most 3·2² = 12 and every cost finite, for any finite input;
//! and the rounding of normalized boxes stays far below the 10⁻⁵ that obvhs's own validation
//! (in debug builds) allows a child to stick out of its parent. Its traversal also clamps box
//! entries to t ≥ 10⁻⁴ of its units, which would cull every box once a hit that near is found:
//! rays therefore start 2⁻¹⁰ of that space before where they enter the scene's bounds (see
//! `Accelerator::bvh_ray`). Scaling by a power of two is exact, so the boxes stay
//! conservative; rays are scaled alike.
use std::time::Duration;

use glam::{DVec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::{Ray as BvhRay, RayHit};

use crate::mesh::Mesh;
use crate::shape::{Ray, Rectangle, Sphere, SurfaceHit};

/// The geometry of one primitive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Geometry {
    /// An analytic sphere.
    Sphere(Sphere),
    /// A parallelogram.
    Rectangle(Rectangle),
    /// Triangle `triangle` of mesh `mesh`.
    Triangle {
        /// Index into the scene's meshes.
        mesh: u32,
        /// Triangle index within the mesh.
        triangle: u32,
    },
}

/// A primitive: geometry with its material, and the light it is when it emits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Primitive {
    /// The shape.
    pub geometry: Geometry,
    /// Index into the scene's materials (unused for emitters that have none).
    pub material: u32,
    /// Index into the scene's lights when the primitive emits.
    pub light: Option<u32>,
}

/// A hit with the primitive it is on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrimitiveHit {
    /// The surface geometry.
    pub surface: SurfaceHit,
    /// Index of the primitive.
    pub primitive: usize,
}

/// The primitives and their BVH.
#[derive(Debug)]
pub struct Accelerator {
    primitives: Vec<Primitive>,
    meshes: Vec<Mesh>,
    bvh: Option<CwBvh>,
    /// The primitive of each box the BVH was built over (primitives with finite bounds).
    boxed: Vec<u32>,
    /// 2⁻ᵏ: world coordinates to the BVH's normalized ones (see the module documentation).
    to_bvh: f64,
    /// The world bounds of every boxed primitive, widened by a relative margin.
    scene_min: DVec3,
    scene_max: DVec3,
}

impl Accelerator {
    /// Builds the BVH over `primitives` (triangles index `meshes`). Any finite geometry builds
    /// and is traversed without panicking; a primitive whose bounds are not finite (a sphere of
    /// radius 10³⁰⁸) is never hit, and near the largest doubles the intersection arithmetic
    /// overflows. Scene files keep coordinates within [`crate::limits::MAX_COORDINATE`], where
    /// it is finite.
    #[must_use]
    pub fn new(primitives: Vec<Primitive>, meshes: Vec<Mesh>) -> Self {
        let bounds: Vec<(u32, (DVec3, DVec3))> = primitives
            .iter()
            .enumerate()
            .map(|(i, p)| (i as u32, geometry_bounds(&p.geometry, &meshes)))
            .filter(|(_, (min, max))| min.is_finite() && max.is_finite())
            .collect();
        let (mut scene_min, mut scene_max) = bounds.iter().fold(
            (DVec3::INFINITY, DVec3::NEG_INFINITY),
            |(lo, hi), (_, (min, max))| (lo.min(*min), hi.max(*max)),
        );
        let largest = scene_min.abs().max(scene_max.abs()).max_element();
        let to_bvh = if bounds.is_empty() {
            1.0
        } else {
            normalizing_scale(largest)
        };
        // Rays are clipped to these bounds in double precision: a margin of 10⁻⁶ of the scene's
        // size keeps primitives on the boundary from being clipped away by rounding.
        let margin = DVec3::splat(1e-6 * largest);
        (scene_min, scene_max) = (scene_min - margin, scene_max + margin);
        let boxes: Vec<Aabb> = bounds
            .iter()
            .map(|(_, (min, max))| padded_aabb((*min * to_bvh, *max * to_bvh)))
            .collect();
        let bvh = (!boxes.is_empty()).then(|| {
            obvhs::cwbvh::builder::build_cwbvh(
                &boxes,
                obvhs::BvhBuildParams::medium_build(),
                &mut Duration::default(),
            )
        });
        Self {
            primitives,
            meshes,
            bvh,
            boxed: bounds.into_iter().map(|(i, _)| i).collect(),
            to_bvh,
            scene_min,
            scene_max,
        }
    }

    /// The primitive of the BVH's primitive `id`.
    fn primitive_of(&self, bvh: &CwBvh, id: usize) -> usize {
        self.boxed[bvh.primitive_indices[id] as usize] as usize
    }

    /// The part of the ray within t ∈ [0, t_max) that crosses the scene's bounds, as the
    /// single-precision ray obvhs traverses with in the BVH's normalized coordinates, starting
    /// [`RAY_LEAD`] before where it enters the bounds, with that start t₀ in world units;
    /// `None` when it misses them or is not finite. Starting there (in double precision) keeps the ray's single-precision rounding
    /// relative to the scene, wherever its origin is. Its t_max is rounded up so that boxes are
    /// never culled by rounding. Negative zeros become positive: obvhs 0.4 picks the traversal
    /// octant by `x < 0` but inverts −0 to a large negative number, and then misses every box.
    fn bvh_ray(&self, ray: &Ray, t_max: f64) -> Option<(BvhRay, f64)> {
        if !(ray.origin.is_finite() && ray.direction.is_finite()) {
            return None;
        }
        let (mut t_enter, mut t_exit) = (0.0f64, t_max);
        for axis in 0..3 {
            let (o, d) = (ray.origin[axis], ray.direction[axis]);
            let (lo, hi) = (self.scene_min[axis], self.scene_max[axis]);
            if d == 0.0 {
                if !(o >= lo && o <= hi) {
                    return None;
                }
                continue;
            }
            let (a, b) = ((lo - o) / d, (hi - o) / d);
            t_enter = t_enter.max(a.min(b));
            t_exit = t_exit.min(a.max(b));
        }
        if !(t_enter <= t_exit) {
            return None;
        }
        // A lead before the entry: obvhs clamps box entries to t ≥ 10⁻⁴ of its units and culls
        // a box entered after the nearest hit so far, so every hit it is told of must lie
        // beyond 10⁻⁴ (else a hit within 10⁻⁴ of the origin would cull every other box, nearer
        // hits included).
        let t0 = t_enter - RAY_LEAD / self.to_bvh;
        let origin = (ray.at(t0) * self.to_bvh).as_vec3();
        if !origin.is_finite() {
            // Only near the largest doubles, where intersections overflow anyway.
            return None;
        }
        let t_max = (t_max - t0) * self.to_bvh;
        let tmax = if t_max.is_finite() {
            (t_max as f32) * (1.0 + 4.0 * f32::EPSILON) + f32::MIN_POSITIVE
        } else {
            f32::INFINITY
        };
        let ray = BvhRay::new(
            Vec3A::from(origin),
            Vec3A::from((ray.direction + DVec3::ZERO).as_vec3()),
            0.0,
            tmax,
        );
        Some((ray, t0))
    }

    /// A world ray parameter `t` as obvhs's, for a ray starting at world `t0`, rounded up.
    fn to_bvh_t(&self, t: f64, t0: f64) -> f32 {
        (((t - t0) * self.to_bvh) as f32).next_up()
    }

    /// The primitives.
    #[must_use]
    pub fn primitives(&self) -> &[Primitive] {
        &self.primitives
    }

    /// The meshes.
    #[must_use]
    pub fn meshes(&self) -> &[Mesh] {
        &self.meshes
    }

    /// The ray parameter of the hit on primitive `index`, in (t_min, t_max).
    fn intersect_primitive(&self, index: usize, ray: &Ray, t_max: f64) -> Option<f64> {
        match &self.primitives[index].geometry {
            Geometry::Sphere(s) => s.intersect(ray, 0.0, t_max),
            Geometry::Rectangle(r) => r.intersect(ray, 0.0, t_max),
            Geometry::Triangle { mesh, triangle } => self.meshes[*mesh as usize]
                .intersect(*triangle as usize, ray, 0.0, t_max)
                .map(|(t, _, _)| t),
        }
    }

    /// The surface of primitive `index` at ray parameter `t`.
    fn surface(&self, index: usize, ray: &Ray, t: f64) -> SurfaceHit {
        match &self.primitives[index].geometry {
            Geometry::Sphere(s) => s.surface(ray, t),
            Geometry::Rectangle(r) => r.surface(ray, t),
            Geometry::Triangle { mesh, triangle } => {
                let mesh = &self.meshes[*mesh as usize];
                let (t, b1, b2) = mesh
                    .intersect(*triangle as usize, ray, 0.0, f64::INFINITY)
                    .unwrap_or((t, 1.0 / 3.0, 1.0 / 3.0));
                mesh.surface(*triangle as usize, t, b1, b2)
            }
        }
    }

    /// The nearest hit with t in (0, t_max).
    #[must_use]
    pub fn intersect(&self, ray: &Ray, t_max: f64) -> Option<PrimitiveHit> {
        let bvh = self.bvh.as_ref()?;
        let (bvh_ray, t0) = self.bvh_ray(ray, t_max)?;
        let mut best: Option<(f64, usize)> = None;
        let mut hit = RayHit::none();
        bvh.ray_traverse(bvh_ray, &mut hit, |_, id| {
            let index = self.primitive_of(bvh, id);
            let limit = best.map_or(t_max, |(t, _)| t);
            match self.intersect_primitive(index, ray, limit) {
                Some(t) => {
                    best = Some((t, index));
                    self.to_bvh_t(t, t0)
                }
                None => f32::INFINITY,
            }
        });
        best.map(|(t, primitive)| PrimitiveHit {
            surface: self.surface(primitive, ray, t),
            primitive,
        })
    }

    /// Whether anything lies on the ray with t in (0, t_max).
    #[must_use]
    pub fn occluded(&self, ray: &Ray, t_max: f64) -> bool {
        let Some(bvh) = self.bvh.as_ref() else {
            return false;
        };
        let Some((bvh_ray, t0)) = self.bvh_ray(ray, t_max) else {
            return false;
        };
        let mut blocked = false;
        bvh.ray_traverse_miss(bvh_ray, |_, id| {
            let index = self.primitive_of(bvh, id);
            match self.intersect_primitive(index, ray, t_max) {
                Some(t) => {
                    blocked = true;
                    self.to_bvh_t(t, t0)
                }
                None => f32::INFINITY,
            }
        });
        blocked
    }
}

/// The largest coordinate of the BVH's normalized space (see the module documentation).
const BVH_EXTENT: f64 = 1.0;

/// How far before their entry into the scene's bounds rays start, in the BVH's units: beyond
/// obvhs's 10⁻⁴.
const RAY_LEAD: f64 = 1.0 / 1024.0;

/// 2⁻ᵏ for the integer k with `largest`·2⁻ᵏ in (½, 1]·[`BVH_EXTENT`], or the nearest within
/// k ∈ [−1000, 1100] (2⁻¹⁰⁹⁹ is a subnormal double, 2¹⁰⁰⁰ a normal one: both exact).
fn normalizing_scale(largest: f64) -> f64 {
    let mut scale = 1.0;
    let mut k = 0;
    while largest * scale > BVH_EXTENT && k < 1100 {
        scale *= 0.5;
        k += 1;
    }
    while largest > 0.0 && largest * scale <= 0.5 * BVH_EXTENT && k > -1000 {
        scale *= 2.0;
        k -= 1;
    }
    scale
}

/// The bounds of a primitive's geometry.
fn geometry_bounds(geometry: &Geometry, meshes: &[Mesh]) -> (DVec3, DVec3) {
    match geometry {
        Geometry::Sphere(s) => s.bounds(),
        Geometry::Rectangle(r) => r.bounds(),
        Geometry::Triangle { mesh, triangle } => {
            let c = meshes[*mesh as usize].corners(*triangle as usize);
            (c[0].min(c[1]).min(c[2]), c[0].max(c[1]).max(c[2]))
        }
    }
}

/// Double-precision bounds (in the BVH's normalized coordinates) widened to a single-precision
/// box that surely contains them and that every ray meeting them meets: by 10⁻⁵ of the box's
/// size and 10⁻⁶ of its distance from the origin (the box's own rounding), plus 2⁻¹⁹ of the
/// scene's extent (about 2·10⁻⁶), which covers the rounding of a ray's origin and direction to
/// single precision over the scene (≈ 6·10⁻⁸ of the distances involved) and obvhs's treatment
/// of direction components below 1.2·10⁻⁷ as 1.2·10⁻⁷.
fn padded_aabb((min, max): (DVec3, DVec3)) -> Aabb {
    let pad = 1e-5 * (max - min).max_element()
        + 1e-6 * min.abs().max(max.abs()).max_element()
        + BVH_EXTENT / f64::from(1u32 << 19);
    Aabb::new(
        Vec3A::from((min - DVec3::splat(pad)).as_vec3()),
        Vec3A::from((max + DVec3::splat(pad)).as_vec3()),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A few hundred random spheres, rectangles and triangles: the BVH's nearest hit and
    /// occlusion answers equal a linear scan over every primitive.
    #[test]
    fn bvh_agrees_with_brute_force() {
        let mut rng = glint_tests::SplitMix64::new(12345u64);
        let mut next = move || rng.uniform();
        let mut random_point =
            |scale: f64| DVec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * scale;
        let mut mesh = Mesh::default();
        let mut primitives = Vec::new();
        for i in 0..300u32 {
            let c = random_point(10.0);
            let geometry = match i % 3 {
                0 => Geometry::Sphere(Sphere {
                    center: c,
                    radius: 0.05 + 0.3 * random_point(1.0).x.abs(),
                }),
                1 => Geometry::Rectangle(
                    Rectangle::new(c, random_point(1.0), random_point(1.0)).unwrap(),
                ),
                _ => {
                    let base = mesh.positions.len() as u32;
                    mesh.positions
                        .extend([c, c + random_point(1.0), c + random_point(1.0)]);
                    mesh.triangles.push([base, base + 1, base + 2]);
                    Geometry::Triangle {
                        mesh: 0,
                        triangle: (mesh.triangles.len() - 1) as u32,
                    }
                }
            };
            primitives.push(Primitive {
                geometry,
                material: 0,
                light: None,
            });
        }
        let accel = Accelerator::new(primitives, vec![mesh]);
        let mut hits = 0;
        for _ in 0..3000 {
            let origin = random_point(14.0);
            let direction = random_point(1.0).normalize();
            let ray = Ray { origin, direction };
            let brute = (0..accel.primitives.len())
                .filter_map(|i| {
                    accel
                        .intersect_primitive(i, &ray, f64::INFINITY)
                        .map(|t| (t, i))
                })
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let fast = accel.intersect(&ray, f64::INFINITY);
            assert_eq!(brute.map(|b| b.1), fast.map(|f| f.primitive));
            if let (Some((t, _)), Some(f)) = (brute, fast) {
                assert!((t - f.surface.t).abs() <= 1e-9 * t.max(1.0));
                hits += 1;
                assert!(accel.occluded(&ray, t * 1.0001));
                assert!(!accel.occluded(&ray, t * 0.9999));
            } else {
                assert!(!accel.occluded(&ray, f64::INFINITY));
            }
        }
        assert!(hits > 100, "the test must exercise hits: {hits}");
    }

    /// Axis-aligned rays with negative zero components (−Y is (−0, −1, −0)) still hit.
    #[test]
    fn negative_zero_directions_hit() {
        let quad = Rectangle::new(
            DVec3::ZERO,
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, -2.0),
        )
        .unwrap();
        let accel = Accelerator::new(
            vec![Primitive {
                geometry: Geometry::Rectangle(quad),
                material: 0,
                light: None,
            }],
            vec![],
        );
        for direction in [
            -DVec3::Y,
            DVec3::new(-0.0, -1.0, 0.0),
            DVec3::new(0.0, -1.0, -0.0),
        ] {
            let ray = Ray {
                origin: DVec3::new(0.5, 3.0, 0.25),
                direction,
            };
            assert!(
                accel.intersect(&ray, f64::INFINITY).is_some(),
                "{direction:?}"
            );
            assert!(accel.occluded(&ray, f64::INFINITY), "{direction:?}");
        }
    }

    /// A number of magnitude 10⁻³⁰⁸ to 10³⁰⁸ (log-uniform, either sign), zero or the largest
    /// double.
    fn any_magnitude() -> impl Strategy<Value = f64> + Clone {
        prop_oneof![
            8 => (any::<bool>(), 1.0..10.0f64, -308i32..=307).prop_map(|(negative, m, e)| {
                let x = m * 10f64.powi(e);
                if negative { -x } else { x }
            }),
            1 => Just(0.0),
            1 => prop_oneof![Just(f64::MAX), Just(-1e308), Just(3e38), Just(-3e38)],
        ]
    }

    /// A number within the scene files' coordinate limit: magnitude 10⁻⁹ to 10¹⁵.
    fn scene_magnitude() -> impl Strategy<Value = f64> + Clone {
        (any::<bool>(), 1.0..10.0f64, -9i32..=14).prop_map(|(negative, m, e)| {
            let x = m * 10f64.powi(e);
            if negative { -x } else { x }
        })
    }

    fn vector(number: impl Strategy<Value = f64> + Clone) -> impl Strategy<Value = DVec3> {
        (number.clone(), number.clone(), number).prop_map(|(x, y, z)| DVec3::new(x, y, z))
    }

    fn unit_vector() -> impl Strategy<Value = DVec3> {
        (-1.0..1.0f64, 0.0..std::f64::consts::TAU).prop_map(|(z, phi)| {
            let r = (1.0 - z * z).sqrt();
            DVec3::new(r * phi.cos(), r * phi.sin(), z)
        })
    }

    /// Spheres, rectangles and triangles with coordinates drawn from `number`.
    fn primitives(
        number: impl Strategy<Value = f64> + Clone,
    ) -> impl Strategy<Value = (Vec<Primitive>, Vec<Mesh>)> {
        let shape = (
            0..3u8,
            vector(number.clone()),
            vector(number.clone()),
            vector(number),
        );
        prop::collection::vec(shape, 1..24).prop_map(|shapes| {
            let mut mesh = Mesh::default();
            let mut primitives = Vec::new();
            for (kind, a, b, c) in shapes {
                let geometry = match kind {
                    0 => Geometry::Sphere(Sphere {
                        center: a,
                        radius: b.x.abs(),
                    }),
                    1 => match Rectangle::new(a, b, c) {
                        Some(r) => Geometry::Rectangle(r),
                        None => continue,
                    },
                    _ => {
                        let base = mesh.positions.len() as u32;
                        mesh.positions.extend([a, b, c]);
                        mesh.triangles.push([base, base + 1, base + 2]);
                        Geometry::Triangle {
                            mesh: 0,
                            triangle: (mesh.triangles.len() - 1) as u32,
                        }
                    }
                };
                primitives.push(Primitive {
                    geometry,
                    material: 0,
                    light: None,
                });
            }
            (primitives, vec![mesh])
        })
    }

    proptest! {
        #![proptest_config(crate::fuzz::config(96))]

        /// No geometry of magnitude up to 10³⁰⁸ panics the BVH, in the build or in traversal
        /// (obvhs indexed out of bounds when its single-precision costs overflowed).
        #[test]
        fn no_magnitude_panics_the_bvh(
            (primitives, meshes) in primitives(any_magnitude()),
            rays in prop::collection::vec((vector(any_magnitude()), unit_vector()), 1..8),
        ) {
            let accel = Accelerator::new(primitives, meshes);
            for (origin, direction) in rays {
                let ray = Ray { origin, direction };
                let hit = accel.intersect(&ray, f64::INFINITY);
                let _ = accel.occluded(&ray, f64::INFINITY);
                if let Some(hit) = hit {
                    prop_assert!(hit.primitive < accel.primitives().len());
                }
            }
        }

        /// Within the scene files' limits (magnitudes 10⁻⁹ to 10¹⁵ mixed in one scene), the
        /// BVH finds the nearest hit a linear scan finds.
        #[test]
        fn within_the_limits_the_bvh_agrees_with_brute_force(
            (primitives, meshes) in primitives(scene_magnitude()),
            rays in prop::collection::vec((vector(scene_magnitude()), unit_vector()), 1..8),
        ) {
            let accel = Accelerator::new(primitives, meshes);
            for (origin, direction) in rays {
                let ray = Ray { origin, direction };
                let brute = (0..accel.primitives.len())
                    .filter_map(|i| accel.intersect_primitive(i, &ray, f64::INFINITY))
                    .min_by(f64::total_cmp);
                let fast = accel.intersect(&ray, f64::INFINITY);
                prop_assert_eq!(brute, fast.map(|f| f.surface.t));
                prop_assert_eq!(brute.is_some(), accel.occluded(&ray, f64::INFINITY));
            }
        }
    }
}
