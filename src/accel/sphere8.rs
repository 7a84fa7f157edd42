//! Spheres in packs of eight, for where the eight-lane code runs ([`super::lanes::avx2`]):
//! the sphere test ([`crate::geometry::sphere_hits`]) on eight AVX lanes ([`Avx8`]), so a
//! leaf of up to eight spheres is one test rather than two [`super::sphere4::Sphere4`]
//! tests, and the tree over them (built with packs of eight) is shallower. Each lane's
//! answer is the scalar test's bit for bit, as with four lanes. Sphereflake (SPD balls
//! 4, depth 5, 1 thread) 165 -> 158 ms, sphere-cloud-1M primary 1.42 -> 1.52 Mrays/s.

use crate::geometry::Sphere;
use crate::geometry::sphere_hits as hits;
use crate::math::Ray;
use crate::math::lanes::{self, F8, Lanes};
#[cfg(target_arch = "x86_64")]
use avx8::Avx8;

/// Eight spheres (centre, radius) lane by lane plus their object indices (`u32::MAX` in
/// unused lanes, whose NaN centres never hit). 160 bytes.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub struct Sphere8 {
    center: [F8; 3],
    radius: F8,
    pub ids: [u32; 8],
}

impl Sphere8 {
    /// Packs up to eight spheres given as (sphere, object index).
    pub fn pack(spheres: &[(Sphere, u32)]) -> Sphere8 {
        debug_assert!(spheres.len() <= 8);
        let nan = F8::splat(f32::NAN);
        let mut p = Sphere8 { center: [nan; 3], radius: F8::splat(0.0), ids: [u32::MAX; 8] };
        for (lane, (s, id)) in spheres.iter().enumerate() {
            for axis in 0..3 {
                p.center[axis].0[lane] = s.center[axis];
            }
            p.radius.0[lane] = s.radius;
            p.ids[lane] = *id;
        }
        p
    }

    /// A bit mask of the lanes hit within `(t_min, t_max)`, and per lane the distance.
    /// With AVX2 (packs of eight are made only then) on AVX lanes, inlined into the
    /// 8-wide walk's leaf code ([`super::leaf_avx2`]); else (tests, `WHITTED_PORTABLE=1`)
    /// the same test on portable [`F8`] lanes.
    #[inline(always)]
    #[allow(unsafe_code)]
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> (u32, F8) {
        #[cfg(target_arch = "x86_64")]
        if super::lanes::avx2() {
            // SAFETY: the processor has AVX2.
            return unsafe { self.intersect_avx2(ray, t_min, t_max) };
        }
        self.intersect_lanes(ray, t_min, t_max)
    }

    /// The test on [`Avx8`] lanes: the same source, as 8-wide AVX instructions. (On
    /// [`F8`], whose loops LLVM is left to vectorize, it came out as a tangle of
    /// shuffles and 4-wide halves, and the sphereflake rendered 20 % slower.)
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    fn intersect_avx2(&self, ray: &Ray, t_min: f32, t_max: f32) -> (u32, F8) {
        let row = |r: &F8| Avx8::load(r);
        let (o, d) = (lanes::splat3::<Avx8>(ray.origin), lanes::splat3::<Avx8>(ray.dir));
        let (hit, t) =
            hits(o, d, self.center.each_ref().map(row), row(&self.radius), Avx8::splat(t_min), Avx8::splat(t_max));
        (Avx8::bits(hit), t.store())
    }

    /// The portable path: the same test on [`F8`] lanes.
    #[inline(always)]
    fn intersect_lanes(&self, ray: &Ray, t_min: f32, t_max: f32) -> (u32, F8) {
        let (o, d) = (lanes::splat3::<F8>(ray.origin), lanes::splat3::<F8>(ray.dir));
        let (hit, t) = hits(o, d, self.center, self.radius, F8::splat(t_min), F8::splat(t_max));
        (F8::bits(hit), t)
    }
}

/// Eight lanes in one AVX register, each operation one AVX instruction with the `f32`
/// operation's IEEE result (compares ordered and quiet: false on NaN, as in Rust).
/// Private to [`Sphere8::intersect_avx2`], whose `#[target_feature(enable = "avx2")]`
/// is what makes using these instructions sound: no value of it exists elsewhere.
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
mod avx8 {
    use super::F8;
    use crate::math::lanes::Lanes;
    use std::arch::x86_64::*;
    use std::ops::{Add, Div, Mul, Neg, Sub};

    #[derive(Clone, Copy)]
    pub(super) struct Avx8(__m256);

    /// The mask of a compare: all bits set in the lanes that hold.
    #[derive(Clone, Copy)]
    pub(super) struct Mask8(__m256);

    // SAFETY (every block below): these run only inlined into
    // `Sphere8::intersect_avx2`, built for AVX2, called only where the processor has it.
    macro_rules! binary {
        ($trait:ident, $f:ident, $t:ident, $intr:ident) => {
            impl $trait for $t {
                type Output = $t;
                #[inline(always)]
                fn $f(self, o: $t) -> $t {
                    $t(unsafe { $intr(self.0, o.0) })
                }
            }
        };
    }
    binary!(Add, add, Avx8, _mm256_add_ps);
    binary!(Sub, sub, Avx8, _mm256_sub_ps);
    binary!(Mul, mul, Avx8, _mm256_mul_ps);
    binary!(Div, div, Avx8, _mm256_div_ps);
    binary!(BitAnd, bitand, Mask8, _mm256_and_ps);
    binary!(BitOr, bitor, Mask8, _mm256_or_ps);
    use std::ops::{BitAnd, BitOr};

    impl Neg for Avx8 {
        type Output = Avx8;
        #[inline(always)]
        fn neg(self) -> Avx8 {
            Avx8(unsafe { _mm256_xor_ps(self.0, _mm256_set1_ps(-0.0)) })
        }
    }

    impl Avx8 {
        #[inline(always)]
        pub(super) fn load(r: &F8) -> Avx8 {
            // `F8` is 32-byte aligned.
            Avx8(unsafe { _mm256_load_ps(r.0.as_ptr()) })
        }

        #[inline(always)]
        pub(super) fn store(self) -> F8 {
            let mut out = F8([0.0; 8]);
            unsafe { _mm256_store_ps(out.0.as_mut_ptr(), self.0) };
            out
        }
    }

    impl Lanes for Avx8 {
        type Mask = Mask8;

        #[inline(always)]
        fn splat(x: f32) -> Self {
            Avx8(unsafe { _mm256_set1_ps(x) })
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            Avx8(unsafe { _mm256_sqrt_ps(self.0) })
        }
        #[inline(always)]
        fn abs(self) -> Self {
            Avx8(unsafe { _mm256_andnot_ps(_mm256_set1_ps(-0.0), self.0) })
        }
        #[inline(always)]
        fn copysign(self, sign: Self) -> Self {
            unsafe {
                let s = _mm256_set1_ps(-0.0);
                Avx8(_mm256_or_ps(_mm256_andnot_ps(s, self.0), _mm256_and_ps(s, sign.0)))
            }
        }
        #[inline(always)]
        fn lt(self, o: Self) -> Mask8 {
            Mask8(unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn le(self, o: Self) -> Mask8 {
            Mask8(unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn gt(self, o: Self) -> Mask8 {
            Mask8(unsafe { _mm256_cmp_ps::<_CMP_GT_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn ge(self, o: Self) -> Mask8 {
            Mask8(unsafe { _mm256_cmp_ps::<_CMP_GE_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn select(mask: Mask8, a: Self, b: Self) -> Self {
            Avx8(unsafe { _mm256_blendv_ps(b.0, a.0, mask.0) })
        }
        #[inline(always)]
        fn bits(mask: Mask8) -> u32 {
            unsafe { _mm256_movemask_ps(mask.0) as u32 }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    #[test]
    fn every_lane_matches_the_scalar_test_bit_for_bit() {
        super::super::sphere4::tests::against_scalar(8, |spheres, ray, t_min, t_max| {
            let pack = Sphere8::pack(spheres);
            let (mask, t) = pack.intersect(ray, t_min, t_max);
            // Where AVX2 runs, `intersect` took the AVX lanes: the portable ones agree.
            let (mask_f8, t_f8) = pack.intersect_lanes(ray, t_min, t_max);
            assert_eq!(mask, mask_f8);
            for lane in (0..8).filter(|l| mask >> l & 1 == 1) {
                assert_eq!(t.0[lane].to_bits(), t_f8.0[lane].to_bits());
            }
            (mask, t.0)
        });
    }
}
