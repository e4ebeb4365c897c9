//! The built scene: primitives in a BVH, materials, lights and the camera. Immutable once
//! built, shared by every rendering thread.

use std::path::PathBuf;

use glam::DVec3;

use crate::accel::{Accelerator, PrimitiveHit};
use crate::camera::Camera;
use crate::light::Light;
use crate::material::Material;
use crate::settings::RenderSettings;
use crate::shape::Ray;

/// A scene ready to render.
#[derive(Debug)]
pub struct Scene {
    /// Primitives and their BVH.
    pub accelerator: Accelerator,
    /// Materials, indexed by [`crate::accel::Primitive::material`].
    pub materials: Vec<Material>,
    /// Each material's name in the scene file (parallel to `materials`).
    pub material_names: Vec<String>,
    /// Lights, indexed by [`crate::accel::Primitive::light`].
    pub lights: Vec<Light>,
    /// The camera.
    pub camera: Camera,
    /// The scene file's render settings (command-line options override them).
    pub settings: RenderSettings,
    /// The asset files (meshes, textures, environment maps) the scene was built from, in the
    /// order they were read: with the scene file, everything the image depends on.
    pub assets: Vec<PathBuf>,
}

impl Scene {
    /// The nearest hit along `ray` with t in (0, t_max).
    #[must_use]
    pub fn intersect(&self, ray: &Ray, t_max: f64) -> Option<PrimitiveHit> {
        self.accelerator.intersect(ray, t_max)
    }

    /// Whether anything blocks `ray` before `t_max`.
    #[must_use]
    pub fn occluded(&self, ray: &Ray, t_max: f64) -> bool {
        self.accelerator.occluded(ray, t_max)
    }

    /// The radiance of the environment along a ray that leaves the scene.
    #[must_use]
    pub fn escaped(&self, direction: DVec3) -> DVec3 {
        self.lights.iter().map(|l| l.escaped(direction)).sum()
    }

    /// Every glint material replaced by its smooth limit (`--smooth`, the paper's Fig. 3).
    pub fn make_smooth(&mut self) {
        for m in &mut self.materials {
            *m = m.smooth_limit();
        }
    }

    /// Sets every glint material's `negligible_count` (0 traverses every query).
    ///
    /// # Errors
    /// [`glint_brdf::BrdfError::InvalidNegligibleCount`] unless `count` is finite and ≥ 0.
    pub fn set_negligible_count(&mut self, count: f64) -> Result<(), glint_brdf::BrdfError> {
        for m in &mut self.materials {
            *m = m.with_negligible_count(count)?;
        }
        Ok(())
    }

    /// Sets the materials to `base` with a particle set of their own for camera frame `frame`
    /// (per-frame glint randomness; only glint materials change). Coherent animations do not
    /// call this.
    ///
    /// # Errors
    /// A material that cannot be rebuilt (never for materials that built once).
    pub fn reseed_glints_for_frame(
        &mut self,
        base: &[Material],
        frame: i64,
    ) -> Result<(), glint_brdf::BrdfError> {
        let salt = (frame as u64).wrapping_add(1);
        for (m, original) in self.materials.iter_mut().zip(base) {
            *m = original.reseeded(salt)?;
        }
        Ok(())
    }

    /// Whether any material has glints.
    #[must_use]
    pub fn has_glints(&self) -> bool {
        self.materials.iter().any(Material::has_glints)
    }
}
