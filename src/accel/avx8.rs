//! Eight lanes in one AVX register ([`Avx8`]), each operation one AVX instruction with
//! the `f32` operation's IEEE result (compares ordered and quiet: false on NaN, as in
//! Rust; `ne` unordered, as Rust's `!=`). The lane type on which the geometry module's
//! shape tests run eight wide: spheres in packs of eight ([`super::sphere8`]) and eight
//! camera or shadow rays against one shape ([`super::packet8`]). (On the portable
//! [`F8`], whose loops LLVM is left to vectorize, they came out as shuffles and 4-wide
//! halves, some 20 % slower.)
//!
//! Sound only where AVX2 runs: every method is `#[inline(always)]` and used only inlined
//! into `#[target_feature(enable = "avx2")]` functions (`Sphere8::intersect_avx2` and
//! `packet8`'s), which are called only where the processor has AVX2. No value of these
//! types is made or used elsewhere; keep it so.

#![allow(unsafe_code)]

use crate::math::lanes::{F8, Lanes};
use std::arch::x86_64::*;
use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Sub};

#[derive(Clone, Copy)]
pub(super) struct Avx8(pub(super) __m256);

/// The mask of a compare: all bits set in the lanes that hold.
#[derive(Clone, Copy)]
pub(super) struct Mask8(__m256);

// SAFETY (every `unsafe` block in this file): it runs only inlined into a function built
// for AVX2 (`Sphere8::intersect_avx2` or one of `packet8`'s), called only where the
// processor has AVX2, which is all the intrinsics below need; the loads and stores
// name their memory's requirements where they make them.
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
        // `F8` is 32-byte aligned, as the aligned load needs.
        Avx8(unsafe { _mm256_load_ps(r.0.as_ptr()) })
    }

    #[inline(always)]
    pub(super) fn store(self) -> F8 {
        let mut out = F8([0.0; 8]);
        // Into an `F8`, 32-byte aligned.
        unsafe { _mm256_store_ps(out.0.as_mut_ptr(), self.0) };
        out
    }

    #[inline(always)]
    pub(super) fn from_array(a: &[f32; 8]) -> Avx8 {
        // Eight f32s from a live `[f32; 8]`; the unaligned load needs no alignment.
        Avx8(unsafe { _mm256_loadu_ps(a.as_ptr()) })
    }

    #[inline(always)]
    pub(super) fn to_array(self) -> [f32; 8] {
        let mut a = [0f32; 8];
        // Eight f32s into a local `[f32; 8]`, unaligned.
        unsafe { _mm256_storeu_ps(a.as_mut_ptr(), self.0) };
        a
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
    fn ne(self, o: Self) -> Mask8 {
        Mask8(unsafe { _mm256_cmp_ps::<_CMP_NEQ_UQ>(self.0, o.0) })
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::lanes::tests::{numbers, scalar_ops};

    /// Every operation on eight pairs, in a function built for AVX2 as the real users are.
    #[target_feature(enable = "avx2")]
    fn ops(a: &[f32; 8], b: &[f32; 8]) -> ([[f32; 8]; 8], [u32; 5], [f32; 8]) {
        let (f, g) = (Avx8::from_array(a), Avx8::from_array(b));
        let wide = [f + g, f - g, f * g, f / g, -f, f.sqrt(), f.abs(), f.copysign(g)].map(Avx8::to_array);
        let masks = [f.lt(g), f.le(g), f.gt(g), f.ge(g), f.ne(g)].map(Avx8::bits);
        (wide, masks, Avx8::select(f.lt(g), f, g).to_array())
    }

    /// As `math::lanes`'s test for the portable lane types: lane by lane, bit for bit.
    #[test]
    fn avx_lanes_are_f32_lane_by_lane() {
        if !std::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut next = numbers();
        for _ in 0..2000 {
            let (a, b): ([f32; 8], [f32; 8]) = (std::array::from_fn(|_| next()), std::array::from_fn(|_| next()));
            // SAFETY: checked for AVX2 above.
            let (wide, masks, select) = unsafe { ops(&a, &b) };
            for lane in 0..8 {
                let (bits, m, s) = scalar_ops(a[lane], b[lane]);
                assert_eq!(wide.map(|x| x[lane].to_bits()), bits, "{} {}", a[lane], b[lane]);
                assert_eq!(masks.map(|m| m >> lane & 1 == 1), m);
                assert_eq!(select[lane].to_bits(), s);
            }
        }
    }
}
