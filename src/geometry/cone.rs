use super::{Hit, Nearest, Surface, disc_bounds, part, turn_fraction};
use crate::math::lanes::{Lanes, V3, add_scaled, dot, splat3, sub, sub_scaled};
use crate::math::{Aabb, Ray, Vec2, Vec3, orthonormal_basis, unit_or};

/// Finite right circular cone: a disc of `radius` at `base`, changing linearly to a disc
/// of `top_radius` at `base + axis * height`. With `top_radius` 0 (the default of
/// [`Cone::new`]) the top is the apex, and only that nappe exists, never its mirror
/// image; with `top_radius` > 0 it is a truncated cone (a frustum), which is what NFF's
/// `c` entity describes. Either end may be closed by a disc.
///
/// ```toml
/// [[cone]]
/// base = [0, 0, -5]
/// axis = [0, 1, 0]
/// radius = 2
/// top_radius = 1   # default 0: a pointed cone
/// height = 3
/// cap = true       # close the base (default true)
/// top_cap = false  # close the top (default true; only with top_radius > 0)
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cone {
    pub base: Vec3,
    /// Unit length (normalised by [`Cone::new`], see [`unit_or`]).
    pub axis: Vec3,
    /// Radius at the base.
    pub radius: f32,
    /// Radius at the top, `>= 0`: 0 is a pointed cone, anything else a truncated one
    /// (it may exceed `radius`, and equal it: the side of a cylinder).
    pub top_radius: f32,
    pub height: f32,
    /// Close the base with a disc.
    pub cap: bool,
    /// Close the top with a disc (ignored when the top is an apex).
    pub top_cap: bool,
}

impl Cone {
    /// A pointed cone. A zero `axis` falls back to +y rather than turning every later hit
    /// into NaN.
    pub fn new(base: Vec3, axis: Vec3, radius: f32, height: f32, cap: bool) -> Self {
        Cone::truncated(base, axis, radius, 0.0, height, cap, false)
    }

    /// A cone whose top has radius `top_radius` (0: pointed, as [`Cone::new`]).
    pub fn truncated(
        base: Vec3,
        axis: Vec3,
        radius: f32,
        top_radius: f32,
        height: f32,
        cap: bool,
        top_cap: bool,
    ) -> Self {
        Cone { base, axis: unit_or(axis, Vec3::Y), radius, top_radius, height, cap, top_cap }
    }

    /// The centre of the top end: the apex of a pointed cone.
    pub fn apex(&self) -> Vec3 {
        self.base + self.height * self.axis
    }

    /// Nearest of the slanted side and the closing discs. Boundaries are inclusive:
    /// tangent rays, the rims and the apex count as hits when the arithmetic lands on
    /// them. A ray parallel to the base plane never hits a cap.
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        if self.top_radius == 0.0 {
            self.intersect_pointed(ray, t_min, t_max)
        } else {
            self.intersect_truncated(ray, t_min, t_max)
        }
    }

    /// The pointed cone: [`Cone::pointed_hits`] for one ray.
    fn intersect_pointed(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        let c = |v: Vec3| v.to_array();
        self.pointed_hits::<f32>(c(ray.origin), c(ray.dir), t_min, t_max).hit()
    }

    /// The pointed cone, solved relative to its apex, lane by lane ([`Lanes`]: one ray, or
    /// several against this cone): the nearest candidate per lane. The one pointed-cone
    /// test, for every width.
    #[inline(always)]
    pub(crate) fn pointed_hits<L: Lanes>(&self, o: V3<L>, d: V3<L>, t_min: L, t_max: L) -> Nearest<L> {
        let zero = L::splat(0.0);
        let axis = splat3::<L>(self.axis);
        let o = sub(o, splat3(self.apex()));
        let da = dot(d, axis);
        let d_perp = sub_scaled(d, da, axis);
        let mut best = Nearest::new(t_min, t_max);

        // Side: |w_perp|² = k² (w·axis)² with w relative to the apex. Solved from the
        // ray's point of closest approach to the apex rather than its origin: the
        // coefficients are then as small as the geometry allows, which keeps b² - a c
        // from cancelling for far cameras and for rays skimming the apex.
        let t0 = -dot(o, d);
        let o0 = add_scaled(o, t0, d);
        let oa0 = dot(o0, axis);
        let o_perp = sub_scaled(o0, oa0, axis);
        let k = self.radius / self.height;
        let k2 = L::splat(k * k);
        let a = dot(d_perp, d_perp) - k2 * da * da;
        let b = dot(o_perp, d_perp) - k2 * oa0 * da;
        let c = dot(o_perp, o_perp) - k2 * oa0 * oa0;
        let disc = b * b - a * c;
        let real = disc.ge(zero);
        if L::bits(real) != 0 {
            let q = -(b + disc.sqrt().copysign(b));
            // a ≈ 0 when the ray is parallel to a generator line: the quadratic becomes
            // linear, c / q is then its root and q / a (the root that went to infinity)
            // is skipped instead of being divided out.
            let far = L::select(a.ne(zero), q / a, L::splat(f32::NAN));
            let base = L::splat(-self.height);
            for dt in [c / q, far] {
                let t = t0 + dt;
                // Between base (-height) and apex (0): excludes the mirror nappe.
                let s = oa0 + dt * da;
                best.take(real & best.improves(t) & s.ge(base) & s.le(zero), t, part::SIDE);
            }
        }

        if self.cap {
            let across = da.ne(zero);
            if L::bits(across) != 0 {
                let oa = dot(o, axis);
                let t = (L::splat(-self.height) - oa) / da;
                let radial = add_scaled(sub_scaled(o, oa, axis), t, d_perp);
                let inside = dot(radial, radial).le(L::splat(self.radius * self.radius));
                best.take(across & best.improves(t) & inside, t, part::BASE_CAP);
            }
        }
        best
    }

    /// The truncated cone, solved relative to the middle of its axis: radius
    /// `mid − k·s` at axial distance `s` from there. Unlike the apex form this stays
    /// accurate when the two radii are close (the apex then lies far away) and works for
    /// equal radii too (k = 0).
    fn intersect_truncated(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        let half = 0.5 * self.height;
        let o = ray.origin - (self.base + half * self.axis);
        let da = ray.dir.dot(self.axis);
        let d_perp = ray.dir - da * self.axis;
        let mut best = Nearest::new(t_min, t_max);

        // As for the pointed cone, from the ray's point of closest approach to the
        // middle, so the coefficients stay as small as the geometry allows.
        let t0 = -o.dot(ray.dir);
        let o0 = o + t0 * ray.dir;
        let oa0 = o0.dot(self.axis);
        let o_perp = o0 - oa0 * self.axis;
        let k = (self.radius - self.top_radius) / self.height;
        let mid = 0.5 * (self.radius + self.top_radius);
        // |o_perp + dt·d_perp|² = (r_c − k·da·dt)², with r_c the radius level with o0.
        let r_c = mid - k * oa0;
        let a = d_perp.length_squared() - k * k * da * da;
        let b = o_perp.dot(d_perp) + k * da * r_c;
        let c = o_perp.length_squared() - r_c * r_c;
        let disc = b * b - a * c;
        if disc >= 0.0 {
            let q = -(b + disc.sqrt().copysign(b));
            // a ≈ 0: parallel to a generator line (or to the axis of a cylinder-like
            // cone); c / q is then the only finite root.
            let far = if a != 0.0 { q / a } else { f32::NAN };
            for dt in [c / q, far] {
                let t = t0 + dt;
                if best.improves(t) {
                    let s = oa0 + dt * da;
                    if (-half..=half).contains(&s) {
                        best.take(true, t, part::SIDE);
                    }
                }
            }
        }

        if da != 0.0 {
            let oa = o.dot(self.axis);
            let o_radial = o - oa * self.axis;
            let caps =
                [(self.cap, -half, self.radius, part::BASE_CAP), (self.top_cap, half, self.top_radius, part::TOP_CAP)];
            for (on, plane, r, id) in caps {
                if !on {
                    continue;
                }
                let t = (plane - oa) / da;
                if best.improves(t) && (o_radial + t * d_perp).length_squared() <= r * r {
                    best.take(true, t, id);
                }
            }
        }
        best.hit()
    }

    pub fn surface(&self, ray: &Ray, hit: &Hit) -> Surface {
        self.surface_uv(ray, hit, true)
    }

    /// The surface, with `uv` zero unless asked for (see [`super::Shape::surface_uv`]).
    #[inline]
    pub fn surface_uv(&self, ray: &Ray, hit: &Hit, want_uv: bool) -> Surface {
        let local = ray.at(hit.t) - self.base;
        let h = local.dot(self.axis);
        let radial = local - h * self.axis;
        let u = if want_uv {
            let (e1, e2) = orthonormal_basis(self.axis);
            turn_fraction(radial, e1, e2)
        } else {
            0.0
        };
        // Polar on the caps: u around the axis, v outwards.
        let cap_uv = |r: f32| {
            if !want_uv { Vec2::ZERO } else { Vec2::new(u, if r > 0.0 { (radial.length() / r).min(1.0) } else { 0.0 }) }
        };
        if hit.part == part::BASE_CAP {
            return Surface { point: self.base + radial, normal: -self.axis, uv: cap_uv(self.radius) };
        }
        if hit.part == part::TOP_CAP {
            return Surface { point: self.apex() + radial, normal: self.axis, uv: cap_uv(self.top_radius) };
        }
        let out = radial.normalize_or_zero();
        // Perpendicular to the generator (height·axis + (top_radius − radius)·out) in
        // the plane of the axis; at an apex, where `out` is undefined, it degrades to the
        // axis.
        let normal = (self.height * out + (self.radius - self.top_radius) * self.axis).normalize_or(self.axis);
        let v = if self.height > 0.0 { (h / self.height).clamp(0.0, 1.0) } else { 0.0 };
        // Snapped radially onto the side so secondary rays start on the surface. (Written
        // so that a pointed cone gets exactly `radius·(1 − v)`.)
        let rho = self.radius * (1.0 - v) + self.top_radius * v;
        // v runs down the image: its top row at the apex end, as on a cylinder.
        let uv = if want_uv { Vec2::new(u, 1.0 - v) } else { Vec2::ZERO };
        Surface { point: self.base + h * self.axis + rho * out, normal, uv }
    }

    /// The base disc's box grown to the apex, or to the top disc's box.
    pub fn bounds(&self) -> Aabb {
        let base = disc_bounds(self.base, self.axis, self.radius);
        if self.top_radius == 0.0 {
            base.grow(self.apex())
        } else {
            base.union(disc_bounds(self.apex(), self.axis, self.top_radius))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::test_util::{Rng, assert_close, assert_offset_rays_do_not_hit_again, assert_vec_close};

    /// Base disc of radius 1 at y = -1, apex at y = 1, around x = 0, z = -5: the side's
    /// radius at height y is (1 - y) / 2.
    fn upright(cap: bool) -> Cone {
        Cone::new(Vec3::new(0.0, -1.0, -5.0), Vec3::Y, 1.0, 2.0, cap)
    }

    fn ray(o: [f32; 3], d: [f32; 3]) -> Ray {
        Ray::new(Vec3::from(o), Vec3::from(d))
    }

    fn hit(c: &Cone, r: &Ray) -> (Hit, Surface) {
        let h = c.intersect(r, 0.0, f32::INFINITY).expect("expected a hit");
        (h, c.surface(r, &h))
    }

    fn side_normal(out: Vec3) -> Vec3 {
        // height 2, radius 1: normalize(2 out + axis).
        (2.0 * out + Vec3::Y).normalize()
    }

    #[test]
    fn side_hit_from_outside() {
        let c = upright(true);
        let (h, s) = hit(&c, &ray([0.0, 0.0, 0.0], [0.0, 0.0, -1.0]));
        assert_eq!(h.part, part::SIDE);
        assert_close(h.t, 4.5, 1e-5);
        assert_vec_close(s.normal, Vec3::new(0.0, 1.0, 2.0) / 5.0f32.sqrt(), 1e-5);
        assert_vec_close(s.point, Vec3::new(0.0, 0.0, -4.5), 1e-5);
        assert_close(s.uv.y, 0.5, 1e-5);
    }

    #[test]
    fn from_inside_hits_far_side() {
        let c = upright(true);
        let (h, s) = hit(&c, &ray([0.0, -0.5, -5.0], [1.0, 0.0, 0.0]));
        assert_eq!(h.part, part::SIDE);
        assert_close(h.t, 0.75, 1e-5);
        assert_vec_close(s.normal, side_normal(Vec3::X), 1e-5);
    }

    #[test]
    fn from_inside_hits_base_cap() {
        let c = upright(true);
        let (h, s) = hit(&c, &ray([0.1, -0.5, -5.0], [0.0, -1.0, 0.0]));
        assert_eq!(h.part, part::BASE_CAP);
        assert_close(h.t, 0.5, 1e-5);
        assert_vec_close(s.normal, -Vec3::Y, 1e-6);
    }

    #[test]
    fn grazing_side_conventions() {
        let c = upright(true);
        let down = [0.0, 0.0, -1.0];
        // At y = 0 the side's radius is 0.5.
        assert_eq!(c.intersect(&ray([0.5 + 1e-3, 0.0, 0.0], down), 0.0, f32::INFINITY), None);
        let (h, s) = hit(&c, &ray([0.5 - 1e-3, 0.0, 0.0], down));
        assert_close(h.t, 5.0 - (0.25f32 - 0.499 * 0.499).sqrt(), 2e-4);
        assert!(s.normal.is_finite());
        // Over the rim, just outside the base disc, parallel to it: miss, no NaN.
        assert_eq!(c.intersect(&ray([0.0, -1.001, 0.0], down), 0.0, f32::INFINITY), None);
    }

    #[test]
    fn mirror_nappe_is_not_hit() {
        let c = upright(true);
        // At y = 2 the mirror cone above the apex would have radius 0.5.
        assert_eq!(c.intersect(&ray([0.0, 2.0, 0.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY), None);
        assert_eq!(c.intersect(&ray([0.2, 1.5, -5.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY), None);
    }

    #[test]
    fn cone_behind_origin_is_missed() {
        for cap in [false, true] {
            let c = upright(cap);
            assert_eq!(c.intersect(&ray([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]), 0.0, f32::INFINITY), None);
            assert_eq!(c.intersect(&ray([0.0, 5.0, -5.0], [0.0, 1.0, 0.0]), 0.0, f32::INFINITY), None);
        }
    }

    #[test]
    fn respects_t_max() {
        let c = upright(true);
        let r = ray([0.0, 0.0, 0.0], [0.0, 0.0, -1.0]);
        assert_eq!(c.intersect(&r, 0.0, 4.49), None);
        assert!(c.intersect(&r, 0.0, 4.51).is_some());
        assert_close(c.intersect(&r, 4.6, f32::INFINITY).unwrap().t, 5.5, 1e-5);
    }

    #[test]
    fn side_nearer_than_base_cap_wins() {
        // Down at 45° from the left: side at y = -2/3, then the cap at y = -1 (x = -0.5).
        let c = upright(true);
        let r = ray([-1.5, 0.0, -5.0], [1.0, -1.0, 0.0]);
        let (h, s) = hit(&c, &r);
        assert_eq!(h.part, part::SIDE);
        assert_close(h.t, 2.0f32.sqrt() * 2.0 / 3.0, 1e-5);
        assert_vec_close(s.normal, side_normal(-Vec3::X), 1e-5);
        let h = c.intersect(&r, 1.0, f32::INFINITY).unwrap();
        assert_eq!(h.part, part::BASE_CAP);
        assert_close(h.t, 2.0f32.sqrt(), 1e-5);
    }

    #[test]
    fn base_cap_nearer_than_side_wins() {
        // From below, slightly slanted: the cap at x = -0.6 first, then the side inside.
        let c = upright(true);
        let r = ray([-0.8, -3.0, -5.0], [0.1, 1.0, 0.0]);
        let (h, s) = hit(&c, &r);
        assert_eq!(h.part, part::BASE_CAP);
        assert_close(h.t, 2.0 * 1.01f32.sqrt(), 1e-5);
        assert_vec_close(s.normal, -Vec3::Y, 1e-6);
        // Without the cap the side is hit from inside, normal still outward.
        let (h, s) = hit(&upright(false), &r);
        assert_eq!(h.part, part::SIDE);
        assert!(h.t > 2.0 * 1.01f32.sqrt());
        assert!(s.normal.x < 0.0 && s.normal.y > 0.0);
    }

    #[test]
    fn along_axis_from_above_and_below() {
        let c = upright(true);
        // From above, exactly on the axis: the apex itself, normal along the axis.
        let (h, s) = hit(&c, &ray([0.0, 5.0, -5.0], [0.0, -1.0, 0.0]));
        assert_eq!(h.part, part::SIDE);
        assert_close(h.t, 4.0, 1e-4);
        assert_vec_close(s.normal, Vec3::Y, 1e-5);
        // From above, just off the axis: the side right under the apex.
        let (h, _) = hit(&c, &ray([0.01, 5.0, -5.0], [0.0, -1.0, 0.0]));
        assert_eq!(h.part, part::SIDE);
        assert_close(h.t, 4.02, 1e-4);
        // From below: the base cap.
        let (h, s) = hit(&c, &ray([0.0, -5.0, -5.0], [0.0, 1.0, 0.0]));
        assert_eq!(h.part, part::BASE_CAP);
        assert_close(h.t, 4.0, 1e-5);
        assert_vec_close(s.normal, -Vec3::Y, 1e-6);
        // From below without the cap: up the inside to the apex.
        let (h, _) = hit(&upright(false), &ray([0.0, -5.0, -5.0], [0.0, 1.0, 0.0]));
        assert_close(h.t, 6.0, 1e-4);
    }

    #[test]
    fn rays_near_the_apex() {
        let c = upright(true);
        // At y = 0.99 the radius is 0.005.
        let (h, s) = hit(&c, &ray([0.0, 0.99, 0.0], [0.0, 0.0, -1.0]));
        assert_close(h.t, 4.995, 2e-5);
        assert_vec_close(s.normal, side_normal(Vec3::Z), 1e-4);
        // Tangent-ish and just above the apex: miss.
        assert_eq!(c.intersect(&ray([0.006, 0.99, 0.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY), None);
        assert_eq!(c.intersect(&ray([0.0, 1.001, 0.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY), None);
        // Steeply from far away, aimed just under the apex: enters the side right there.
        let from = Vec3::new(3.0, 21.0, -5.0);
        let r = Ray::new(from, Vec3::new(0.0, 0.99, -5.0) - from);
        let (h, s) = hit(&c, &r);
        assert_eq!(h.part, part::SIDE);
        let p = r.at(h.t);
        assert!((p - c.apex()).length() < 0.02, "{p}");
        assert_close(Vec2::new(p.x, p.z + 5.0).length(), (1.0 - p.y) / 2.0, 1e-4);
        assert!(s.normal.x > 0.0 && s.normal.y > 0.0);
    }

    #[test]
    fn ray_parallel_to_a_generator_line() {
        // Direction (-1, 2) is parallel to the right-hand generator, so a ≈ 0.
        let c = upright(true);
        let d = [-1.0, 2.0, 0.0];
        // Along x = -y / 2 from below: the base cap at (0.5, -1).
        let (h, _) = hit(&c, &ray([1.5, -3.0, -5.0], d));
        assert_eq!(h.part, part::BASE_CAP);
        assert_close(h.t, 5.0f32.sqrt(), 1e-5);
        // Open cone: up the inside to the left wall at (-0.25, 0.5).
        let (h, s) = hit(&upright(false), &ray([1.5, -3.0, -5.0], d));
        assert_eq!(h.part, part::SIDE);
        assert_close(h.t, 1.75 * 5.0f32.sqrt(), 1e-4);
        assert_vec_close(s.point, Vec3::new(-0.25, 0.5, -5.0), 1e-4);
        // Coming down the same line from above: the left wall from outside.
        let (h, _) = hit(&c, &ray([-1.5, 3.0, -5.0], [1.0, -2.0, 0.0]));
        assert_eq!(h.part, part::SIDE);
        assert_close(h.t, 1.25 * 5.0f32.sqrt(), 1e-4);
        // Parallel and outside, to the right: nothing.
        assert_eq!(c.intersect(&ray([3.0, -3.0, -5.0], d), 0.0, f32::INFINITY), None);
    }

    #[test]
    fn offset_rays_do_not_hit_again() {
        let c = Cone::new(Vec3::new(2.0, -1.0, -20.0), Vec3::new(0.3, 1.0, 0.2), 1.5, 3.0, true);
        // Only a hit right at the apex or rim can leave the solid at once.
        assert_offset_rays_do_not_hit_again(c, 23, |s| s.uv.y > 0.999 || s.uv.y < 1e-3);
    }

    #[test]
    fn bounds_are_tight_and_contain_the_surface() {
        let b = upright(true).bounds();
        assert_vec_close(b.min, Vec3::new(-1.0, -1.0, -6.0), 1e-6);
        assert_vec_close(b.max, Vec3::new(1.0, 1.0, -4.0), 1e-6);
        // Pointing down: the box reaches down to the apex, not up from it.
        let down = Cone::new(Vec3::ZERO, -Vec3::Y, 1.0, 3.0, true).bounds();
        assert_vec_close(down.min, Vec3::new(-1.0, -3.0, -1.0), 1e-6);
        assert_vec_close(down.max, Vec3::new(1.0, 0.0, 1.0), 1e-6);

        let c = Cone::new(Vec3::new(1.0, 2.0, 3.0), Vec3::new(1.0, -2.0, -0.5), 0.7, 2.5, true);
        let b = c.bounds();
        let (e1, e2) = orthonormal_basis(c.axis);
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for i in 0..360 {
            let a = std::f32::consts::TAU * i as f32 / 360.0;
            for j in 0..=10 {
                let f = j as f32 / 10.0;
                let p = c.base + f * c.height * c.axis + (1.0 - f) * c.radius * (a.cos() * e1 + a.sin() * e2);
                assert!(p.cmpge(b.min - 1e-5).all() && p.cmple(b.max + 1e-5).all(), "{p} outside {b:?}");
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
        assert_vec_close(lo, b.min, 1e-3);
        assert_vec_close(hi, b.max, 1e-3);
    }

    #[test]
    fn uv_stays_in_unit_square() {
        let c = upright(true);
        let b = c.bounds();
        let mut rng = Rng::new(8);
        for _ in 0..1000 {
            let r = rng.ray(b.min, b.max, 2.0);
            if let Some(h) = c.intersect(&r, 0.0, f32::INFINITY) {
                let uv = c.surface(&r, &h).uv;
                assert!((0.0..=1.0).contains(&uv.x) && (0.0..=1.0).contains(&uv.y), "{uv}");
            }
        }
    }

    /// Inside/outside sign with a magnitude never above the true distance.
    fn sdf(c: &Cone, p: Vec3) -> f32 {
        let local = p - c.base;
        let h = local.dot(c.axis);
        let rho = (local - h * c.axis).length();
        let cos = c.height / c.height.hypot(c.radius - c.top_radius);
        let f = h / c.height;
        let side = (rho - (c.radius * (1.0 - f) + c.top_radius * f)) * cos;
        side.max((-h).max(h - c.height))
    }

    fn random_rays(cap: bool, seed: u64) {
        let c = Cone::new(Vec3::new(0.3, -0.7, 0.5), Vec3::new(0.2, 1.0, -0.4), 0.9, 1.6, cap);
        random_rays_on(&c, seed);
    }

    /// Random rays against `c`: every hit lies on the part it names, and (when closed)
    /// no crossing of the surface is skipped before it.
    fn random_rays_on(c: &Cone, seed: u64) {
        let c = *c;
        let cap = c.cap && (c.top_cap || c.top_radius == 0.0);
        let b = c.bounds();
        let mut rng = Rng::new(seed);
        let tol = 1e-3 * c.radius.max(c.top_radius).max(c.height);
        let mut hits = 0;
        for _ in 0..4000 {
            let r = rng.ray(b.min, b.max, 2.5);
            let t_min = if rng.unit() < 0.5 { 0.0 } else { rng.range(0.0, 2.0) };
            let t_max = if rng.unit() < 0.5 { f32::INFINITY } else { t_min + rng.range(0.0, 8.0) };
            let Some(h) = c.intersect(&r, t_min, t_max) else {
                if cap {
                    assert_no_crossing(&c, &r, t_min, t_max.min(t_min + 20.0));
                }
                continue;
            };
            hits += 1;
            assert!(h.t > t_min && h.t < t_max, "t {} outside ({t_min}, {t_max})", h.t);
            let p = r.at(h.t);
            let local = p - c.base;
            let height = local.dot(c.axis);
            let rho = (local - height * c.axis).length();
            match h.part {
                part::SIDE => {
                    let f = height / c.height;
                    let expected = c.radius * (1.0 - f) + c.top_radius * f;
                    assert!((rho - expected).abs() < tol, "{p} off the side");
                    assert!(height > -tol && height < c.height + tol, "{p} off the nappe");
                }
                part::BASE_CAP => assert!(height.abs() < tol && rho < c.radius + tol),
                part::TOP_CAP => assert!((height - c.height).abs() < tol && rho < c.top_radius + tol),
                _ => panic!("unexpected part {}", h.part),
            }
            let s = c.surface(&r, &h);
            assert_close(s.normal.length(), 1.0, 1e-4);
            assert!((s.point - p).length() < tol);
            if cap {
                assert_no_crossing(&c, &r, t_min, h.t);
            }
        }
        assert!(hits > 1000, "only {hits} hits");
    }

    fn assert_no_crossing(c: &Cone, r: &Ray, t0: f32, t1: f32) {
        let start = sdf(c, r.at(t0));
        if start.abs() < 1e-3 {
            return;
        }
        for k in 1..64 {
            let t = t0 + (t1 - t0) * k as f32 / 64.0;
            assert!(sdf(c, r.at(t)) * start.signum() > -1e-3, "skipped a crossing at {t} before {t1}: {r:?}");
        }
    }

    #[test]
    fn random_rays_hit_on_surface_and_first_with_cap() {
        random_rays(true, 0xC0DE);
    }

    #[test]
    fn random_rays_hit_on_surface_open_cone() {
        random_rays(false, 0xFACE);
    }

    // ---- truncated cones -------------------------------------------------------------

    /// Radius 1 at y = -1 narrowing to 0.5 at y = 1, around x = 0, z = -5: the side's
    /// radius at height y is 0.75 − y / 4.
    fn frustum(cap: bool, top_cap: bool) -> Cone {
        Cone::truncated(Vec3::new(0.0, -1.0, -5.0), Vec3::Y, 1.0, 0.5, 2.0, cap, top_cap)
    }

    /// Outward normal of `frustum` on the side, towards horizontal direction `out`.
    fn frustum_normal(out: Vec3) -> Vec3 {
        // height 2, radii 1 and 0.5: normalize(2·out + 0.5·axis).
        (2.0 * out + 0.5 * Vec3::Y).normalize()
    }

    #[test]
    fn truncated_side_hits_between_the_two_radii() {
        let c = frustum(false, false);
        for (y, radius) in [(-0.9f32, 0.975f32), (0.0, 0.75), (0.9, 0.525)] {
            let (h, s) = hit(&c, &ray([0.0, y, 0.0], [0.0, 0.0, -1.0]));
            assert_eq!(h.part, part::SIDE);
            assert_close(h.t, 5.0 - radius, 1e-5);
            assert_vec_close(s.point, Vec3::new(0.0, y, -5.0 + radius), 1e-5);
            assert_vec_close(s.normal, frustum_normal(Vec3::Z), 1e-5);
            assert_close(s.uv.y, (1.0 - y) / 2.0, 1e-5);
        }
        // Above the top and below the base: nothing, open or closed.
        for cone in [frustum(false, false), frustum(true, true)] {
            assert_eq!(cone.intersect(&ray([0.0, 1.01, 0.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY), None);
            assert_eq!(cone.intersect(&ray([0.0, -1.01, 0.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY), None);
        }
        // Beside the narrow end, inside the wide end's radius: missed at the top...
        assert_eq!(c.intersect(&ray([0.6, 0.9, 0.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY), None);
        // ...but hit lower down where the side is wider.
        let (h, _) = hit(&c, &ray([0.6, -0.9, 0.0], [0.0, 0.0, -1.0]));
        assert_close(h.t, 5.0 - (0.975f32 * 0.975 - 0.36).sqrt(), 1e-5);
    }

    #[test]
    fn truncated_open_ends_let_rays_through_and_caps_close_them() {
        // Straight down the axis: through both open ends; onto the top disc when closed.
        let down = ray([0.0, 5.0, -5.0], [0.0, -1.0, 0.0]);
        assert_eq!(frustum(false, false).intersect(&down, 0.0, f32::INFINITY), None);
        let (h, s) = hit(&frustum(true, true), &down);
        assert_eq!(h.part, part::TOP_CAP);
        assert_close(h.t, 4.0, 1e-5);
        assert_vec_close(s.normal, Vec3::Y, 1e-6);
        assert_vec_close(s.point, Vec3::new(0.0, 1.0, -5.0), 1e-5);
        // Only the base closed: the ray goes in at the top and stops on the base inside.
        let (h, s) = hit(&frustum(true, false), &down);
        assert_eq!(h.part, part::BASE_CAP);
        assert_close(h.t, 6.0, 1e-5);
        assert_vec_close(s.normal, -Vec3::Y, 1e-6);
        // Slanted through the open top onto the inside of the side: the normal stays
        // outward (the integrator flips it towards the ray).
        let r = ray([0.0, 2.0, -5.0], [0.4, -1.0, 0.0]);
        let (h, s) = hit(&frustum(false, false), &r);
        assert_eq!(h.part, part::SIDE);
        let p = r.at(h.t);
        assert_close(p.x, 0.75 - p.y / 4.0, 1e-4);
        assert!(s.normal.x > 0.0 && s.normal.y > 0.0, "{}", s.normal);
    }

    #[test]
    fn truncated_cone_with_equal_radii_is_a_cylinder_side() {
        let cone = Cone::truncated(Vec3::new(0.0, -1.0, -5.0), Vec3::Y, 1.0, 1.0, 2.0, true, true);
        let cyl = crate::geometry::Cylinder::new(Vec3::new(0.0, -1.0, -5.0), Vec3::Y, 1.0, 2.0, true);
        let mut rng = Rng::new(99);
        let b = cyl.bounds();
        let mut hits = 0;
        for _ in 0..2000 {
            let r = rng.ray(b.min, b.max, 2.0);
            let (a, c) = (cone.intersect(&r, 0.0, f32::INFINITY), cyl.intersect(&r, 0.0, f32::INFINITY));
            assert_eq!(a.is_some(), c.is_some(), "{r:?}");
            if let (Some(a), Some(c)) = (a, c) {
                hits += 1;
                assert_close(a.t, c.t, 1e-4);
                assert_eq!(a.part, c.part);
                assert_vec_close(cone.surface(&r, &a).normal, cyl.surface(&r, &c).normal, 1e-4);
            }
        }
        assert!(hits > 500, "{hits}");
    }

    #[test]
    fn truncated_cone_widening_upwards() {
        // Radius 0.5 at the base, 1 at the top: the mirror image of `frustum`.
        let c = Cone::truncated(Vec3::new(0.0, -1.0, -5.0), Vec3::Y, 0.5, 1.0, 2.0, false, false);
        let (h, s) = hit(&c, &ray([0.0, 0.5, 0.0], [0.0, 0.0, -1.0]));
        assert_close(h.t, 5.0 - 0.875, 1e-5);
        assert_vec_close(s.normal, (2.0 * Vec3::Z - 0.5 * Vec3::Y).normalize(), 1e-5);
    }

    #[test]
    fn nearly_equal_radii_stay_accurate() {
        // The apex of this cone would be 20,000 units away.
        let c = Cone::truncated(Vec3::new(3.0, -1.0, -5.0), Vec3::Y, 1.0, 0.9999, 2.0, false, false);
        let (h, s) = hit(&c, &ray([3.0, 0.0, 0.0], [0.0, 0.0, -1.0]));
        assert_close(h.t, 5.0 - 0.99995, 1e-5);
        assert_vec_close(s.normal, Vec3::Z, 1e-4);
    }

    #[test]
    fn truncated_bounds_are_tight_and_contain_the_surface() {
        let b = frustum(true, true).bounds();
        assert_vec_close(b.min, Vec3::new(-1.0, -1.0, -6.0), 1e-6);
        assert_vec_close(b.max, Vec3::new(1.0, 1.0, -4.0), 1e-6);
        let c = Cone::truncated(Vec3::new(1.0, 2.0, 3.0), Vec3::new(1.0, -2.0, -0.5), 0.4, 0.9, 2.5, true, true);
        let b = c.bounds();
        let (e1, e2) = orthonormal_basis(c.axis);
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for i in 0..360 {
            let a = std::f32::consts::TAU * i as f32 / 360.0;
            for j in 0..=10 {
                let f = j as f32 / 10.0;
                let r = c.radius * (1.0 - f) + c.top_radius * f;
                let p = c.base + f * c.height * c.axis + r * (a.cos() * e1 + a.sin() * e2);
                assert!(p.cmpge(b.min - 1e-5).all() && p.cmple(b.max + 1e-5).all(), "{p} outside {b:?}");
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
        assert_vec_close(lo, b.min, 1e-3);
        assert_vec_close(hi, b.max, 1e-3);
    }

    #[test]
    fn random_rays_hit_on_surface_truncated() {
        let axis = Vec3::new(0.2, 1.0, -0.4);
        for (i, (r0, r1)) in [(0.9, 0.3), (0.3, 0.9), (0.7, 0.7)].into_iter().enumerate() {
            for (cap, top_cap) in [(true, true), (false, false)] {
                let c = Cone::truncated(Vec3::new(0.3, -0.7, 0.5), axis, r0, r1, 1.6, cap, top_cap);
                random_rays_on(&c, 0x7A0 + i as u64);
            }
        }
    }

    #[test]
    fn offset_rays_do_not_hit_again_truncated() {
        let c = Cone::truncated(Vec3::new(2.0, -1.0, -20.0), Vec3::new(0.3, 1.0, 0.2), 1.5, 0.6, 3.0, true, true);
        assert_offset_rays_do_not_hit_again(c, 31, |s| s.uv.y > 0.999 || s.uv.y < 1e-3);
    }

    #[test]
    fn pointed_cone_is_unchanged_by_the_truncated_path() {
        // `Cone::new` keeps the original apex algorithm: bit-identical hits and surfaces.
        let c = Cone::new(Vec3::new(0.3, -0.7, 0.5), Vec3::new(0.2, 1.0, -0.4), 0.9, 1.6, true);
        assert_eq!(c.top_radius, 0.0);
        let b = c.bounds();
        let mut rng = Rng::new(5);
        for _ in 0..2000 {
            let r = rng.ray(b.min, b.max, 2.0);
            assert_eq!(c.intersect(&r, 0.0, f32::INFINITY), c.intersect_pointed(&r, 0.0, f32::INFINITY));
        }
    }
}
