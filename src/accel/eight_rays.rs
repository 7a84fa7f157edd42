//! Rays through the object tree eight at a time: where neighbouring rays (a tile's
//! camera rays) head into one octant they go down the eight-wide tree as one packet
//! ([`super::wide8::Bvh8::nearest_packet`]), one node visit serving all eight.

use super::World;
#[cfg(target_arch = "x86_64")]
use super::{Inline, LeafItem, NONE, Nearest, WideBvh};
use crate::geometry::Hit;
#[cfg(target_arch = "x86_64")]
use crate::geometry::{Quad, part};
use crate::math::Ray;
#[cfg(target_arch = "x86_64")]
use crate::math::Vec2;
#[cfg(target_arch = "x86_64")]
use crate::math::lanes::{F8, Lanes};

impl World<'_> {
    /// [`World::closest`] (from 0, without bound) for each ray of `found`, its answer
    /// written beside it: the same answers, eight at a time where they make a packet.
    pub fn closest_found(&self, found: &mut [(Ray, Option<(Hit, u32)>)]) {
        for group in found.chunks_mut(8) {
            if let Ok(group) = <&mut [_; 8]>::try_from(&mut *group)
                && self.closest_packet(group)
            {
                continue;
            }
            for (ray, hit) in group {
                *hit = self.closest(ray, 0.0, f32::INFINITY);
            }
        }
    }

    /// Eight rays as one packet, if the tree and their directions allow it.
    #[inline]
    fn closest_packet(&self, group: &mut [(Ray, Option<(Hit, u32)>); 8]) -> bool {
        #[cfg(target_arch = "x86_64")]
        if let WideBvh::Eight(tree) = &self.top4
            && !self.flat
            && group.iter().all(|(r, _)| r.origin.is_finite() && r.dir.is_finite())
        {
            let rays = group.each_ref().map(|(r, _)| r);
            let mut nearest = [Nearest::default(); 8];
            let packed = tree.nearest_packet(
                rays,
                0xff,
                0.0,
                [f32::INFINITY; 8],
                &self.leaves,
                // Inlined into the walk, built for AVX2, so the spheres' AVX test is too.
                #[inline(always)]
                |mask, range, t| {
                    for at in range {
                        match &self.leaves[at] {
                            // A quad (an SPD floor) met by several rays: tested once for them.
                            LeafItem::Inline(Inline::Quad(q), i) if mask & (mask - 1) != 0 => {
                                quad_lanes(q, *i, rays, mask, t, &mut nearest)
                            }
                            _ => {
                                let mut m = mask;
                                while m != 0 {
                                    let k = m.trailing_zeros() as usize;
                                    m &= m - 1;
                                    t[k] = self.leaf_nearest(at, rays[k], 0.0, t[k], &mut nearest[k]);
                                }
                            }
                        }
                    }
                },
            );
            if packed {
                for ((_, hit), nearest) in group.iter_mut().zip(nearest) {
                    *hit = nearest.get();
                }
            }
            return packed;
        }
        false
    }

    /// [`World::closest`] for each of `rays`, into `out` (as long): in a world of one
    /// mesh, eight at a time, as one packet where they head into one octant
    /// ([`super::wide8::Bvh8::nearest_packet`]), else two walks at a time, interleaved
    /// ([`super::wide8::Bvh8::nearest_hits`]); elsewhere one ray after another.
    pub fn closest_each(&self, rays: &[Ray], t_min: f32, t_max: f32, out: &mut [Option<(Hit, u32)>]) {
        let Some(mesh) = self.single_mesh() else {
            for (ray, hit) in rays.iter().zip(out) {
                *hit = self.closest(ray, t_min, t_max);
            }
            return;
        };
        let (mut eights, mut hits8) = (rays.chunks_exact(8), out.chunks_exact_mut(8));
        for (g, out) in (&mut eights).zip(&mut hits8) {
            let found = mesh.closest_eight(g.try_into().expect("eight rays"), t_min, [t_max; 8], 0xff);
            out.copy_from_slice(&found.map(|h| h.map(|h| (h, 0))));
        }
        let (rays, out) = (eights.remainder(), hits8.into_remainder());
        let (mut groups, mut hits) = (rays.chunks_exact(2), out.chunks_exact_mut(2));
        for (g, out) in (&mut groups).zip(&mut hits) {
            let found = mesh.closest_each([&g[0], &g[1]], t_min, [t_max; 2]);
            out.copy_from_slice(&found.map(|h| h.map(|h| (h, 0))));
        }
        for (ray, out) in groups.remainder().iter().zip(hits.into_remainder()) {
            *out = mesh.closest(ray, t_min, t_max).map(|h| (h, 0));
        }
    }
}

/// Calls of [`quad_lanes`], for a test to see that it ran.
#[cfg(all(test, target_arch = "x86_64"))]
pub(super) static QUAD_PACKETS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// [`World::leaf_nearest`] of a quad entry for the rays `mask` of a packet at once: the
/// one quad test ([`Quad::hits`]) on eight lanes, so each ray gets the answer and bound
/// its own test would give.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn quad_lanes(q: &Quad, i: u32, rays: [&Ray; 8], mask: u32, t: &mut [f32; 8], nearest: &mut [Nearest; 8]) {
    #[cfg(test)]
    QUAD_PACKETS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    // Inclusive once something is hit, as in `leaf_nearest`: ties go to the lower index.
    let limit = F8(std::array::from_fn(|k| if nearest[k].index != NONE { t[k].next_up() } else { t[k] }));
    let lanes = |f: fn(&Ray) -> [f32; 3]| {
        let v = rays.map(f);
        std::array::from_fn(|axis| F8(std::array::from_fn(|k| v[k][axis])))
    };
    let (o, d) = (lanes(|r| r.origin.to_array()), lanes(|r| r.dir.to_array()));
    let (hit, at, a, b) = q.hits::<F8>(o, d, F8::splat(0.0), limit);
    let mut m = F8::bits(hit) & mask;
    while m != 0 {
        let k = m.trailing_zeros() as usize;
        m &= m - 1;
        let h = Hit { prim: 0, t: at.0[k], uv: Vec2::new(a.0[k], b.0[k]), part: part::SIDE };
        if nearest[k].offer(h, i) {
            t[k] = h.t;
        }
    }
}
