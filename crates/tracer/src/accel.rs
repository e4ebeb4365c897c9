//! The acceleration structure: an `obvhs` compressed wide BVH (CWBVH) over the bounds of every
//! primitive. Traversal is obvhs's (single precision boxes, padded so that flat primitives are
//! never missed); each primitive is intersected in double precision.

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
}

impl Accelerator {
    /// Builds the BVH over `primitives` (triangles index `meshes`).
    #[must_use]
    pub fn new(primitives: Vec<Primitive>, meshes: Vec<Mesh>) -> Self {
        let bounds: Vec<Aabb> = primitives
            .iter()
            .map(|p| padded_aabb(geometry_bounds(&p.geometry, &meshes)))
            .collect();
        let bvh = (!bounds.is_empty()).then(|| {
            obvhs::cwbvh::builder::build_cwbvh(
                &bounds,
                obvhs::BvhBuildParams::medium_build(),
                &mut Duration::default(),
            )
        });
        Self {
            primitives,
            meshes,
            bvh,
        }
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
        let mut best: Option<(f64, usize)> = None;
        let mut hit = RayHit::none();
        bvh.ray_traverse(to_bvh_ray(ray, t_max), &mut hit, |_, id| {
            let index = bvh.primitive_indices[id] as usize;
            let limit = best.map_or(t_max, |(t, _)| t);
            match self.intersect_primitive(index, ray, limit) {
                Some(t) => {
                    best = Some((t, index));
                    t as f32
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
        let mut blocked = false;
        bvh.ray_traverse_miss(to_bvh_ray(ray, t_max), |_, id| {
            let index = bvh.primitive_indices[id] as usize;
            match self.intersect_primitive(index, ray, t_max) {
                Some(t) => {
                    blocked = true;
                    t as f32
                }
                None => f32::INFINITY,
            }
        });
        blocked
    }
}

/// The single-precision ray obvhs traverses with; its t_max is rounded up so that boxes are
/// never culled by rounding. Negative zeros become positive: obvhs 0.4 picks the traversal
/// octant by `x < 0` but inverts −0 to a large negative number, and then misses every box.
fn to_bvh_ray(ray: &Ray, t_max: f64) -> BvhRay {
    let tmax = if t_max.is_finite() {
        (t_max as f32) * (1.0 + 4.0 * f32::EPSILON) + f32::MIN_POSITIVE
    } else {
        f32::INFINITY
    };
    BvhRay::new(
        Vec3A::from(ray.origin.as_vec3()),
        Vec3A::from((ray.direction + DVec3::ZERO).as_vec3()),
        0.0,
        tmax,
    )
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

/// Double-precision bounds widened to a single-precision box that surely contains them.
fn padded_aabb((min, max): (DVec3, DVec3)) -> Aabb {
    let pad =
        1e-5 * (max - min).max_element() + 1e-6 * min.abs().max(max.abs()).max_element() + 1e-6;
    Aabb::new(
        Vec3A::from((min - DVec3::splat(pad)).as_vec3()),
        Vec3A::from((max + DVec3::splat(pad)).as_vec3()),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
