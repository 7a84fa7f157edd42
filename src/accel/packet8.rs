//! Eight camera (or shadow) rays of an image tile at once against one quad, sphere,
//! cylinder or pointed cone: the tile's rays all test the same few objects
//! ([`super::World::seen_from`]), so going object by object, eight rays a test, replaces
//! eight scalar tests (each a chain of dependent operations) with one. The shape tests
//! are the geometry module's own, generic over the lane type ([`Quad::hits`],
//! [`crate::geometry::sphere_hits`], `Cylinder::hits`, `Cone::pointed_hits`), here on
//! eight AVX lanes ([`Avx8`]): each lane does the scalar test's operations in the same
//! order, so its answer is bit-identical to the scalar one and images do not depend on
//! the path.
//!
//! Calling these is sound only where the processor has AVX2.
//!
//! The shape tests are `#[inline]`, so that [`super::World::eight_lanes`] gets them
//! inlined whichever of the release build's four codegen units they land in: in an
//! experiment that only added code elsewhere, they moved to another unit and were
//! called out of line, each test a call with its rays and best hits read from memory.

use super::avx8::Avx8;
use super::lanes::Best8;
use crate::geometry::{Cone, Cylinder, Nearest, Quad, Sphere, part, sphere_hits};
use crate::math::Ray;
use crate::math::lanes::{self, Lanes};
use std::arch::x86_64::*;

/// Eight rays, lane by lane.
pub struct Rays8 {
    o: [Avx8; 3],
    d: [Avx8; 3],
}

impl Rays8 {
    /// Lanes past the end of `rays` repeat its first ray (their answers are not read).
    ///
    /// Each ray read as two vectors (its origin and the direction's x; the direction's
    /// y and z), turned into rows by shuffles four rays at a time: about 60 instructions
    /// where a float at a time into arrays took 130 (1 % of a room render's).
    #[target_feature(enable = "avx2")]
    pub fn new<T>(rays: &[(Ray, T)]) -> Self {
        let ray = |lane: usize| &rays[if lane < rays.len() { lane } else { 0 }].0;
        let a: [__m128; 8] = std::array::from_fn(|k| {
            let r = ray(k);
            _mm_setr_ps(r.origin.x, r.origin.y, r.origin.z, r.dir.x)
        });
        let b: [__m128; 8] = std::array::from_fn(|k| {
            let r = ray(k);
            _mm_setr_ps(r.dir.y, r.dir.z, 0.0, 0.0)
        });
        // Four rays' vectors as the four rows of their components.
        let rows4 = |v: &[__m128]| {
            let (t0, t1) = (_mm_unpacklo_ps(v[0], v[1]), _mm_unpacklo_ps(v[2], v[3]));
            let (t2, t3) = (_mm_unpackhi_ps(v[0], v[1]), _mm_unpackhi_ps(v[2], v[3]));
            [_mm_movelh_ps(t0, t1), _mm_movehl_ps(t1, t0), _mm_movelh_ps(t2, t3), _mm_movehl_ps(t3, t2)]
        };
        let (a_lo, a_hi, b_lo, b_hi) = (rows4(&a[..4]), rows4(&a[4..]), rows4(&b[..4]), rows4(&b[4..]));
        let row = |lo: __m128, hi: __m128| Avx8(_mm256_set_m128(hi, lo));
        Rays8 {
            o: [row(a_lo[0], a_hi[0]), row(a_lo[1], a_hi[1]), row(a_lo[2], a_hi[2])],
            d: [row(a_lo[3], a_hi[3]), row(b_lo[0], b_hi[0]), row(b_lo[1], b_hi[1])],
        }
    }

    /// Eight rays given lane by lane: origins and directions, a row per axis.
    #[target_feature(enable = "avx2")]
    pub fn from_lanes(origins: &[[f32; 8]; 3], dirs: &[[f32; 8]; 3]) -> Self {
        Rays8 { o: origins.each_ref().map(Avx8::from_array), d: dirs.each_ref().map(Avx8::from_array) }
    }
}

#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
fn load(a: &[f32; 8]) -> __m256 {
    // SAFETY: reads eight f32s from a live `[f32; 8]`; the unaligned load has no
    // alignment requirement.
    unsafe { _mm256_loadu_ps(a.as_ptr()) }
}

#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
fn store(v: __m256) -> [f32; 8] {
    let mut a = [0f32; 8];
    // SAFETY: an unaligned store of eight f32s into a local `[f32; 8]`.
    unsafe { _mm256_storeu_ps(a.as_mut_ptr(), v) };
    a
}

#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
fn load_u32(a: &[u32; 8]) -> __m256i {
    // SAFETY: reads eight u32s from a live `[u32; 8]`; the unaligned load has no
    // alignment requirement.
    unsafe { _mm256_loadu_si256(a.as_ptr().cast()) }
}

#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
fn store_u32(v: __m256i) -> [u32; 8] {
    let mut a = [0u32; 8];
    // SAFETY: an unaligned store of eight u32s into a local `[u32; 8]`.
    unsafe { _mm256_storeu_si256(a.as_mut_ptr().cast(), v) };
    a
}

impl Best8 {
    /// Keeps, in the lanes of `hit` (a bit mask), distance, coordinates (`[t, u, v]`),
    /// part (`part`, lane by lane) and primitive 0 of object `index`. A vector at a
    /// time: written lane by lane, the distances stalled the next object's test, which
    /// loads them whole.
    #[target_feature(enable = "avx2")]
    fn take_lanes(&mut self, hit: u32, [t, u, v]: [Avx8; 3], part: [u8; 8], index: u32) {
        if hit == 0 {
            return;
        }
        let bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        let mask = _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(hit as i32), bits), bits);
        let m = _mm256_castsi256_ps(mask);
        self.t = store(_mm256_blendv_ps(load(&self.t), t.0, m));
        self.u = store(_mm256_blendv_ps(load(&self.u), u.0, m));
        self.v = store(_mm256_blendv_ps(load(&self.v), v.0, m));
        self.index = store_u32(_mm256_blendv_epi8(load_u32(&self.index), _mm256_set1_epi32(index as i32), mask));
        self.prim = store_u32(_mm256_andnot_si256(mask, load_u32(&self.prim)));
        // The parts too without a loop over the lanes (whose exit the branch predictor
        // misses): the eight bytes as one word, blended by a byte mask of `hit`.
        let bytes = BYTE_MASKS[(hit & 15) as usize] | BYTE_MASKS[(hit >> 4 & 15) as usize] << 32;
        let (old, new) = (u64::from_le_bytes(self.part), u64::from_le_bytes(part));
        self.part = (old & !bytes | new & bytes).to_le_bytes();
        self.owned = if index == self.owner { self.owned | hit } else { hit };
        self.owner = index;
    }
}

/// Per four lanes' bits, a mask of their bytes (little-endian: lane 0 the lowest).
const BYTE_MASKS: [u64; 16] = {
    let mut m = [0u64; 16];
    let mut n = 0;
    while n < 16 {
        let mut lane = 0;
        while lane < 4 {
            if n >> lane & 1 != 0 {
                m[n] |= 0xff << (8 * lane);
            }
            lane += 1;
        }
        n += 1;
    }
    m
};

/// [`Quad::intersect`] in eight lanes, with `t_min` 0 and each lane's bound `best.t`;
/// the lanes `live` (a bit mask) that hit keep it as object `index`.
#[target_feature(enable = "avx2")]
#[inline]
pub fn quad(q: &Quad, r: &Rays8, live: u32, best: &mut Best8, index: u32) {
    let (hit, t, a, b) = q.hits(r.o, r.d, Avx8::splat(0.0), Avx8::from_array(&best.t));
    best.take_lanes(Avx8::bits(hit) & live, [t, a, b], [part::SIDE; 8], index);
}

/// [`Sphere::intersect`] in eight lanes, as [`quad`].
#[target_feature(enable = "avx2")]
#[inline]
pub fn sphere(s: &Sphere, r: &Rays8, live: u32, best: &mut Best8, index: u32) {
    let zero = Avx8::splat(0.0);
    let (hit, t) =
        sphere_hits(r.o, r.d, lanes::splat3(s.center), Avx8::splat(s.radius), zero, Avx8::from_array(&best.t));
    best.take_lanes(Avx8::bits(hit) & live, [t, zero, zero], [part::SIDE; 8], index);
}

/// Keeps the candidates a shape of several surfaces took, in the lanes `live`, as object
/// `index`.
#[target_feature(enable = "avx2")]
#[inline]
fn keep_nearest(near: Nearest<Avx8>, best: &mut Best8, live: u32, index: u32) {
    let hit = Avx8::bits(near.taken()) & live;
    if hit == 0 {
        return;
    }
    let (zero, part) = (Avx8::splat(0.0), near.part.to_array());
    best.take_lanes(hit, [near.t, zero, zero], part.map(|p| p as u8), index);
}

/// [`Cylinder::intersect`] in eight lanes, as [`quad`].
#[target_feature(enable = "avx2")]
#[inline]
pub fn cylinder(cyl: &Cylinder, r: &Rays8, live: u32, best: &mut Best8, index: u32) {
    let near = cyl.hits(r.o, r.d, Avx8::splat(0.0), Avx8::from_array(&best.t));
    keep_nearest(near, best, live, index);
}

/// [`Cone::intersect`] in eight lanes for a pointed cone (`top_radius` 0), as [`quad`].
#[target_feature(enable = "avx2")]
#[inline]
pub fn pointed_cone(cone: &Cone, r: &Rays8, live: u32, best: &mut Best8, index: u32) {
    debug_assert!(cone.top_radius == 0.0);
    let near = cone.pointed_hits(r.o, r.d, Avx8::splat(0.0), Avx8::from_array(&best.t));
    keep_nearest(near, best, live, index);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::tri4::tests::numbers;
    use crate::geometry::Hit;
    use crate::math::Vec3;

    /// Eight rays from near `from`, some of them at `aim` (± a little), with bounds
    /// from earlier hits in some lanes; each lane's answer against the scalar test's.
    #[allow(unsafe_code)]
    fn check(
        f: &mut impl FnMut() -> f32,
        aim: Vec3,
        mut scalar: impl FnMut(&Ray, f32) -> Option<Hit>,
        wide: impl Fn(&Rays8, &mut Best8),
    ) -> u32 {
        let from = Vec3::new(f(), f(), f()) * 3.0;
        let rays: Vec<(Ray, ())> = (0..8)
            .map(|_| {
                let o = from + Vec3::new(f(), f(), f()) * 0.1;
                (Ray::new(o, aim + Vec3::new(f(), f(), f()) * 0.6 - o), ())
            })
            .collect();
        let mut best = Best8::new();
        for lane in 0..8 {
            if f() > 1.0 {
                (best.t[lane], best.index[lane]) = (f().abs() * 4.0, 3);
                (best.part[lane], best.prim[lane]) = (lane as u8 + 1, 40 + lane as u32);
            }
        }
        let before = (best.t, best.index, best.part, best.prim);
        // SAFETY: the caller checked for AVX2.
        unsafe { wide(&Rays8::new(&rays), &mut best) };
        let mut hits = 0;
        for (lane, (ray, ())) in rays.iter().enumerate() {
            match scalar(ray, before.0[lane]) {
                Some(h) => {
                    hits += 1;
                    assert_eq!(best.index[lane], 9, "lane {lane}: {ray:?}");
                    let (got, _) = best.get(lane);
                    assert_eq!([got.t, got.uv.x, got.uv.y].map(f32::to_bits), [h.t, h.uv.x, h.uv.y].map(f32::to_bits));
                    assert_eq!((got.part, got.prim), (h.part, h.prim));
                }
                None => {
                    let kept = (best.t[lane].to_bits(), best.index[lane], best.part[lane], best.prim[lane]);
                    assert_eq!(kept, (before.0[lane].to_bits(), before.1[lane], before.2[lane], before.3[lane]));
                }
            }
        }
        hits
    }

    /// One to eight rays made into lanes: lane k holds ray k's six numbers, and the lanes
    /// past the last the first ray's.
    #[test]
    #[allow(unsafe_code)]
    fn rays_go_into_their_lanes() {
        if !std::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut f = numbers(3);
        for n in 1..=8 {
            let rays: Vec<(Ray, ())> =
                (0..n).map(|_| (Ray { origin: Vec3::new(f(), f(), f()), dir: Vec3::new(f(), f(), f()) }, ())).collect();
            // SAFETY: checked for AVX2 above.
            let wide = unsafe { Rays8::new(&rays) };
            let rows = [wide.o, wide.d].map(|r| r.map(|v| v.to_array()));
            for lane in 0..8 {
                let r = rays[if lane < n { lane } else { 0 }].0;
                let got = [0, 1, 2]
                    .map(|axis| rows[0][axis][lane])
                    .into_iter()
                    .chain([0, 1, 2].map(|axis| rows[1][axis][lane]));
                let want = r.origin.to_array().into_iter().chain(r.dir.to_array());
                assert!(got.map(f32::to_bits).eq(want.map(f32::to_bits)), "{n} rays, lane {lane}");
            }
        }
    }

    #[test]
    #[allow(unsafe_code)]
    fn every_lane_matches_the_scalar_tests_bit_for_bit() {
        if !std::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut f = numbers(7);
        let (mut quad_hits, mut sphere_hits) = (0, 0);
        for _ in 0..5_000 {
            let q = Quad::new(Vec3::new(f(), f(), f()), Vec3::new(f(), f(), f()), Vec3::new(f(), f(), f()));
            let aim = q.corner + 0.5 * (q.edge_u + q.edge_v);
            // SAFETY (in the closure): checked for AVX2 above.
            quad_hits += check(&mut f, aim, |r, t| q.intersect(r, 0.0, t), |r, b| unsafe { quad(&q, r, 0xff, b, 9) });
            let s = Sphere::new(Vec3::new(f(), f(), f()), f().abs() + 0.05);
            sphere_hits +=
                check(&mut f, s.center, |r, t| s.intersect(r, 0.0, t), |r, b| unsafe { sphere(&s, r, 0xff, b, 9) });
        }
        assert!(quad_hits > 5_000 && sphere_hits > 5_000, "{quad_hits} {sphere_hits}");
        let (mut cylinder_hits, mut cone_hits) = ([0; 3], [0; 3]);
        for _ in 0..5_000 {
            let (base, axis) = (Vec3::new(f(), f(), f()), Vec3::new(f(), f(), f()));
            let (radius, height) = (f().abs() + 0.05, f().abs() * 2.0 + 0.05);
            let c = Cylinder::new(base, axis, radius, height, f() > -1.0);
            let aim = c.base + c.axis * (height * 0.5);
            // SAFETY (in the closures): checked for AVX2 above.
            check(
                &mut f,
                aim,
                |r, t| c.intersect(r, 0.0, t).inspect(|h| cylinder_hits[h.part as usize] += 1),
                |r, b| unsafe { cylinder(&c, r, 0xff, b, 9) },
            );
            let k = Cone::new(base, axis, radius, height, f() > -1.0);
            let aim = k.base + k.axis * (height * f().abs() * 0.5);
            check(
                &mut f,
                aim,
                |r, t| k.intersect(r, 0.0, t).inspect(|h| cone_hits[h.part as usize] += 1),
                |r, b| unsafe { pointed_cone(&k, r, 0xff, b, 9) },
            );
        }
        // Side walls and caps, both caps of a cylinder.
        assert!(
            cylinder_hits.iter().all(|&n| n > 1_000) && cone_hits[..2].iter().all(|&n| n > 1_000),
            "{cylinder_hits:?} {cone_hits:?}"
        );
    }
}
