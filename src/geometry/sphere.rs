use super::{Hit, Surface, part};
use crate::math::lanes::{Lanes, V3, dot, sub, sub_scaled};
use crate::math::{Aabb, Ray, Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    pub center: Vec3,
    pub radius: f32,
}

/// Where a ray (origin `o`, unit direction `d`) meets spheres (`center`, `radius`), lane
/// by lane ([`Lanes`]: one sphere, or several against one ray): whether it does within
/// `(t_min, t_max)`, and the nearer such distance. The one sphere test, for every width.
#[inline(always)]
pub fn hits<L: Lanes>(o: V3<L>, d: V3<L>, center: V3<L>, radius: L, t_min: L, t_max: L) -> (L::Mask, L) {
    // Ray Tracing Gems ch. 7: with |d| = 1, the discriminant r² - |oc - b d|² does not
    // suffer the cancellation of b² - c when the sphere is small and far away, and
    // q = -(b + sign(b) √disc) keeps the near root accurate.
    let oc = sub(o, center);
    let b = dot(oc, d);
    let r2 = radius * radius;
    let perp = sub_scaled(oc, b, d);
    let disc = r2 - dot(perp, perp);
    // A NaN discriminant is no hit here, as its NaN roots would be none below.
    let real = disc.ge(L::splat(0.0));
    let c = dot(oc, oc) - r2;
    // From outside a sphere that lies behind it (c > 0, b > 0) both roots are negative,
    // as computed below (q < 0, c / q < 0), so none is past a `t_min` of zero or more:
    // where that holds for every lane that meets its sphere (the sphere a shadow or
    // reflected ray leaves, and its neighbours behind), the root and the division are
    // not needed. The same answer, sooner.
    let zero = L::splat(0.0);
    let behind = c.gt(zero) & b.gt(zero) & t_min.ge(zero);
    // Most tests in a cloud miss every sphere: the root and the division skipped then
    // too, by the same test (one branch, not two, each a coin toss to the predictor).
    if L::bits(real) & !L::bits(behind) == 0 {
        return (zero.lt(zero), zero); // no lane hits
    }
    let q = -(b + disc.sqrt().copysign(b));
    let (t0, t1) = (c / q, q);
    let ordered = t0.le(t1);
    let (near, far) = (L::select(ordered, t0, t1), L::select(ordered, t1, t0));
    // Comparisons written so that a NaN root (q = 0) is rejected.
    let near_ok = near.gt(t_min) & near.lt(t_max);
    let far_ok = far.gt(t_min) & far.lt(t_max);
    ((near_ok | far_ok) & real, L::select(near_ok, near, far))
}

impl Sphere {
    pub fn new(center: Vec3, radius: f32) -> Self {
        Sphere { center, radius }
    }

    /// A ray exactly tangent to the sphere (discriminant 0) counts as a hit.
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        let c = |v: Vec3| v.to_array();
        let (hit, t) = hits::<f32>(c(ray.origin), c(ray.dir), c(self.center), self.radius, t_min, t_max);
        hit.then_some(Hit { prim: 0, t, uv: Vec2::ZERO, part: part::SIDE })
    }

    pub fn surface(&self, ray: &Ray, hit: &Hit) -> Surface {
        self.surface_uv(ray, hit, true)
    }

    /// The surface, with `uv` zero unless asked for (see [`super::Shape::surface_uv`]).
    #[inline]
    pub fn surface_uv(&self, ray: &Ray, hit: &Hit, uv: bool) -> Surface {
        let normal = (ray.at(hit.t) - self.center).normalize_or(Vec3::Y);
        // Snapped back onto the sphere so that secondary rays start from the surface and
        // not from wherever the rounding of `origin + t dir` put them.
        let point = self.center + self.radius * normal;
        if !uv {
            return Surface { point, normal, uv: Vec2::ZERO };
        }
        let u = 0.5 + normal.x.atan2(normal.z) * (0.5 * FRAC_1_PI);
        let v = 0.5 - normal.y.clamp(-1.0, 1.0).asin() / PI;
        Surface { point, normal, uv: Vec2::new(u.clamp(0.0, 1.0), v.clamp(0.0, 1.0)) }
    }

    pub fn bounds(&self) -> Aabb {
        let r = Vec3::splat(self.radius.abs());
        Aabb { min: self.center - r, max: self.center + r }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::test_util::{Rng, assert_close, assert_vec_close};
    use crate::math::{reflect, surface_offset};

    fn unit_sphere_ahead() -> Sphere {
        Sphere::new(Vec3::new(0.0, 0.0, -5.0), 1.0)
    }

    fn ray(o: [f32; 3], d: [f32; 3]) -> Ray {
        Ray::new(Vec3::from(o), Vec3::from(d))
    }

    #[test]
    fn hit_from_outside_head_on() {
        let s = unit_sphere_ahead();
        let r = ray([0.0, 0.0, 0.0], [0.0, 0.0, -1.0]);
        let h = s.intersect(&r, 0.0, f32::INFINITY).unwrap();
        assert_close(h.t, 4.0, 1e-5);
        let surf = s.surface(&r, &h);
        assert_vec_close(surf.normal, Vec3::Z, 1e-5);
        assert_vec_close(surf.point, Vec3::new(0.0, 0.0, -4.0), 1e-5);
    }

    #[test]
    fn hit_from_outside_off_center() {
        // x = 0.6 meets the sphere at z = -5 + 0.8: t = 4.2, normal (0.6, 0, 0.8).
        let s = unit_sphere_ahead();
        let r = ray([0.6, 0.0, 0.0], [0.0, 0.0, -1.0]);
        let h = s.intersect(&r, 0.0, f32::INFINITY).unwrap();
        assert_close(h.t, 4.2, 1e-5);
        assert_vec_close(s.surface(&r, &h).normal, Vec3::new(0.6, 0.0, 0.8), 1e-5);
    }

    #[test]
    fn hit_from_inside_reaches_far_wall() {
        let s = unit_sphere_ahead();
        let r = ray([0.0, 0.0, -5.5], [0.0, 0.0, -1.0]);
        let h = s.intersect(&r, 0.0, f32::INFINITY).unwrap();
        assert_close(h.t, 0.5, 1e-5);
        // The normal still faces out of the sphere, i.e. along the ray.
        assert_vec_close(s.surface(&r, &h).normal, -Vec3::Z, 1e-5);
    }

    #[test]
    fn grazing_just_outside_misses() {
        let s = unit_sphere_ahead();
        let r = ray([1.0 + 1e-3, 0.0, 0.0], [0.0, 0.0, -1.0]);
        assert_eq!(s.intersect(&r, 0.0, f32::INFINITY), None);
    }

    #[test]
    fn grazing_just_inside_hits() {
        let s = unit_sphere_ahead();
        let r = ray([1.0 - 1e-3, 0.0, 0.0], [0.0, 0.0, -1.0]);
        let h = s.intersect(&r, 0.0, f32::INFINITY).unwrap();
        let half_chord = (1.0f32 - 0.999 * 0.999).sqrt();
        assert_close(h.t, 5.0 - half_chord, 1e-4);
        let n = s.surface(&r, &h).normal;
        assert!(n.is_finite());
        assert_close(n.length(), 1.0, 1e-5);
    }

    #[test]
    fn exactly_tangent_counts_as_hit() {
        let s = unit_sphere_ahead();
        let r = ray([1.0, 0.0, 0.0], [0.0, 0.0, -1.0]);
        let h = s.intersect(&r, 0.0, f32::INFINITY).unwrap();
        assert_close(h.t, 5.0, 1e-5);
        assert_vec_close(s.surface(&r, &h).normal, Vec3::X, 1e-5);
    }

    #[test]
    fn sphere_behind_origin_is_missed() {
        let s = unit_sphere_ahead();
        let r = ray([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
        assert_eq!(s.intersect(&r, 0.0, f32::INFINITY), None);
    }

    #[test]
    fn respects_t_max_and_t_min() {
        let s = unit_sphere_ahead();
        let r = ray([0.0, 0.0, 0.0], [0.0, 0.0, -1.0]);
        assert_eq!(s.intersect(&r, 0.0, 3.9), None);
        assert!(s.intersect(&r, 0.0, 4.1).is_some());
        // Past the near root, the far one is the answer.
        assert_close(s.intersect(&r, 4.5, f32::INFINITY).unwrap().t, 6.0, 1e-5);
        assert_eq!(s.intersect(&r, 6.1, f32::INFINITY), None);
    }

    #[test]
    fn offset_reflected_and_exiting_rays_do_not_hit_again() {
        let s = Sphere::new(Vec3::new(3.0, -2.0, -40.0), 2.5);
        let mut rng = Rng::new(7);
        for _ in 0..500 {
            let r = Ray::new(Vec3::ZERO, s.center + rng.in_box(-Vec3::splat(2.4), Vec3::splat(2.4)));
            let Some(h) = s.intersect(&r, 0.0, f32::INFINITY) else {
                continue;
            };
            let surf = s.surface(&r, &h);
            let eps = surface_offset(surf.point);
            let bounce = Ray::new(surf.point + eps * surf.normal, reflect(r.dir, surf.normal));
            assert_eq!(s.intersect(&bounce, 0.0, f32::INFINITY), None);
            // Leaving through the far wall, the continued ray must not see the sphere.
            let inner = Ray::new(surf.point - eps * surf.normal, r.dir);
            let far = s.intersect(&inner, 0.0, f32::INFINITY).unwrap();
            let exit = s.surface(&inner, &far);
            let out = Ray::new(exit.point + surface_offset(exit.point) * exit.normal, r.dir);
            assert_eq!(s.intersect(&out, 0.0, f32::INFINITY), None);
        }
    }

    #[test]
    fn uv_is_equirectangular() {
        let s = Sphere::new(Vec3::ZERO, 2.0);
        let uv_at = |d: Vec3| {
            let r = Ray::new(5.0 * d, -d);
            s.surface(&r, &s.intersect(&r, 0.0, f32::INFINITY).unwrap()).uv
        };
        let front = uv_at(Vec3::Z);
        assert_close(front.x, 0.5, 1e-5);
        assert_close(front.y, 0.5, 1e-5);
        assert_close(uv_at(Vec3::Y).y, 0.0, 1e-3);
        assert_close(uv_at(-Vec3::Y).y, 1.0, 1e-3);
        assert_close(uv_at(Vec3::X).x, 0.75, 1e-5);
        assert_close(uv_at(-Vec3::X).x, 0.25, 1e-5);
    }

    #[test]
    fn bounds_are_tight() {
        let b = Sphere::new(Vec3::new(1.0, 2.0, 3.0), 0.5).bounds();
        assert_eq!(b.min, Vec3::new(0.5, 1.5, 2.5));
        assert_eq!(b.max, Vec3::new(1.5, 2.5, 3.5));
    }

    #[test]
    fn random_rays_hit_on_surface_and_first() {
        let s = Sphere::new(Vec3::new(0.5, -0.25, 1.0), 1.5);
        let sdf = |p: Vec3| (p - s.center).length() - s.radius;
        let b = s.bounds();
        let mut rng = Rng::new(0x5EED);
        let mut hits = 0;
        for _ in 0..4000 {
            let r = rng.ray(b.min, b.max, 3.0);
            let t_min = if rng.unit() < 0.5 { 0.0 } else { rng.range(0.0, 2.0) };
            let t_max = if rng.unit() < 0.5 { f32::INFINITY } else { t_min + rng.range(0.0, 8.0) };
            let hit = s.intersect(&r, t_min, t_max);
            let end = match hit {
                Some(h) => {
                    hits += 1;
                    assert!(h.t > t_min && h.t < t_max, "t {} outside ({t_min}, {t_max})", h.t);
                    let p = r.at(h.t);
                    assert!(sdf(p).abs() < 1e-3 * s.radius, "{p} off the surface");
                    let n = s.surface(&r, &h).normal;
                    assert_close(n.length(), 1.0, 1e-4);
                    h.t
                }
                None => t_max.min(t_min + 20.0),
            };
            // No crossing may be skipped between t_min and the reported hit (or the end).
            let start = sdf(r.at(t_min));
            if start.abs() < 1e-3 {
                continue;
            }
            for k in 1..64 {
                let t = t_min + (end - t_min) * k as f32 / 64.0;
                let d = sdf(r.at(t));
                assert!(d * start.signum() > -1e-3, "crossing before t = {end} at {t}: {r:?}");
            }
        }
        assert!(hits > 1000, "only {hits} hits: the test is not exercising much");
    }

    /// The shortcut for spheres behind the ray's origin gives the full test's answer:
    /// rays leave points on (and just off) spheres, towards random directions, and
    /// `t_min = 0` (shortcut taken) must agree with a tiny negative `t_min` (which turns
    /// it off, and accepts the same roots unless one is zero).
    #[test]
    fn spheres_behind_the_origin_are_missed_as_the_full_test_misses_them() {
        let mut rng = Rng::new(0x5eed_5eed);
        let (mut behind, mut hits) = (0, 0);
        for _ in 0..20_000 {
            let s = Sphere::new(rng.in_box(Vec3::splat(-3.0), Vec3::splat(3.0)), rng.range(0.05, 2.0));
            let n = rng.direction();
            let p = s.center + n * s.radius;
            let origin = match rng.next_u64() % 3 {
                0 => p,
                1 => p + n * surface_offset(p),
                _ => rng.in_box(Vec3::splat(-6.0), Vec3::splat(6.0)),
            };
            let r = Ray::new(origin, rng.direction());
            let t_max = if rng.unit() < 0.5 { f32::INFINITY } else { rng.range(0.01, 8.0) };
            let oc = (r.origin - s.center).to_array();
            let b = oc[0] * r.dir.x + oc[1] * r.dir.y + oc[2] * r.dir.z;
            let c = oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2] - s.radius * s.radius;
            behind += (c > 0.0 && b > 0.0) as u32;
            let fast = s.intersect(&r, 0.0, t_max);
            let full = s.intersect(&r, -1e-30, t_max);
            if full.is_some_and(|h| h.t <= 0.0) {
                continue; // a root at zero (an origin exactly on the sphere, c = 0)
            }
            assert_eq!(fast.map(|h| h.t.to_bits()), full.map(|h| h.t.to_bits()), "{r:?} against {s:?}");
            hits += fast.is_some() as u32;
        }
        assert!(behind > 5_000 && hits > 2_000, "{behind} behind, {hits} hits: too few to tell");
    }
}
