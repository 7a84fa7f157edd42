//! Triangles in packs of four, laid out lane by lane, so one Möller–Trumbore test runs
//! on four triangles at once. The test is the scalar routine's own code
//! ([`crate::geometry::triangle_hits`]), so each lane's result is bit-identical to the
//! scalar one and images do not depend on the path.

use crate::geometry::triangle_hits;
use crate::math::lanes::Lanes;
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

impl Tri4 {
    /// Packs up to four triangles given as (v0, e1, e2, id).
    /// The box of the pack's triangles (its unused lanes, all zeros, left out), from the
    /// corners as the test sees them: `v0`, `v0 + e1`, `v0 + e2`.
    pub fn bounds(&self) -> crate::math::Aabb {
        let mut b = crate::math::Aabb::EMPTY;
        for lane in (0..4).filter(|&lane| self.ids[lane] != u32::MAX) {
            let at = |rows: &[Vec4; 3]| Vec3::new(rows[0][lane], rows[1][lane], rows[2][lane]);
            let v0 = at(&self.v0);
            b = b.grow(v0).grow(v0 + at(&self.e1)).grow(v0 + at(&self.e2));
        }
        b
    }

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
    /// `(t_min, t_max)`: the scalar test's code ([`crate::geometry::triangle_hits`]) four
    /// lanes wide.
    #[inline(always)]
    pub fn intersect(&self, r: &Ray4, t_min: f32, t_max: f32) -> (u32, Vec4, Vec4, Vec4) {
        let (lo, hi) = (Vec4::splat(t_min), Vec4::splat(t_max));
        let (ok, t, b1, b2) = triangle_hits(r.o, r.d, [self.v0, self.e1, self.e2], lo, hi);
        (Vec4::bits(ok), t, b1, b2)
    }
}

/// Two packs in one test of eight lanes (0-3 `a`, 4-7 `b`), for processors with AVX2:
/// [`Tri4::intersect`]'s operations in the same order, lane by lane, so each lane's
/// answer is bit-identical to the four-lane (and the scalar) one. A leaf of five to eight
/// triangles is then one test, not two.
///
/// Calling it is sound only where the processor has AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
#[allow(unsafe_code)]
pub fn intersect_pair(a: &Tri4, b: &Tri4, r: &Ray4, t_min: f32, t_max: f32) -> (u32, [f32; 8], [f32; 8], [f32; 8]) {
    use std::arch::x86_64::*;
    let m = |lo: Vec4, hi: Vec4| _mm256_set_m128(hi.into(), lo.into());
    let m3 = |lo: &[Vec4; 3], hi: &[Vec4; 3]| [m(lo[0], hi[0]), m(lo[1], hi[1]), m(lo[2], hi[2])];
    let (v0, e1, e2) = (m3(&a.v0, &b.v0), m3(&a.e1, &b.e1), m3(&a.e2, &b.e2));
    let (o, d) = (m3(&r.o, &r.o), m3(&r.d, &r.d));
    let (mul, sub, add) = (_mm256_mul_ps, _mm256_sub_ps, _mm256_add_ps);
    let cross = |a: &[__m256; 3], b: &[__m256; 3]| {
        [
            sub(mul(a[1], b[2]), mul(b[1], a[2])),
            sub(mul(a[2], b[0]), mul(b[2], a[0])),
            sub(mul(a[0], b[1]), mul(b[0], a[1])),
        ]
    };
    let dot = |a: &[__m256; 3], b: &[__m256; 3]| add(add(mul(a[0], b[0]), mul(a[1], b[1])), mul(a[2], b[2]));
    let p = cross(&d, &e2);
    let det = dot(&e1, &p);
    let inv = _mm256_div_ps(_mm256_set1_ps(1.0), det);
    let s = [sub(o[0], v0[0]), sub(o[1], v0[1]), sub(o[2], v0[2])];
    let b1 = mul(dot(&s, &p), inv);
    let q = cross(&s, &e1);
    let b2 = mul(dot(&d, &q), inv);
    let t = mul(dot(&e2, &q), inv);
    let (zero, one) = (_mm256_setzero_ps(), _mm256_set1_ps(1.0));
    let abs = _mm256_andnot_ps(_mm256_set1_ps(-0.0), inv);
    let and = _mm256_and_ps;
    let ok = and(
        and(
            and(_mm256_cmp_ps::<_CMP_LT_OQ>(abs, _mm256_set1_ps(f32::INFINITY)), _mm256_cmp_ps::<_CMP_GE_OQ>(b1, zero)),
            and(_mm256_cmp_ps::<_CMP_LE_OQ>(b1, one), _mm256_cmp_ps::<_CMP_GE_OQ>(b2, zero)),
        ),
        and(
            and(_mm256_cmp_ps::<_CMP_LE_OQ>(add(b1, b2), one), _mm256_cmp_ps::<_CMP_GT_OQ>(t, _mm256_set1_ps(t_min))),
            _mm256_cmp_ps::<_CMP_LT_OQ>(t, _mm256_set1_ps(t_max)),
        ),
    );
    let mask = _mm256_movemask_ps(ok) as u32;
    if mask == 0 {
        return (0, [0.0; 8], [0.0; 8], [0.0; 8]);
    }
    let out = |v: __m256| {
        let mut a = [0f32; 8];
        // SAFETY: an unaligned store of eight f32s into a local `[f32; 8]`.
        unsafe { _mm256_storeu_ps(a.as_mut_ptr(), v) };
        a
    };
    (mask, out(t), out(b1), out(b2))
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::geometry::intersect_triangle;

    /// Uniform numbers in [-2, 2) from a seeded LCG.
    pub(in crate::accel) fn numbers(mut s: u64) -> impl FnMut() -> f32 {
        move || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 40) as f32 / (1u64 << 24) as f32) * 4.0 - 2.0
        }
    }

    #[test]
    fn every_lane_matches_the_scalar_test_bit_for_bit() {
        let mut f = numbers(12345);
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

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn a_pair_of_packs_matches_two_four_lane_tests_bit_for_bit() {
        if !std::is_x86_feature_detected!("avx2") {
            eprintln!("no AVX2 here: the pair test is not run");
            return;
        }
        let mut f = numbers(777);
        let mut hits = 0;
        for _ in 0..10_000 {
            let tris: Vec<_> = (0..8)
                .map(|i| (Vec3::new(f(), f(), f()), Vec3::new(f(), f(), f()), Vec3::new(f(), f(), f()), i))
                .collect();
            let (a, b) = (Tri4::pack(&tris[..4]), Tri4::pack(&tris[4..]));
            let (v0, e1, e2, _) = tris[(f().abs() * 3.9) as usize];
            let origin = Vec3::new(f(), f(), f()) * 3.0;
            let ray = Ray4::new(&Ray::new(origin, v0 + (e1 + e2) * 0.33 - origin));
            let (t_min, t_max) = (if f() > 1.0 { 0.5 } else { 0.0 }, 3.0 + f());
            // SAFETY: AVX2 was detected above.
            #[allow(unsafe_code)]
            let (mask, t, b1, b2) = unsafe { intersect_pair(&a, &b, &ray, t_min, t_max) };
            for (half, pack) in [&a, &b].into_iter().enumerate() {
                let (m4, t4, b14, b24) = pack.intersect(&ray, t_min, t_max);
                assert_eq!((mask >> (4 * half)) & 15, m4);
                for lane in (0..4).filter(|l| m4 & (1 << l) != 0) {
                    let k = 4 * half + lane;
                    assert_eq!(
                        (t[k].to_bits(), b1[k].to_bits(), b2[k].to_bits()),
                        (t4[lane].to_bits(), b14[lane].to_bits(), b24[lane].to_bits())
                    );
                    hits += 1;
                }
            }
        }
        assert!(hits > 1000, "{hits}");
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
