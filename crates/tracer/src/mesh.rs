//! Triangle meshes: loaded from OBJ files (`tobj`, triangulated, one index per vertex) or built
//! in code, with optional vertex normals and texture coordinates.

use std::path::Path;

use glam::{DAffine3, DMat3, DVec2, DVec3};

use crate::error::TracerError;
use crate::limits;
use crate::shape::{Ray, SurfaceHit};

/// Checks the numbers of the OBJ's statements before parsing: `v`, `vn` and `vt` values as the
/// single-precision numbers the OBJ reader makes of them (positions finite and within
/// [`limits::MAX_COORDINATE`], normals and texture coordinates finite), and the indices of `f`
/// and `l` statements (not 0; positive ones at most the file's count of that kind, negative
/// ones at most the count before the statement). tobj 4 multiplies unchecked indices and
/// overflows on `f 1/1/-9` after one normal or on an index of 2⁶³. An error names the
/// statement by its OBJ index (from 1, as faces count) or its kind, and its line.
fn check_obj_values(bytes: &[u8]) -> Result<(), String> {
    const KINDS: [&str; 3] = ["v", "vt", "vn"];
    let text = String::from_utf8_lossy(bytes);
    let kind_of = |word: Option<&str>| KINDS.iter().position(|k| Some(*k) == word);
    let mut totals = [0usize; 3];
    for line in text.lines() {
        if let Some(kind) = kind_of(line.split_whitespace().next()) {
            totals[kind] += 1;
        }
    }
    let mut counts = [0usize; 3];
    for (line_index, line) in text.lines().enumerate() {
        let line_number = line_index + 1;
        let mut words = line.split_whitespace();
        let first = words.next();
        if matches!(first, Some("f" | "l")) {
            for corner in words {
                for (kind, index) in corner.split('/').enumerate().take(3) {
                    // Words that are not numbers are the OBJ reader's error to report.
                    let Ok(index) = index.parse::<i64>() else {
                        continue;
                    };
                    let fits = match index {
                        0 => false,
                        i if i > 0 => i.unsigned_abs() <= totals[kind] as u64,
                        i => i.unsigned_abs() <= counts[kind] as u64,
                    };
                    if !fits {
                        return Err(format!(
                            "{} (line {line_number}): index {index} refers to no `{}` ({} in the file, {} before this line)",
                            first.unwrap_or_default(),
                            KINDS[kind],
                            totals[kind],
                            counts[kind]
                        ));
                    }
                }
            }
            continue;
        }
        let Some(kind) = kind_of(first) else {
            continue;
        };
        counts[kind] += 1;
        let (what, limit, take) = match kind {
            0 => ("position", limits::MAX_COORDINATE, 3),
            1 => ("texture coordinate", f64::INFINITY, 2),
            _ => ("normal", f64::INFINITY, 3),
        };
        for word in words.take(take) {
            let Ok(value) = word.parse::<f64>() else {
                continue;
            };
            let single = f64::from(value as f32);
            if !(single.is_finite() && single.abs() <= limit) {
                let bound = if limit.is_finite() {
                    format!(" and within ±{limit:e}")
                } else {
                    String::new()
                };
                return Err(format!(
                    "{} {} (line {line_number}): the {what} component {} must be finite{bound}",
                    KINDS[kind],
                    counts[kind],
                    limits::echo(word),
                ));
            }
        }
    }
    Ok(())
}

/// An indexed triangle mesh in world space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<DVec3>,
    /// Vertex normals (empty: flat shading).
    pub normals: Vec<DVec3>,
    /// Vertex texture coordinates (empty: each triangle gets (0,0), (1,0), (1,1)).
    pub uvs: Vec<DVec2>,
    /// Vertex indices, three per triangle.
    pub triangles: Vec<[u32; 3]>,
}

impl Mesh {
    /// The surface area, and the area the triangles' texture coordinates cover in the uv plane
    /// (each triangle's whatever its winding; ½ per triangle without coordinates, as shading
    /// gives each triangle (0,0), (1,0), (1,1)).
    #[must_use]
    pub fn surface_and_uv_area(&self) -> (f64, f64) {
        let (mut surface, mut uv) = (0.0, 0.0);
        for &[a, b, c] in &self.triangles {
            let [a, b, c] = [a, b, c].map(|i| i as usize);
            let p = &self.positions;
            surface += 0.5 * (p[b] - p[a]).cross(p[c] - p[a]).length();
            uv += if self.uvs.is_empty() {
                0.5
            } else {
                let t = &self.uvs;
                0.5 * (t[b] - t[a]).perp_dot(t[c] - t[a]).abs()
            };
        }
        (surface, uv)
    }

    /// Loads every model of an OBJ file into one mesh. The file must be a regular file of at
    /// most [`limits::MAX_MESH_FILE_BYTES`]; `mtllib` statements are ignored (no other file is
    /// opened).
    ///
    /// # Errors
    /// [`TracerError::Asset`] naming the file when it cannot be read or parsed, has no
    /// triangles, or has a value out of range (naming the `v`, `vn` or `vt` statement by its
    /// OBJ index, counted from 1 as faces count them, and its line).
    pub fn load_obj(path: &Path) -> Result<Self, TracerError> {
        let bytes = limits::read_file(path, limits::MAX_MESH_FILE_BYTES).map_err(|problem| {
            TracerError::Asset {
                path: path.to_path_buf(),
                problem,
            }
        })?;
        Self::from_obj_bytes(&bytes, path)
    }

    /// Parses OBJ text, as [`Mesh::load_obj`] does once the file is read; `path` names it in
    /// errors.
    ///
    /// # Errors
    /// As [`Mesh::load_obj`].
    pub fn from_obj_bytes(bytes: &[u8], path: &Path) -> Result<Self, TracerError> {
        let asset_error = |problem: String| TracerError::Asset {
            path: path.to_path_buf(),
            problem,
        };
        check_obj_values(bytes).map_err(asset_error)?;
        let (models, _materials) = tobj::load_obj_buf(
            &mut std::io::Cursor::new(bytes),
            &tobj::GPU_LOAD_OPTIONS,
            |_| Err(tobj::LoadError::OpenFileFailed),
        )
        .map_err(|e| asset_error(e.to_string()))?;
        let mut mesh = Self::default();
        let mut with_normals = true;
        let mut with_uvs = true;
        for model in &models {
            let m = &model.mesh;
            with_normals &= !m.normals.is_empty();
            with_uvs &= !m.texcoords.is_empty();
        }
        for model in &models {
            let m = &model.mesh;
            let base = mesh.positions.len();
            mesh.positions.extend(
                m.positions
                    .chunks_exact(3)
                    .map(|p| DVec3::new(p[0].into(), p[1].into(), p[2].into())),
            );
            if with_normals {
                mesh.normals.extend(
                    m.normals
                        .chunks_exact(3)
                        .map(|n| DVec3::new(n[0].into(), n[1].into(), n[2].into())),
                );
            }
            if with_uvs {
                mesh.uvs.extend(
                    m.texcoords
                        .chunks_exact(2)
                        .map(|t| DVec2::new(t[0].into(), t[1].into())),
                );
            }
            let Ok(base) = u32::try_from(base) else {
                return Err(asset_error("more than 2³² vertices".into()));
            };
            for tri in m.indices.chunks_exact(3) {
                let corner = |i: u32| base.saturating_add(i);
                mesh.triangles
                    .push([corner(tri[0]), corner(tri[1]), corner(tri[2])]);
            }
        }
        mesh.validate().map_err(asset_error)?;
        Ok(mesh)
    }

    /// Checks that indices are in range, attributes match the positions, values are finite and
    /// positions within [`limits::MAX_COORDINATE`].
    ///
    /// # Errors
    /// A description of the first problem found.
    pub fn validate(&self) -> Result<(), String> {
        if self.triangles.is_empty() {
            return Err("the mesh has no triangles".into());
        }
        let n = self.positions.len();
        if !self.normals.is_empty() && self.normals.len() != n {
            return Err(format!("{} normals for {n} positions", self.normals.len()));
        }
        if !self.uvs.is_empty() && self.uvs.len() != n {
            return Err(format!(
                "{} texture coordinates for {n} positions",
                self.uvs.len()
            ));
        }
        if let Some(i) = self
            .positions
            .iter()
            .position(|p| !(p.is_finite() && p.abs().max_element() <= limits::MAX_COORDINATE))
        {
            return Err(format!(
                "vertex {i} at {} is not finite or beyond the coordinate limit {:e}",
                limits::vector(self.positions[i]),
                limits::MAX_COORDINATE
            ));
        }
        if let Some(i) = self.normals.iter().position(|n| !n.is_finite()) {
            return Err(format!("the normal of vertex {i} is not finite"));
        }
        if let Some(i) = self.uvs.iter().position(|t| !t.is_finite()) {
            return Err(format!(
                "the texture coordinates of vertex {i} are not finite"
            ));
        }
        if let Some(t) = self
            .triangles
            .iter()
            .position(|t| t.iter().any(|&i| i as usize >= n))
        {
            return Err(format!("triangle {t} indexes past the {n} vertices"));
        }
        Ok(())
    }

    /// The mesh moved by `transform` (normals by its inverse transpose).
    #[must_use]
    pub fn transformed(mut self, transform: &DAffine3) -> Self {
        let normal_matrix: DMat3 = transform.matrix3.inverse().transpose();
        for p in &mut self.positions {
            *p = transform.transform_point3(*p);
        }
        for n in &mut self.normals {
            *n = (normal_matrix * *n).normalize_or_zero();
        }
        if transform.matrix3.determinant() < 0.0 {
            for t in &mut self.triangles {
                t.swap(1, 2);
            }
        }
        self
    }

    /// The three corners of triangle `index`.
    #[must_use]
    pub fn corners(&self, index: usize) -> [DVec3; 3] {
        self.triangles[index].map(|i| self.positions[i as usize])
    }

    /// The ray parameter in (t_min, t_max) where the ray meets triangle `index`, with the
    /// barycentric coordinates (b1, b2) of the hit (Möller–Trumbore).
    #[must_use]
    pub fn intersect(
        &self,
        index: usize,
        ray: &Ray,
        t_min: f64,
        t_max: f64,
    ) -> Option<(f64, f64, f64)> {
        let [p0, p1, p2] = self.corners(index);
        let e1 = p1 - p0;
        let e2 = p2 - p0;
        let pvec = ray.direction.cross(e2);
        let det = e1.dot(pvec);
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let inv = 1.0 / det;
        let tvec = ray.origin - p0;
        let b1 = tvec.dot(pvec) * inv;
        if !(0.0..=1.0).contains(&b1) {
            return None;
        }
        let qvec = tvec.cross(e1);
        let b2 = ray.direction.dot(qvec) * inv;
        if !(b2 >= 0.0 && b1 + b2 <= 1.0) {
            return None;
        }
        let t = e2.dot(qvec) * inv;
        (t > t_min && t < t_max).then_some((t, b1, b2))
    }

    /// The texture coordinates of triangle `index`'s corners.
    fn corner_uvs(&self, index: usize) -> [DVec2; 3] {
        if self.uvs.is_empty() {
            [DVec2::ZERO, DVec2::X, DVec2::ONE]
        } else {
            self.triangles[index].map(|i| self.uvs[i as usize])
        }
    }

    /// The hit on triangle `index` at barycentrics (b1, b2): ∂p/∂u, ∂p/∂v solve
    /// [Δp₁ Δp₂] = [∂p/∂u ∂p/∂v]·[Δuv₁ Δuv₂] (pbrt-v4, "Triangle"); a triangle with degenerate
    /// texture coordinates gets an arbitrary tangent frame.
    #[must_use]
    pub fn surface(&self, index: usize, t: f64, b1: f64, b2: f64) -> SurfaceHit {
        let [p0, p1, p2] = self.corners(index);
        let [uv0, uv1, uv2] = self.corner_uvs(index);
        let b0 = 1.0 - b1 - b2;
        let geometric_normal = (p1 - p0).cross(p2 - p0).normalize();
        let (duv1, duv2) = (uv1 - uv0, uv2 - uv0);
        let (dp1, dp2) = (p1 - p0, p2 - p0);
        let det = duv1.perp_dot(duv2);
        let (dpdu, dpdv) = if det.abs() > 1e-14 * duv1.length() * duv2.length() && det != 0.0 {
            (
                (duv2.y * dp1 - duv1.y * dp2) / det,
                (duv1.x * dp2 - duv2.x * dp1) / det,
            )
        } else {
            glint_brdf::frame::orthonormal_basis(geometric_normal)
        };
        let shading_normal = if self.normals.is_empty() {
            geometric_normal
        } else {
            let [n0, n1, n2] = self.triangles[index].map(|i| self.normals[i as usize]);
            let n = (b0 * n0 + b1 * n1 + b2 * n2).normalize_or_zero();
            if n == DVec3::ZERO {
                geometric_normal
            } else if n.dot(geometric_normal) < 0.0 {
                -n
            } else {
                n
            }
        };
        SurfaceHit {
            t,
            point: b0 * p0 + b1 * p1 + b2 * p2,
            geometric_normal,
            shading_normal,
            uv: b0 * uv0 + b1 * uv1 + b2 * uv2,
            dpdu,
            dpdv,
        }
    }
}

impl Mesh {
    /// (∂n/∂u, ∂n/∂v) of the unit shading normal of triangle `index` at `point` (a point of the
    /// triangle): the derivatives of the normalized barycentric interpolation of the vertex
    /// normals, oriented as [`Mesh::surface`] orients the normal. Zero for flat shading (no
    /// vertex normals) and for degenerate texture coordinates or corners: the normal's jumps
    /// across edges are not seen (see `crate::differentials`).
    #[must_use]
    pub fn shading_normal_derivatives(&self, index: usize, point: DVec3) -> (DVec3, DVec3) {
        let none = (DVec3::ZERO, DVec3::ZERO);
        if self.normals.is_empty() {
            return none;
        }
        let [p0, p1, p2] = self.corners(index);
        let [uv0, uv1, uv2] = self.corner_uvs(index);
        let [n0, n1, n2] = self.triangles[index].map(|i| self.normals[i as usize]);
        let (duv1, duv2) = (uv1 - uv0, uv2 - uv0);
        let det = duv1.perp_dot(duv2);
        if !(det.abs() > 1e-14 * duv1.length() * duv2.length() && det != 0.0) {
            return none;
        }
        // The point's barycentrics (b1, b2) by least squares on the edges Δp₁, Δp₂.
        let (dp1, dp2, d) = (p1 - p0, p2 - p0, point - p0);
        let (a, b, c) = (dp1.dot(dp1), dp1.dot(dp2), dp2.dot(dp2));
        let det_p = a * c - b * b;
        if !(det_p > 0.0 && det_p.is_finite()) {
            return none;
        }
        let (r, s) = (dp1.dot(d), dp2.dot(d));
        let (b1, b2) = ((c * r - b * s) / det_p, (a * s - b * r) / det_p);
        let (dn1, dn2) = (n1 - n0, n2 - n0);
        let interpolated = n0 + b1 * dn1 + b2 * dn2;
        let length = interpolated.length();
        if !(length > 0.0 && length.is_finite()) {
            return none;
        }
        let n = interpolated / length;
        // (b1, b2) = [Δuv₁ Δuv₂]⁻¹ (uv − uv₀): ∂b1/∂u = Δv₂/det, ∂b2/∂u = −Δv₁/det, etc.
        let raw_u = (duv2.y * dn1 - duv1.y * dn2) / det;
        let raw_v = (duv1.x * dn2 - duv2.x * dn1) / det;
        // ∂(ñ/|ñ|) = (∂ñ − n (n·∂ñ)) / |ñ|, negated where `surface` flips n to the front side.
        let sign = if n.dot(dp1.cross(dp2)) < 0.0 {
            -1.0
        } else {
            1.0
        };
        let project = |dn: DVec3| sign * (dn - n * n.dot(dn)) / length;
        let derivatives = (project(raw_u), project(raw_v));
        if derivatives.0.is_finite() && derivatives.1.is_finite() {
            derivatives
        } else {
            none
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> Mesh {
        Mesh {
            positions: vec![
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(2.0, 0.0, 0.0),
                DVec3::new(2.0, 0.5, -1.0),
                DVec3::new(0.0, 0.5, -1.0),
            ],
            normals: vec![],
            uvs: vec![
                DVec2::new(0.0, 0.0),
                DVec2::new(3.0, 0.0),
                DVec2::new(3.0, 1.0),
                DVec2::new(0.0, 1.0),
            ],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        }
    }

    #[test]
    fn triangle_tangents_match_finite_differences_of_the_uv_map() {
        let mesh = quad();
        // On this planar quad p is affine in (u, v): p = p0 + u·(2/3, 0, 0) + v·(0, 0.5, −1).
        let expected_dpdu = DVec3::new(2.0 / 3.0, 0.0, 0.0);
        let expected_dpdv = DVec3::new(0.0, 0.5, -1.0);
        for (i, target) in [DVec3::new(1.5, 0.1, -0.2), DVec3::new(0.3, 0.4, -0.8)]
            .into_iter()
            .enumerate()
        {
            let origin = DVec3::new(0.7, 3.0, 1.0);
            let ray = Ray {
                origin,
                direction: (target - origin).normalize(),
            };
            let hit = (0..2)
                .find_map(|k| {
                    mesh.intersect(k, &ray, 0.0, f64::INFINITY)
                        .map(|(t, b1, b2)| mesh.surface(k, t, b1, b2))
                })
                .unwrap_or_else(|| panic!("ray {i} misses"));
            assert!((hit.point - target).length() < 1e-12);
            assert!((hit.dpdu - expected_dpdu).length() < 1e-12);
            assert!((hit.dpdv - expected_dpdv).length() < 1e-12);
            let p_from_uv = DVec3::ZERO + hit.uv.x * expected_dpdu + hit.uv.y * expected_dpdv;
            assert!((p_from_uv - hit.point).length() < 1e-12);
        }
    }

    #[test]
    fn bad_meshes_are_rejected() {
        let mut mesh = quad();
        mesh.triangles.push([0, 1, 9]);
        assert!(mesh.validate().unwrap_err().contains("triangle 2"));
        assert!(Mesh::default().validate().is_err());
        let missing = Mesh::load_obj(Path::new("/nonexistent/mesh.obj"));
        assert!(matches!(missing, Err(TracerError::Asset { .. })));
    }

    /// Values an OBJ cannot use are errors naming the file, the statement by its OBJ index and
    /// line: NaN or infinite normals and texture coordinates, positions beyond the coordinate
    /// limit (as the single-precision numbers the reader makes of them).
    #[test]
    fn bad_obj_values_are_named_by_file_and_index() {
        let good = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\nvn 0 0 1\nvn 0 0 1\nf 1/1/1 2/2/2 3/3/3\n";
        assert!(Mesh::from_obj_bytes(good.as_bytes(), Path::new("good.obj")).is_ok());
        for (from, to, words) in [
            (
                "vn 0 0 1\nvn 0 0 1\nf",
                "vn 0 0 1\nvn 0 nan 1\nf",
                "vn 3 (line 9)",
            ),
            ("vt 1 0\n", "vt inf 0\n", "vt 2 (line 5)"),
            ("v 1 0 0\n", "v 3e38 0 0\n", "v 2 (line 2)"),
            ("v 1 0 0\n", "v 1 1e39 0\n", "v 2 (line 2)"),
            ("v 1 0 0\n", "v 1 0 -2e15\n", "within ±1e15"),
        ] {
            let text = good.replacen(from, to, 1);
            let error = Mesh::from_obj_bytes(text.as_bytes(), Path::new("bad.obj")).unwrap_err();
            let message = error.to_string();
            assert!(message.contains("bad.obj"), "{message}");
            assert!(message.contains(words), "{to}: `{message}` lacks `{words}`");
        }
        // Face indices tobj would overflow on, and 0, are errors naming the line.
        for (face, words) in [
            ("f 1/1/-9 2/2/2 3/3/3", "index -9 refers to no `vn`"),
            (
                "f 1/1/1 2/9223372036854775807/2 3/3/3",
                "index 9223372036854775807",
            ),
            ("f 0 2 3", "index 0"),
            ("f 1 2 4", "index 4 refers to no `v` (3 in the file"),
        ] {
            let text = good.replacen("f 1/1/1 2/2/2 3/3/3", face, 1);
            let message = Mesh::from_obj_bytes(text.as_bytes(), Path::new("f.obj"))
                .unwrap_err()
                .to_string();
            assert!(
                message.contains("f (line 10)") && message.contains(words),
                "{message}"
            );
        }
        // A material library is never opened (here a device that would never end).
        let with_library = format!("mtllib /dev/zero\n{good}");
        assert!(Mesh::from_obj_bytes(with_library.as_bytes(), Path::new("m.obj")).is_ok());
        // A file that is no regular file is refused before it is read.
        if Path::new("/dev/zero").exists() {
            let zero = Mesh::load_obj(Path::new("/dev/zero"))
                .unwrap_err()
                .to_string();
            assert!(zero.contains("not a regular file"), "{zero}");
        }
    }

    #[test]
    fn mirroring_transforms_keep_outward_winding() {
        let mesh = quad();
        let n_before = (mesh.positions[1] - mesh.positions[0])
            .cross(mesh.positions[2] - mesh.positions[0])
            .normalize();
        let mirror = DAffine3::from_scale(DVec3::new(-1.0, 1.0, 1.0));
        let moved = mesh.transformed(&mirror);
        let [p0, p1, p2] = moved.corners(0);
        let n_after = (p1 - p0).cross(p2 - p0).normalize();
        assert!((n_after - DVec3::new(-n_before.x, n_before.y, n_before.z)).length() < 1e-12);
    }
}
