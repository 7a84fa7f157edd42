//! Spheres in packs of eight, for where the eight-lane code runs ([`super::lanes::avx2`]):
//! the sphere test ([`crate::geometry::sphere_hits`]) on eight AVX lanes ([`Avx8`]), so a
//! leaf of up to eight spheres is one test rather than two [`super::sphere4::Sphere4`]
//! tests, and the tree over them (built with packs of eight) is shallower. Each lane's
//! answer is the scalar test's bit for bit, as with four lanes. Sphereflake (SPD balls
//! 4, depth 5, 1 thread) 165 -> 158 ms, sphere-cloud-1M primary 1.42 -> 1.52 Mrays/s.

#[cfg(target_arch = "x86_64")]
use super::avx8::Avx8;
use crate::geometry::Sphere;
use crate::geometry::sphere_hits as hits;
use crate::math::Ray;
use crate::math::lanes::{self, F8, Lanes};

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

    /// A bit mask of the lanes hit within `(t_min, t_max)`, and per lane the distance:
    /// on AVX lanes where AVX2 runs, else (tests, `WHITTED_PORTABLE=1`) the same test
    /// on portable [`F8`] lanes. The world's leaves use [`Sphere8::intersect_unchecked`].
    #[cfg(test)]
    #[allow(unsafe_code)]
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> (u32, F8) {
        #[cfg(target_arch = "x86_64")]
        if super::lanes::avx2() {
            // SAFETY: the processor has AVX2.
            return unsafe { self.intersect_avx2(ray, t_min, t_max) };
        }
        self.intersect_lanes(ray, t_min, t_max)
    }

    /// [`Sphere8::intersect`] without asking, pack by pack, whether AVX2 runs: on AVX
    /// lanes on x86-64, inlined into the 8-wide walk's leaf code (its leaf closures are
    /// `#[inline(always)]`) and the light buffers' loops. The check was 1 % of the
    /// sphereflake's instructions, and the portable path inlined beside it made the
    /// code round it worse.
    ///
    /// # Safety
    /// On x86-64 the processor has AVX2. (The world makes packs of eight only for an
    /// 8-wide tree, which only such a processor gets: [`super::World::spheres8`].)
    #[inline(always)]
    #[allow(unsafe_code)]
    pub unsafe fn intersect_unchecked(&self, ray: &Ray, t_min: f32, t_max: f32) -> (u32, F8) {
        // SAFETY: the caller promises AVX2.
        #[cfg(target_arch = "x86_64")]
        return unsafe { self.intersect_avx2(ray, t_min, t_max) };
        #[cfg(not(target_arch = "x86_64"))]
        self.intersect_lanes(ray, t_min, t_max)
    }

    /// The test on [`Avx8`] lanes: the same source, as 8-wide AVX instructions. (On
    /// [`F8`], whose loops LLVM is left to vectorize, it came out as a tangle of
    /// shuffles and 4-wide halves, and the sphereflake rendered 20 % slower.) Built for
    /// AVX2 and called only where it runs, as [`Avx8`] requires.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    fn intersect_avx2(&self, ray: &Ray, t_min: f32, t_max: f32) -> (u32, F8) {
        // The rows loaded one by one, not through a closure and `array::map`, which the
        // compiler may leave as calls where this is inlined into a bigger loop.
        let (o, d) = (lanes::splat3::<Avx8>(ray.origin), lanes::splat3::<Avx8>(ray.dir));
        let center = [Avx8::load(&self.center[0]), Avx8::load(&self.center[1]), Avx8::load(&self.center[2])];
        let (hit, t) = hits(o, d, center, Avx8::load(&self.radius), Avx8::splat(t_min), Avx8::splat(t_max));
        (Avx8::bits(hit), t.store())
    }

    /// The portable path: the same test on [`F8`] lanes.
    #[cfg(any(test, not(target_arch = "x86_64")))]
    #[inline(always)]
    fn intersect_lanes(&self, ray: &Ray, t_min: f32, t_max: f32) -> (u32, F8) {
        let (o, d) = (lanes::splat3::<F8>(ray.origin), lanes::splat3::<F8>(ray.dir));
        let (hit, t) = hits(o, d, self.center, self.radius, F8::splat(t_min), F8::splat(t_max));
        (F8::bits(hit), t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
