//! Triangle meshes: shared vertices, optional per-vertex normals (smooth shading) and
//! texture coordinates.
//!
//! ```toml
//! [[mesh]]
//! file = "bunny.obj"
//! smooth = true   # interpolate vertex normals (computed when the file has none)
//! material = "clay"
//! transform = { scale = 10, rotate = [0, 30, 0], translate = [0, -1, -5] }
//!
//! [[mesh]]   # or the data inline, as `whitted convert` writes NFF polygons
//! positions = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
//! normals = [[0, 0, 1], [0, 0, 1], [0, 0, 1]]   # optional: one per position
//! triangles = [[0, 1, 2]]                       # indices into positions, from 0
//! smooth = true
//! material = "clay"
//! ```

use super::{Hit, Surface, part};
use crate::math::lanes::{Lanes, V3, cross, dot, sub};
use crate::math::{Aabb, Ray, Vec2, Vec3};

#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    positions: Vec<Vec3>,
    /// One per vertex, or empty for flat shading.
    normals: Vec<Vec3>,
    /// One per vertex, or empty (texture coordinates are then the barycentrics).
    uvs: Vec<Vec2>,
    triangles: Vec<[u32; 3]>,
    bounds: Aabb,
}

/// Why a mesh cannot be built; loaders add the file and line.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MeshError {
    #[error("the mesh has no triangles")]
    Empty,
    #[error("triangle {triangle} refers to vertex {index}, but there are only {count}")]
    BadIndex { triangle: usize, index: u32, count: usize },
    #[error("vertex {0} is not finite")]
    NonFinite(usize),
    #[error("{what} has {got} entries for {count} vertices")]
    Mismatch { what: &'static str, got: usize, count: usize },
}

/// Möller–Trumbore on a triangle given as a corner and two edges; returns (t, b1, b2).
/// Shared by the brute-force and BVH paths, so both find bit-identical hits.
#[inline(always)]
pub fn intersect_triangle(v0: Vec3, e1: Vec3, e2: Vec3, ray: &Ray, t_min: f32, t_max: f32) -> Option<(f32, f32, f32)> {
    let c = |v: Vec3| v.to_array();
    let (hit, t, b1, b2) = triangle_hits::<f32>(c(ray.origin), c(ray.dir), [c(v0), c(e1), c(e2)], t_min, t_max);
    hit.then_some((t, b1, b2))
}

/// Möller–Trumbore, lane by lane ([`Lanes`]: one triangle, or several against one ray):
/// a ray (origin `o`, direction `d`) against triangles given as corner and two edges
/// (`[v0, e1, e2]`). Whether it hits within `(t_min, t_max)`, and the distance and
/// barycentrics (b1 along `e1`, b2 along `e2`). The one triangle test, for every width.
#[inline(always)]
pub fn triangle_hits<L: Lanes>(o: V3<L>, d: V3<L>, [v0, e1, e2]: [V3<L>; 3], t_min: L, t_max: L) -> (L::Mask, L, L, L) {
    let p = cross(d, e2);
    let det = dot(e1, p);
    let inv = L::splat(1.0) / det;
    let s = sub(o, v0);
    let b1 = dot(s, p) * inv;
    let q = cross(s, e1);
    let b2 = dot(d, q) * inv;
    let t = dot(e2, q) * inv;
    // Not finite: a ray parallel to the plane, or a degenerate triangle (NaN fails too).
    let (zero, one) = (L::splat(0.0), L::splat(1.0));
    let ok = inv.abs().lt(L::splat(f32::INFINITY))
        & b1.ge(zero)
        & b1.le(one)
        & b2.ge(zero)
        & (b1 + b2).le(one)
        & t.gt(t_min)
        & t.lt(t_max);
    (ok, t, b1, b2)
}

impl Mesh {
    /// `smooth`: keep `normals` (or compute area-weighted ones when empty); otherwise
    /// drop them and shade flat.
    pub fn new(
        positions: Vec<Vec3>,
        normals: Vec<Vec3>,
        uvs: Vec<Vec2>,
        triangles: Vec<[u32; 3]>,
        smooth: bool,
    ) -> Result<Mesh, MeshError> {
        if triangles.is_empty() {
            return Err(MeshError::Empty);
        }
        if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
            return Err(MeshError::NonFinite(i));
        }
        for (what, got) in [("normals", normals.len()), ("uvs", uvs.len())] {
            if got != 0 && got != positions.len() {
                return Err(MeshError::Mismatch { what, got, count: positions.len() });
            }
        }
        for (t, tri) in triangles.iter().enumerate() {
            if let Some(&index) = tri.iter().find(|&&i| i as usize >= positions.len()) {
                return Err(MeshError::BadIndex { triangle: t, index, count: positions.len() });
            }
        }
        let bounds = Aabb::from_points(positions.iter().copied());
        let mut mesh = Mesh { positions, normals, uvs, triangles, bounds };
        if !smooth {
            mesh.normals.clear();
        } else if mesh.normals.is_empty() || mesh.normals.iter().any(|n| !n.is_finite()) {
            mesh.normals = mesh.vertex_normals();
        }
        Ok(mesh)
    }

    /// Area-weighted average of the faces around each vertex.
    fn vertex_normals(&self) -> Vec<Vec3> {
        let mut n = vec![Vec3::ZERO; self.positions.len()];
        for &[a, b, c] in &self.triangles {
            let [pa, pb, pc] = [a, b, c].map(|i| self.positions[i as usize]);
            let face = (pb - pa).cross(pc - pa); // length = twice the area
            for i in [a, b, c] {
                n[i as usize] += face;
            }
        }
        n.into_iter().map(|v| v.normalize_or_zero()).collect()
    }

    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// Per-vertex normals; empty when shaded flat.
    pub fn normals(&self) -> &[Vec3] {
        &self.normals
    }

    /// Per-vertex texture coordinates; empty when the barycentrics serve instead.
    pub fn uvs(&self) -> &[Vec2] {
        &self.uvs
    }

    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    pub fn is_smooth(&self) -> bool {
        !self.normals.is_empty()
    }

    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Corners of triangle `i`.
    #[inline]
    pub fn corners(&self, i: usize) -> [Vec3; 3] {
        self.triangles[i].map(|v| self.positions[v as usize])
    }

    /// Applies an affine map to the mesh. Normals go through the inverse transpose of
    /// the linear part, so they stay perpendicular under non-uniform scaling; a map that
    /// mirrors (negative determinant) flips the winding to keep faces outward.
    pub fn transform(&mut self, m: &glam::Affine3A) {
        for p in &mut self.positions {
            *p = m.transform_point3(*p);
        }
        let normal_matrix = m.matrix3.inverse().transpose();
        for n in &mut self.normals {
            *n = (normal_matrix * glam::Vec3A::from(*n)).normalize_or_zero().into();
        }
        if m.matrix3.determinant() < 0.0 {
            for t in &mut self.triangles {
                t.swap(1, 2);
            }
        }
        self.bounds = Aabb::from_points(self.positions.iter().copied());
    }

    /// Tests every triangle (the `--accel none` path; the BVH path tests the same way).
    pub fn intersect(&self, ray: &Ray, t_min: f32, mut t_max: f32) -> Option<Hit> {
        let mut best = None;
        for i in 0..self.triangles.len() {
            let [v0, v1, v2] = self.corners(i);
            if let Some((t, b1, b2)) = intersect_triangle(v0, v1 - v0, v2 - v0, ray, t_min, t_max) {
                t_max = t;
                best = Some(Hit { t, uv: Vec2::new(b1, b2), part: part::SIDE, prim: i as u32 });
            }
        }
        best
    }

    /// Any triangle in the way; `None` when the segment is clear.
    pub fn occluded(&self, ray: &Ray, t_min: f32, t_max: f32) -> bool {
        (0..self.triangles.len()).any(|i| {
            let [v0, v1, v2] = self.corners(i);
            intersect_triangle(v0, v1 - v0, v2 - v0, ray, t_min, t_max).is_some()
        })
    }

    /// Shading normal interpolated from the vertices (kept on the geometric normal's
    /// side, so inside/outside stays right for refraction), or the face normal when flat.
    pub fn surface(&self, _ray: &Ray, hit: &Hit) -> Surface {
        let i = hit.prim as usize;
        let (b1, b2) = (hit.uv.x, hit.uv.y);
        let b0 = 1.0 - b1 - b2;
        let [a, b, c] = self.triangles[i];
        let [p0, p1, p2] = self.corners(i);
        let point = b0 * p0 + b1 * p1 + b2 * p2;
        let geometric = (p1 - p0).cross(p2 - p0).normalize_or_zero();
        let normal = if self.normals.is_empty() {
            geometric
        } else {
            let n = (b0 * self.normals[a as usize] + b1 * self.normals[b as usize] + b2 * self.normals[c as usize])
                .normalize_or_zero();
            if n == Vec3::ZERO {
                geometric
            } else if n.dot(geometric) < 0.0 {
                -n
            } else {
                n
            }
        };
        let uv = if self.uvs.is_empty() {
            hit.uv
        } else {
            b0 * self.uvs[a as usize] + b1 * self.uvs[b as usize] + b2 * self.uvs[c as usize]
        };
        Surface { point, normal, uv }
    }

    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Bytes held by the mesh's arrays.
    pub fn memory_bytes(&self) -> usize {
        self.positions.capacity() * 12
            + self.normals.capacity() * 12
            + self.uvs.capacity() * 8
            + self.triangles.capacity() * 12
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad_mesh(smooth: bool, normals: Vec<Vec3>) -> Result<Mesh, MeshError> {
        let p = vec![
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        ];
        Mesh::new(p, normals, vec![], vec![[0, 1, 2], [0, 2, 3]], smooth)
    }

    #[test]
    fn hits_the_nearer_triangle_and_reports_which() {
        let m = quad_mesh(false, vec![]).unwrap();
        let r = Ray::new(Vec3::new(-0.5, 0.5, 3.0), Vec3::NEG_Z);
        let h = m.intersect(&r, 0.0, f32::INFINITY).unwrap();
        assert_eq!(h.prim, 1);
        assert!((h.t - 3.0).abs() < 1e-6);
        assert_eq!(m.surface(&r, &h).normal, Vec3::Z);
        assert!(m.intersect(&r, 0.0, 2.0).is_none(), "t_max respected");
        assert!(m.occluded(&r, 0.0, 4.0) && !m.occluded(&r, 0.0, 2.0));
        let behind = Ray::new(Vec3::new(0.0, 0.0, 3.0), Vec3::Z);
        assert!(m.intersect(&behind, 0.0, f32::INFINITY).is_none());
    }

    #[test]
    fn smooth_normals_interpolate_and_flat_ones_do_not() {
        let tilted = vec![
            Vec3::new(-1.0, 0.0, 1.0).normalize(),
            Vec3::new(1.0, 0.0, 1.0).normalize(),
            Vec3::new(1.0, 0.0, 1.0).normalize(),
            Vec3::new(-1.0, 0.0, 1.0).normalize(),
        ];
        let smooth = quad_mesh(true, tilted.clone()).unwrap();
        let flat = quad_mesh(false, tilted).unwrap();
        let left = Ray::new(Vec3::new(-0.9, 0.5, 3.0), Vec3::NEG_Z);
        let right = Ray::new(Vec3::new(0.9, -0.5, 3.0), Vec3::NEG_Z);
        let n = |m: &Mesh, r: &Ray| m.surface(r, &m.intersect(r, 0.0, 10.0).unwrap()).normal;
        assert!(n(&smooth, &left).x < -0.5 && n(&smooth, &right).x > 0.5);
        assert_eq!(n(&flat, &left), Vec3::Z);
        assert_eq!(n(&flat, &right), Vec3::Z);
    }

    #[test]
    fn computed_normals_point_out_of_a_closed_shape() {
        // A tetrahedron wound outwards.
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        let m = Mesh::new(p, vec![], vec![], vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], true).unwrap();
        let r = Ray::new(Vec3::splat(2.0), -Vec3::ONE);
        let s = m.surface(&r, &m.intersect(&r, 0.0, 10.0).unwrap());
        assert!(s.normal.dot(Vec3::ONE) > 0.0, "{}", s.normal);
    }

    #[test]
    fn bad_meshes_are_refused() {
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
        assert_eq!(Mesh::new(p.clone(), vec![], vec![], vec![], true), Err(MeshError::Empty));
        assert_eq!(
            Mesh::new(p.clone(), vec![], vec![], vec![[0, 1, 3]], true),
            Err(MeshError::BadIndex { triangle: 0, index: 3, count: 3 })
        );
        let mut bad = p.clone();
        bad[1].y = f32::NAN;
        assert_eq!(Mesh::new(bad, vec![], vec![], vec![[0, 1, 2]], true), Err(MeshError::NonFinite(1)));
        assert!(matches!(
            Mesh::new(p, vec![Vec3::Z], vec![], vec![[0, 1, 2]], true),
            Err(MeshError::Mismatch { what: "normals", .. })
        ));
    }

    #[test]
    fn transforms_move_points_and_keep_normals_perpendicular() {
        let mut m = quad_mesh(true, vec![]).unwrap();
        // Squash x, tilt about y: the normal must stay perpendicular to the surface.
        let a = glam::Affine3A::from_rotation_y(0.5) * glam::Affine3A::from_scale(Vec3::new(3.0, 1.0, 1.0));
        m.transform(&a);
        let [p0, p1, p2] = m.corners(0);
        let face = (p1 - p0).cross(p2 - p0).normalize();
        let r = Ray::new(Vec3::new(0.1, 0.1, 0.0) + face * 5.0, -face);
        let s = m.surface(&r, &m.intersect(&r, 0.0, 10.0).unwrap());
        assert!((s.normal - face).length() < 1e-5, "{} vs {face}", s.normal);
        // A mirroring map keeps the face normal pointing the way the normals do.
        let mut m = quad_mesh(true, vec![]).unwrap();
        m.transform(&glam::Affine3A::from_scale(Vec3::new(1.0, 1.0, -1.0)));
        let [p0, p1, p2] = m.corners(0);
        assert!((p1 - p0).cross(p2 - p0).z < 0.0);
    }
}
