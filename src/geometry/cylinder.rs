use super::{Hit, Nearest, Surface, disc_bounds, part, turn_fraction};
use crate::math::lanes::{Lanes, V3, add_scaled, dot, splat3, sub, sub_scaled};
use crate::math::{Aabb, Ray, Vec2, Vec3, orthonormal_basis, unit_or};

/// Finite circular cylinder from `base` to `base + axis * height`, optionally closed by
/// two disc caps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cylinder {
    pub base: Vec3,
    /// Unit length (normalised by [`Cylinder::new`], see [`unit_or`]).
    pub axis: Vec3,
    pub radius: f32,
    pub height: f32,
    pub caps: bool,
}

impl Cylinder {
    /// A zero `axis` falls back to +y rather than turning every later hit into NaN.
    pub fn new(base: Vec3, axis: Vec3, radius: f32, height: f32, caps: bool) -> Self {
        Cylinder { base, axis: unit_or(axis, Vec3::Y), radius, height, caps }
    }

    /// Nearest of the side wall and (with `caps`) both caps. Boundaries are inclusive:
    /// a ray tangent to the wall or through a cap's rim hits. A ray parallel to the axis
    /// never hits the wall (even running along it) and one parallel to the caps never
    /// hits a cap. Inlined into the tree's leaf loop: 1 to 2 % on scenes of many
    /// cylinders (bench/lattice_nff.py, the rings), where a leaf is one cylinder.
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        let c = |v: Vec3| v.to_array();
        self.hits::<f32>(c(ray.origin), c(ray.dir), t_min, t_max).hit()
    }

    /// [`Cylinder::intersect`] lane by lane ([`Lanes`]: one ray, or several against this
    /// cylinder): the nearest candidate per lane. The one cylinder test, for every width.
    #[inline(always)]
    pub(crate) fn hits<L: Lanes>(&self, o: V3<L>, d: V3<L>, t_min: L, t_max: L) -> Nearest<L> {
        let zero = L::splat(0.0);
        let axis = splat3::<L>(self.axis);
        let o = sub(o, splat3(self.base));
        let oa = dot(o, axis);
        let da = dot(d, axis);
        let o_perp = sub_scaled(o, oa, axis);
        let d_perp = sub_scaled(d, da, axis);
        let r2 = L::splat(self.radius * self.radius);
        let mut best = Nearest::new(t_min, t_max);

        // Side: |o_perp + t d_perp|² = r², half-b form. As for the sphere, the
        // discriminant is taken from the distance of closest approach in the cross
        // section, which avoids the cancellation of b² - a c.
        let a = dot(d_perp, d_perp);
        let wall = a.gt(L::splat(1e-12));
        if L::bits(wall) != 0 {
            let b = dot(o_perp, d_perp);
            let closest = sub_scaled(o_perp, b / a, d_perp);
            let disc = a * (r2 - dot(closest, closest));
            let real = wall & disc.ge(zero);
            if L::bits(real) != 0 {
                let c = dot(o_perp, o_perp) - r2;
                let q = -(b + disc.sqrt().copysign(b));
                let height = L::splat(self.height);
                for t in [c / q, q / a] {
                    let h = oa + t * da;
                    best.take(real & best.improves(t) & h.ge(zero) & h.le(height), t, part::SIDE);
                }
            }
        }

        if self.caps {
            let across = da.ne(zero);
            if L::bits(across) != 0 {
                for (plane, id) in [(0.0, part::BASE_CAP), (self.height, part::TOP_CAP)] {
                    let t = (L::splat(plane) - oa) / da;
                    let p = add_scaled(o_perp, t, d_perp);
                    best.take(across & best.improves(t) & dot(p, p).le(r2), t, id);
                }
            }
        }
        best
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
        let u = || {
            let (e1, e2) = orthonormal_basis(self.axis);
            turn_fraction(radial, e1, e2)
        };
        let (point, normal, uv) = match hit.part {
            part::BASE_CAP | part::TOP_CAP => {
                let (plane, normal) =
                    if hit.part == part::TOP_CAP { (self.height, self.axis) } else { (0.0, -self.axis) };
                // Polar: u around the axis as on the wall (the seam lines up), v outwards.
                let uv = if want_uv {
                    let rho = if self.radius > 0.0 { (radial.length() / self.radius).min(1.0) } else { 0.0 };
                    Vec2::new(u(), rho)
                } else {
                    Vec2::ZERO
                };
                (self.base + plane * self.axis + radial, normal, uv)
            }
            _ => {
                let normal = radial.try_normalize().unwrap_or_else(|| orthonormal_basis(self.axis).0);
                let uv = if want_uv {
                    // v runs down the image: its top row at the top end (base + height·axis).
                    let v = if self.height > 0.0 { (h / self.height).clamp(0.0, 1.0) } else { 0.0 };
                    Vec2::new(u(), 1.0 - v)
                } else {
                    Vec2::ZERO
                };
                // Snapped onto the wall so secondary rays start on the surface.
                (self.base + h * self.axis + self.radius * normal, normal, uv)
            }
        };
        Surface { point, normal, uv }
    }

    pub fn bounds(&self) -> Aabb {
        disc_bounds(self.base, self.axis, self.radius).union(disc_bounds(
            self.base + self.height * self.axis,
            self.axis,
            self.radius,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::test_util::{Rng, assert_close, assert_offset_rays_do_not_hit_again, assert_vec_close};

    /// Radius 1, from y = -1 to y = 1, centred on (0, 0, -5).
    fn upright(caps: bool) -> Cylinder {
        Cylinder::new(Vec3::new(0.0, -1.0, -5.0), Vec3::Y, 1.0, 2.0, caps)
    }

    fn ray(o: [f32; 3], d: [f32; 3]) -> Ray {
        Ray::new(Vec3::from(o), Vec3::from(d))
    }

    fn hit(c: &Cylinder, r: &Ray) -> (Hit, Surface) {
        let h = c.intersect(r, 0.0, f32::INFINITY).expect("expected a hit");
        (h, c.surface(r, &h))
    }

    #[test]
    fn side_hit_from_outside() {
        let c = upright(true);
        let r = ray([0.0, 0.0, 0.0], [0.0, 0.0, -1.0]);
        let (h, s) = hit(&c, &r);
        assert_close(h.t, 4.0, 1e-5);
        assert_eq!(h.part, part::SIDE);
        assert_vec_close(s.normal, Vec3::Z, 1e-5);
        assert_vec_close(s.point, Vec3::new(0.0, 0.0, -4.0), 1e-5);
    }

    #[test]
    fn side_hit_from_outside_off_centre() {
        // x = 0.6: wall at z = -5 + 0.8, normal (0.6, 0, 0.8).
        let c = upright(true);
        let (h, s) = hit(&c, &ray([0.6, 0.5, 0.0], [0.0, 0.0, -1.0]));
        assert_close(h.t, 4.2, 1e-5);
        assert_vec_close(s.normal, Vec3::new(0.6, 0.0, 0.8), 1e-5);
        assert_close(s.uv.y, 0.25, 1e-5); // 3/4 of the way up: a quarter down the image
    }

    #[test]
    fn from_inside_hits_far_wall() {
        let c = upright(true);
        let (h, s) = hit(&c, &ray([0.0, 0.0, -5.0], [1.0, 0.0, 0.0]));
        assert_close(h.t, 1.0, 1e-5);
        assert_eq!(h.part, part::SIDE);
        assert_vec_close(s.normal, Vec3::X, 1e-5);
    }

    #[test]
    fn from_inside_hits_top_cap() {
        let c = upright(true);
        let (h, s) = hit(&c, &ray([0.2, 0.25, -5.0], [0.0, 1.0, 0.0]));
        assert_close(h.t, 0.75, 1e-5);
        assert_eq!(h.part, part::TOP_CAP);
        assert_vec_close(s.normal, Vec3::Y, 1e-6);
    }

    #[test]
    fn grazing_side_tangent_conventions() {
        let c = upright(true);
        let down = [0.0, 0.0, -1.0];
        assert_eq!(c.intersect(&ray([1.0 + 1e-3, 0.0, 0.0], down), 0.0, f32::INFINITY), None);
        let h = c.intersect(&ray([1.0 - 1e-3, 0.0, 0.0], down), 0.0, f32::INFINITY).unwrap();
        assert_close(h.t, 5.0 - (1.0f32 - 0.999 * 0.999).sqrt(), 1e-4);
        // Exactly tangent: counts as a hit, with a finite normal.
        let r = ray([1.0, 0.0, 0.0], down);
        let (h, s) = hit(&c, &r);
        assert_close(h.t, 5.0, 1e-5);
        assert_vec_close(s.normal, Vec3::X, 1e-5);
    }

    #[test]
    fn grazing_along_the_wall_and_over_the_rim() {
        let c = upright(true);
        // Running down the wall itself, parallel to the axis: the wall is not hit, the
        // top cap's rim is (inclusive), and nothing is NaN.
        let r = ray([1.0, 3.0, -5.0], [0.0, -1.0, 0.0]);
        let h = c.intersect(&r, 0.0, f32::INFINITY).unwrap();
        assert!(h.t.is_finite());
        assert_eq!(h.part, part::TOP_CAP);
        assert_close(h.t, 2.0, 1e-5);
        // Just outside the wall, parallel: miss.
        assert_eq!(c.intersect(&ray([1.001, 3.0, -5.0], [0.0, -1.0, 0.0]), 0.0, f32::INFINITY), None);
        // Skimming just over the top: miss; just under: side wall.
        assert_eq!(c.intersect(&ray([0.0, 1.001, 0.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY), None);
        let h = c.intersect(&ray([0.0, 0.999, 0.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY).unwrap();
        assert_eq!(h.part, part::SIDE);
        assert_close(h.t, 4.0, 1e-5);
    }

    #[test]
    fn cylinder_behind_origin_is_missed() {
        for caps in [false, true] {
            let c = upright(caps);
            assert_eq!(c.intersect(&ray([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]), 0.0, f32::INFINITY), None);
            assert_eq!(c.intersect(&ray([0.0, 5.0, -5.0], [0.0, 1.0, 0.0]), 0.0, f32::INFINITY), None);
        }
    }

    #[test]
    fn respects_t_max() {
        let c = upright(true);
        let r = ray([0.0, 0.0, 0.0], [0.0, 0.0, -1.0]);
        assert_eq!(c.intersect(&r, 0.0, 3.99), None);
        assert!(c.intersect(&r, 0.0, 4.01).is_some());
        // Past the near wall the far one answers.
        assert_close(c.intersect(&r, 4.5, f32::INFINITY).unwrap().t, 6.0, 1e-5);
    }

    #[test]
    fn side_wall_nearer_than_base_cap_wins() {
        // From the left, heading down at 45°: wall at x = -1 (y = -0.5), then the base cap
        // at y = -1 (x = -0.5). The wall is nearer.
        let c = upright(true);
        let r = ray([-2.0, 0.5, -5.0], [1.0, -1.0, 0.0]);
        let (h, s) = hit(&c, &r);
        assert_eq!(h.part, part::SIDE);
        assert_close(h.t, 2.0f32.sqrt(), 1e-5);
        assert_vec_close(s.normal, -Vec3::X, 1e-5);
        // The cap really is on the ray further along.
        let h = c.intersect(&r, 1.5, f32::INFINITY).unwrap();
        assert_eq!(h.part, part::BASE_CAP);
        assert_close(h.t, 1.5 * 2.0f32.sqrt(), 1e-5);
    }

    #[test]
    fn top_cap_nearer_than_side_wall_wins() {
        // From above, slanting: top cap at x = -0.5, then the wall (from inside) at x = -1.
        let c = upright(true);
        let r = ray([0.0, 2.0, -5.0], [-0.5, -1.0, 0.0]);
        let (h, s) = hit(&c, &r);
        assert_eq!(h.part, part::TOP_CAP);
        assert_close(h.t, 1.25f32.sqrt(), 1e-5);
        assert_vec_close(s.normal, Vec3::Y, 1e-6);
        // Without caps the inside of the wall is hit, normal still outward.
        let open = upright(false);
        let (h, s) = hit(&open, &r);
        assert_eq!(h.part, part::SIDE);
        assert_close(h.t, 5.0f32.sqrt(), 1e-5);
        assert_vec_close(s.normal, -Vec3::X, 1e-5);
    }

    #[test]
    fn along_axis_from_above_and_below() {
        let c = upright(true);
        let (h, s) = hit(&c, &ray([0.0, 5.0, -5.0], [0.0, -1.0, 0.0]));
        assert_eq!(h.part, part::TOP_CAP);
        assert_close(h.t, 4.0, 1e-5);
        assert_vec_close(s.normal, Vec3::Y, 1e-6);
        let (h, s) = hit(&c, &ray([0.5, -5.0, -5.0], [0.0, 1.0, 0.0]));
        assert_eq!(h.part, part::BASE_CAP);
        assert_close(h.t, 4.0, 1e-5);
        assert_vec_close(s.normal, -Vec3::Y, 1e-6);
        // Open tube: straight through.
        assert_eq!(upright(false).intersect(&ray([0.0, 5.0, -5.0], [0.0, -1.0, 0.0]), 0.0, f32::INFINITY), None);
    }

    #[test]
    fn tilted_cylinder_hit() {
        // Axis along +x from x = 0 to x = 4, radius 0.5, at y = 0, z = -3.
        let c = Cylinder::new(Vec3::new(0.0, 0.0, -3.0), Vec3::new(2.0, 0.0, 0.0), 0.5, 4.0, true);
        assert_eq!(c.axis, Vec3::X);
        let (h, s) = hit(&c, &ray([1.0, 0.0, 0.0], [0.0, 0.0, -1.0]));
        assert_close(h.t, 2.5, 1e-5);
        assert_vec_close(s.normal, Vec3::Z, 1e-5);
        assert_close(s.uv.y, 0.75, 1e-5);
        let (h, s) = hit(&c, &ray([6.0, 0.1, -3.0], [-1.0, 0.0, 0.0]));
        assert_eq!(h.part, part::TOP_CAP);
        assert_close(h.t, 2.0, 1e-5);
        assert_vec_close(s.normal, Vec3::X, 1e-6);
    }

    #[test]
    fn offset_rays_do_not_hit_again() {
        let c = Cylinder::new(Vec3::new(2.0, -1.0, -20.0), Vec3::new(0.3, 1.0, 0.2), 1.5, 3.0, true);
        assert_offset_rays_do_not_hit_again(c, 17, |_| false);
    }

    #[test]
    fn uv_stays_in_unit_square() {
        let c = upright(true);
        let mut rng = Rng::new(5);
        let b = c.bounds();
        for _ in 0..1000 {
            let r = rng.ray(b.min, b.max, 2.0);
            if let Some(h) = c.intersect(&r, 0.0, f32::INFINITY) {
                let uv = c.surface(&r, &h).uv;
                assert!((0.0..=1.0).contains(&uv.x) && (0.0..=1.0).contains(&uv.y), "{uv}");
            }
        }
    }

    #[test]
    fn bounds_are_tight() {
        let b = upright(true).bounds();
        assert_vec_close(b.min, Vec3::new(-1.0, -1.0, -6.0), 1e-6);
        assert_vec_close(b.max, Vec3::new(1.0, 1.0, -4.0), 1e-6);
        // Tilted: contains the rims, and each face of the box is touched by some rim point.
        let c = Cylinder::new(Vec3::new(1.0, 2.0, 3.0), Vec3::new(1.0, 2.0, -0.5), 0.7, 2.5, true);
        let b = c.bounds();
        let (e1, e2) = orthonormal_basis(c.axis);
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for i in 0..3600 {
            let a = std::f32::consts::TAU * i as f32 / 3600.0;
            for h in [0.0, c.height] {
                let p = c.base + h * c.axis + c.radius * (a.cos() * e1 + a.sin() * e2);
                assert!(p.cmpge(b.min - 1e-5).all() && p.cmple(b.max + 1e-5).all());
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
        assert_vec_close(lo, b.min, 1e-3);
        assert_vec_close(hi, b.max, 1e-3);
    }

    /// Signed "distance" whose sign is inside/outside and whose magnitude never exceeds
    /// the true distance: enough to detect a skipped crossing.
    fn sdf(c: &Cylinder, p: Vec3) -> f32 {
        let local = p - c.base;
        let h = local.dot(c.axis);
        let rho = (local - h * c.axis).length();
        (rho - c.radius).max((-h).max(h - c.height))
    }

    fn random_rays(caps: bool, seed: u64) {
        let c = Cylinder::new(Vec3::new(0.3, -0.7, 0.5), Vec3::new(0.2, 1.0, -0.4), 0.8, 1.7, caps);
        let b = c.bounds();
        let mut rng = Rng::new(seed);
        let tol = 1e-3 * c.radius.max(c.height);
        let mut hits = 0;
        for _ in 0..4000 {
            let r = rng.ray(b.min, b.max, 2.5);
            let t_min = if rng.unit() < 0.5 { 0.0 } else { rng.range(0.0, 2.0) };
            let t_max = if rng.unit() < 0.5 { f32::INFINITY } else { t_min + rng.range(0.0, 8.0) };
            let Some(h) = c.intersect(&r, t_min, t_max) else {
                if caps {
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
                    assert!((rho - c.radius).abs() < tol, "{p} off the wall");
                    assert!(height > -tol && height < c.height + tol);
                }
                part::BASE_CAP => assert!(height.abs() < tol && rho < c.radius + tol),
                part::TOP_CAP => assert!((height - c.height).abs() < tol && rho < c.radius + tol),
                _ => panic!("unknown part"),
            }
            let s = c.surface(&r, &h);
            assert_close(s.normal.length(), 1.0, 1e-4);
            assert!((s.point - p).length() < tol);
            if caps {
                assert_no_crossing(&c, &r, t_min, h.t);
            }
        }
        assert!(hits > 1000, "only {hits} hits");
    }

    fn assert_no_crossing(c: &Cylinder, r: &Ray, t0: f32, t1: f32) {
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
    fn random_rays_hit_on_surface_and_first_with_caps() {
        random_rays(true, 0xC411);
    }

    #[test]
    fn random_rays_hit_on_surface_open_tube() {
        random_rays(false, 0x0BE4);
    }
}
