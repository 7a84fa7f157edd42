use super::{Hit, Surface, part};
use crate::math::lanes::{Lanes, V3, add_scaled, cross, dot, splat3, sub};
use crate::math::{Aabb, Ray, Vec2, Vec3};

/// Parallelogram `corner + a edge_u + b edge_v`, `a, b ∈ [0, 1]`.
///
/// Build it with [`Quad::new`]: the private fields cache values derived from the public
/// ones, so editing the public fields afterwards leaves them stale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quad {
    pub corner: Vec3,
    pub edge_u: Vec3,
    pub edge_v: Vec3,
    /// Unit `edge_u × edge_v` (zero for a degenerate quad, which then is never hit).
    normal: Vec3,
    /// Plane offset: `normal · x = plane_d` on the quad.
    plane_d: f32,
    /// `n / (n · n)` with the unnormalised cross product `n`: turns the cross products
    /// in `intersect` into the coordinates (a, b) without a division per ray.
    w: Vec3,
}

impl Quad {
    pub fn new(corner: Vec3, edge_u: Vec3, edge_v: Vec3) -> Self {
        let n = edge_u.cross(edge_v);
        let nn = n.length_squared();
        let normal = n.normalize_or_zero();
        let w = if nn > 0.0 { n / nn } else { Vec3::ZERO };
        Quad { corner, edge_u, edge_v, normal, plane_d: normal.dot(corner), w }
    }

    pub fn normal(&self) -> Vec3 {
        self.normal
    }

    /// The plane: unit normal `n` and offset `d`, `n · x = d` on the quad.
    pub fn plane(&self) -> (Vec3, f32) {
        (self.normal, self.plane_d)
    }

    /// Two-sided. Edges are inclusive; a ray parallel to the plane (even one lying in
    /// it) misses.
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        let c = |v: Vec3| v.to_array();
        let (hit, t, a, b) = self.hits::<f32>(c(ray.origin), c(ray.dir), t_min, t_max);
        hit.then_some(Hit { prim: 0, t, uv: Vec2::new(a, b), part: part::SIDE })
    }

    /// Where rays (origin `o`, direction `d`) meet the quad, lane by lane ([`Lanes`]: one
    /// ray, or several against this quad): whether they do within `(t_min, t_max)`, and
    /// the distance and coordinates (a, b) there (0 in lanes that miss early). The one
    /// quad test, for every width, as [`super::sphere_hits`] is the sphere's.
    #[inline(always)]
    pub fn hits<L: Lanes>(&self, o: V3<L>, d: V3<L>, t_min: L, t_max: L) -> (L::Mask, L, L, L) {
        let zero = L::splat(0.0);
        let n = splat3::<L>(self.normal);
        let denom = dot(n, d);
        // `|denom| > 1e-9` rather than `!(|denom| <= 1e-9)`: they differ only on a NaN,
        // whose `t` is NaN and misses below.
        let facing = denom.abs().gt(L::splat(1e-9));
        if L::bits(facing) == 0 {
            return (facing, zero, zero, zero);
        }
        let t = (L::splat(self.plane_d) - dot(n, o)) / denom;
        let hit = facing & t.gt(t_min) & t.lt(t_max);
        if L::bits(hit) == 0 {
            return (hit, zero, zero, zero);
        }
        // `ray.at(t) - corner`.
        let p = sub(add_scaled(o, t, d), splat3(self.corner));
        let w = splat3::<L>(self.w);
        let a = dot(w, cross(p, splat3(self.edge_v)));
        let b = dot(w, cross(splat3(self.edge_u), p));
        let one = L::splat(1.0);
        let within = |x: L| x.ge(zero) & x.le(one);
        (hit & within(a) & within(b), t, a, b)
    }

    #[inline]
    pub fn surface(&self, _ray: &Ray, hit: &Hit) -> Surface {
        // Rebuilt from (a, b) rather than `origin + t dir`: exactly on the plane.
        let point = self.corner + hit.uv.x * self.edge_u + hit.uv.y * self.edge_v;
        // Texture v runs down the image (row 0 at v = 0), edge_v up it: corner is the
        // image's bottom-left, so a quad with edge_v pointing up shows it upright.
        Surface { point, normal: self.normal, uv: Vec2::new(hit.uv.x, 1.0 - hit.uv.y) }
    }

    pub fn bounds(&self) -> Aabb {
        let c = self.corner;
        Aabb::from_points([c, c + self.edge_u, c + self.edge_v, c + self.edge_u + self.edge_v])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::test_util::{Rng, assert_close, assert_vec_close};
    use crate::math::{reflect, surface_offset};

    /// 2×2 square in the plane z = -5, facing +z.
    fn square() -> Quad {
        Quad::new(Vec3::new(-1.0, -1.0, -5.0), Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, 2.0, 0.0))
    }

    fn ray(o: [f32; 3], d: [f32; 3]) -> Ray {
        Ray::new(Vec3::from(o), Vec3::from(d))
    }

    #[test]
    fn hit_from_front() {
        let q = square();
        let r = ray([0.0, 0.0, 0.0], [0.0, 0.0, -1.0]);
        let h = q.intersect(&r, 0.0, f32::INFINITY).unwrap();
        assert_close(h.t, 5.0, 1e-5);
        let s = q.surface(&r, &h);
        assert_vec_close(s.normal, Vec3::Z, 1e-6);
        assert_vec_close(s.point, Vec3::new(0.0, 0.0, -5.0), 1e-5);
        assert_vec_close(s.uv.extend(0.0), Vec3::new(0.5, 0.5, 0.0), 1e-6);
    }

    #[test]
    fn hit_from_back_keeps_winding_normal() {
        let q = square();
        let r = ray([0.5, -0.5, -8.0], [0.0, 0.0, 1.0]);
        let h = q.intersect(&r, 0.0, f32::INFINITY).unwrap();
        assert_close(h.t, 3.0, 1e-5);
        assert_vec_close(q.surface(&r, &h).normal, Vec3::Z, 1e-6);
        assert_vec_close(h.uv.extend(0.0), Vec3::new(0.75, 0.25, 0.0), 1e-6);
    }

    #[test]
    fn slanted_parallelogram_coordinates() {
        // Sheared edges: (a, b) must solve p = corner + a eu + b ev, not be projections.
        let q = Quad::new(Vec3::new(0.0, 0.0, -2.0), Vec3::new(2.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 0.0));
        let target = q.corner + 0.25 * q.edge_u + 0.5 * q.edge_v;
        let r = Ray::new(Vec3::new(0.3, 0.1, 3.0), target - Vec3::new(0.3, 0.1, 3.0));
        let h = q.intersect(&r, 0.0, f32::INFINITY).unwrap();
        assert_close(h.uv.x, 0.25, 1e-5);
        assert_close(h.uv.y, 0.5, 1e-5);
        assert_close(h.t, (target - r.origin).length(), 1e-4);
        // A point inside the bounding rectangle but outside the parallelogram.
        let r = ray([0.2, 0.9, 0.0], [0.0, 0.0, -1.0]);
        assert_eq!(q.intersect(&r, 0.0, f32::INFINITY), None);
    }

    #[test]
    fn grazing_edge_is_inclusive() {
        let q = square();
        let on_edge = q.intersect(&ray([1.0, 0.0, 0.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY).unwrap();
        assert_close(on_edge.uv.x, 1.0, 1e-6);
        assert_close(on_edge.t, 5.0, 1e-5);
        assert!(q.intersect(&ray([1.0 - 1e-3, 0.0, 0.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY).is_some());
        assert_eq!(q.intersect(&ray([1.0 + 1e-3, 0.0, 0.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY), None);
    }

    #[test]
    fn ray_skimming_in_plane_misses() {
        let q = square();
        assert_eq!(q.intersect(&ray([-3.0, 0.0, -5.0], [1.0, 0.0, 0.0]), 0.0, f32::INFINITY), None);
        // Almost parallel, just above: crosses the plane far away, outside the quad.
        assert_eq!(q.intersect(&ray([-3.0, 0.0, -4.999], [1.0, 0.0, -1e-6]), 0.0, f32::INFINITY), None);
    }

    #[test]
    fn quad_behind_origin_is_missed() {
        let q = square();
        assert_eq!(q.intersect(&ray([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]), 0.0, f32::INFINITY), None);
    }

    #[test]
    fn respects_t_max() {
        let q = square();
        let r = ray([0.0, 0.0, 0.0], [0.0, 0.0, -1.0]);
        assert_eq!(q.intersect(&r, 0.0, 4.99), None);
        assert!(q.intersect(&r, 0.0, 5.01).is_some());
        assert_eq!(q.intersect(&r, 5.01, f32::INFINITY), None);
    }

    #[test]
    fn offset_rays_do_not_hit_again() {
        let q = Quad::new(Vec3::new(10.0, -3.0, -30.0), Vec3::new(4.0, 1.0, 1.0), Vec3::new(-1.0, 3.0, 2.0));
        let mut rng = Rng::new(11);
        let mut hits = 0;
        for _ in 0..500 {
            let target = q.corner + rng.unit() * q.edge_u + rng.unit() * q.edge_v;
            let origin = rng.in_box(Vec3::splat(-20.0), Vec3::splat(20.0));
            let r = Ray::new(origin, target - origin);
            let Some(h) = q.intersect(&r, 0.0, f32::INFINITY) else {
                continue;
            };
            hits += 1;
            let s = q.surface(&r, &h);
            // Offset to the side the ray came from, then reflect: stays on that side.
            let side = -r.dir.dot(s.normal).signum() * s.normal;
            let bounce = Ray::new(s.point + surface_offset(s.point) * side, reflect(r.dir, s.normal));
            assert_eq!(q.intersect(&bounce, 0.0, f32::INFINITY), None);
            // Transmitted: offset to the far side, carry on.
            let through = Ray::new(s.point - surface_offset(s.point) * side, r.dir);
            assert_eq!(q.intersect(&through, 0.0, f32::INFINITY), None);
        }
        assert!(hits > 400);
    }

    #[test]
    fn degenerate_quad_is_never_hit() {
        let q = Quad::new(Vec3::ZERO, Vec3::X, 2.0 * Vec3::X);
        assert_eq!(q.intersect(&ray([0.5, 0.0, 1.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY), None);
    }

    #[test]
    fn bounds_cover_all_corners() {
        let q = Quad::new(Vec3::new(1.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(-1.0, 0.0, 2.0));
        let b = q.bounds();
        assert_eq!(b.min, Vec3::new(0.0, 0.0, 0.0));
        assert_eq!(b.max, Vec3::new(2.0, 1.0, 2.0));
    }

    #[test]
    fn random_hits_lie_on_the_quad() {
        let q = Quad::new(Vec3::new(-1.0, 0.5, 0.0), Vec3::new(2.0, 0.5, -0.5), Vec3::new(0.3, 0.0, 1.5));
        let b = q.bounds();
        let mut rng = Rng::new(99);
        for _ in 0..3000 {
            let r = rng.ray(b.min, b.max, 3.0);
            let Some(h) = q.intersect(&r, 0.0, f32::INFINITY) else {
                continue;
            };
            let p = r.at(h.t);
            assert!((p - q.corner).dot(q.normal).abs() < 1e-4);
            let s = q.surface(&r, &h);
            assert_vec_close(s.point, p, 1e-4);
            assert!((0.0..=1.0).contains(&s.uv.x) && (0.0..=1.0).contains(&s.uv.y));
        }
    }
}
