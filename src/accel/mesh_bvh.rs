//! A mesh object's own tree over its triangles, walked one ray, a few interleaved, or
//! eight as a packet at a time.

use super::tri4::{Ray4, Tri4};
use super::{Bvh, Visit, WideBvh, wide};
use crate::geometry::{Hit, Mesh, part};
use crate::math::{Ray, Vec2};

/// A mesh's own BVH, with its triangles copied in leaf order into packs of four; a
/// wide-tree leaf names a run of packs.
#[derive(Debug)]
pub(super) struct MeshBvh {
    tree: WideBvh,
    pub(super) packs: Vec<Tri4>,
    /// The mean largest side of the leaves' boxes: shadow rays whose origins lie much
    /// farther apart than this start in different leaves.
    leaf_size: f32,
}

impl MeshBvh {
    pub(super) fn build(mesh: &Mesh, width: Option<usize>) -> MeshBvh {
        let bounds: Vec<_> =
            (0..mesh.triangle_count()).map(|i| crate::math::Aabb::from_points(mesh.corners(i))).collect();
        let bvh = Bvh::build_packed(&bounds, 4);
        let mut tree = wide(&bvh, width);
        // Every leaf of the binary tree is a leaf of the wide one, in packs of four.
        let pack_count = bvh.nodes.iter().filter(|n| n.is_leaf()).map(|n| n.count.div_ceil(4) as usize).sum();
        let mut packs = crate::pages::with_capacity(pack_count);
        let mut chunk = Vec::with_capacity(4);
        tree.map_leaves(|first, count| {
            let start = packs.len() as u32;
            for ids in bvh.indices[first as usize..(first + count) as usize].chunks(4) {
                chunk.clear();
                chunk.extend(ids.iter().map(|&id| {
                    let [v0, v1, v2] = mesh.corners(id as usize);
                    (v0, v1 - v0, v2 - v0, id)
                }));
                packs.push(Tri4::pack(&chunk));
            }
            (start, packs.len() as u32 - start)
        });
        debug_assert_eq!(packs.len(), pack_count);
        let leaves = bvh.nodes.iter().filter(|n| n.is_leaf());
        let sides: f64 =
            leaves.clone().map(|n| (0..3).map(|a| n.max[a] - n.min[a]).fold(0.0f32, f32::max) as f64).sum();
        let leaf_size = (sides / leaves.count().max(1) as f64) as f32;
        MeshBvh { tree, packs, leaf_size }
    }

    /// The mesh in pieces for a light buffer to list: each leaf's packs and the box of
    /// their triangles as the packs hold them. A shadow ray blocked by the mesh is
    /// blocked by a triangle in one of them, which lies along the ray's segment, so in
    /// its cell and nearer the light than its origin.
    pub(super) fn pieces(&self, mut f: impl FnMut(std::ops::Range<u32>, crate::math::Aabb)) {
        self.tree.each_leaf(|first, count| {
            let b = self.packs[first as usize..(first + count) as usize]
                .iter()
                .fold(crate::math::Aabb::EMPTY, |b, pack| b.union(pack.bounds()));
            f(first..first + count, b);
        });
    }

    /// How many [`MeshBvh::pieces`] there are.
    pub(super) fn leaf_count(&self) -> usize {
        let mut n = 0;
        self.tree.each_leaf(|_, _| n += 1);
        n
    }

    /// Whether the mesh is small enough (a polygon, a quad of an NFF scene) for its
    /// triangles to be tested without walking its tree: the object's box in the top
    /// tree has been entered already, and the walk's own node visit cost more than the
    /// test (a 512 x 512 sphereflake's ground: about 470 instructions a ray, mostly
    /// the walk). The same hits: any triangle a ray meets lies in a leaf it enters.
    #[inline(always)]
    pub(super) fn direct(&self) -> bool {
        self.packs.len() <= DIRECT_PACKS
    }

    pub(super) fn memory_bytes(&self) -> usize {
        self.tree.memory_bytes() + self.packs.capacity() * std::mem::size_of::<Tri4>()
    }

    #[inline]
    pub(super) fn closest(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        let r4 = Ray4::new(ray);
        let mut best: Option<Hit> = None;
        if self.direct() {
            self.nearest_in(0..self.packs.len(), &r4, t_min, t_max, &mut best);
            return best;
        }
        self.tree.traverse::<true, _>(
            ray,
            t_min,
            t_max,
            &self.packs,
            #[inline(always)]
            |range, t_cur| Visit::Continue(self.nearest_in(range, &r4, t_min, t_cur, &mut best)),
        );
        best
    }

    /// [`MeshBvh::closest`] for `N` rays at once ([`WideBvh::nearest_hits`]).
    #[inline]
    pub(super) fn closest_each<const N: usize>(
        &self,
        rays: [&Ray; N],
        t_min: f32,
        t_max: [f32; N],
    ) -> [Option<Hit>; N] {
        let r4 = rays.map(Ray4::new);
        let mut best = [None; N];
        self.tree.nearest_hits(rays, t_min, t_max, &self.packs, |k, range, t_cur| {
            self.nearest_in(range, &r4[k], t_min, t_cur, &mut best[k])
        });
        best
    }

    /// [`MeshBvh::closest`] (from `t_min`, within `t_max[k]`) for the rays of `live` (a
    /// bit each). Rays that all head into one octant (camera rays, mostly) go down the
    /// 8-wide tree as one packet ([`wide8::Bvh8::nearest_packet`]); others walk
    /// two at a time.
    pub(super) fn closest_eight(&self, rays: &[Ray; 8], t_min: f32, t_max: [f32; 8], live: u32) -> [Option<Hit>; 8] {
        #[cfg(target_arch = "x86_64")]
        if let WideBvh::Eight(tree) = &self.tree {
            let mut best = [None; 8];
            let leaf = super::wide8::each_ray(|k, range, t_cur| {
                self.nearest_in(range, &Ray4::new(&rays[k]), t_min, t_cur, &mut best[k])
            });
            if tree.nearest_packet(rays.each_ref(), live, t_min, t_max, &self.packs, leaf) {
                return best;
            }
        }
        let mut hits = [None; 8];
        in_groups(live, 2, |g| match *g {
            [a, b] => {
                let found = self.closest_each([&rays[a], &rays[b]], t_min, [t_max[a], t_max[b]]);
                (hits[a], hits[b]) = (found[0], found[1]);
            }
            _ => g.iter().for_each(|&k| hits[k] = self.closest(&rays[k], t_min, t_max[k])),
        });
        hits
    }

    /// The triangles of leaf `range` against the ray, keeping the nearest in `best`;
    /// returns the new bound.
    #[inline(always)]
    fn nearest_in(
        &self,
        range: std::ops::Range<usize>,
        r4: &Ray4,
        t_min: f32,
        mut t_cur: f32,
        best: &mut Option<Hit>,
    ) -> f32 {
        // Once something is hit the bound is inclusive, so an equally distant triangle
        // with a lower id wins, as when every triangle is tested in order.
        #[cfg(target_arch = "x86_64")]
        if self.tree.width() == 8 && range.len() == 2 {
            let limit = if best.is_some() { t_cur.next_up() } else { t_cur };
            let (a, b) = (&self.packs[range.start], &self.packs[range.start + 1]);
            // SAFETY: the 8-wide tree exists only where the processor has AVX2.
            #[allow(unsafe_code)]
            let (mask, t, b1, b2) = unsafe { super::tri4::intersect_pair(a, b, r4, t_min, limit) };
            let id = |lane: usize| if lane < 4 { a.ids[lane] } else { b.ids[lane - 4] };
            return keep_nearest(mask, &t, &b1, &b2, id, best, t_cur);
        }
        for pack in &self.packs[range] {
            let limit = if best.is_some() { t_cur.next_up() } else { t_cur };
            let (mask, t, b1, b2) = pack.intersect(r4, t_min, limit);
            let (t, b1, b2) = (t.to_array(), b1.to_array(), b2.to_array());
            t_cur = keep_nearest(mask, &t, &b1, &b2, |lane| pack.ids[lane], best, t_cur);
        }
        t_cur
    }

    #[inline]
    pub(super) fn occluded(&self, ray: &Ray, t_min: f32, t_max: f32) -> bool {
        self.occluded_in(ray, t_min, t_max).is_some()
    }

    /// [`MeshBvh::occluded`], with the packs (a leaf's range) where a triangle blocks.
    #[inline]
    pub(super) fn occluded_in(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<std::ops::Range<usize>> {
        let r4 = Ray4::new(ray);
        if self.direct() {
            let all = 0..self.packs.len();
            return self.leaf_blocks(all.clone(), &r4, t_min, t_max).then_some(all);
        }
        let mut hit = None;
        self.tree.traverse::<false, _>(
            ray,
            t_min,
            t_max,
            &self.packs,
            #[inline(always)]
            |range, t_cur| {
                if self.leaf_blocks(range.clone(), &r4, t_min, t_max) {
                    hit = Some(range);
                    Visit::Stop
                } else {
                    Visit::Continue(t_cur)
                }
            },
        );
        hit
    }

    /// Whether a triangle of packs `range` (a leaf's, from [`MeshBvh::occluded_in`])
    /// blocks the ray between 0 and `t_max`.
    #[inline]
    pub(super) fn packs_block(&self, range: std::ops::Range<usize>, ray: &Ray, t_max: f32) -> bool {
        self.leaf_blocks(range, &Ray4::new(ray), 0.0, t_max)
    }

    /// [`MeshBvh::occluded`] (from 0) for `N` rays at once ([`WideBvh::any_hits`]).
    #[inline]
    pub(super) fn occluded_each<const N: usize>(&self, rays: [&Ray; N], t_max: [f32; N]) -> [bool; N] {
        let r4 = rays.map(Ray4::new);
        self.tree.any_hits(rays, 0.0, t_max, &self.packs, |k, range| self.leaf_blocks(range, &r4[k], 0.0, t_max[k]))
    }

    /// The lanes of `live` (a bit each) whose ray `ray(lane)` a triangle blocks between
    /// 0 and `t_max[lane]` ([`MeshBvh::occluded_eight`]).
    pub(super) fn occluded_lanes(&self, ray: impl Fn(usize) -> Ray, t_max: [f32; 8], live: u32) -> u32 {
        lane_rays(ray, live).map_or(0, |rays| self.occluded_eight(&rays, t_max, live))
    }

    /// The lanes of `live` (a bit each) whose ray a triangle blocks between 0 and
    /// `t_max[lane]`. Rays that all head into one octant from origins within a few
    /// leaves of each other (shadow rays from neighbouring points to one light, mostly)
    /// go down the 8-wide tree as one packet ([`wide8::Bvh8::any_packet`]); others three
    /// walks at a time. Shadow rays from origins farther apart part ways near them,
    /// where a packet tests eight rays for one, and lose the interleaved walks' overlap
    /// of cache misses: from 8 neighbouring pixels of the benchmark camera on the
    /// 10M-triangle cube-sphere (leaves about a pixel wide, origins 5 to 9 leaves apart)
    /// packets were 4 to 13 % slower; on the 1M-triangle one (leaves four pixels wide,
    /// origins 1.5 to 2.5 leaves apart) 6 to 19 % faster.
    pub(super) fn occluded_eight(&self, rays: &[Ray; 8], t_max: [f32; 8], live: u32) -> u32 {
        if let Some(blocked) = self.occluded_packet(rays, t_max, live) {
            return blocked;
        }
        let mut blocked = 0;
        in_groups(live, 3, |g| match *g {
            [a, b, c] => {
                let hit = self.occluded_each([&rays[a], &rays[b], &rays[c]], [t_max[a], t_max[b], t_max[c]]);
                for (lane, hit) in [a, b, c].into_iter().zip(hit) {
                    blocked |= (hit as u32) << lane;
                }
            }
            [a, b] => {
                let hit = self.occluded_each([&rays[a], &rays[b]], [t_max[a], t_max[b]]);
                blocked |= (hit[0] as u32) << a | (hit[1] as u32) << b;
            }
            _ => g.iter().for_each(|&lane| blocked |= (self.occluded(&rays[lane], 0.0, t_max[lane]) as u32) << lane),
        });
        blocked
    }

    /// [`MeshBvh::occluded_eight`]'s packet, or `None` where it does not take the rays.
    #[inline]
    pub(super) fn occluded_packet(&self, rays: &[Ray; 8], t_max: [f32; 8], live: u32) -> Option<u32> {
        #[cfg(target_arch = "x86_64")]
        if let WideBvh::Eight(tree) = &self.tree
            && origins_within(rays, live, SHADOW_PACKET_LEAVES * self.leaf_size)
        {
            return tree.any_packet(rays.each_ref(), live, 0.0, t_max, &self.packs, |k, range| {
                self.leaf_blocks(range, &Ray4::new(&rays[k]), 0.0, t_max[k])
            });
        }
        None
    }

    /// [`MeshBvh::closest`] (from 0, within `t_max[lane]`) for the rays `ray(lane)` of
    /// the lanes of `live` ([`MeshBvh::closest_eight`]).
    pub(super) fn closest_lanes(&self, ray: impl Fn(usize) -> Ray, t_max: [f32; 8], live: u32) -> [Option<Hit>; 8] {
        lane_rays(ray, live).map_or([None; 8], |rays| self.closest_eight(&rays, 0.0, t_max, live))
    }

    /// Whether a triangle of leaf `range` lies across the ray within `(t_min, t_max)`.
    #[inline(always)]
    fn leaf_blocks(&self, range: std::ops::Range<usize>, r4: &Ray4, t_min: f32, t_max: f32) -> bool {
        #[cfg(target_arch = "x86_64")]
        if self.tree.width() == 8 && range.len() == 2 {
            let (a, b) = (&self.packs[range.start], &self.packs[range.start + 1]);
            // SAFETY: the 8-wide tree exists only where the processor has AVX2.
            #[allow(unsafe_code)]
            return unsafe { super::tri4::intersect_pair(a, b, r4, t_min, t_max).0 != 0 };
        }
        self.packs[range].iter().any(|p| p.intersect(r4, t_min, t_max).0 != 0)
    }
}

/// Packs of four triangles a mesh may have for [`MeshBvh::direct`] to test them all.
const DIRECT_PACKS: usize = 2;

/// How many leaves apart (in [`MeshBvh::leaf_size`]) the origins of shadow rays may lie
/// for them to go as one packet.
const SHADOW_PACKET_LEAVES: f32 = 3.0;

/// Whether the origins of the rays of `live` (a bit each) lie within `size` of each
/// other along each axis.
#[inline]
fn origins_within(rays: &[Ray; 8], live: u32, size: f32) -> bool {
    let first = rays[live.trailing_zeros().min(7) as usize].origin;
    let (mut lo, mut hi) = (first, first);
    for k in (0..8).filter(|k| live >> k & 1 != 0) {
        (lo, hi) = (lo.min(rays[k].origin), hi.max(rays[k].origin));
    }
    (hi - lo).max_element() <= size
}

/// The rays `ray(lane)` of the lanes of `live` (a bit each), the dead lanes carrying a
/// copy of a live one, never looked at; `None` if no lane is live.
#[inline]
fn lane_rays(ray: impl Fn(usize) -> Ray, live: u32) -> Option<[Ray; 8]> {
    let first = ray((live != 0).then(|| live.trailing_zeros() as usize)?);
    Some(std::array::from_fn(|lane| if live >> lane & 1 != 0 { ray(lane) } else { first }))
}

/// The lanes set in `live` to `f`, `size` at a time, then those left over.
#[inline(always)]
fn in_groups(live: u32, size: usize, mut f: impl FnMut(&[usize])) {
    let (mut lanes, mut n) = ([0usize; 8], 0);
    for lane in crate::math::lanes::set_lanes(live) {
        (lanes[n], n) = (lane, n + 1);
    }
    let mut groups = lanes[..n].chunks_exact(size);
    (&mut groups).for_each(&mut f);
    f(groups.remainder());
}

/// Folds the lanes of one triangle test that hit (`mask`) into `best`, the nearest
/// so far, ties to the lower id; returns the bound for the rest of the walk.
#[inline(always)]
fn keep_nearest(
    mut mask: u32,
    t: &[f32],
    b1: &[f32],
    b2: &[f32],
    id: impl Fn(usize) -> u32,
    best: &mut Option<Hit>,
    mut t_cur: f32,
) -> f32 {
    while mask != 0 {
        let lane = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        let id = id(lane);
        if best.as_ref().is_none_or(|b| t[lane] < b.t || (t[lane] == b.t && id < b.prim)) {
            t_cur = t[lane];
            *best = Some(Hit { t: t[lane], uv: Vec2::new(b1[lane], b2[lane]), part: part::SIDE, prim: id });
        }
    }
    t_cur
}
