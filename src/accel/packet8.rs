//! Eight camera rays of an image tile at once against one quad or sphere: the tile's
//! rays all test the same few objects ([`super::World::seen_from`]), so going object by
//! object, eight rays a test, replaces eight scalar tests (each a chain of dependent
//! operations) with one. Each lane does [`Quad::intersect`]'s or [`Sphere::intersect`]'s
//! operations in the same order, so its answer is bit-identical to the scalar one and
//! images do not depend on the path.
//!
//! Calling these is sound only where the processor has AVX2.
//!
//! The shape tests are `#[inline]`, so that [`super::World::eight_lanes`] gets them
//! inlined whichever of the release build's four codegen units they land in: in an
//! experiment that only added code elsewhere, they moved to another unit and were
//! called out of line, each test a call with its rays and best hits read from memory.

use super::lanes::Best8;
use crate::geometry::{Cone, Cylinder, Quad, Sphere, part, sphere_hits};
use crate::math::Ray;
use crate::math::lanes::{self, F8, Lanes};
use std::arch::x86_64::*;

/// Eight rays, lane by lane.
pub struct Rays8 {
    o: [__m256; 3],
    d: [__m256; 3],
}

impl Rays8 {
    /// Lanes past the end of `rays` repeat its first ray (their answers are not read).
    #[target_feature(enable = "avx2")]
    pub fn new<T>(rays: &[(Ray, T)]) -> Self {
        let mut rows = [[0f32; 8]; 6];
        for lane in 0..8 {
            let r = &rays[if lane < rays.len() { lane } else { 0 }].0;
            for (row, x) in rows.iter_mut().zip(r.origin.to_array().into_iter().chain(r.dir.to_array())) {
                row[lane] = x;
            }
        }
        let row = |k: usize| load(&rows[k]);
        Rays8 { o: [row(0), row(1), row(2)], d: [row(3), row(4), row(5)] }
    }

    /// Eight rays given lane by lane: origins and directions, a row per axis.
    #[target_feature(enable = "avx2")]
    pub fn from_lanes(origins: &[[f32; 8]; 3], dirs: &[[f32; 8]; 3]) -> Self {
        Rays8 { o: origins.each_ref().map(|r| load(r)), d: dirs.each_ref().map(|r| load(r)) }
    }
}

#[target_feature(enable = "avx2")]
fn splat3(v: crate::math::Vec3) -> [__m256; 3] {
    [_mm256_set1_ps(v.x), _mm256_set1_ps(v.y), _mm256_set1_ps(v.z)]
}

/// glam's `Vec3::dot`: `(x·x') + (y·y') + (z·z')`, left to right.
#[target_feature(enable = "avx2")]
fn dot(a: &[__m256; 3], b: &[__m256; 3]) -> __m256 {
    _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(a[0], b[0]), _mm256_mul_ps(a[1], b[1])), _mm256_mul_ps(a[2], b[2]))
}

/// glam's `Vec3::cross`.
#[target_feature(enable = "avx2")]
fn cross(a: &[__m256; 3], b: &[__m256; 3]) -> [__m256; 3] {
    let (mul, sub) = (_mm256_mul_ps, _mm256_sub_ps);
    [
        sub(mul(a[1], b[2]), mul(b[1], a[2])),
        sub(mul(a[2], b[0]), mul(b[2], a[0])),
        sub(mul(a[0], b[1]), mul(b[0], a[1])),
    ]
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

/// Keeps, in the lanes of `hit`, distance `t` and coordinates (`u`, `v`) of object `index`.
#[target_feature(enable = "avx2")]
fn keep(best: &mut Best8, hit: u32, t: __m256, u: __m256, v: __m256, index: u32) {
    best.take_lanes(hit, [t, u, v], |_| part::SIDE, index);
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
    /// Keeps, in the lanes of `hit` (a bit mask), distance, coordinates (`[t, u, v]`)
    /// and part (`part(lane)`) of object `index`. A vector at a time: written lane by
    /// lane, the distances stalled the next object's test, which loads them whole.
    #[target_feature(enable = "avx2")]
    fn take_lanes(&mut self, hit: u32, [t, u, v]: [__m256; 3], part: impl Fn(usize) -> u8, index: u32) {
        if hit == 0 {
            return;
        }
        let bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        let mask = _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(hit as i32), bits), bits);
        let m = _mm256_castsi256_ps(mask);
        self.t = store(_mm256_blendv_ps(load(&self.t), t, m));
        self.u = store(_mm256_blendv_ps(load(&self.u), u, m));
        self.v = store(_mm256_blendv_ps(load(&self.v), v, m));
        self.index = store_u32(_mm256_blendv_epi8(load_u32(&self.index), _mm256_set1_epi32(index as i32), mask));
        let mut lanes = hit;
        while lanes != 0 {
            let lane = lanes.trailing_zeros() as usize;
            lanes &= lanes - 1;
            (self.part[lane], self.prim[lane]) = (part(lane), 0);
        }
        self.owned = if index == self.owner { self.owned | hit } else { hit };
        self.owner = index;
    }
}

/// [`Quad::intersect`] in eight lanes, with `t_min` 0 and each lane's bound `best.t`;
/// the lanes `live` (a bit mask) that hit keep it as object `index`.
#[target_feature(enable = "avx2")]
#[inline]
pub fn quad(q: &Quad, r: &Rays8, live: u32, best: &mut Best8, index: u32) {
    let (normal, plane_d) = q.plane();
    let (n, corner, eu, ev, w) = (splat3(normal), splat3(q.corner), splat3(q.edge_u), splat3(q.edge_v), splat3(q.w()));
    let denom = dot(&n, &r.d);
    let abs = _mm256_andnot_ps(_mm256_set1_ps(-0.0), denom);
    // `!(|denom| <= 1e-9)`: a NaN goes on, as in the scalar test.
    let facing = _mm256_cmp_ps::<_CMP_NLE_UQ>(abs, _mm256_set1_ps(1e-9));
    let t = _mm256_div_ps(_mm256_sub_ps(_mm256_set1_ps(plane_d), dot(&n, &r.o)), denom);
    let ahead = _mm256_and_ps(
        _mm256_cmp_ps::<_CMP_GT_OQ>(t, _mm256_setzero_ps()),
        _mm256_cmp_ps::<_CMP_LT_OQ>(t, load(&best.t)),
    );
    let mut hit = _mm256_movemask_ps(_mm256_and_ps(facing, ahead)) as u32 & live;
    if hit == 0 {
        return;
    }
    // `ray.at(t) - corner`.
    let p: [__m256; 3] =
        std::array::from_fn(|i| _mm256_sub_ps(_mm256_add_ps(r.o[i], _mm256_mul_ps(t, r.d[i])), corner[i]));
    let a = dot(&w, &cross(&p, &ev));
    let b = dot(&w, &cross(&eu, &p));
    let (zero, one) = (_mm256_setzero_ps(), _mm256_set1_ps(1.0));
    let inside = |x: __m256| _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(x, zero), _mm256_cmp_ps::<_CMP_LE_OQ>(x, one));
    hit &= _mm256_movemask_ps(_mm256_and_ps(inside(a), inside(b))) as u32;
    keep(best, hit, t, a, b, index);
}

/// [`Sphere::intersect`] in eight lanes, as [`quad`]: its own code
/// ([`crate::geometry::sphere_hits`]), eight lanes wide.
#[target_feature(enable = "avx2")]
#[inline]
pub fn sphere(s: &Sphere, r: &Rays8, live: u32, best: &mut Best8, index: u32) {
    let (o, d) = (r.o.map(|v| F8(store(v))), r.d.map(|v| F8(store(v))));
    let (zero, radius) = (F8::splat(0.0), F8::splat(s.radius));
    let (hit, t) = sphere_hits(o, d, lanes::splat3(s.center), radius, zero, F8(best.t));
    let hit = F8::bits(hit) & live;
    if hit != 0 {
        keep(best, hit, load(&t.0), _mm256_setzero_ps(), _mm256_setzero_ps(), index);
    }
}

/// The nearest of a shape's candidate hits so far, per lane ([`crate::geometry`]'s
/// `Nearest`): a candidate counts where it lies past 0 and before the best so far.
struct Nearest8 {
    t: __m256,
    part: __m256,
    taken: __m256,
}

impl Nearest8 {
    #[target_feature(enable = "avx2")]
    fn new(best: &Best8) -> Self {
        Nearest8 { t: load(&best.t), part: _mm256_setzero_ps(), taken: _mm256_setzero_ps() }
    }

    #[target_feature(enable = "avx2")]
    fn improves(&self, t: __m256) -> __m256 {
        _mm256_and_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(t, _mm256_setzero_ps()), _mm256_cmp_ps::<_CMP_LT_OQ>(t, self.t))
    }

    /// Takes `t` as part `part` in the lanes of `ok`.
    #[target_feature(enable = "avx2")]
    fn take(&mut self, ok: __m256, t: __m256, part: u8) {
        self.t = _mm256_blendv_ps(self.t, t, ok);
        self.part = _mm256_blendv_ps(self.part, _mm256_set1_ps(part as f32), ok);
        self.taken = _mm256_or_ps(self.taken, ok);
    }

    /// Keeps the hits taken, in the lanes `live`, as object `index`.
    #[target_feature(enable = "avx2")]
    fn keep(self, best: &mut Best8, live: u32, index: u32) {
        let hit = _mm256_movemask_ps(self.taken) as u32 & live;
        let (zero, part) = (_mm256_setzero_ps(), store(self.part));
        best.take_lanes(hit, [self.t, zero, zero], |lane| part[lane] as u8, index);
    }
}

/// `a ≤ x ≤ b`.
#[target_feature(enable = "avx2")]
fn between(x: __m256, a: f32, b: f32) -> __m256 {
    _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(x, _mm256_set1_ps(a)), _mm256_cmp_ps::<_CMP_LE_OQ>(x, _mm256_set1_ps(b)))
}

/// `-(b + √disc·sign(b))`, the root of the half-b quadratic that does not cancel.
#[target_feature(enable = "avx2")]
fn stable_root(b: __m256, disc: __m256) -> __m256 {
    let sign = _mm256_set1_ps(-0.0);
    let root = _mm256_or_ps(_mm256_andnot_ps(sign, _mm256_sqrt_ps(disc)), _mm256_and_ps(sign, b));
    _mm256_xor_ps(_mm256_add_ps(b, root), sign)
}

/// `v - s·axis`, component by component.
#[target_feature(enable = "avx2")]
fn minus_along(v: &[__m256; 3], s: __m256, axis: &[__m256; 3]) -> [__m256; 3] {
    std::array::from_fn(|i| _mm256_sub_ps(v[i], _mm256_mul_ps(s, axis[i])))
}

/// [`Cylinder::intersect`] in eight lanes, as [`quad`].
#[target_feature(enable = "avx2")]
#[inline]
pub fn cylinder(cyl: &Cylinder, r: &Rays8, live: u32, best: &mut Best8, index: u32) {
    let (mul, sub, add, div) = (_mm256_mul_ps, _mm256_sub_ps, _mm256_add_ps, _mm256_div_ps);
    let (base, axis) = (splat3(cyl.base), splat3(cyl.axis));
    let o: [__m256; 3] = std::array::from_fn(|i| sub(r.o[i], base[i]));
    let oa = dot(&o, &axis);
    let da = dot(&r.d, &axis);
    let (o_perp, d_perp) = (minus_along(&o, oa, &axis), minus_along(&r.d, da, &axis));
    let r2 = cyl.radius * cyl.radius;
    let mut near = Nearest8::new(best);

    let a = dot(&d_perp, &d_perp);
    let wall = _mm256_cmp_ps::<_CMP_GT_OQ>(a, _mm256_set1_ps(1e-12));
    let b = dot(&o_perp, &d_perp);
    let closest = minus_along(&o_perp, div(b, a), &d_perp);
    let disc = mul(a, sub(_mm256_set1_ps(r2), dot(&closest, &closest)));
    let real = _mm256_and_ps(wall, _mm256_cmp_ps::<_CMP_GE_OQ>(disc, _mm256_setzero_ps()));
    if _mm256_movemask_ps(real) as u32 & live != 0 {
        let c = sub(dot(&o_perp, &o_perp), _mm256_set1_ps(r2));
        let q = stable_root(b, disc);
        for t in [div(c, q), div(q, a)] {
            let h = add(oa, mul(t, da));
            near.take(_mm256_and_ps(_mm256_and_ps(real, near.improves(t)), between(h, 0.0, cyl.height)), t, part::SIDE);
        }
    }
    if cyl.caps {
        let across = _mm256_cmp_ps::<_CMP_NEQ_UQ>(da, _mm256_setzero_ps());
        for (plane, id) in [(0.0, part::BASE_CAP), (cyl.height, part::TOP_CAP)] {
            let t = div(sub(_mm256_set1_ps(plane), oa), da);
            let p: [__m256; 3] = std::array::from_fn(|i| add(o_perp[i], mul(t, d_perp[i])));
            let inside = _mm256_cmp_ps::<_CMP_LE_OQ>(dot(&p, &p), _mm256_set1_ps(r2));
            near.take(_mm256_and_ps(_mm256_and_ps(across, near.improves(t)), inside), t, id);
        }
    }
    near.keep(best, live, index);
}

/// [`Cone::intersect`] in eight lanes for a pointed cone (`top_radius` 0), as [`quad`].
#[target_feature(enable = "avx2")]
#[inline]
pub fn pointed_cone(cone: &Cone, r: &Rays8, live: u32, best: &mut Best8, index: u32) {
    debug_assert!(cone.top_radius == 0.0);
    let (mul, sub, add, div) = (_mm256_mul_ps, _mm256_sub_ps, _mm256_add_ps, _mm256_div_ps);
    let (apex, axis) = (splat3(cone.apex()), splat3(cone.axis));
    let o: [__m256; 3] = std::array::from_fn(|i| sub(r.o[i], apex[i]));
    let da = dot(&r.d, &axis);
    let d_perp = minus_along(&r.d, da, &axis);
    let mut near = Nearest8::new(best);

    let t0 = _mm256_xor_ps(dot(&o, &r.d), _mm256_set1_ps(-0.0));
    let o0: [__m256; 3] = std::array::from_fn(|i| add(o[i], mul(t0, r.d[i])));
    let oa0 = dot(&o0, &axis);
    let o_perp = minus_along(&o0, oa0, &axis);
    let k = cone.radius / cone.height;
    let k2 = _mm256_set1_ps(k * k);
    let a = sub(dot(&d_perp, &d_perp), mul(mul(k2, da), da));
    let b = sub(dot(&o_perp, &d_perp), mul(mul(k2, oa0), da));
    let c = sub(dot(&o_perp, &o_perp), mul(mul(k2, oa0), oa0));
    let disc = sub(mul(b, b), mul(a, c));
    let real = _mm256_cmp_ps::<_CMP_GE_OQ>(disc, _mm256_setzero_ps());
    if _mm256_movemask_ps(real) as u32 & live != 0 {
        let q = stable_root(b, disc);
        // `q / a`, or NaN (no root) where `a` is 0.
        let flat = _mm256_cmp_ps::<_CMP_EQ_OQ>(a, _mm256_setzero_ps());
        let far = _mm256_blendv_ps(div(q, a), _mm256_set1_ps(f32::NAN), flat);
        for dt in [div(c, q), far] {
            let t = add(t0, dt);
            let s = add(oa0, mul(dt, da));
            near.take(
                _mm256_and_ps(_mm256_and_ps(real, near.improves(t)), between(s, -cone.height, 0.0)),
                t,
                part::SIDE,
            );
        }
    }
    if cone.cap {
        let across = _mm256_cmp_ps::<_CMP_NEQ_UQ>(da, _mm256_setzero_ps());
        let oa = dot(&o, &axis);
        let t = div(sub(_mm256_set1_ps(-cone.height), oa), da);
        let off = minus_along(&o, oa, &axis);
        let radial: [__m256; 3] = std::array::from_fn(|i| add(off[i], mul(t, d_perp[i])));
        let inside = _mm256_cmp_ps::<_CMP_LE_OQ>(dot(&radial, &radial), _mm256_set1_ps(cone.radius * cone.radius));
        near.take(_mm256_and_ps(_mm256_and_ps(across, near.improves(t)), inside), t, part::BASE_CAP);
    }
    near.keep(best, live, index);
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
            }
        }
        let before = (best.t, best.index);
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
                    assert_eq!((best.t[lane].to_bits(), best.index[lane]), (before.0[lane].to_bits(), before.1[lane]))
                }
            }
        }
        hits
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
