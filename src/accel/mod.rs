//! Ray queries over all objects of a scene: the nearest hit, and how much light gets
//! through along a shadow ray.
//!
//! Two levels: a [`Bvh`] over the scene's objects, and inside each mesh object a BVH
//! over its triangles, whose vertices are copied in leaf order so a leaf's triangles
//! are read from one contiguous run of memory. With [`AccelKind::None`] every object,
//! and every triangle of every mesh, is tested; both paths use the same intersection
//! routines and break ties the same way (the lower index wins), so they produce
//! identical images.

// Where there is no AVX2 code (not x86-64), the eight-lane entry points take their
// portable path, one ray at a time: their lane arguments and lane-only helpers go
// unused there.
#![cfg_attr(not(target_arch = "x86_64"), allow(dead_code, unused_variables, unused_mut))]

mod absorb;
mod eight_rays;
mod shadow;
pub mod bvh;
pub mod lanes;
#[cfg(target_arch = "x86_64")]
mod packet8;
pub use lanes::Best8;
mod sphere4;
mod tri4;
pub mod wide;
#[cfg(target_arch = "x86_64")]
pub mod wide8;
pub mod wide_bvh;

pub use bvh::{Bvh, Node, Visit};
pub use wide::Bvh4;
pub use wide_bvh::WideBvh;

use crate::geometry::{Hit, Mesh, Shape, part};
use crate::math::{Aabb, Ray, Vec2, Vec3};
use crate::scene::Scene;
use glam::DVec3;
use sphere4::Sphere4;
use std::time::{Duration, Instant};
use tri4::{Ray4, Tri4};

/// Which acceleration structure answers ray queries.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AccelKind {
    /// Bounding volume hierarchy (binned SAH).
    #[default]
    Bvh,
    /// Test every object (and every triangle).
    None,
}

impl std::fmt::Display for AccelKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl AccelKind {
    /// Every structure this build has, for toggles that cycle through them.
    pub const ALL: &'static [AccelKind] = &[AccelKind::Bvh, AccelKind::None];

    pub fn name(self) -> &'static str {
        match self {
            AccelKind::Bvh => "bvh",
            AccelKind::None => "none",
        }
    }
}

/// A mesh's own BVH, with its triangles copied in leaf order into packs of four; a
/// wide-tree leaf names a run of packs.
#[derive(Debug)]
struct MeshBvh {
    tree: WideBvh,
    packs: Vec<Tri4>,
    /// The mean largest side of the leaves' boxes: shadow rays whose origins lie much
    /// farther apart than this start in different leaves.
    leaf_size: f32,
}

impl MeshBvh {
    fn build(mesh: &Mesh, width: Option<usize>) -> MeshBvh {
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

    fn memory_bytes(&self) -> usize {
        self.tree.memory_bytes() + self.packs.capacity() * std::mem::size_of::<Tri4>()
    }

    #[inline]
    fn closest(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        let r4 = Ray4::new(ray);
        let mut best: Option<Hit> = None;
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
    fn closest_each<const N: usize>(&self, rays: [&Ray; N], t_min: f32, t_max: [f32; N]) -> [Option<Hit>; N] {
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
    fn closest_eight(&self, rays: &[Ray; 8], t_min: f32, t_max: [f32; 8], live: u32) -> [Option<Hit>; 8] {
        #[cfg(target_arch = "x86_64")]
        if let WideBvh::Eight(tree) = &self.tree {
            let mut best = [None; 8];
            if tree.nearest_packet(rays.each_ref(), live, t_min, t_max, &self.packs, |k, range, t_cur| {
                self.nearest_in(range, &Ray4::new(&rays[k]), t_min, t_cur, &mut best[k])
            }) {
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
            let (mask, t, b1, b2) = unsafe { tri4::intersect_pair(a, b, r4, t_min, limit) };
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
    fn occluded(&self, ray: &Ray, t_min: f32, t_max: f32) -> bool {
        let r4 = Ray4::new(ray);
        let mut hit = false;
        self.tree.traverse::<false, _>(
            ray,
            t_min,
            t_max,
            &self.packs,
            #[inline(always)]
            |range, t_cur| {
                if self.leaf_blocks(range, &r4, t_min, t_max) {
                    hit = true;
                    Visit::Stop
                } else {
                    Visit::Continue(t_cur)
                }
            },
        );
        hit
    }

    /// [`MeshBvh::occluded`] (from 0) for `N` rays at once ([`WideBvh::any_hits`]).
    #[inline]
    fn occluded_each<const N: usize>(&self, rays: [&Ray; N], t_max: [f32; N]) -> [bool; N] {
        let r4 = rays.map(Ray4::new);
        self.tree.any_hits(rays, 0.0, t_max, &self.packs, |k, range| self.leaf_blocks(range, &r4[k], 0.0, t_max[k]))
    }

    /// The lanes of `live` (a bit each) whose ray `ray(lane)` a triangle blocks between
    /// 0 and `t_max[lane]` ([`MeshBvh::occluded_eight`]).
    fn occluded_lanes(&self, ray: impl Fn(usize) -> Ray, t_max: [f32; 8], live: u32) -> u32 {
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
    fn occluded_eight(&self, rays: &[Ray; 8], t_max: [f32; 8], live: u32) -> u32 {
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
    fn occluded_packet(&self, rays: &[Ray; 8], t_max: [f32; 8], live: u32) -> Option<u32> {
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
    fn closest_lanes(&self, ray: impl Fn(usize) -> Ray, t_max: [f32; 8], live: u32) -> [Option<Hit>; 8] {
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
            return unsafe { tri4::intersect_pair(a, b, r4, t_min, t_max).0 != 0 };
        }
        self.packs[range].iter().any(|p| p.intersect(r4, t_min, t_max).0 != 0)
    }
}

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
    for lane in (0..8).filter(|lane| live >> lane & 1 != 0) {
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

/// Bounds on the distances `t` at which `o + t d` lies in the slab `[b_lo, b_hi]` of one
/// axis, for any `o` in `[o_lo, o_hi]` and `d` in `[d_lo, d_hi]`: `(-inf, inf)` when `d`
/// may be 0, else found from the extreme origins and directions.
fn axis_reach(b_lo: f64, b_hi: f64, o_lo: f64, o_hi: f64, d_lo: f64, d_hi: f64) -> (f64, f64) {
    if d_lo > 0.0 {
        // Entering at (b_lo - o) / d, least for the farthest origin; leaving at
        // (b_hi - o) / d, most for the nearest. Either divided by the direction that
        // makes it least, or most.
        let (n_in, n_out) = (b_lo - o_hi, b_hi - o_lo);
        (n_in / if n_in >= 0.0 { d_hi } else { d_lo }, n_out / if n_out >= 0.0 { d_lo } else { d_hi })
    } else if d_hi < 0.0 {
        // The mirror image of the case above.
        axis_reach(-b_hi, -b_lo, -o_hi, -o_lo, -d_hi, -d_lo)
    } else {
        (f64::NEG_INFINITY, f64::INFINITY)
    }
}

/// Scenes of at most this many objects cull them per image tile for camera rays
/// ([`World::seen_from`]): a test per object per tile, cheap while objects are few...
const CONE_MAX_OBJECTS: usize = 64;
/// ...and worth it while a tile sees few of them: past this the tree does better.
const CONE_MAX_SEEN: usize = 6;

/// No object: the index of the best hit before there is one.
const NONE: u32 = u32::MAX;

/// The nearest hit so far and its object ([`NONE`] before any), field by field.
#[derive(Clone, Copy)]
struct Nearest {
    t: f32,
    uv: Vec2,
    part: u8,
    prim: u32,
    index: u32,
}

impl Default for Nearest {
    fn default() -> Self {
        Nearest { t: 0.0, uv: Vec2::ZERO, part: 0, prim: 0, index: NONE }
    }
}

impl Nearest {
    /// Keeps hit `h` on object `i` if it is nearer, or as near with a lower index.
    #[inline(always)]
    fn offer(&mut self, h: Hit, i: u32) -> bool {
        let better = self.index == NONE || h.t < self.t || (h.t == self.t && i < self.index);
        if better {
            (self.t, self.uv, self.part, self.prim, self.index) = (h.t, h.uv, h.part, h.prim, i);
        }
        better
    }

    #[inline(always)]
    fn get(self) -> Option<(Hit, u32)> {
        (self.index != NONE).then_some((Hit { t: self.t, uv: self.uv, part: self.part, prim: self.prim }, self.index))
    }
}

fn wide(bvh: &Bvh, width: Option<usize>) -> WideBvh {
    match width {
        Some(w) => WideBvh::with_width(bvh, w),
        None => WideBvh::from_binary(bvh),
    }
}

/// An entry of a top-level leaf. Spheres, the commonest object in big scenes, are
/// copied into the leaf in packs of four and tested together (inline, so a leaf's
/// spheres are one read from the node, not two); other objects are named by index.
#[derive(Clone, Copy, Debug)]
enum LeafItem {
    Spheres(Sphere4),
    Other(u32),
}

/// The read-only ray-query structure shared by all render threads.
#[derive(Debug)]
pub struct World<'s> {
    scene: &'s Scene,
    kind: AccelKind,
    /// Over objects; empty with `AccelKind::None`. Leaf positions index `leaves`.
    top4: WideBvh,
    leaves: Vec<LeafItem>,
    /// Per object: the BVH of a mesh object (with `AccelKind::Bvh`).
    meshes: Vec<Option<MeshBvh>>,
    /// Per object, the share of light its material lets through (0 = opaque), looked
    /// up once here rather than through the material on every shadow ray.
    transmission: Vec<f32>,
    /// The objects whose material absorbs light inside ([`World::transmittance_color`]).
    absorbing: Vec<u32>,
    build_time: Duration,
    /// Test objects one by one: no top-level tree, or a single object (one mesh), whose
    /// own tree's root box already does what the top level would.
    flat: bool,
    /// Whether the eight-lane code runs ([`lanes::avx2`]), for [`World::closest_among_each`].
    avx2: bool,
}

impl<'s> World<'s> {
    pub fn new(scene: &'s Scene, kind: AccelKind) -> Self {
        World::with_width(scene, kind, None)
    }

    /// With trees of this many children per node (4, or 8 where the processor has
    /// AVX2), rather than the best this processor walks: lets tests cover both.
    pub fn with_width(scene: &'s Scene, kind: AccelKind, width: Option<usize>) -> Self {
        let start = Instant::now();
        let transmission = scene.objects.iter().map(|o| scene.material(o.material).transparency).collect();
        let absorbing = (0..scene.objects.len() as u32)
            .filter(|&i| scene.material(scene.objects[i as usize].material).absorbs())
            .collect();
        let (top, meshes) = match kind {
            AccelKind::None => (Bvh { nodes: vec![], indices: vec![] }, scene.objects.iter().map(|_| None).collect()),
            AccelKind::Bvh => {
                use rayon::prelude::*;
                let bounds: Vec<_> = scene.objects.iter().map(|o| o.shape.bounds()).collect();
                let meshes = scene
                    .objects
                    .par_iter()
                    .map(|o| match &o.shape {
                        Shape::Mesh(m) => Some(MeshBvh::build(m, width)),
                        _ => None,
                    })
                    .collect();
                // Leaves test spheres four at a time, so in a scene of (nearly) only
                // spheres the tree is costed like a mesh's, by packs; elsewhere objects
                // differ too much in cost for packs to be the unit.
                let round = scene.objects.iter().filter(|o| matches!(o.shape, Shape::Sphere(_))).count();
                let top = if round >= 64 && round * 10 >= scene.objects.len() * 9 {
                    Bvh::build_packed(&bounds, 4)
                } else {
                    Bvh::build(&bounds)
                };
                (top, meshes)
            }
        };
        let mut top4 = if top.nodes.is_empty() { WideBvh::default() } else { wide(&top, width) };
        let mut leaves = Vec::new();
        top4.map_leaves(|first, count| {
            let start = leaves.len() as u32;
            let ids = &top.indices[first as usize..(first + count) as usize];
            let sphere = |i: u32| match &scene.objects[i as usize].shape {
                Shape::Sphere(s) => Some((*s, i)),
                _ => None,
            };
            let round: Vec<_> = ids.iter().filter_map(|&i| sphere(i)).collect();
            for chunk in round.chunks(4) {
                leaves.push(LeafItem::Spheres(Sphere4::pack(chunk)));
            }
            leaves.extend(ids.iter().filter(|&&i| sphere(i).is_none()).map(|&i| LeafItem::Other(i)));
            (start, leaves.len() as u32 - start)
        });
        let flat = kind == AccelKind::None || scene.objects.len() == 1;
        let leaves = crate::pages::on_huge_pages(leaves);
        let avx2 = lanes::avx2();
        World { scene, kind, top4, leaves, meshes, transmission, absorbing, build_time: start.elapsed(), flat, avx2 }
    }

    pub fn scene(&self) -> &'s Scene {
        self.scene
    }

    pub fn kind(&self) -> AccelKind {
        self.kind
    }

    /// Time spent building the acceleration structures.
    pub fn build_time(&self) -> Duration {
        self.build_time
    }

    /// Bytes held by the acceleration structures (not the scene's own geometry).
    pub fn memory_bytes(&self) -> usize {
        self.leaves.capacity() * std::mem::size_of::<LeafItem>()
            + self.top4.memory_bytes()
            + self.meshes.iter().flatten().map(MeshBvh::memory_bytes).sum::<usize>()
    }

    /// Leaf entries whose boxes the ray enters, nearest first when `NEAREST_FIRST`
    /// (else in node order, which saves sorting when every hit counts);
    /// `test(index of the entry in `leaves`, t_max)` as in [`Bvh::traverse`].
    #[inline]
    fn traverse_objects<const NEAREST_FIRST: bool>(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        mut test: impl FnMut(usize, f32) -> Visit,
    ) {
        // A ray from an overflowed point or in a direction of NaNs meets nothing (and
        // its box tests would not say so).
        if !(ray.origin.is_finite() && ray.dir.is_finite()) {
            return;
        }
        let leaf = |range: std::ops::Range<usize>, mut t_cur: f32| {
            for at in range {
                match test(at, t_cur) {
                    Visit::Continue(t) => t_cur = t,
                    Visit::Stop => return Visit::Stop,
                }
            }
            Visit::Continue(t_cur)
        };
        self.top4.traverse::<NEAREST_FIRST, _>(ray, t_min, t_max, &self.leaves, leaf)
    }

    #[inline]
    fn intersect_object(&self, i: usize, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        match &self.meshes[i] {
            Some(m) => m.closest(ray, t_min, t_max),
            None => self.scene.objects[i].shape.intersect(ray, t_min, t_max),
        }
    }

    #[inline]
    fn blocks(&self, i: usize, ray: &Ray, t_max: f32) -> bool {
        match (&self.meshes[i], &self.scene.objects[i].shape) {
            (Some(m), _) => m.occluded(ray, 0.0, t_max),
            (None, Shape::Mesh(m)) => m.occluded(ray, 0.0, t_max),
            (None, s) => s.intersect(ray, 0.0, t_max).is_some(),
        }
    }

    /// The nearest hit in `(t_min, t_max)` and the index of the object hit.
    #[inline]
    pub fn closest(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<(Hit, u32)> {
        if self.flat {
            return self.closest_of(0..self.scene.objects.len() as u32, ray, t_min, t_max);
        }
        {
            let r4 = Ray4::new(ray);
            // The best hit so far field by field, not as an `Option<(Hit, u32)>`: written
            // piecewise and read back whole, the option stalled store forwarding (a
            // quarter of this function's time in the room).
            let mut nearest = Nearest::default();
            self.traverse_objects::<true>(ray, t_min, t_max, |at, t_cur| {
                Visit::Continue(self.leaf_nearest(at, &r4, ray, t_min, t_cur, &mut nearest))
            });
            nearest.get()
        }
    }

    /// The objects of leaf entry `at` against the ray, within `(t_min, t_cur)`, kept in
    /// `nearest` if nearer (ties to the lower index); returns the new bound. The answer
    /// does not depend on the order entries come in.
    #[inline(always)]
    fn leaf_nearest(&self, at: usize, r4: &Ray4, ray: &Ray, t_min: f32, mut t_cur: f32, nearest: &mut Nearest) -> f32 {
        // Once something is hit the bound is inclusive, so an object at exactly
        // the same distance with a lower index wins, as in the brute-force loop.
        let limit = if nearest.index != NONE { t_cur.next_up() } else { t_cur };
        let mut offer = |h: Hit, i: u32| {
            if nearest.offer(h, i) {
                t_cur = h.t;
            }
        };
        match self.leaves[at] {
            LeafItem::Spheres(ref pack) => {
                let (mut mask, t) = pack.intersect(r4, t_min, limit);
                while mask != 0 {
                    let lane = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    offer(Hit { t: t[lane], uv: Vec2::ZERO, part: part::SIDE, prim: 0 }, pack.ids[lane]);
                }
            }
            LeafItem::Other(i) => {
                if let Some(h) = self.intersect_object(i as usize, ray, t_min, limit) {
                    offer(h, i);
                }
            }
        }
        t_cur
    }

    /// Whether groups of rays may be tested against only the objects they may meet
    /// ([`World::seen_from`], [`World::seen_along`], [`World::may_shadow`]): in a small
    /// scene with a tree asked for. In a large one the tree does better.
    #[inline]
    pub fn culls(&self) -> bool {
        self.kind == AccelKind::Bvh && self.scene.objects.len() <= CONE_MAX_OBJECTS
    }

    /// The objects whose boxes meet the cone of rays from `apex` within the four edge
    /// directions `edges` (see [`crate::camera::CameraRig::cone`]), in index order, into
    /// `seen`; `false` (and `seen` left unusable) when that would not pay: no tree was
    /// asked for, the scene is not small, or the cone sees many objects. Camera rays
    /// through an image tile then test only these, with [`World::closest_among`].
    pub fn seen_from(&self, apex: Vec3, edges: [Vec3; 4], seen: &mut Vec<u32>) -> bool {
        seen.clear();
        if !self.culls() {
            return false;
        }
        // Inward normals of the cone's four sides, in f64 so that the test cannot
        // round a box out that a ray of the cone reaches.
        let e = edges.map(|v| v.as_dvec3());
        let axis = e[0] + e[1] + e[2] + e[3];
        let sides: [DVec3; 4] = std::array::from_fn(|i| {
            let n = e[i].cross(e[(i + 1) % 4]);
            if n.dot(axis) < 0.0 { -n } else { n }
        });
        let apex = apex.as_dvec3();
        for (i, o) in self.scene.objects.iter().enumerate() {
            let b = o.shape.bounds();
            let (centre, half) = ((b.min + b.max).as_dvec3() * 0.5 - apex, (b.max - b.min).as_dvec3() * 0.5);
            // Wholly behind one side: no ray of the cone reaches it. (NaN keeps it.)
            if !sides.iter().any(|n| n.dot(centre) + n.abs().dot(half) < 0.0) {
                if seen.len() == CONE_MAX_SEEN {
                    return false;
                }
                seen.push(i as u32);
            }
        }
        true
    }

    /// The objects that any of `rays` (from their origins on) may meet, in index order,
    /// into `seen`; `false` (and `seen` unusable) when that would not pay, as in
    /// [`World::seen_from`]. For rays of one kind sent on from one object's hits in an
    /// image tile, which leave from nearby points in nearby directions, it is a few;
    /// [`World::closest_among`] them then finds what the tree finds.
    ///
    /// Per axis, interval arithmetic in f64 bounds the distances at which a ray with
    /// origin in the rays' box and direction in theirs can be within an object's slab
    /// (its box widened by 1e-3, relative, for rounding); an object is passed over when
    /// no distance past 0 lies within all three.
    pub fn seen_along<T>(&self, rays: &[(Ray, T)], seen: &mut Vec<u32>) -> bool {
        seen.clear();
        if !self.culls() {
            return false;
        }
        let (mut o_lo, mut o_hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        let (mut d_lo, mut d_hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for (r, _) in rays {
            let (o, d) = (r.origin.as_dvec3(), r.dir.as_dvec3());
            (o_lo, o_hi, d_lo, d_hi) = (o_lo.min(o), o_hi.max(o), d_lo.min(d), d_hi.max(d));
        }
        if !(o_lo.is_finite() && o_hi.is_finite() && d_lo.is_finite() && d_hi.is_finite()) {
            return false;
        }
        for (i, object) in self.scene.objects.iter().enumerate() {
            let b = object.shape.bounds();
            let (b_lo, b_hi) = (b.min.as_dvec3(), b.max.as_dvec3());
            let m = 1e-3 * (1.0 + b_lo.abs().max(b_hi.abs()).max_element());
            let (b_lo, b_hi) = (b_lo - m, b_hi + m);
            // NaN bounds keep the object.
            let (mut enter, mut leave) = (0.0f64, f64::INFINITY);
            for k in 0..3 {
                let (lo, hi) = axis_reach(b_lo[k], b_hi[k], o_lo[k], o_hi[k], d_lo[k], d_hi[k]);
                (enter, leave) = (enter.max(lo), leave.min(hi));
            }
            if !(enter > leave) {
                if seen.len() == CONE_MAX_SEEN {
                    return false;
                }
                seen.push(i as u32);
            }
        }
        true
    }

    /// The objects that could stand between a point of the boxes `from` and the point
    /// `light`, in index order, into `blockers`; `false` (and `blockers` unusable) when
    /// that would not pay or cannot be bounded, as in [`World::seen_from`]. `from` pairs
    /// an object with a box round points on it (the hits of an image tile): shadow
    /// rays leave from those points, pushed off the surface towards the light, and
    /// then test only the objects found here, with [`World::transmittance_among`].
    ///
    /// Two conservative tests, in f64 with margins of 1e-3 (relative) that cover the
    /// rounding of the f32 ones. A quad is passed over when the light and every point
    /// not on the quad itself lie strictly on one side of its plane (a point on it
    /// starts its shadow ray off the plane on the light's side: true of two-sided
    /// shading, not of [`crate::integrator::Integrator::one_sided`]). Any object is passed
    /// over when its bounding sphere misses the cone, apex at the light, that the
    /// segments to the points' bounding sphere fill, or lies beyond its reach.
    pub fn may_shadow(&self, from: &[(u32, Aabb)], light: Vec3, blockers: &mut Vec<u32>) -> bool {
        blockers.clear();
        if !self.culls() {
            return false;
        }
        let margin = |b: Aabb| {
            let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
            let m = 1e-3 * (1.0 + lo.abs().max(hi.abs()).max_element());
            (lo - m, hi + m)
        };
        let sphere = |(lo, hi): (DVec3, DVec3)| ((lo + hi) * 0.5, (hi - lo).length() * 0.5);
        let union = |skip: Option<u32>| {
            from.iter().filter(|(o, _)| Some(*o) != skip).fold(Aabb::EMPTY, |b, (_, p)| b.union(*p))
        };
        let light = light.as_dvec3();
        let (centre, radius) = sphere(margin(union(None)));
        let axis = centre - light;
        let reach = axis.length();
        // The light inside (or nearly) the points' sphere: no cone to speak of.
        if !(radius.is_finite() && reach.is_finite() && radius < 0.9 * reach) {
            return false;
        }
        let spread = (radius / reach).asin();
        for (i, o) in self.scene.objects.iter().enumerate() {
            if let Shape::Quad(q) = &o.shape {
                let (normal, d) = q.plane();
                let (n, d) = (normal.as_dvec3(), d as f64);
                let side = |x: DVec3| n.dot(x) - d;
                let others = union(Some(i as u32));
                let (lo, hi) = margin(others);
                let corners =
                    (0..8).map(|k| DVec3::new([lo.x, hi.x][k & 1], [lo.y, hi.y][k >> 1 & 1], [lo.z, hi.z][k >> 2]));
                let l = side(light);
                let tol = 1e-3 * (1.0 + n.abs().dot(light.abs()) + d.abs());
                if others.min.x > others.max.x || (l.abs() > tol && corners.into_iter().all(|c| side(c) * l > 0.0)) {
                    continue;
                }
            }
            let (c, r) = sphere(margin(o.shape.bounds()));
            let v = c - light;
            let e = v.length();
            let blocks = if !(r.is_finite() && e.is_finite()) || e <= r {
                true
            } else {
                let angle = (v.dot(axis) / (e * reach)).clamp(-1.0, 1.0).acos();
                e - r <= reach + radius && angle <= spread + (r / e).asin() + 1e-3
            };
            if blocks {
                if blockers.len() == CONE_MAX_SEEN {
                    return false;
                }
                blockers.push(i as u32);
            }
        }
        true
    }

    /// [`World::transmittance`] counting objects `ids` (in index order) only: for
    /// shadow rays no other object can block ([`World::may_shadow`]).
    #[inline]
    pub fn transmittance_among(&self, ids: &[u32], ray: &Ray, t_max: f32) -> f32 {
        self.transmittance_of(ids.iter().copied(), ray, t_max)
    }

    /// Testing objects `ids` one by one, in the order given.
    #[inline(always)]
    fn transmittance_of(&self, ids: impl IntoIterator<Item = u32>, ray: &Ray, t_max: f32) -> f32 {
        let mut light = 1.0f64;
        for i in ids {
            if self.blocks(i as usize, ray, t_max) {
                light *= self.transmission[i as usize] as f64;
                if light == 0.0 {
                    return 0.0;
                }
            }
        }
        light as f32
    }

    /// [`World::closest`] among objects `ids` (in index order) only: for rays that can
    /// reach no others ([`World::seen_from`]), the same answer without the tree.
    #[inline(always)]
    pub fn closest_among(&self, ids: &[u32], ray: &Ray, t_min: f32, t_max: f32) -> Option<(Hit, u32)> {
        self.closest_of(ids.iter().copied(), ray, t_min, t_max)
    }

    /// [`World::closest_among`] `ids` for each ray of `found`, its answer written beside
    /// it: with AVX2, eight rays at a time, object by object (the same answers).
    pub fn closest_among_each(&self, ids: &[u32], found: &mut [(Ray, Option<(Hit, u32)>)]) {
        self.closest_among_each_or(ids, found, |_, _, _| false);
    }

    /// [`World::closest_among_each`], where each block of eight rays found with AVX2 is
    /// first offered, with its hits in lanes, to `take(first, rays, hits)` (`first`: the
    /// block's first index in `found`). A block `take` keeps is left without hits in
    /// `found` (as it came): the caller shades it from the lanes.
    pub fn closest_among_each_or(
        &self,
        ids: &[u32],
        found: &mut [(Ray, Option<(Hit, u32)>)],
        mut take: impl FnMut(usize, &[(Ray, Option<(Hit, u32)>)], &Best8) -> bool,
    ) {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            for (block, rays) in found.chunks_mut(8).enumerate() {
                // SAFETY: `avx2` is set only where the processor has AVX2.
                #[allow(unsafe_code)]
                unsafe {
                    self.closest_among_8(ids, rays, |rays, best| take(8 * block, rays, best))
                };
            }
            return;
        }
        for (ray, hit) in found {
            *hit = self.closest_among(ids, ray, 0.0, f32::INFINITY);
        }
    }

    /// [`World::transmittance_among`] `ids` for eight shadow rays given lane by lane
    /// (origins, unit directions, lengths), in the lanes `live` (the others are 0): with
    /// AVX2, the eight tested together, object by object (the same answers).
    pub fn transmittance_among_lanes(
        &self,
        ids: &[u32],
        origins: &[[f32; 8]; 3],
        dirs: &[[f32; 8]; 3],
        t_max: [f32; 8],
        live: u32,
    ) -> [f32; 8] {
        if ids.is_empty() {
            // Nothing may stand in the way (half of the room's shadow rays): every live
            // lane sees all of the light, as the tests below would find.
            return std::array::from_fn(|lane| if live >> lane & 1 != 0 { 1.0 } else { 0.0 });
        }
        let ray = |lane: usize| Ray {
            origin: Vec3::new(origins[0][lane], origins[1][lane], origins[2][lane]),
            dir: Vec3::new(dirs[0][lane], dirs[1][lane], dirs[2][lane]),
        };
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only where the processor has AVX2.
            #[allow(unsafe_code)]
            return unsafe {
                self.transmittance_among_8(ids, &packet8::Rays8::from_lanes(origins, dirs), ray, t_max, live)
            };
        }
        std::array::from_fn(|lane| {
            if live >> lane & 1 == 0 { 0.0 } else { self.transmittance_among(ids, &ray(lane), t_max[lane]) }
        })
    }

    /// The eight rays of [`World::transmittance_among_lanes`] (`ray` gives them one by
    /// one): each live lane's light is multiplied by each object's transmission, in the
    /// order given, where the object lies across it, as in [`World::transmittance_of`].
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn transmittance_among_8(
        &self,
        ids: &[u32],
        wide: &packet8::Rays8,
        ray: impl Fn(usize) -> Ray,
        t_max: [f32; 8],
        live: u32,
    ) -> [f32; 8] {
        let mut light = [1.0f64; 8];
        for &i in ids {
            let mut best = Best8::within(t_max);
            let mut blocked = 0u32;
            if let Some(mesh) = &self.meshes[i as usize] {
                blocked = mesh.occluded_lanes(&ray, t_max, live);
            } else if !self.eight_lanes(i, wide, live, &mut best) {
                for lane in (0..8).filter(|lane| live >> lane & 1 != 0) {
                    blocked |= (self.blocks(i as usize, &ray(lane), t_max[lane]) as u32) << lane;
                }
            }
            // Each object has a fresh `best`: the lanes it holds are those it blocks.
            blocked |= best.taken_by(i);
            while blocked != 0 {
                let lane = blocked.trailing_zeros() as usize;
                blocked &= blocked - 1;
                light[lane] *= self.transmission[i as usize] as f64;
            }
        }
        std::array::from_fn(|lane| if live >> lane & 1 == 0 { 0.0 } else { light[lane] as f32 })
    }

    /// Object `i` against the lanes `live` of `rays`, where it has an eight-lane test
    /// (quads, spheres, cylinders, pointed cones): the lanes that hit it before their
    /// bound in `best` keep it there. `false`, and nothing done, for other shapes.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn eight_lanes(&self, i: u32, rays: &packet8::Rays8, live: u32, best: &mut Best8) -> bool {
        match (&self.meshes[i as usize], &self.scene.objects[i as usize].shape) {
            (None, Shape::Quad(q)) => packet8::quad(q, rays, live, best, i),
            (None, Shape::Sphere(s)) => packet8::sphere(s, rays, live, best, i),
            (None, Shape::Cylinder(c)) => packet8::cylinder(c, rays, live, best, i),
            (None, Shape::Cone(c)) if c.top_radius == 0.0 => packet8::pointed_cone(c, rays, live, best, i),
            _ => return false,
        }
        true
    }

    /// Up to eight rays of [`World::closest_among_each`]: objects with an eight-lane
    /// test ([`World::eight_lanes`]) tested once, others ray by ray. Each ray meets the
    /// objects in the order given, with the bound its earlier hits set, as in
    /// [`World::closest_of`].
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn closest_among_8(
        &self,
        ids: &[u32],
        rays: &mut [(Ray, Option<(Hit, u32)>)],
        take: impl FnOnce(&[(Ray, Option<(Hit, u32)>)], &Best8) -> bool,
    ) {
        let live = (1u32 << rays.len()) - 1;
        let wide = packet8::Rays8::new(rays);
        let mut best = Best8::new();
        for &i in ids {
            if let Some(mesh) = &self.meshes[i as usize] {
                let found = mesh.closest_lanes(|lane| rays[lane].0, best.t, live);
                for (lane, h) in found.into_iter().enumerate() {
                    if let Some(h) = h {
                        best.set(lane, h, i);
                    }
                }
            } else if !self.eight_lanes(i, &wide, live, &mut best) {
                for (lane, (ray, _)) in rays.iter().enumerate() {
                    if let Some(h) = self.intersect_object(i as usize, ray, 0.0, best.t[lane]) {
                        best.set(lane, h, i);
                    }
                }
            }
        }
        if take(rays, &best) {
            return; // their hits stay `None`, as `found` came
        }
        for (lane, (_, hit)) in rays.iter_mut().enumerate() {
            *hit = (best.index[lane] != NONE).then(|| best.get(lane));
        }
    }

    /// Testing objects `ids` one by one, in the order given; the first of equally near
    /// hits wins.
    #[inline(always)]
    fn closest_of(&self, ids: impl IntoIterator<Item = u32>, ray: &Ray, t_min: f32, t_max: f32) -> Option<(Hit, u32)> {
        // Field by field, as in `closest`.
        let (mut t_max, mut best, mut index) = (t_max, Hit { t: 0.0, uv: Vec2::ZERO, part: 0, prim: 0 }, NONE);
        for i in ids {
            if let Some(h) = self.intersect_object(i as usize, ray, t_min, t_max) {
                t_max = h.t;
                (best.t, best.uv, best.part, best.prim, index) = (h.t, h.uv, h.part, h.prim, i);
            }
        }
        (index != NONE).then_some((best, index))
    }

    /// [`World::closest`] for each of `rays`, into `out` (as long): in a world of one
    /// mesh, eight at a time, as one packet where they head into one octant
    /// ([`wide8::Bvh8::nearest_packet`]), else two walks at a time, interleaved
    /// ([`wide8::Bvh8::nearest_hits`]); elsewhere one ray after another.
    pub fn closest_each(&self, rays: &[Ray], t_min: f32, t_max: f32, out: &mut [Option<(Hit, u32)>]) {
        let [Some(mesh)] = &self.meshes[..] else {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Camera;
    use crate::geometry::{Cone, Cylinder, Polygon, Quad, Sphere, Triangle};
    use crate::material::Material;
    use crate::math::Color;
    use crate::math::Vec3;
    use crate::sampler::Rng;

    fn v(r: &mut Rng, scale: f32) -> Vec3 {
        Vec3::new(r.next_f32() - 0.5, r.next_f32() - 0.5, r.next_f32() - 0.5) * scale
    }

    fn unit(r: &mut Rng) -> Vec3 {
        loop {
            let d = v(r, 2.0);
            if d.length_squared() > 1e-3 && d.length_squared() <= 1.0 {
                return d.normalize();
            }
        }
    }

    /// `n` objects of every kind scattered in a 20-unit box, some transparent.
    fn random_scene(seed: u64, n: usize) -> Scene {
        let mut r = Rng::new(seed);
        let mut scene = Scene::new(Camera::new(Vec3::ZERO, Vec3::NEG_Z, Vec3::Y, 40.0, 8, 8));
        let opaque = scene.add_material(Material::color(Color::ONE));
        let glass = scene.add_material(Material::color(Color::ONE).transparent(0.6, 1.0));
        for i in 0..n {
            let c = v(&mut r, 20.0);
            let size = 0.2 + r.next_f32() * 2.0;
            let shape: Shape = match i % 7 {
                0 => Sphere::new(c, size).into(),
                1 => Quad::new(c, unit(&mut r) * size, unit(&mut r) * size).into(),
                2 => {
                    let (a, b) = crate::math::orthonormal_basis(unit(&mut r));
                    let k = 3 + (r.below(5) as usize);
                    let pts = (0..k)
                        .map(|j| {
                            let ang = j as f32 / k as f32 * std::f32::consts::TAU;
                            c + size * (ang.cos() * a + ang.sin() * b)
                        })
                        .collect();
                    Polygon::new(pts).unwrap().into()
                }
                3 => Cylinder::new(c, unit(&mut r), size * 0.5, size * 2.0, r.below(2) == 0).into(),
                4 => {
                    // Pointed or truncated (narrowing or widening), open or closed.
                    let top = [0.0, 0.4, 1.6][r.below(3) as usize] * size;
                    let closed = r.below(2) == 0;
                    Cone::truncated(c, unit(&mut r), size, top, size * 1.5, closed, closed).into()
                }
                5 => Triangle::new(c, c + v(&mut r, 3.0), c + v(&mut r, 3.0)).into(),
                _ => {
                    // A small random triangle soup, as a mesh.
                    let pos: Vec<Vec3> = (0..30).map(|_| c + v(&mut r, 4.0)).collect();
                    let tris = (0..10).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
                    Mesh::new(pos, vec![], vec![], tris, r.below(2) == 0).unwrap().into()
                }
            };
            let m = if r.below(4) == 0 { glass } else { opaque };
            scene.add(shape, m);
        }
        scene
    }

    /// Calls `f((tx, ty), (x0, y0), seen)` for each 4 x 4 pixel tile of the scene's
    /// image whose cone of camera rays culls the objects to `seen`.
    fn culled_tiles(world: &World, rig: &crate::camera::CameraRig, mut f: impl FnMut((u32, u32), (f32, f32), &[u32])) {
        let camera = world.scene().camera;
        let mut seen = Vec::new();
        for (ty, tx) in
            (0..camera.height.div_ceil(4)).flat_map(|ty| (0..camera.width.div_ceil(4)).map(move |tx| (ty, tx)))
        {
            let (x0, y0) = (tx as f32 * 4.0, ty as f32 * 4.0);
            let (apex, edges) = rig.cone(x0, y0, x0 + 4.0, y0 + 4.0);
            if world.seen_from(apex, edges, &mut seen) {
                f((tx, ty), (x0, y0), &seen);
            }
        }
    }

    #[test]
    fn camera_rays_through_a_tile_test_only_what_its_cone_sees_and_find_the_same() {
        // Small random scenes seen by cameras from outside and from inside; every
        // 4 x 4 pixel tile culls to its cone, and each ray, through the pixel centre
        // and through the tile's corners, must find what the tree finds, alone and
        // eight at a time (81 rays: a short last group).
        let (mut culled, mut hits, mut dropped) = (0, 0, 0);
        for seed in 0..12u64 {
            let mut scene = random_scene(seed, 14);
            let mut r = Rng::new(seed + 100);
            let eye = if seed % 2 == 0 { v(&mut r, 60.0) } else { v(&mut r, 8.0) };
            scene.camera = Camera::new(eye, v(&mut r, 5.0), Vec3::Y, 30.0 + 60.0 * r.next_f32(), 32, 24);
            let world = World::new(&scene, AccelKind::Bvh);
            let rig = scene.camera.rig().unwrap();
            culled_tiles(&world, &rig, |(tx, ty), (x0, y0), seen| {
                culled += 1;
                dropped += scene.objects.len() - seen.len();
                assert!(seen.windows(2).all(|w| w[0] < w[1]));
                let at = (0..=8).flat_map(|j| (0..=8).map(move |i| (i as f32 * 0.5, j as f32 * 0.5)));
                let mut each: Vec<_> = at.clone().map(|(sx, sy)| (rig.ray(x0 + sx, y0 + sy), None)).collect();
                world.closest_among_each(seen, &mut each);
                for ((sx, sy), (ray, together)) in at.zip(&each) {
                    let want = world.closest(ray, 0.0, f32::INFINITY);
                    let got = world.closest_among(seen, ray, 0.0, f32::INFINITY);
                    assert_eq!(got, want, "seed {seed}, tile ({tx}, {ty}), at ({sx}, {sy})");
                    assert_eq!(*together, want, "eight at a time: seed {seed}, tile ({tx}, {ty}), at ({sx}, {sy})");
                    hits += want.is_some() as u32;
                }
            });
        }
        assert!(culled > 100 && hits > 1000 && dropped > 1000, "{culled} tiles, {hits} hits, {dropped} objects culled");
        // Not for big scenes, nor without a tree.
        let big = random_scene(1, 100);
        let rig = big.camera.rig().unwrap();
        let (apex, edges) = rig.cone(0.0, 0.0, 1.0, 1.0);
        assert!(!World::new(&big, AccelKind::Bvh).seen_from(apex, edges, &mut Vec::new()));
        let small = random_scene(1, 3);
        assert!(!World::new(&small, AccelKind::None).seen_from(apex, edges, &mut Vec::new()));
    }

    #[test]
    fn rays_from_nearby_points_in_nearby_directions_test_only_what_they_may_meet_and_find_the_same() {
        // Bundles of rays as a tile's reflections send on: origins within a small box
        // (sometimes a single point, or one coordinate shared, as on an axis-aligned
        // mirror), directions within a narrow cone, some with a zero component. Where
        // the bundle culls, each ray must find what the tree finds.
        let (mut culled, mut hits, mut dropped) = (0, 0, 0);
        let mut seen = Vec::new();
        for seed in 0..10u64 {
            let scene = random_scene(seed, 20);
            let world = World::new(&scene, AccelKind::Bvh);
            let mut r = Rng::new(seed + 300);
            for bundle in 0..400 {
                let centre = v(&mut r, 25.0);
                let spread = [0.0, 0.05, 1.0][bundle % 3];
                let aim = unit(&mut r);
                let aim = if bundle % 5 == 0 { Vec3::new(aim.x, 0.0, aim.z).normalize() } else { aim };
                let width = [0.01, 0.1, 0.3][bundle % 4 % 3];
                let rays: Vec<(Ray, ())> = (0..24)
                    .map(|_| {
                        let mut o = centre + v(&mut r, spread);
                        if bundle % 7 == 0 {
                            o.y = centre.y;
                        }
                        let mut d = aim + v(&mut r, width);
                        if bundle % 5 == 0 && r.below(2) == 0 {
                            d.y = 0.0;
                        }
                        (Ray::new(o, d), ())
                    })
                    .collect();
                if !world.seen_along(&rays, &mut seen) {
                    continue;
                }
                culled += 1;
                dropped += scene.objects.len() - seen.len();
                assert!(seen.windows(2).all(|w| w[0] < w[1]));
                for (ray, ()) in &rays {
                    let want = world.closest(ray, 0.0, f32::INFINITY);
                    assert_eq!(world.closest_among(&seen, ray, 0.0, f32::INFINITY), want, "seed {seed}, {ray:?}");
                    hits += want.is_some() as u32;
                }
            }
        }
        assert!(
            culled > 1000 && hits > 5000 && dropped > 10_000,
            "{culled} bundles, {hits} hits, {dropped} objects culled"
        );
    }

    #[test]
    fn shadow_rays_from_a_tiles_hits_need_only_the_objects_that_may_shadow_them() {
        // As a render does: a tile's camera hits, boxed per object; for lights here and
        // there, the shadow ray from each hit (pushed off its surface towards the light)
        // must pass the same light testing the culled list as testing everything.
        let (mut checked, mut culled_lists, mut dropped, mut partial) = (0, 0, 0, 0);
        for seed in 0..16u64 {
            let mut scene = random_scene(seed, 12);
            // Walls too: quads are culled by their planes.
            let wall = scene.objects[0].material;
            for (c, u, v) in
                [(Vec3::new(-30.0, -30.0, -30.0), Vec3::X, Vec3::Y), (Vec3::new(-30.0, -30.0, -30.0), Vec3::Z, Vec3::X)]
            {
                scene.add(Quad::new(c, u * 60.0, v * 60.0), wall);
            }
            let mut r = Rng::new(seed + 7);
            scene.camera = Camera::new(v(&mut r, 25.0), v(&mut r, 5.0), Vec3::Y, 50.0, 24, 16);
            let lights: Vec<Vec3> = (0..4).map(|_| v(&mut r, 28.0)).collect();
            let world = World::new(&scene, AccelKind::Bvh);
            let rig = scene.camera.rig().unwrap();
            culled_tiles(&world, &rig, |(tx, ty), (x0, y0), seen| {
                let mut found = Vec::new();
                let mut boxes: Vec<(u32, Aabb)> = Vec::new();
                for (sx, sy) in (0..8).flat_map(|j| (0..8).map(move |i| (i as f32 * 0.5 + 0.25, j as f32 * 0.5 + 0.25)))
                {
                    let ray = rig.ray(x0 + sx, y0 + sy);
                    if let Some((h, i)) = world.closest_among(seen, &ray, 0.0, f32::INFINITY) {
                        match boxes.iter_mut().find(|(o, _)| *o == i) {
                            Some((_, b)) => *b = b.grow(ray.at(h.t)),
                            None => boxes.push((i, Aabb::EMPTY.grow(ray.at(h.t)))),
                        }
                        found.push((ray, h, i));
                    }
                }
                for &light in &lights {
                    let mut few = Vec::new();
                    if !world.may_shadow(&boxes, light, &mut few) {
                        continue;
                    }
                    culled_lists += 1;
                    dropped += scene.objects.len() - few.len();
                    let mut shadows = Vec::new();
                    for (ray, h, i) in &found {
                        let s = scene.objects[*i as usize].shape.surface(ray, h);
                        let side = if ray.dir.dot(s.normal) < 0.0 { s.normal } else { -s.normal };
                        let from = s.point + crate::math::surface_offset(s.point) * side;
                        let (to, distance) = ((light - from).normalize(), (light - from).length());
                        if side.dot(to) <= 0.0 {
                            continue; // shading sends no shadow ray
                        }
                        let shadow = Ray { origin: from, dir: to };
                        let (want, got) = (
                            world.transmittance(&shadow, distance),
                            world.transmittance_among(&few, &shadow, distance),
                        );
                        assert_eq!(got.to_bits(), want.to_bits(), "seed {seed}, tile ({tx}, {ty}), light {light}");
                        shadows.push(((shadow, distance), want));
                        checked += 1;
                    }
                    // And all of them together, eight at a time, one lane in three dead.
                    for (g, group) in shadows.chunks(8).enumerate() {
                        let (mut origins, mut dirs, mut t_max) = ([[0.0; 8]; 3], [[0.0; 8]; 3], [0.0; 8]);
                        for (lane, ((ray, t), _)) in group.iter().enumerate() {
                            for axis in 0..3 {
                                (origins[axis][lane], dirs[axis][lane]) = (ray.origin[axis], ray.dir[axis]);
                            }
                            t_max[lane] = *t;
                        }
                        let live = (0..group.len()).filter(|lane| (g + lane) % 3 != 0).fold(0, |m, l| m | 1 << l);
                        let got = world.transmittance_among_lanes(&few, &origins, &dirs, t_max, live);
                        for (lane, (_, want)) in group.iter().enumerate() {
                            let want = if live >> lane & 1 == 0 { 0.0 } else { *want };
                            assert_eq!(
                                got[lane].to_bits(),
                                want.to_bits(),
                                "seed {seed}, tile ({tx}, {ty}), light {light}"
                            );
                        }
                    }
                    partial += (shadows.iter().any(|&(_, v)| v > 0.0 && v < 1.0)) as u32;
                }
            });
        }
        assert!(
            checked > 5000 && culled_lists > 100 && dropped > 500 && partial > 20,
            "{checked} rays, {culled_lists} lists, {dropped} dropped, {partial} with light through glass"
        );
    }

    #[test]
    fn bvh_and_brute_force_agree_on_random_rays_of_every_kind() {
        let mut rays = 0;
        for seed in 0..6u64 {
            let scene = random_scene(seed, 70 + 40 * seed as usize);
            // Even seeds walk 4-wide trees, odd ones 8-wide where the processor can.
            let width = Some(if seed % 2 == 0 { 4 } else { 8 });
            let (bvh, brute) = (World::with_width(&scene, AccelKind::Bvh, width), World::new(&scene, AccelKind::None));
            let mut r = Rng::new(1000 + seed);
            for i in 0..40_000 {
                let origin = v(&mut r, 30.0);
                let ray = Ray::new(origin, unit(&mut r));
                let (a, b) = (bvh.closest(&ray, 0.0, f32::INFINITY), brute.closest(&ray, 0.0, f32::INFINITY));
                assert_eq!(a, b, "seed {seed} ray {i}: {ray:?}");
                let t_max = 5.0 + 20.0 * r.next_f32();
                assert_eq!(bvh.transmittance(&ray, t_max), brute.transmittance(&ray, t_max), "seed {seed} ray {i}");
                rays += 1;
            }
        }
        assert_eq!(rays, 240_000);
    }

    /// A scene of nearly only spheres takes the packed path (four spheres a test): it
    /// must still give the brute-force answers, ties between coincident spheres included.
    #[test]
    fn sphere_packs_agree_with_testing_every_object() {
        let mut scene = random_scene(9, 14);
        let mut r = Rng::new(77);
        let opaque = scene.add_material(Material::color(Color::ONE));
        let glass = scene.add_material(Material::color(Color::ONE).transparent(0.7, 1.0));
        for i in 0..600 {
            let s = Sphere::new(v(&mut r, 20.0), 0.1 + r.next_f32() * 1.5);
            let m = if r.below(3) == 0 { glass } else { opaque };
            scene.add(s, m);
            if i % 50 == 0 {
                scene.add(s, opaque); // the same sphere again: the lower index must win
            }
        }
        for width in [4, 8] {
            sphere_packs_agree(&scene, width, &mut r);
        }
    }

    fn sphere_packs_agree(scene: &Scene, width: usize, r: &mut Rng) {
        let (bvh, brute) = (World::with_width(scene, AccelKind::Bvh, Some(width)), World::new(scene, AccelKind::None));
        let packs = bvh.leaves.iter().filter(|l| matches!(l, LeafItem::Spheres(_))).count();
        assert!(packs > 0 && packs * 2 < scene.objects.len(), "spheres not packed");
        for i in 0..40_000 {
            let ray = Ray::new(v(r, 30.0), unit(r));
            let (a, b) = (bvh.closest(&ray, 0.0, f32::INFINITY), brute.closest(&ray, 0.0, f32::INFINITY));
            assert_eq!(a, b, "ray {i}: {ray:?}");
            let t_max = 5.0 + 20.0 * r.next_f32();
            assert_eq!(bvh.transmittance(&ray, t_max), brute.transmittance(&ray, t_max), "ray {i}");
        }
        // Rays eight at a time: from one eye over a grid (packets), and scattered.
        let eye = v(r, 30.0);
        let mut found: Vec<(Ray, Option<(Hit, u32)>)> = (0..64 * 64)
            .map(|i| {
                let d = -eye + Vec3::new((i % 64) as f32 * 0.6 - 19.0, (i / 64) as f32 * 0.6 - 19.0, 0.0);
                (Ray::new(eye, d), None)
            })
            .chain((0..1000).map(|_| (Ray::new(v(r, 30.0), unit(r)), None)))
            .collect();
        bvh.closest_found(&mut found);
        let hits = found.iter().filter(|(_, h)| h.is_some()).count();
        assert!(hits > 500 && hits + 500 < found.len(), "{hits} of {} hit", found.len());
        for (i, (ray, hit)) in found.iter().enumerate() {
            assert_eq!(*hit, brute.closest(ray, 0.0, f32::INFINITY), "ray {i} of eight at a time");
        }
    }

    #[test]
    fn mesh_bvh_agrees_with_testing_every_triangle() {
        let mesh = crate::scene::generate::cube_sphere(24);
        for width in [4, 8] {
            mesh_bvh_agrees(&mesh, width);
        }
    }

    fn mesh_bvh_agrees(mesh: &Mesh, width: usize) {
        let tree = MeshBvh::build(mesh, Some(width));
        let mut r = Rng::new(5);
        for i in 0..100_000 {
            let ray = Ray::new(v(&mut r, 3.0), unit(&mut r));
            let a = tree.closest(&ray, 0.0, f32::INFINITY);
            let b = mesh.intersect(&ray, 0.0, f32::INFINITY);
            assert_eq!(a, b, "ray {i}: {ray:?}");
            assert_eq!(tree.occluded(&ray, 0.0, 1.0), mesh.occluded(&ray, 0.0, 1.0), "ray {i}");
        }
    }

    /// Shadow rays and closest hits in a world of one mesh, batched, as one by one:
    /// from points on and around the mesh, blocked and not, opaque and glass, both tree
    /// widths.
    #[test]
    fn rays_in_batches_match_one_by_one() {
        let mut r = Rng::new(9);
        for (transparency, width) in [(0.0, 8), (0.6, 8), (0.0, 4)] {
            let mut scene = Scene::new(Camera::new(Vec3::ZERO, Vec3::NEG_Z, Vec3::Y, 40.0, 8, 8));
            let m = scene.add_material(Material::color(Color::ONE).transparent(transparency, 1.0));
            scene.add(crate::scene::generate::cube_sphere(12), m);
            let world = World::with_width(&scene, AccelKind::Bvh, Some(width));
            // Lengths up to 6 (rays from outside the unit sphere may end before it).
            let rays: Vec<(Ray, f32)> =
                (0..3001).map(|_| (Ray::new(v(&mut r, 1.5), unit(&mut r)), 6.0 * r.next_f32())).collect();
            let want: Vec<f32> = rays.iter().map(|(ray, t)| world.transmittance(ray, *t)).collect();
            let mut got = vec![0.0; rays.len()];
            world.transmittance_each(&rays, &mut got);
            assert_eq!(got, want, "transparency {transparency}, width {width}");
            // And closest hits likewise, within the same lengths and without bound.
            for t_max in [2.5, f32::INFINITY] {
                let rays: Vec<Ray> = rays.iter().map(|(ray, _)| *ray).collect();
                let want: Vec<_> = rays.iter().map(|ray| world.closest(ray, 0.0, t_max)).collect();
                let mut got = vec![None; rays.len()];
                world.closest_each(&rays, 0.0, t_max, &mut got);
                assert_eq!(got, want, "width {width}, t_max {t_max}");
                let hits = want.iter().filter(|h| h.is_some()).count();
                assert!(hits > 300 && hits < 2990, "{hits} of {} hit", want.len());
            }
            let blocked = want.iter().filter(|&&l| l < 1.0).count();
            assert!(blocked > 300 && blocked < 2700, "{blocked} of {} blocked", want.len());
            // Bundles of eight, as packets take them: camera rays from one eye, and
            // shadow rays from points close together to one light.
            let eye = Vec3::new(0.3, 0.4, 3.0);
            let camera: Vec<Ray> = (0..64 * 64)
                .map(|i| Ray::new(eye, Vec3::new((i % 64) as f32 / 64.0 - 0.5, (i / 64) as f32 / 64.0 - 0.5, -1.5)))
                .collect();
            let want: Vec<_> = camera.iter().map(|ray| world.closest(ray, 0.0, f32::INFINITY)).collect();
            let mut got = vec![None; camera.len()];
            world.closest_each(&camera, 0.0, f32::INFINITY, &mut got);
            assert_eq!(got, want, "camera rays, width {width}");
            let light = Vec3::new(3.0, 1.0, 0.5);
            let shadow: Vec<(Ray, f32)> = want
                .iter()
                .zip(&camera)
                .filter_map(|(hit, ray)| hit.map(|(h, _)| ray.at(h.t) - 1e-3 * ray.dir))
                .map(|p| (Ray::new(p, light - p), (light - p).length() * 0.999))
                .collect();
            let want: Vec<f32> = shadow.iter().map(|(ray, t)| world.transmittance(ray, *t)).collect();
            let mut got = vec![0.0; shadow.len()];
            world.transmittance_each(&shadow, &mut got);
            assert_eq!(got, want, "shadow rays, width {width}");
            let blocked = want.iter().filter(|&&l| l < 1.0).count();
            assert!(blocked > 100 && blocked + 100 < want.len(), "{blocked} of {} blocked", want.len());
        }
    }

    #[test]
    fn memory_is_reported_per_structure() {
        let scene = random_scene(1, 50);
        assert!(World::new(&scene, AccelKind::Bvh).memory_bytes() > 0);
        assert_eq!(World::new(&scene, AccelKind::None).memory_bytes(), 0);
    }
}
