//! The `[[shapes]]` sections: their form in the file (spheres, rectangles, OBJ meshes with a
//! transform) and their building into primitives, with the sphere and rectangle geometry that
//! area lights share.

use glam::{DAffine3, DQuat, DVec3};
use serde::Deserialize;

use super::builder::{Builder, Checked};
use super::materials::UsedMaterials;
use super::numbers::Colour;
use crate::accel::{Geometry, Primitive};
use crate::error::TracerError;
use crate::limits::{self, echo};
use crate::mesh::Mesh;
use crate::shape::{Rectangle, Sphere};

/// The shape types, by their `type`.
const SHAPE_TYPES: &[&str] = &["sphere", "rectangle", "mesh"];

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SphereSection {
    center: [f64; 3],
    radius: f64,
    material: String,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RectangleSection {
    center: [f64; 3],
    u: [f64; 3],
    v: [f64; 3],
    material: String,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshSection {
    file: String,
    material: String,
    #[serde(default)]
    transform: TransformSection,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct TransformSection {
    translate: Option<[f64; 3]>,
    scale: Option<Colour>,
    /// Axis (x, y, z) and angle in degrees.
    rotate: Option<[f64; 4]>,
}

impl Builder<'_> {
    fn transform(&self, field: &str, t: &TransformSection) -> Checked<DAffine3> {
        let scale = match t.scale {
            None => DVec3::ONE,
            Some(s) => s.rgb(),
        };
        if !(scale.is_finite()
            && scale.abs().max_element() <= limits::MAX_COORDINATE
            && scale.abs().min_element() > 0.0)
        {
            return self.fail(
                format!("{field}.scale"),
                format!(
                    "must be non-zero and within ±{:e}, got {}",
                    limits::MAX_COORDINATE,
                    limits::vector(scale)
                ),
            );
        }
        let rotation = match t.rotate {
            None => DQuat::IDENTITY,
            Some([x, y, z, degrees]) => {
                let axis = self.direction(&format!("{field}.rotate"), [x, y, z])?;
                if !degrees.is_finite() {
                    return self.fail(format!("{field}.rotate"), "the angle must be finite");
                }
                DQuat::from_axis_angle(axis, degrees.to_radians())
            }
        };
        let translation = self.point(
            &format!("{field}.translate"),
            t.translate.unwrap_or([0.0; 3]),
        )?;
        Ok(DAffine3::from_scale_rotation_translation(
            scale,
            rotation,
            translation,
        ))
    }

    pub(super) fn rectangle(
        &self,
        field: &str,
        center: [f64; 3],
        u: [f64; 3],
        v: [f64; 3],
    ) -> Checked<Rectangle> {
        let center = self.point(&format!("{field}.center"), center)?;
        let u = self.point(&format!("{field}.u"), u)?;
        let v = self.point(&format!("{field}.v"), v)?;
        match Rectangle::new(center, u, v) {
            Some(r) => Ok(r),
            None => self.fail(
                format!("{field}.v"),
                "the edges u and v are parallel, zero or too small: the rectangle has no area",
            ),
        }
    }

    pub(super) fn sphere(&self, field: &str, center: [f64; 3], radius: f64) -> Checked<Sphere> {
        Ok(Sphere {
            center: self.point(&format!("{field}.center"), center)?,
            radius: self.within(
                &format!("{field}.radius"),
                radius,
                limits::MIN_RADIUS,
                limits::MAX_COORDINATE,
            )?,
        })
    }

    /// Builds the `[[shapes]]` into `primitives` (and their meshes into `meshes`), building the
    /// materials they use into `materials`.
    pub(super) fn shapes(
        &self,
        sections: Vec<toml::Value>,
        materials: &mut UsedMaterials<'_>,
        primitives: &mut Vec<Primitive>,
        meshes: &mut Vec<Mesh>,
    ) -> Checked<()> {
        for (i, shape) in sections.into_iter().enumerate() {
            let field = format!("shapes[{i}]");
            self.room_for(&field, primitives.len(), 1)?;
            let (kind, shape) = self.tagged(&field, shape, SHAPE_TYPES)?;
            match kind.as_str() {
                "sphere" => {
                    let s: SphereSection = self.section(&field, shape)?;
                    let sphere = self.sphere(&field, s.center, s.radius)?;
                    // (u, v) cover [0, 1]² once.
                    let surface_per_uv = 4.0 * std::f64::consts::PI * sphere.radius.powi(2);
                    let material = self.use_material(
                        materials,
                        &s.material,
                        &format!("{field}.material"),
                        &field,
                        Some(surface_per_uv).filter(|r| *r > 0.0 && r.is_finite()),
                    )?;
                    primitives.push(Primitive {
                        geometry: Geometry::Sphere(sphere),
                        material,
                        light: None,
                    });
                }
                "rectangle" => {
                    let r: RectangleSection = self.section(&field, shape)?;
                    let rectangle = self.rectangle(&field, r.center, r.u, r.v)?;
                    let material = self.use_material(
                        materials,
                        &r.material,
                        &format!("{field}.material"),
                        &field,
                        Some(rectangle.area()).filter(|r| *r > 0.0 && r.is_finite()),
                    )?;
                    primitives.push(Primitive {
                        geometry: Geometry::Rectangle(rectangle),
                        material,
                        light: None,
                    });
                }
                _ => {
                    let m: MeshSection = self.section(&field, shape)?;
                    let transform = self.transform(&format!("{field}.transform"), &m.transform)?;
                    let path = self.asset(&m.file);
                    let file_field = format!("{field}.file");
                    self.spend_asset_bytes(&file_field, &path)?;
                    let mesh = Mesh::load_obj(&path).map_err(|e| TracerError::Scene {
                        file: self.file.to_path_buf(),
                        field: file_field.clone(),
                        problem: e.to_string(),
                    })?;
                    let mesh = mesh.transformed(&transform);
                    // The transform may carry vertices past the coordinate limit.
                    mesh.validate().map_err(|problem| TracerError::Scene {
                        file: self.file.to_path_buf(),
                        field: format!("{field}.transform"),
                        problem: format!("{}: after the transform, {problem}", echo(&m.file)),
                    })?;
                    self.room_for(&file_field, primitives.len(), mesh.triangles.len())?;
                    let (surface, uv) = mesh.surface_and_uv_area();
                    let material = self.use_material(
                        materials,
                        &m.material,
                        &format!("{field}.material"),
                        &field,
                        Some(surface / uv).filter(|r| *r > 0.0 && r.is_finite()),
                    )?;
                    let mesh_index = meshes.len() as u32;
                    for t in 0..mesh.triangles.len() as u32 {
                        primitives.push(Primitive {
                            geometry: Geometry::Triangle {
                                mesh: mesh_index,
                                triangle: t,
                            },
                            material,
                            light: None,
                        });
                    }
                    meshes.push(mesh);
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use crate::scene_file::load_scene;

    /// An OBJ mesh beside the scene file, moved by a transform, is found by rays.
    #[test]
    fn obj_meshes_load_relative_to_the_scene_with_their_transform() {
        let dir = std::env::temp_dir().join(format!("glint-scene-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("meshes")).unwrap();
        std::fs::write(
            dir.join("meshes/quad.obj"),
            "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 4/4 3/3 2/2\n",
        )
        .unwrap();
        let text = r#"
[camera]
position = [0, 3, 0.01]
look_at = [0, 0, 0]
[materials.grey]
type = "diffuse"
[[shapes]]
type = "mesh"
file = "meshes/quad.obj"
material = "grey"
transform = { scale = 2, translate = [0, 0.5, 0], rotate = [0, 1, 0, 30] }
[[lights]]
type = "directional"
direction = [0, 1, 0]
irradiance = 1
"#;
        let path = dir.join("scene.toml");
        std::fs::write(&path, text).unwrap();
        let scene = load_scene(&path).unwrap();
        assert_eq!(scene.accelerator.primitives().len(), 2);
        let ray = crate::shape::Ray {
            origin: DVec3::new(1.5, 3.0, 0.0),
            direction: -DVec3::Y,
        };
        let hit = scene
            .intersect(&ray, f64::INFINITY)
            .expect("the scaled quad spans ±2");
        assert!((hit.surface.point.y - 0.5).abs() < 1e-12);
        let miss = crate::shape::Ray {
            origin: DVec3::new(2.9, 3.0, 0.0),
            direction: -DVec3::Y,
        };
        // Rotated by 30°, the square's corner region at (2.9, 0) lies outside it.
        assert!(scene.intersect(&miss, f64::INFINITY).is_none());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
