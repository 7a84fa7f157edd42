//! Spheres in packs of four, laid out lane by lane, so one test runs on four spheres at
//! once. The test is [`Sphere::intersect`]'s own code ([`crate::geometry::sphere_hits`]),
//! so each lane's answer is bit-identical to the scalar one and images do not depend on
//! the path.

use super::tri4::Ray4;
use crate::geometry::Sphere;
use crate::geometry::sphere_hits as hits;
use crate::math::lanes::Lanes;
use glam::Vec4;

/// Four spheres (centre, radius) plus their object indices (`u32::MAX` in unused lanes,
/// whose NaN centres never hit). 80 bytes.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub struct Sphere4 {
    center: [Vec4; 3],
    radius: Vec4,
    pub ids: [u32; 4],
}

impl Sphere4 {
    /// Packs up to four spheres given as (sphere, object index).
    pub fn pack(spheres: &[(Sphere, u32)]) -> Sphere4 {
        debug_assert!(spheres.len() <= 4);
        let nan = Vec4::splat(f32::NAN);
        let mut p = Sphere4 { center: [nan; 3], radius: Vec4::ZERO, ids: [u32::MAX; 4] };
        for (lane, (s, id)) in spheres.iter().enumerate() {
            for axis in 0..3 {
                p.center[axis][lane] = s.center[axis];
            }
            p.radius[lane] = s.radius;
            p.ids[lane] = *id;
        }
        p
    }

    /// Per lane the hit distance, and a bit mask of the lanes hit within `(t_min, t_max)`:
    /// the scalar test's code ([`crate::geometry::sphere_hits`]) four lanes wide.
    #[inline(always)]
    pub fn intersect(&self, r: &Ray4, t_min: f32, t_max: f32) -> (u32, Vec4) {
        let (hit, t) = hits(r.o, r.d, self.center, self.radius, Vec4::splat(t_min), Vec4::splat(t_max));
        (Vec4::bits(hit), t)
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::math::{Ray, Vec3};

    /// Random packs of one to `most` spheres and rays at them (some from inside a sphere,
    /// some far away, some tangent-ish), each tested by `test` (bit mask of the lanes
    /// hit, distance per lane), which must agree with the scalar test lane by lane, bit
    /// for bit, and leave the empty lanes alone.
    pub(in crate::accel) fn against_scalar(
        most: usize,
        mut test: impl FnMut(&[(Sphere, u32)], &Ray, f32, f32) -> (u32, [f32; 8]),
    ) {
        let mut s = 99u64;
        let mut f = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 40) as f32 / (1u64 << 24) as f32) * 4.0 - 2.0
        };
        let (mut hits, mut inside) = (0, 0);
        for _ in 0..20_000 {
            let n = (1 + (f().abs() * 3.9) as usize).min(most);
            let spheres: Vec<_> =
                (0..n as u32).map(|i| (Sphere::new(Vec3::new(f(), f(), f()), f().abs() + 0.01), i)).collect();
            let aim = spheres[(f().abs() * 0.49 * n as f32) as usize].0.center + Vec3::new(f(), f(), f()) * 0.5;
            let origin = Vec3::new(f(), f(), f()) * if f() > 0.0 { 1.0 } else { 4.0 };
            let ray = Ray::new(origin, aim - origin);
            let (t_min, t_max) = (if f() > 1.0 { 0.5 } else { 0.0 }, 2.0 + f() * 0.9);
            let (mask, t) = test(&spheres, &ray, t_min, t_max);
            assert_eq!(mask >> n, 0, "an empty lane hit");
            for (lane, (sphere, _)) in spheres.iter().enumerate() {
                let scalar = sphere.intersect(&ray, t_min, t_max).map(|h| h.t.to_bits());
                let wide = (mask & (1 << lane) != 0).then(|| t[lane].to_bits());
                assert_eq!(scalar, wide, "lane {lane} of {spheres:?}, {ray:?}");
                hits += scalar.is_some() as u32;
                inside += ((origin - sphere.center).length() < sphere.radius) as u32;
            }
        }
        assert!(hits > 5000 && inside > 1000, "{hits} {inside}");
    }

    #[test]
    fn every_lane_matches_the_scalar_test_bit_for_bit() {
        against_scalar(4, |spheres, ray, t_min, t_max| {
            let (mask, t) = Sphere4::pack(spheres).intersect(&Ray4::new(ray), t_min, t_max);
            let t = t.to_array();
            (mask, std::array::from_fn(|i| if i < 4 { t[i] } else { 0.0 }))
        });
    }

    #[test]
    fn empty_lanes_never_hit() {
        let pack = Sphere4::pack(&[(Sphere::new(Vec3::ZERO, 1.0), 7)]);
        for dir in [Vec3::NEG_Z, Vec3::Z, Vec3::X] {
            let (mask, _) = pack.intersect(&Ray4::new(&Ray::new(Vec3::new(0.0, 0.0, 5.0), dir)), 0.0, f32::INFINITY);
            assert!(mask <= 1, "{mask}");
        }
    }
}
