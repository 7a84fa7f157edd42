use super::{Hit, Surface, part};
use crate::math::{Aabb, Ray, Vec2, Vec3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    pub v0: Vec3,
    pub v1: Vec3,
    pub v2: Vec3,
}

impl Triangle {
    pub fn new(v0: Vec3, v1: Vec3, v2: Vec3) -> Self {
        Triangle { v0, v1, v2 }
    }

    /// Möller–Trumbore, two-sided; `Hit::uv` holds the barycentrics (b1, b2) of v1 and
    /// v2. Edges and vertices are inclusive. Rays within ~1e-7 rad of the plane, and
    /// degenerate triangles, miss.
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        let e1 = self.v1 - self.v0;
        let e2 = self.v2 - self.v0;
        let p = ray.dir.cross(e2);
        let det = e1.dot(p);
        // Relative test (det = -dir · (e1 × e2) scales with the edges): an absolute
        // epsilon would reject small triangles and accept skimming rays on big ones.
        let transversal = det * det > 1e-14 * e1.length_squared() * e2.length_squared();
        if !transversal {
            return None;
        }
        let (t, b1, b2) = super::intersect_triangle(self.v0, e1, e2, ray, t_min, t_max)?;
        Some(Hit { prim: 0, t, uv: Vec2::new(b1, b2), part: part::SIDE })
    }

    pub fn surface(&self, _ray: &Ray, hit: &Hit) -> Surface {
        let (b1, b2) = (hit.uv.x, hit.uv.y);
        // From the barycentrics rather than `origin + t dir`: exactly in the triangle.
        let point = (1.0 - b1 - b2) * self.v0 + b1 * self.v1 + b2 * self.v2;
        let normal = (self.v1 - self.v0).cross(self.v2 - self.v0).normalize_or_zero();
        Surface { point, normal, uv: hit.uv }
    }

    pub fn bounds(&self) -> Aabb {
        Aabb::from_points([self.v0, self.v1, self.v2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::test_util::{Rng, assert_close, assert_vec_close};
    use crate::math::{reflect, surface_offset};

    /// In the plane z = -5, counter-clockwise seen from +z.
    fn tri() -> Triangle {
        Triangle::new(Vec3::new(-1.0, -1.0, -5.0), Vec3::new(1.0, -1.0, -5.0), Vec3::new(0.0, 1.0, -5.0))
    }

    fn ray(o: [f32; 3], d: [f32; 3]) -> Ray {
        Ray::new(Vec3::from(o), Vec3::from(d))
    }

    #[test]
    fn hit_from_front() {
        let tr = tri();
        let r = ray([0.0, 0.0, 0.0], [0.0, 0.0, -1.0]);
        let h = tr.intersect(&r, 0.0, f32::INFINITY).unwrap();
        assert_close(h.t, 5.0, 1e-5);
        // (0, 0) = 0.25 v0 + 0.25 v1 + 0.5 v2.
        assert_close(h.uv.x, 0.25, 1e-6);
        assert_close(h.uv.y, 0.5, 1e-6);
        let s = tr.surface(&r, &h);
        assert_vec_close(s.normal, Vec3::Z, 1e-6);
        assert_vec_close(s.point, Vec3::new(0.0, 0.0, -5.0), 1e-6);
    }

    #[test]
    fn hit_from_back_keeps_winding_normal() {
        let tr = tri();
        let r = ray([0.0, -0.5, -9.0], [0.0, 0.0, 1.0]);
        let h = tr.intersect(&r, 0.0, f32::INFINITY).unwrap();
        assert_close(h.t, 4.0, 1e-5);
        assert_vec_close(tr.surface(&r, &h).normal, Vec3::Z, 1e-6);
    }

    #[test]
    fn slanted_hit() {
        let tr = Triangle::new(Vec3::new(0.0, 0.0, -2.0), Vec3::new(2.0, 0.0, -4.0), Vec3::new(0.0, 2.0, -2.0));
        let target = 0.2 * tr.v0 + 0.5 * tr.v1 + 0.3 * tr.v2;
        let origin = Vec3::new(1.0, 1.0, 1.0);
        let r = Ray::new(origin, target - origin);
        let h = tr.intersect(&r, 0.0, f32::INFINITY).unwrap();
        assert_close(h.t, (target - origin).length(), 1e-5);
        assert_close(h.uv.x, 0.5, 1e-5);
        assert_close(h.uv.y, 0.3, 1e-5);
        assert_vec_close(tr.surface(&r, &h).normal, Vec3::new(1.0, 0.0, 1.0).normalize(), 1e-6);
    }

    #[test]
    fn grazing_edges_are_inclusive() {
        let tr = tri();
        let down = [0.0, 0.0, -1.0];
        // On the bottom edge y = -1, and on vertex v2.
        assert!(tr.intersect(&ray([0.0, -1.0, 0.0], down), 0.0, f32::INFINITY).is_some());
        assert!(tr.intersect(&ray([0.0, 1.0, 0.0], down), 0.0, f32::INFINITY).is_some());
        assert!(tr.intersect(&ray([0.0, -1.0 + 1e-3, 0.0], down), 0.0, f32::INFINITY).is_some());
        assert_eq!(tr.intersect(&ray([0.0, -1.0 - 1e-3, 0.0], down), 0.0, f32::INFINITY), None);
        // In the plane: miss, not NaN.
        assert_eq!(tr.intersect(&ray([-3.0, 0.0, -5.0], [1.0, 0.0, 0.0]), 0.0, f32::INFINITY), None);
    }

    #[test]
    fn miss_beside_the_slanted_edge() {
        // Inside the bounding box but past the edge v1-v2 (the line 2x + y = 1).
        let tr = tri();
        assert_eq!(tr.intersect(&ray([0.8, 0.8, 0.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY), None);
        assert_eq!(tr.intersect(&ray([-0.8, 0.8, 0.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY), None);
        assert!(tr.intersect(&ray([0.4, 0.1, 0.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY).is_some());
    }

    #[test]
    fn triangle_behind_origin_is_missed() {
        assert_eq!(tri().intersect(&ray([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]), 0.0, f32::INFINITY), None);
    }

    #[test]
    fn respects_t_max() {
        let tr = tri();
        let r = ray([0.0, 0.0, 0.0], [0.0, 0.0, -1.0]);
        assert_eq!(tr.intersect(&r, 0.0, 4.99), None);
        assert!(tr.intersect(&r, 0.0, 5.01).is_some());
        assert_eq!(tr.intersect(&r, 5.01, f32::INFINITY), None);
    }

    #[test]
    fn degenerate_triangle_is_never_hit() {
        let tr = Triangle::new(Vec3::ZERO, Vec3::X, 2.0 * Vec3::X);
        assert_eq!(tr.intersect(&ray([0.5, 0.0, 1.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY), None);
        let point = Triangle::new(Vec3::ONE, Vec3::ONE, Vec3::ONE);
        assert_eq!(point.intersect(&ray([1.0, 1.0, 2.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY), None);
    }

    #[test]
    fn tiny_triangle_is_still_hit() {
        let s = 1e-4;
        let tr = Triangle::new(Vec3::new(0.0, 0.0, -1.0), Vec3::new(s, 0.0, -1.0), Vec3::new(0.0, s, -1.0));
        let h = tr.intersect(&ray([s / 4.0, s / 4.0, 0.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY).unwrap();
        assert_close(h.t, 1.0, 1e-6);
    }

    #[test]
    fn offset_rays_do_not_hit_again() {
        let tr = Triangle::new(Vec3::new(10.0, -3.0, -30.0), Vec3::new(14.0, -2.0, -29.0), Vec3::new(9.0, 0.0, -28.0));
        let mut rng = Rng::new(41);
        let mut hits = 0;
        for _ in 0..500 {
            let (a, b) = (rng.unit(), rng.unit());
            let (a, b) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
            let target = tr.v0 + a * (tr.v1 - tr.v0) + b * (tr.v2 - tr.v0);
            let origin = rng.in_box(Vec3::splat(-20.0), Vec3::splat(20.0));
            let r = Ray::new(origin, target - origin);
            let Some(h) = tr.intersect(&r, 0.0, f32::INFINITY) else {
                continue;
            };
            hits += 1;
            let s = tr.surface(&r, &h);
            let side = -r.dir.dot(s.normal).signum() * s.normal;
            let bounce = Ray::new(s.point + surface_offset(s.point) * side, reflect(r.dir, s.normal));
            assert_eq!(tr.intersect(&bounce, 0.0, f32::INFINITY), None);
            let through = Ray::new(s.point - surface_offset(s.point) * side, r.dir);
            assert_eq!(tr.intersect(&through, 0.0, f32::INFINITY), None);
        }
        assert!(hits > 400);
    }

    #[test]
    fn bounds_are_vertex_box() {
        let b = tri().bounds();
        assert_eq!(b.min, Vec3::new(-1.0, -1.0, -5.0));
        assert_eq!(b.max, Vec3::new(1.0, 1.0, -5.0));
    }

    #[test]
    fn random_hits_lie_in_the_triangle() {
        let tr = Triangle::new(Vec3::new(-1.0, 0.2, 0.3), Vec3::new(1.5, -0.4, 0.1), Vec3::new(0.2, 1.3, -0.8));
        let b = tr.bounds();
        let n = (tr.v1 - tr.v0).cross(tr.v2 - tr.v0).normalize();
        let mut rng = Rng::new(77);
        let mut hits = 0;
        for _ in 0..3000 {
            let r = rng.ray(b.min, b.max, 2.0);
            let Some(h) = tr.intersect(&r, 0.0, f32::INFINITY) else {
                continue;
            };
            hits += 1;
            let p = r.at(h.t);
            assert!((p - tr.v0).dot(n).abs() < 1e-4);
            assert!(h.uv.min_element() >= 0.0 && h.uv.x + h.uv.y <= 1.0);
            assert_vec_close(tr.surface(&r, &h).point, p, 1e-4);
        }
        assert!(hits > 500);
    }
}
