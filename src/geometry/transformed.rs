//! Objects placed with a transform. Most shapes are simply rebuilt in place (a rotated,
//! uniformly scaled sphere is still a sphere; any affine image of a quad, polygon or
//! triangle is one too; meshes move their vertices). Only spheres, cylinders and cones
//! under non-uniform scaling need the general route: the ray is carried into the
//! shape's own space, intersected there, and the result carried back.
//!
//! ```toml
//! [[sphere]]
//! center = [0, 0, 0]
//! radius = 1
//! transform = { scale = [2, 1, 1], rotate = [0, 0, 30], translate = [0, 1, -5] }
//! ```
//! Order: scale, then rotate about x, then y, then z (degrees), then translate.
//! Normals are carried by the inverse transpose of the linear part, which keeps them
//! perpendicular to the surface under non-uniform scaling.

use super::{Cone, Cylinder, Hit, Polygon, PolygonError, Quad, Shape, Sphere, Surface, Triangle};
use crate::math::{Aabb, Ray, Vec3};
use glam::{Affine3A, Mat3, Mat3A, Vec3A};

/// The affine map `translate · Rz · Ry · Rx · scale`, angles in degrees.
pub fn affine(translate: Vec3, rotate_degrees: Vec3, scale: Vec3) -> Affine3A {
    let r = Mat3::from_rotation_z(rotate_degrees.z.to_radians())
        * Mat3::from_rotation_y(rotate_degrees.y.to_radians())
        * Mat3::from_rotation_x(rotate_degrees.x.to_radians());
    Affine3A::from_mat3_translation(r * Mat3::from_diagonal(scale), translate)
}

/// A shape in its own space, with the maps to and from the world.
#[derive(Clone, Debug, PartialEq)]
pub struct Transformed {
    shape: Shape,
    to_object: Affine3A,
    to_world: Affine3A,
    normal_to_world: Mat3A,
    bounds: Aabb,
}

/// The uniform scale factor of `m`'s linear part, if it is a rotation times a scale.
fn similarity_scale(m: &Affine3A) -> Option<f32> {
    let g = m.matrix3.transpose() * m.matrix3; // = s² I for a similarity
    let s2 = g.x_axis.x;
    let tol = 1e-5 * s2;
    let off = [g.x_axis.y, g.x_axis.z, g.y_axis.z].iter().all(|v| v.abs() <= tol);
    let diag = (g.y_axis.y - s2).abs() <= tol && (g.z_axis.z - s2).abs() <= tol;
    (off && diag && s2 > 0.0).then(|| s2.sqrt())
}

/// `shape` moved by `m`. Fails only for a polygon the map makes degenerate.
pub fn apply(shape: Shape, m: &Affine3A) -> Result<Shape, PolygonError> {
    let p = |v: Vec3| m.transform_point3(v);
    let v = |d: Vec3| m.transform_vector3(d);
    let similar = similarity_scale(m);
    Ok(match (shape, similar) {
        (Shape::Quad(q), _) => Quad::new(p(q.corner), v(q.edge_u), v(q.edge_v)).into(),
        (Shape::Polygon(g), _) => Polygon::new(g.vertices().iter().map(|&x| p(x)).collect())?.into(),
        (Shape::Triangle(t), _) => Triangle::new(p(t.v0), p(t.v1), p(t.v2)).into(),
        (Shape::Mesh(mesh), _) => {
            let mut mesh = std::sync::Arc::unwrap_or_clone(mesh);
            mesh.transform(m);
            mesh.into()
        }
        (Shape::Sphere(s), Some(k)) => Sphere::new(p(s.center), s.radius * k).into(),
        (Shape::Cylinder(c), Some(k)) => Cylinder::new(p(c.base), v(c.axis), c.radius * k, c.height * k, c.caps).into(),
        (Shape::Cone(c), Some(k)) => {
            Cone::truncated(p(c.base), v(c.axis), c.radius * k, c.top_radius * k, c.height * k, c.cap, c.top_cap).into()
        }
        (Shape::Transformed(t), _) => {
            let to_world = *m * t.to_world;
            Shape::Transformed(Box::new(Transformed::new(t.shape, to_world)))
        }
        (shape, _) => Shape::Transformed(Box::new(Transformed::new(shape, *m))),
    })
}

/// Mesh `mesh` placed again by `m`, its triangles shared rather than copied: the
/// acceleration structure keeps one tree per mesh, and rays are carried into the mesh's
/// own space, so a thousand instances cost a thousand transforms, not a thousand meshes.
pub fn instance(mesh: &std::sync::Arc<super::Mesh>, m: &Affine3A) -> Shape {
    Shape::Transformed(Box::new(Transformed::new(Shape::Mesh(mesh.clone()), *m)))
}

impl Transformed {
    fn new(shape: Shape, to_world: Affine3A) -> Self {
        let to_object = to_world.inverse();
        let b = shape.bounds();
        let corners = (0..8).map(|i| {
            let c = Vec3::new(
                if i & 1 == 0 { b.min.x } else { b.max.x },
                if i & 2 == 0 { b.min.y } else { b.max.y },
                if i & 4 == 0 { b.min.z } else { b.max.z },
            );
            to_world.transform_point3(c)
        });
        let bounds = Aabb::from_points(corners);
        Transformed { shape, to_object, to_world, normal_to_world: to_world.matrix3.inverse().transpose(), bounds }
    }

    /// The ray in object space (unit direction) and the object-space length of one world unit along it.
    #[inline]
    fn object_ray(&self, ray: &Ray) -> (Ray, f32) {
        let d = self.to_object.transform_vector3(ray.dir);
        let len = d.length();
        (Ray { origin: self.to_object.transform_point3(ray.origin), dir: d / len }, len)
    }

    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        self.intersect_with(ray, t_min, t_max, |r, t_min, t_max| self.shape.intersect(r, t_min, t_max))
    }

    /// The shape placed here when it is a mesh (an instance), for the acceleration
    /// structure to find the mesh's own tree.
    pub fn mesh(&self) -> Option<&std::sync::Arc<super::Mesh>> {
        match &self.shape {
            Shape::Mesh(m) => Some(m),
            _ => None,
        }
    }

    /// `hit(object-space ray, t_min, t_max)`, the bounds and the answer's distance
    /// carried between the spaces: how the shape's own tree is asked.
    #[inline]
    pub fn intersect_with(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        hit: impl FnOnce(&Ray, f32, f32) -> Option<Hit>,
    ) -> Option<Hit> {
        let (r, len) = self.object_ray(ray);
        hit(&r, t_min * len, t_max * len).map(|h| Hit { t: h.t / len, ..h })
    }

    /// Whether `blocked(object-space ray, t_max)` says the segment to `t_max` is blocked.
    #[inline]
    pub fn blocks_with(&self, ray: &Ray, t_max: f32, blocked: impl FnOnce(&Ray, f32) -> bool) -> bool {
        let (r, len) = self.object_ray(ray);
        blocked(&r, t_max * len)
    }

    pub fn surface(&self, ray: &Ray, hit: &Hit) -> Surface {
        self.surface_uv(ray, hit, true)
    }

    /// The surface, with `uv` zero unless asked for (see [`Shape::surface_uv`]).
    pub fn surface_uv(&self, ray: &Ray, hit: &Hit, uv: bool) -> Surface {
        let (r, len) = self.object_ray(ray);
        let s = self.shape.surface_uv(&r, &Hit { t: hit.t * len, ..*hit }, uv);
        Surface {
            point: self.to_world.transform_point3(s.point),
            normal: (self.normal_to_world * Vec3A::from(s.normal)).normalize_or_zero().into(),
            uv: s.uv,
        }
    }

    pub fn bounds(&self) -> Aabb {
        self.bounds
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rigid_and_uniform_maps_rebuild_the_shape() {
        let m = affine(Vec3::new(1.0, 2.0, 3.0), Vec3::new(0.0, 90.0, 0.0), Vec3::splat(2.0));
        match apply(Sphere::new(Vec3::X, 1.0).into(), &m).unwrap() {
            Shape::Sphere(s) => {
                assert!((s.center - Vec3::new(1.0, 2.0, 1.0)).length() < 1e-5, "{}", s.center);
                assert!((s.radius - 2.0).abs() < 1e-6);
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn stretched_sphere_is_an_ellipsoid_with_correct_normals() {
        // x stretched by 3: an ellipsoid with semi-axes (3, 1, 1).
        let e = apply(Sphere::new(Vec3::ZERO, 1.0).into(), &affine(Vec3::ZERO, Vec3::ZERO, Vec3::new(3.0, 1.0, 1.0)))
            .unwrap();
        assert!(matches!(e, Shape::Transformed(_)));
        let along_x = Ray::new(Vec3::new(10.0, 0.0, 0.0), Vec3::NEG_X);
        let h = e.intersect(&along_x, 0.0, f32::INFINITY).unwrap();
        assert!((h.t - 7.0).abs() < 1e-4, "{}", h.t);
        let down = Ray::new(Vec3::new(0.0, 10.0, 0.0), Vec3::NEG_Y);
        assert!((e.intersect(&down, 0.0, f32::INFINITY).unwrap().t - 9.0).abs() < 1e-4);
        // At (3/√2, 1/√2, 0) on the ellipse x²/9 + y² = 1 the normal is ∝ (x/9, y): (1, 3) normalised.
        let p = Vec3::new(3.0 / 2f32.sqrt(), 1.0 / 2f32.sqrt(), 0.0);
        let ray = Ray::new(p + Vec3::new(1.0, 3.0, 0.0), -Vec3::new(1.0, 3.0, 0.0));
        let s = e.surface(&ray, &e.intersect(&ray, 0.0, f32::INFINITY).unwrap());
        assert!((s.point - p).length() < 1e-4, "{}", s.point);
        assert!((s.normal - Vec3::new(1.0, 3.0, 0.0).normalize()).length() < 1e-4, "{}", s.normal);
        let b = e.bounds();
        assert!(b.min.x <= -3.0 && b.max.x >= 3.0 && b.max.y >= 1.0);
        assert!(e.intersect(&along_x, 0.0, 6.9).is_none(), "t_max is in world units");
    }

    #[test]
    fn rotation_order_is_x_then_y_then_z() {
        let m = affine(Vec3::ZERO, Vec3::new(90.0, 90.0, 0.0), Vec3::ONE);
        // +y → (x by 90°) +z → (y by 90°) +x
        assert!((m.transform_vector3(Vec3::Y) - Vec3::X).length() < 1e-6);
    }
}
