//! Triangles in packs of four, laid out lane by lane, so one Möller–Trumbore test runs
//! on four triangles at once. The arithmetic is the scalar routine's
//! ([`crate::geometry::intersect_triangle`]) operation for operation, so each lane's
//! result is bit-identical to the scalar one and images do not depend on the path.

use crate::math::{Ray, Vec3};
use glam::Vec4;

/// Four triangles as corner `v0` and edges `e1`, `e2`, plus their ids in the mesh
/// (`u32::MAX` in unused lanes, whose zero edges never hit). 160 bytes.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub struct Tri4 {
    v0: [Vec4; 3],
    e1: [Vec4; 3],
    e2: [Vec4; 3],
    pub ids: [u32; 4],
}

/// A ray splatted across four lanes.
pub struct Ray4 {
    pub(super) o: [Vec4; 3],
    pub(super) d: [Vec4; 3],
}

impl Ray4 {
    #[inline]
    pub fn new(r: &Ray) -> Self {
        let s = |v: Vec3| [Vec4::splat(v.x), Vec4::splat(v.y), Vec4::splat(v.z)];
        Ray4 { o: s(r.origin), d: s(r.dir) }
    }
}

#[inline(always)]
fn cross(a: &[Vec4; 3], b: &[Vec4; 3]) -> [Vec4; 3] {
    [a[1] * b[2] - b[1] * a[2], a[2] * b[0] - b[2] * a[0], a[0] * b[1] - b[0] * a[1]]
}

#[inline(always)]
fn dot(a: &[Vec4; 3], b: &[Vec4; 3]) -> Vec4 {
    (a[0] * b[0]) + (a[1] * b[1]) + (a[2] * b[2])
}

impl Tri4 {
    /// Packs up to four triangles given as (v0, e1, e2, id).
    pub fn pack(tris: &[(Vec3, Vec3, Vec3, u32)]) -> Tri4 {
        debug_assert!(tris.len() <= 4);
        let mut t = Tri4 { v0: [Vec4::ZERO; 3], e1: [Vec4::ZERO; 3], e2: [Vec4::ZERO; 3], ids: [u32::MAX; 4] };
        for (lane, &(v0, e1, e2, id)) in tris.iter().enumerate() {
            for axis in 0..3 {
                t.v0[axis][lane] = v0[axis];
                t.e1[axis][lane] = e1[axis];
                t.e2[axis][lane] = e2[axis];
            }
            t.ids[lane] = id;
        }
        t
    }

    /// Per lane: distance and barycentrics, and a bit mask of the lanes hit within
    /// `(t_min, t_max)`.
    #[inline(always)]
    pub fn intersect(&self, r: &Ray4, t_min: f32, t_max: f32) -> (u32, Vec4, Vec4, Vec4) {
        let p = cross(&r.d, &self.e2);
        let det = dot(&self.e1, &p);
        let inv = Vec4::ONE / det;
        let s = [r.o[0] - self.v0[0], r.o[1] - self.v0[1], r.o[2] - self.v0[2]];
        let b1 = dot(&s, &p) * inv;
        let q = cross(&s, &self.e1);
        let b2 = dot(&r.d, &q) * inv;
        let t = dot(&self.e2, &q) * inv;
        let finite = inv.abs().cmplt(Vec4::INFINITY); // also false for NaN
        let ok = finite
            & b1.cmpge(Vec4::ZERO)
            & b1.cmple(Vec4::ONE)
            & b2.cmpge(Vec4::ZERO)
            & (b1 + b2).cmple(Vec4::ONE)
            & t.cmpgt(Vec4::splat(t_min))
            & t.cmplt(Vec4::splat(t_max));
        (ok.bitmask(), t, b1, b2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::intersect_triangle;

    #[test]
    fn every_lane_matches_the_scalar_test_bit_for_bit() {
        let mut s = 12345u64;
        let mut f = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 40) as f32 / (1u64 << 24) as f32) * 4.0 - 2.0
        };
        let mut hits = 0;
        for _ in 0..20_000 {
            let tris: Vec<_> = (0..4)
                .map(|i| {
                    let v0 = Vec3::new(f(), f(), f());
                    (v0, Vec3::new(f(), f(), f()), Vec3::new(f(), f(), f()), i)
                })
                .collect();
            let pack = Tri4::pack(&tris);
            // Aimed near one triangle's centre, so that many rays hit.
            let (v0, e1, e2, _) = tris[(f().abs() * 1.9) as usize];
            let origin = Vec3::new(f(), f(), f()) * 3.0;
            let target = v0 + (e1 + e2) * 0.33 + Vec3::new(f(), f(), f()) * 0.2;
            let ray = Ray::new(origin, target - origin);
            let (mask, t, b1, b2) = pack.intersect(&Ray4::new(&ray), 0.0, 10.0);
            for (lane, &(v0, e1, e2, _)) in tris.iter().enumerate() {
                let scalar = intersect_triangle(v0, e1, e2, &ray, 0.0, 10.0);
                let wide = (mask & (1 << lane) != 0).then(|| (t[lane], b1[lane], b2[lane]));
                assert_eq!(
                    scalar.map(|(a, b, c)| (a.to_bits(), b.to_bits(), c.to_bits())),
                    wide.map(|(a, b, c)| (a.to_bits(), b.to_bits(), c.to_bits()))
                );
                hits += scalar.is_some() as u32;
            }
        }
        assert!(hits > 10_000, "{hits}");
    }

    #[test]
    fn empty_lanes_never_hit() {
        let pack = Tri4::pack(&[(Vec3::ZERO, Vec3::X, Vec3::Y, 7)]);
        let ray = Ray::new(Vec3::new(0.0, 0.0, 1.0), Vec3::NEG_Z);
        let (mask, ..) = pack.intersect(&Ray4::new(&ray), 0.0, 10.0);
        assert_eq!(mask, 1);
        let ray = Ray::new(Vec3::new(5.0, 5.0, 1.0), Vec3::NEG_Z);
        assert_eq!(pack.intersect(&Ray4::new(&ray), 0.0, 10.0).0, 0);
    }
}
