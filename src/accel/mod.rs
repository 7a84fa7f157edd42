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
#[cfg(target_arch = "x86_64")]
mod avx8;
pub mod bvh;
mod cull;
mod eight_rays;
pub mod lanes;
mod light_buffer;
mod mesh_bvh;
#[cfg(target_arch = "x86_64")]
mod packet8;
mod shadow;
pub use lanes::Best8;
pub use shadow::{LastBlocker, ShadowLanes};
mod sphere4;
mod sphere8;
mod tri4;
pub mod wide;
#[cfg(target_arch = "x86_64")]
pub mod wide8;
pub mod wide_bvh;

pub use bvh::{Bvh, Node, Visit};
pub use wide::Bvh4;
pub use wide_bvh::WideBvh;

use crate::geometry::{Cone, Cylinder, Hit, Mesh, Quad, Shape, Triangle, part};
use crate::material::Material;
use crate::math::{Ray, Vec2};
use crate::scene::Scene;
use mesh_bvh::MeshBvh;
use sphere4::Sphere4;
use sphere8::Sphere8;
use std::collections::HashMap;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tri4::Ray4;

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

/// No object: the index of the best hit before there is one, or of the object a
/// shadow ray leaves where that is not known.
pub const NONE: u32 = u32::MAX;

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

/// Spheres per leaf pack: eight where the top tree will be 8-wide (its walk is built for
/// AVX2, so [`Sphere8`]'s lanes run as 8-wide instructions), else four.
fn sphere_pack(width: Option<usize>) -> usize {
    WideBvh::chosen_width(width)
}

fn wide(bvh: &Bvh, width: Option<usize>) -> WideBvh {
    match width {
        Some(w) => WideBvh::with_width(bvh, w),
        None => WideBvh::from_binary(bvh),
    }
}

/// An entry of a top-level leaf. Spheres, the commonest object in big scenes, are
/// copied into the leaf in packs of four (eight where the 8-wide tree is walked) and
/// tested together (inline, so a leaf's spheres are one read from the node, not two);
/// the other analytic shapes are copied in one by one ([`Inline`]); meshes, polygons and
/// transformed shapes are named by index.
#[derive(Clone, Copy, Debug)]
enum LeafItem {
    Spheres(Sphere4),
    Spheres8(Sphere8),
    Inline(Inline, u32),
    Other(u32),
    /// Only past the tree's leaves, for the light buffers: the packs `start..end` of
    /// mesh object `i`, a leaf of its tree.
    Piece(u32, u32, u32),
}

// An entry is as big as a pack of eight spheres: the copied shapes take no more room.
const _: () = assert!(std::mem::size_of::<LeafItem>() <= 192);

/// A cylinder, cone, quad or triangle copied into its leaf entry, with its object index:
/// tested from the entry, whose lines the walk has started loading, not through the
/// scene's object list (a dependent read of another 112-byte object per test). Tree of
/// cones (bench/tree_nff.py), 1 thread, alternating, medians of 12: 145 to 133 ms; rings
/// of cylinders: 195 to 187 ms (cachegrind: 5 % fewer first-level cache read misses).
#[derive(Clone, Copy, Debug)]
enum Inline {
    Cylinder(Cylinder),
    Cone(Cone),
    Quad(Quad),
    Triangle(Triangle),
}

impl Inline {
    fn of(shape: &Shape) -> Option<Inline> {
        match *shape {
            Shape::Cylinder(s) => Some(Inline::Cylinder(s)),
            Shape::Cone(s) => Some(Inline::Cone(s)),
            Shape::Quad(s) => Some(Inline::Quad(s)),
            Shape::Triangle(s) => Some(Inline::Triangle(s)),
            _ => None,
        }
    }

    /// [`Shape::intersect`] of the shape copied.
    #[inline(always)]
    fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        match self {
            Inline::Cylinder(s) => s.intersect(ray, t_min, t_max),
            Inline::Cone(s) => s.intersect(ray, t_min, t_max),
            Inline::Quad(s) => s.intersect(ray, t_min, t_max),
            Inline::Triangle(s) => s.intersect(ray, t_min, t_max),
        }
    }
}

/// The read-only ray-query structure shared by all render threads.
#[derive(Debug)]
pub struct World<'s> {
    scene: &'s Scene,
    kind: AccelKind,
    /// Over objects; empty with `AccelKind::None`. Leaf positions index `leaves`.
    top4: WideBvh,
    leaves: Vec<LeafItem>,
    /// Per object: the BVH of a mesh object or instance (with `AccelKind::Bvh`), one
    /// per mesh, shared by its instances.
    meshes: Vec<Option<Arc<MeshBvh>>>,
    /// Per object, the share of light its material lets through (0 = opaque), looked
    /// up once here rather than through the material on every shadow ray.
    transmission: Vec<f32>,
    /// The objects whose material absorbs light inside ([`World::transmittance_color`]).
    absorbing: Vec<u32>,
    /// Per object, its material: one load per shaded hit rather than two dependent ones
    /// through the object (112 bytes apart) and the scene's material list.
    materials: Vec<&'s Material>,
    build_time: Duration,
    /// Test objects one by one: no top-level tree, or a single object (one mesh), whose
    /// own tree's root box already does what the top level would.
    flat: bool,
    /// Whether the eight-lane code runs ([`lanes::avx2`]), for [`World::closest_among_each`].
    avx2: bool,
    /// Per light of the scene, its light buffer where it has one.
    light_buffers: Vec<Option<light_buffer::LightBuffer>>,
    /// Per object, the bounds the culling of a small scene tests (empty where it
    /// does not cull): worked out once here, not in every test of every tile.
    cull: Vec<cull::CullBounds>,
}

impl<'s> World<'s> {
    pub fn new(scene: &'s Scene, kind: AccelKind) -> Self {
        World::with_width(scene, kind, None)
    }

    /// With trees of this many children per node (4, or 8 where the processor has
    /// AVX2), rather than the best this processor walks: lets tests cover both.
    pub fn with_width(scene: &'s Scene, kind: AccelKind, width: Option<usize>) -> Self {
        let start = Instant::now();
        let transmission: Vec<f32> = scene.objects.iter().map(|o| scene.material(o.material).transparency).collect();
        let materials = scene.objects.iter().map(|o| scene.material(o.material)).collect();
        let absorbing = (0..scene.objects.len() as u32)
            .filter(|&i| scene.material(scene.objects[i as usize].material).absorbs())
            .collect();
        let (top, meshes): (Bvh, Vec<Option<Arc<MeshBvh>>>) = match kind {
            AccelKind::None => (Bvh { nodes: vec![], indices: vec![] }, scene.objects.iter().map(|_| None).collect()),
            AccelKind::Bvh => {
                use rayon::prelude::*;
                let bounds: Vec<_> = scene.objects.iter().map(|o| o.shape.bounds()).collect();
                // One tree per mesh, shared by the objects that place it (instances).
                let mesh_of = |o: &crate::scene::Object| match &o.shape {
                    Shape::Mesh(m) => Some(m.clone()),
                    Shape::Transformed(t) => t.mesh().cloned(),
                    _ => None,
                };
                let mut unique: Vec<Arc<Mesh>> = Vec::new();
                let mut index = HashMap::new();
                for m in scene.objects.iter().filter_map(mesh_of) {
                    index.entry(Arc::as_ptr(&m)).or_insert_with(|| {
                        unique.push(m.clone());
                        unique.len() - 1
                    });
                }
                let trees: Vec<Arc<MeshBvh>> = unique.par_iter().map(|m| Arc::new(MeshBvh::build(m, width))).collect();
                let meshes =
                    scene.objects.iter().map(|o| mesh_of(o).map(|m| trees[index[&Arc::as_ptr(&m)]].clone())).collect();
                // Leaves test spheres four at a time, so in a scene of (nearly) only
                // spheres the tree is costed like a mesh's, by packs; elsewhere objects
                // differ too much in cost for packs to be the unit.
                let round = scene.objects.iter().filter(|o| matches!(o.shape, Shape::Sphere(_))).count();
                let top = if round >= 64 && round * 10 >= scene.objects.len() * 9 {
                    Bvh::build_packed(&bounds, sphere_pack(width))
                } else {
                    Bvh::build(&bounds)
                };
                (top, meshes)
            }
        };
        let mut top4 = if top.nodes.is_empty() { WideBvh::default() } else { wide(&top, width) };
        let bound = |ids: &mut dyn Iterator<Item = u32>| {
            ids.fold(crate::math::Aabb::EMPTY, |b, i| b.union(scene.objects[i as usize].shape.bounds()))
        };
        // Packs of eight only where the 8-wide walk (built for AVX2) tests them.
        let pack = if top4.width() == 8 { 8 } else { 4 };
        let sphere = |i: u32| match &scene.objects[i as usize].shape {
            Shape::Sphere(s) => Some((*s, i)),
            _ => None,
        };
        // The entries counted first, so that their lists are filled without growing
        // (each growth copied them into fresh memory, faulted in page by page).
        let entries: usize = top
            .nodes
            .iter()
            .filter(|n| n.is_leaf())
            .map(|n| {
                let ids = &top.indices[n.first as usize..(n.first + n.count) as usize];
                let round = ids.iter().filter(|&&i| sphere(i).is_some()).count();
                round.div_ceil(pack) + ids.len() - round
            })
            .sum();
        let mut leaves = Vec::with_capacity(entries);
        let mut boxes: Vec<crate::math::Aabb> = Vec::with_capacity(entries);
        // Per entry, the range of its spheres in `packed` (empty where it is no pack), for
        // the light buffers' cells to regroup them.
        let (mut ranges, mut packed) = (Vec::with_capacity(entries), Vec::new());
        let mut round = Vec::new();
        top4.map_leaves(|first, count| {
            let start = leaves.len() as u32;
            let ids = &top.indices[first as usize..(first + count) as usize];
            round.clear();
            round.extend(ids.iter().filter_map(|&i| sphere(i)));
            for chunk in round.chunks(pack) {
                ranges.push((packed.len() as u32, (packed.len() + chunk.len()) as u32));
                packed.extend_from_slice(chunk);
                boxes.push(bound(&mut chunk.iter().map(|&(_, i)| i)));
                leaves.push(match pack {
                    8 => LeafItem::Spheres8(Sphere8::pack(chunk)),
                    _ => LeafItem::Spheres(Sphere4::pack(chunk)),
                });
            }
            boxes.extend(ids.iter().filter(|&&i| sphere(i).is_none()).map(|&i| bound(&mut std::iter::once(i))));
            ranges.resize(boxes.len(), (0, 0));
            leaves.extend(ids.iter().filter(|&&i| sphere(i).is_none()).map(|&i| {
                match Inline::of(&scene.objects[i as usize].shape) {
                    Some(shape) => LeafItem::Inline(shape, i),
                    None => LeafItem::Other(i),
                }
            }));
            (start, leaves.len() as u32 - start)
        });
        debug_assert_eq!(leaves.len(), entries, "every leaf's entries counted");
        let flat = kind == AccelKind::None || scene.objects.len() == 1;
        let buffered = !flat
            && scene.lights.iter().any(|l| l.position().is_some())
            && light_buffer::LightBuffer::wanted(leaves.len());
        // Cells a side as the tree's entries ask, before the pieces below join them.
        let side = light_buffer::LightBuffer::side(leaves.len());
        if buffered {
            // The light buffers list an opaque mesh leaf by leaf of its tree, as entries
            // past the tree's own ([`LeafItem::Piece`]), not the whole mesh: a shadow ray
            // tests the few leaves along it rather than walking the mesh from its root
            // (the torus of bench/mixed_nff.py: docs/performance.md, stop 53).
            let mesh_of = |item: &LeafItem| match *item {
                LeafItem::Other(i) => {
                    opaque_plain_mesh(scene, &meshes, &transmission, i as usize).filter(|m| !m.direct()).map(|m| (i, m))
                }
                _ => None,
            };
            // At most three times as many pieces as the tree has entries: each costs the
            // build its placing in every light's cells, and a mesh much finer than the rest
            // of the scene gains less from them than that (`bench/mixed_nff.py --mesh 256`,
            // a torus of 131 k triangles: build 28 to 39 ms, render no faster).
            let mut budget = 3 * leaves.len();
            for at in 0..leaves.len() {
                let Some((i, mesh)) = mesh_of(&leaves[at]) else { continue };
                let count = mesh.leaf_count();
                if count > budget {
                    continue;
                }
                budget -= count;
                boxes[at] = crate::math::Aabb::EMPTY;
                mesh.pieces(|packs, b| {
                    leaves.push(LeafItem::Piece(i, packs.start, packs.end));
                    boxes.push(b);
                });
            }
        }
        let avx2 = lanes::avx2();
        let members = light_buffer::Members {
            ranges: &ranges,
            spheres: &packed,
            width: pack,
            pack: match pack {
                8 => |s| LeafItem::Spheres8(Sphere8::pack(s)),
                _ => |s| LeafItem::Spheres(Sphere4::pack(s)),
            },
        };
        let mut light_buffers = match buffered {
            false => scene.lights.iter().map(|_| None).collect(),
            true => light_buffer::LightBuffer::for_lights(&scene.lights, &boxes, side, &members),
        };
        // The packs the buffers' cells regrouped spheres into join the entries, in one
        // fresh array, made there.
        let packs: usize = light_buffers.iter().flatten().map(|b| b.pack_count()).sum();
        let leaves = match packs {
            0 => crate::pages::on_huge_pages(leaves),
            _ => {
                let mut all = crate::pages::with_capacity(leaves.len() + packs);
                all.extend_from_slice(&leaves);
                let mut plans = Vec::with_capacity(light_buffers.len());
                let mut base = all.len();
                for buffer in light_buffers.iter_mut().flatten() {
                    let plan = buffer.place_packs(base as u32);
                    base += plan.len();
                    plans.push(plan);
                }
                // Made on every thread, each pack into its place (an indexed parallel
                // extension writes where it collects), the fresh pages faulted in by each.
                let of: Vec<(usize, usize)> =
                    plans.iter().enumerate().flat_map(|(p, plan)| (0..plan.len()).map(move |k| (p, k))).collect();
                use rayon::prelude::*;
                all.par_extend(of.par_iter().map(|&(p, k)| plans[p].pack(k, &members)));
                all
            }
        };
        let cull = match kind == AccelKind::Bvh && cull::small(scene) {
            true => scene.objects.iter().map(|o| cull::CullBounds::of(o.shape.bounds())).collect(),
            false => Vec::new(),
        };
        World {
            scene,
            kind,
            top4,
            leaves,
            meshes,
            transmission,
            absorbing,
            materials,
            build_time: start.elapsed(),
            flat,
            avx2,
            light_buffers,
            cull,
        }
    }

    pub fn scene(&self) -> &'s Scene {
        self.scene
    }

    /// The material of object `index`.
    #[inline(always)]
    pub fn material(&self, index: u32) -> &'s Material {
        self.materials[index as usize]
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
            + self.unique_meshes().map(|m| m.memory_bytes()).sum::<usize>()
            + self.light_buffer_bytes()
    }

    /// Of [`World::memory_bytes`], the bytes of the lights' buffers.
    pub fn light_buffer_bytes(&self) -> usize {
        self.light_buffers.iter().flatten().map(|b| b.memory_bytes()).sum()
    }

    /// Each mesh tree once, however many objects share it.
    fn unique_meshes(&self) -> impl Iterator<Item = &MeshBvh> {
        let mut seen = std::collections::HashSet::new();
        self.meshes.iter().flatten().filter(move |m| seen.insert(Arc::as_ptr(m))).map(|m| &**m)
    }

    /// The tree of object `i` if it is an opaque mesh in place ([`World::opaque_mesh`]).
    #[inline(always)]
    fn opaque_object_mesh(&self, i: usize) -> Option<&MeshBvh> {
        opaque_plain_mesh(self.scene, &self.meshes, &self.transmission, i)
    }

    /// The tree of object `i` if it is a mesh in place (not an instance, whose rays need
    /// carrying into its space): for the paths that ask a mesh's tree directly.
    #[inline]
    fn plain_mesh(&self, i: usize) -> Option<&MeshBvh> {
        match (&self.meshes[i], &self.scene.objects[i].shape) {
            (Some(m), Shape::Mesh(_)) => Some(m),
            _ => None,
        }
    }

    /// The tree of the only object, a mesh in place: worlds of one mesh have their own
    /// batched paths.
    #[inline]
    fn single_mesh(&self) -> Option<&MeshBvh> {
        match self.meshes.len() {
            1 => self.plain_mesh(0),
            _ => None,
        }
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
        // The walks are built for AVX2 (the 8-wide one) or baseline x86-64: a leaf
        // closure inlined into the walk, and `test` into it, has the shape tests built
        // the walk's way, the spheres' AVX test inlined rather than called once per pack
        // (a closure takes the target features of the function it is written in, here
        // plain x86-64, so inlining it is the way in: docs/performance.md).
        self.top4.traverse::<NEAREST_FIRST, _>(
            ray,
            t_min,
            t_max,
            &self.leaves,
            #[inline(always)]
            |range, t_cur| leaf_loop(range, t_cur, &mut test),
        )
    }

    #[inline]
    fn intersect_object(&self, i: usize, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        match (&self.meshes[i], &self.scene.objects[i].shape) {
            (Some(m), Shape::Transformed(t)) => t.intersect_with(ray, t_min, t_max, |r, a, b| m.closest(r, a, b)),
            (Some(m), _) => m.closest(ray, t_min, t_max),
            (None, s) => s.intersect(ray, t_min, t_max),
        }
    }

    #[inline]
    fn blocks(&self, i: usize, ray: &Ray, t_max: f32) -> bool {
        match (&self.meshes[i], &self.scene.objects[i].shape) {
            (Some(m), Shape::Transformed(t)) => t.blocks_with(ray, t_max, |r, t_max| m.occluded(r, 0.0, t_max)),
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
        // The best hit so far field by field, not as an `Option<(Hit, u32)>`: written
        // piecewise and read back whole, the option stalled store forwarding (a quarter
        // of this function's time in the room).
        let mut nearest = Nearest::default();
        self.traverse_objects::<true>(
            ray,
            t_min,
            t_max,
            // Inlined into the walk, built for AVX2 where it is 8-wide, so the spheres' AVX
            // test is too ([`World::traverse_objects`]).
            #[inline(always)]
            |at, t_cur| Visit::Continue(self.leaf_nearest(at, ray, t_min, t_cur, &mut nearest)),
        );
        nearest.get()
    }

    /// [`Sphere8::intersect`] for a pack of this world's leaves, without asking again,
    /// pack by pack, whether AVX2 runs ([`Sphere8::intersect_unchecked`]).
    #[inline(always)]
    #[allow(unsafe_code)]
    fn spheres8(&self, pack: &Sphere8, ray: &Ray, t_min: f32, t_max: f32) -> (u32, crate::math::lanes::F8) {
        debug_assert!(self.avx2);
        // SAFETY: packs of eight are made only where the top tree is 8-wide (`World::new`),
        // and an 8-wide tree only where the processor has AVX2 (`WideBvh::with_width`,
        // `lanes::avx2`).
        unsafe { pack.intersect_unchecked(ray, t_min, t_max) }
    }

    /// The objects of leaf entry `at` against the ray, within `(t_min, t_cur)`, kept in
    /// `nearest` if nearer (ties to the lower index); returns the new bound. The answer
    /// does not depend on the order entries come in. (Packs of four, only in the 4-wide
    /// tree, take the ray splatted to four lanes: made here, not before every walk.)
    #[inline(always)]
    fn leaf_nearest(&self, at: usize, ray: &Ray, t_min: f32, mut t_cur: f32, nearest: &mut Nearest) -> f32 {
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
                let (mut mask, t) = pack.intersect(&Ray4::new(ray), t_min, limit);
                while mask != 0 {
                    let lane = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    offer(Hit { t: t[lane], uv: Vec2::ZERO, part: part::SIDE, prim: 0 }, pack.ids[lane]);
                }
            }
            LeafItem::Spheres8(ref pack) => {
                let (mut mask, t) = self.spheres8(pack, ray, t_min, limit);
                while mask != 0 {
                    let lane = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    offer(Hit { t: t.0[lane], uv: Vec2::ZERO, part: part::SIDE, prim: 0 }, pack.ids[lane]);
                }
            }
            LeafItem::Inline(ref shape, i) => {
                if let Some(h) = shape.intersect(ray, t_min, limit) {
                    offer(h, i);
                }
            }
            LeafItem::Other(i) => {
                if let Some(h) = self.intersect_object(i as usize, ray, t_min, limit) {
                    offer(h, i);
                }
            }
            // Not in the tree.
            LeafItem::Piece(..) => {}
        }
        t_cur
    }
}

/// The tree of object `i` where it is a mesh in place (not an instance) and opaque.
#[inline(always)]
fn opaque_plain_mesh<'a>(
    scene: &Scene,
    meshes: &'a [Option<Arc<MeshBvh>>],
    transmission: &[f32],
    i: usize,
) -> Option<&'a MeshBvh> {
    match (&meshes[i], &scene.objects[i].shape) {
        (Some(m), Shape::Mesh(_)) if transmission[i] == 0.0 => Some(m),
        _ => None,
    }
}

/// The entries `range` of a leaf, each by `test(entry, t_max)`, the bound shrinking as
/// it says; stops when it says so.
#[inline(always)]
fn leaf_loop(range: std::ops::Range<usize>, mut t_cur: f32, test: &mut impl FnMut(usize, f32) -> Visit) -> Visit {
    for at in range {
        match test(at, t_cur) {
            Visit::Continue(t) => t_cur = t,
            Visit::Stop => return Visit::Stop,
        }
    }
    Visit::Continue(t_cur)
}

#[cfg(test)]
mod tests;
