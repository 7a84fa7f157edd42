//! One ray or several side by side: the arithmetic a shape test needs, for a lane type
//! that is a plain `f32` (one ray) or a vector of them (one ray against several shapes,
//! lane by lane). A test written once, generic over [`Lanes`], is the same source for
//! every width, as Mitsuba 3 instantiates one shading code as scalar or wide variants:
//! each lane does the scalar test's operations in the same order, so its answer is the
//! scalar one bit for bit, and images do not depend on which width ran.
//!
//! `f32` and glam's [`Vec4`] (SSE2 on x86-64, NEON on aarch64, scalar elsewhere) are
//! lane types; nothing here is architecture-specific.

use glam::{BVec4A, Vec4};
use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Sub};

/// A number per lane.
pub trait Lanes:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self> + Neg<Output = Self>
{
    /// A yes or no per lane.
    type Mask: Copy + BitAnd<Output = Self::Mask> + BitOr<Output = Self::Mask>;

    fn splat(x: f32) -> Self;
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    /// The magnitude of `self` with the sign of `sign` (`f32::copysign`, lane by lane).
    fn copysign(self, sign: Self) -> Self;
    fn lt(self, other: Self) -> Self::Mask;
    fn le(self, other: Self) -> Self::Mask;
    fn gt(self, other: Self) -> Self::Mask;
    fn ge(self, other: Self) -> Self::Mask;
    /// Unordered, as Rust's `!=`: true where either side is NaN.
    fn ne(self, other: Self) -> Self::Mask;
    /// `a` where `mask`, else `b`.
    fn select(mask: Self::Mask, a: Self, b: Self) -> Self;
    /// The lanes of `mask` as bits, lane 0 lowest.
    fn bits(mask: Self::Mask) -> u32;
}

impl Lanes for f32 {
    type Mask = bool;

    #[inline(always)]
    fn splat(x: f32) -> Self {
        x
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32::sqrt(self)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32::abs(self)
    }
    #[inline(always)]
    fn copysign(self, sign: Self) -> Self {
        f32::copysign(self, sign)
    }
    #[inline(always)]
    fn lt(self, other: Self) -> bool {
        self < other
    }
    #[inline(always)]
    fn le(self, other: Self) -> bool {
        self <= other
    }
    #[inline(always)]
    fn gt(self, other: Self) -> bool {
        self > other
    }
    #[inline(always)]
    fn ge(self, other: Self) -> bool {
        self >= other
    }
    #[inline(always)]
    fn ne(self, other: Self) -> bool {
        self != other
    }
    #[inline(always)]
    fn select(mask: bool, a: Self, b: Self) -> Self {
        if mask { a } else { b }
    }
    #[inline(always)]
    fn bits(mask: bool) -> u32 {
        mask as u32
    }
}

impl Lanes for Vec4 {
    type Mask = BVec4A;

    #[inline(always)]
    fn splat(x: f32) -> Self {
        Vec4::splat(x)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        Vec4::sqrt(self)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        Vec4::abs(self)
    }
    #[inline(always)]
    fn copysign(self, sign: Self) -> Self {
        Vec4::copysign(self, sign)
    }
    #[inline(always)]
    fn lt(self, other: Self) -> BVec4A {
        self.cmplt(other)
    }
    #[inline(always)]
    fn le(self, other: Self) -> BVec4A {
        self.cmple(other)
    }
    #[inline(always)]
    fn gt(self, other: Self) -> BVec4A {
        self.cmpgt(other)
    }
    #[inline(always)]
    fn ge(self, other: Self) -> BVec4A {
        self.cmpge(other)
    }
    #[inline(always)]
    fn ne(self, other: Self) -> BVec4A {
        self.cmpne(other)
    }
    #[inline(always)]
    fn select(mask: BVec4A, a: Self, b: Self) -> Self {
        Vec4::select(mask, a, b)
    }
    #[inline(always)]
    fn bits(mask: BVec4A) -> u32 {
        mask.bitmask()
    }
}

/// Three lanes-wide numbers: a vector per lane, axis by axis.
pub type V3<L> = [L; 3];

/// The lanes a bit mask selects (its set bits), lowest first, one step each: a loop
/// over all eight lanes that skips the others branches on each lane's bit, which the
/// branch predictor cannot guess where lanes come and go with the data.
#[inline(always)]
pub fn set_lanes(mut mask: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let lane = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            lane
        })
    })
}

/// glam's `Vec3::dot`, `(x·x') + (y·y') + (z·z')`, left to right.
#[inline(always)]
pub fn dot<L: Lanes>(a: V3<L>, b: V3<L>) -> L {
    (a[0] * b[0]) + (a[1] * b[1]) + (a[2] * b[2])
}

/// glam's `Vec3::cross`.
#[inline(always)]
pub fn cross<L: Lanes>(a: V3<L>, b: V3<L>) -> V3<L> {
    [a[1] * b[2] - b[1] * a[2], a[2] * b[0] - b[2] * a[0], a[0] * b[1] - b[0] * a[1]]
}

/// `a - b`, axis by axis.
#[inline(always)]
pub fn sub<L: Lanes>(a: V3<L>, b: V3<L>) -> V3<L> {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `a - s·b`, axis by axis (glam's `a - s * b`).
#[inline(always)]
pub fn sub_scaled<L: Lanes>(a: V3<L>, s: L, b: V3<L>) -> V3<L> {
    [a[0] - s * b[0], a[1] - s * b[1], a[2] - s * b[2]]
}

/// `a + s·b`, axis by axis (glam's `a + s * b`).
#[inline(always)]
pub fn add_scaled<L: Lanes>(a: V3<L>, s: L, b: V3<L>) -> V3<L> {
    [a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2]]
}

/// A glam vector as one lane type per axis, the same in every lane.
#[inline(always)]
pub fn splat3<L: Lanes>(v: glam::Vec3) -> V3<L> {
    [L::splat(v.x), L::splat(v.y), L::splat(v.z)]
}

/// Eight lanes as a plain array, every operation a loop over the lanes: where it is
/// inlined into code built for AVX2 the compiler makes each loop one 8-wide
/// instruction; elsewhere it stays correct, lane after lane.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub struct F8(pub [f32; 8]);

/// A yes or no per lane of [`F8`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct M8(pub [bool; 8]);

macro_rules! lanewise {
    ($trait:ident, $f:ident, $t:ty, $op:tt) => {
        impl $trait for $t {
            type Output = $t;
            #[inline(always)]
            fn $f(self, o: $t) -> $t {
                let (a, b) = (self.0, o.0);
                Self(std::array::from_fn(|i| a[i] $op b[i]))
            }
        }
    };
}
lanewise!(Add, add, F8, +);
lanewise!(Sub, sub, F8, -);
lanewise!(Mul, mul, F8, *);
lanewise!(Div, div, F8, /);
lanewise!(BitAnd, bitand, M8, &);
lanewise!(BitOr, bitor, M8, |);

impl Neg for F8 {
    type Output = F8;
    #[inline(always)]
    fn neg(self) -> F8 {
        F8(self.0.map(|x| -x))
    }
}

impl F8 {
    #[inline(always)]
    fn compare(self, o: F8, f: impl Fn(f32, f32) -> bool) -> M8 {
        M8(std::array::from_fn(|i| f(self.0[i], o.0[i])))
    }
}

impl Lanes for F8 {
    type Mask = M8;

    #[inline(always)]
    fn splat(x: f32) -> Self {
        F8([x; 8])
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        F8(self.0.map(f32::sqrt))
    }
    #[inline(always)]
    fn abs(self) -> Self {
        F8(self.0.map(f32::abs))
    }
    #[inline(always)]
    fn copysign(self, sign: Self) -> Self {
        F8(std::array::from_fn(|i| self.0[i].copysign(sign.0[i])))
    }
    #[inline(always)]
    fn lt(self, o: Self) -> M8 {
        self.compare(o, |a, b| a < b)
    }
    #[inline(always)]
    fn le(self, o: Self) -> M8 {
        self.compare(o, |a, b| a <= b)
    }
    #[inline(always)]
    fn gt(self, o: Self) -> M8 {
        self.compare(o, |a, b| a > b)
    }
    #[inline(always)]
    fn ge(self, o: Self) -> M8 {
        self.compare(o, |a, b| a >= b)
    }
    #[inline(always)]
    fn ne(self, o: Self) -> M8 {
        self.compare(o, |a, b| a != b)
    }
    #[inline(always)]
    fn select(mask: M8, a: Self, b: Self) -> Self {
        F8(std::array::from_fn(|i| if mask.0[i] { a.0[i] } else { b.0[i] }))
    }
    #[inline(always)]
    fn bits(mask: M8) -> u32 {
        mask.0.iter().enumerate().fold(0, |bits, (i, &m)| bits | (m as u32) << i)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Test numbers: ordinary ones in [-4, 4) and, one time in two or so, a special one
    /// (NaN, infinities, signed zeros, tiny and huge).
    pub(crate) fn numbers() -> impl FnMut() -> f32 {
        let specials = [0.0, -0.0, 1.0, -1.5, 1e-30, -3e30, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, 2.5];
        let mut s = 7u64;
        move || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            match (s >> 60) as usize {
                k if k < specials.len() => specials[k],
                _ => ((s >> 33) as f32 / (1u64 << 31) as f32) * 8.0 - 4.0,
            }
        }
    }

    /// Every operation of [`Lanes`] on one pair of `f32`s: results as bits, compares
    /// (`lt`, `le`, `gt`, `ge`, `ne`), and `select` on `lt`.
    pub(crate) fn scalar_ops(x: f32, y: f32) -> ([u32; 8], [bool; 5], u32) {
        let bits = [x + y, x - y, x * y, x / y, -x, x.sqrt(), x.abs(), x.copysign(y)].map(f32::to_bits);
        let masks = [x.lt(y), x.le(y), x.gt(y), x.ge(y), Lanes::ne(x, y)];
        (bits, masks, <f32 as Lanes>::select(x.lt(y), x, y).to_bits())
    }

    /// `set_lanes` gives each set bit's lane once, lowest first, and nothing else.
    #[test]
    fn set_lanes_are_the_set_bits_in_order() {
        for mask in 0..=0xffu32 {
            let got: Vec<usize> = set_lanes(mask).collect();
            let want: Vec<usize> = (0..8).filter(|k| mask >> k & 1 != 0).collect();
            assert_eq!(got, want, "{mask:#b}");
        }
        assert_eq!(set_lanes(1 << 31).collect::<Vec<_>>(), [31]);
    }

    /// Every operation of the wide lane types, lane by lane, is the `f32` one bit for bit
    /// (NaN, infinities, signed zeros included): what makes one test's code answer the
    /// same at every width. (`accel::avx8` checks its AVX lanes the same way.)
    #[test]
    fn wide_lanes_are_f32_lane_by_lane() {
        let mut next = numbers();
        for _ in 0..2000 {
            let (a, b): ([f32; 8], [f32; 8]) = (std::array::from_fn(|_| next()), std::array::from_fn(|_| next()));
            let (f, g) = (F8(a), F8(b));
            let wide8 = [f + g, f - g, f * g, f / g, -f, f.sqrt(), f.abs(), f.copysign(g)];
            let masks8 = [f.lt(g), f.le(g), f.gt(g), f.ge(g), f.ne(g)].map(F8::bits);
            let select8 = F8::select(f.lt(g), f, g);
            let (v, w) = (Vec4::from_slice(&a[..4]), Vec4::from_slice(&b[..4]));
            let wide4 = [v + w, v - w, v * w, v / w, -v, v.sqrt(), Lanes::abs(v), Lanes::copysign(v, w)];
            let masks4 = [v.lt(w), v.le(w), v.gt(w), v.ge(w), Lanes::ne(v, w)].map(Vec4::bits);
            let select4 = <Vec4 as Lanes>::select(v.lt(w), v, w);
            for lane in 0..8 {
                let (bits, masks, select) = scalar_ops(a[lane], b[lane]);
                assert_eq!(wide8.map(|x| x.0[lane].to_bits()), bits, "{} {}", a[lane], b[lane]);
                assert_eq!(masks8.map(|m| m >> lane & 1 == 1), masks);
                assert_eq!(select8.0[lane].to_bits(), select);
                if lane < 4 {
                    assert_eq!(wide4.map(|x| x[lane].to_bits()), bits, "{} {}", a[lane], b[lane]);
                    assert_eq!(masks4.map(|m| m >> lane & 1 == 1), masks);
                    assert_eq!(select4[lane].to_bits(), select);
                }
            }
        }
    }
}
