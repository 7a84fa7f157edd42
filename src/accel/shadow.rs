//! Shadow rays: how much light gets through along a segment, one ray at a time or in
//! batches.

use super::tri4::Ray4;
use super::{Inline, LeafItem, Visit, World};
use crate::math::Ray;

/// The leaf entry that blocked the last of a run of shadow rays (a light's, from one
/// level's hits), for [`World::transmittance_hinted`]; `default()` names none. Where
/// that entry is an opaque mesh, also the leaf of its tree whose triangles did (its
/// packs' start and end), to test before walking the mesh's tree.
#[derive(Clone, Copy, Debug)]
pub struct LastBlocker(pub(super) u32, pub(super) u32, pub(super) u32);

impl LastBlocker {
    /// Names leaf entry `at`, without a part of it.
    pub(super) fn at(at: u32) -> Self {
        LastBlocker(at, 0, 0)
    }
}

/// Eight shadow rays side by side: origins, unit directions and lengths lane by lane,
/// the lanes to test (`live`; the others get 0), and the object each leaves, on its
/// light's side ([`super::NONE`] where not known).
pub struct ShadowLanes<'a> {
    pub from: &'a [[f32; 8]; 3],
    pub dirs: &'a [[f32; 8]; 3],
    pub t_max: [f32; 8],
    pub live: u32,
    pub leaving: [u32; 8],
}

impl Default for LastBlocker {
    fn default() -> Self {
        LastBlocker::at(u32::MAX)
    }
}

impl World<'_> {
    /// [`World::transmittance`] for each shadow ray and length of `rays`, into `out` (as
    /// long): in a world of one mesh, eight at a time, as one packet where
    /// `MeshBvh::occluded_eight` takes them ([`super::wide8::Bvh8::any_packet`]),
    /// the others three walks at a time, interleaved ([`super::wide8::Bvh8::any_hits`]);
    /// elsewhere one ray after another. (In a world of objects, neither packets nor
    /// interleaved walks paid: the sphereflake took as long, docs/performance.md; there
    /// the wave walks each ray as it comes, with [`World::transmittance_hinted`].)
    pub fn transmittance_each(&self, rays: &[(Ray, f32)], out: &mut [f32]) {
        match self.single_mesh() {
            Some(_) => self.mesh_transmittance_each(rays, out),
            _ => {
                for ((ray, t), light) in rays.iter().zip(out) {
                    *light = self.transmittance(ray, *t);
                }
            }
        }
    }

    /// Whether [`World::transmittance_each`] takes shadow rays in packets (a world of
    /// one mesh), so that callers should gather them first.
    pub fn packs_shadow_rays(&self) -> bool {
        self.single_mesh().is_some()
    }

    /// [`World::transmittance`], trying first the leaf entry that blocked the last shadow
    /// ray given the same `blocker`, and keeping there the entry that blocks this one.
    /// Neighbouring shadow rays to one light tend to be blocked by the same objects (a
    /// pack of spheres: the cached object's neighbours come with it): one pack test in
    /// place of a walk from the root. The answer is the same either way, since it is 0
    /// as soon as one opaque object lies across the segment.
    #[inline]
    pub fn transmittance_hinted(&self, ray: &Ray, t_max: f32, blocker: &mut LastBlocker) -> f32 {
        if self.flat {
            return self.transmittance_of(0..self.scene.objects.len() as u32, ray, t_max);
        }
        // A ray of NaNs or from an overflowed point is not tested: the walk meets nothing.
        if blocker.0 != u32::MAX
            && ray.origin.is_finite()
            && ray.dir.is_finite()
            && self.hint_stops(ray, t_max, blocker)
        {
            return 0.0;
        }
        let mut light = 1.0f64;
        self.traverse_objects::<false>(
            ray,
            0.0,
            t_max,
            // Inlined into the walk, as in `closest` ([`World::traverse_objects`]).
            #[inline(always)]
            |at, _| {
                if self.leaf_stops_noted(at, ray, t_max, &mut light, blocker) {
                    return Visit::Stop;
                }
                // Every object along the whole segment counts, not just the nearest.
                Visit::Continue(t_max)
            },
        );
        light as f32
    }

    fn mesh_transmittance_each(&self, rays: &[(Ray, f32)], out: &mut [f32]) {
        let Some(mesh) = self.single_mesh() else { unreachable!("a world of one mesh") };
        // As `transmittance` finds it: the mesh's transmission if it lies across the ray.
        let light = |blocked: bool| if blocked { (1.0f64 * self.transmission[0] as f64) as f32 } else { 1.0 };
        // Rays the packets do not take wait in `left` to walk three at a time.
        let (mut left, mut n) = ([0usize; 3], 0);
        for (start, g) in rays.chunks(8).enumerate().map(|(i, g)| (8 * i, g)) {
            if let Ok(g) = <&[(Ray, f32); 8]>::try_from(g)
                && let Some(blocked) = mesh.occluded_packet(&g.map(|(r, _)| r), g.map(|(_, t)| t), 0xff)
            {
                for (k, light_k) in out[start..start + 8].iter_mut().enumerate() {
                    *light_k = light(blocked >> k & 1 != 0);
                }
                continue;
            }
            for i in start..start + g.len() {
                (left[n], n) = (i, n + 1);
                if n == 3 {
                    let [a, b, c] = left.map(|i| &rays[i]);
                    let blocked = mesh.occluded_each([&a.0, &b.0, &c.0], [a.1, b.1, c.1]);
                    for (i, blocked) in left.into_iter().zip(blocked) {
                        out[i] = light(blocked);
                    }
                    n = 0;
                }
            }
        }
        for &i in &left[..n] {
            out[i] = light(mesh.occluded(&rays[i].0, 0.0, rays[i].1));
        }
    }

    /// The share of light that travels from `ray.origin` a distance `t_max` along the
    /// ray: the product of the transmission of every object in the way, each counted
    /// once however many of its surfaces the segment crosses (two overlapping 70 %
    /// spheres pass 0.49). Stops at the first opaque object. The product is kept in
    /// f64 so that the order objects are met in does not change the f32 result.
    #[inline]
    pub fn transmittance(&self, ray: &Ray, t_max: f32) -> f32 {
        self.transmittance_hinted(ray, t_max, &mut LastBlocker::default())
    }

    /// Whether the last blocker (`blocker`, which names an entry) stops the ray: the
    /// entry tested, but of an opaque mesh only the leaf of its tree that blocked,
    /// not the whole tree, which the walk or list that follows reaches anyway where
    /// the mesh lies in the way (so a ray that the leaf lets through does not walk
    /// the mesh's tree twice).
    #[inline(always)]
    pub(super) fn hint_stops(&self, ray: &Ray, t_max: f32, blocker: &mut LastBlocker) -> bool {
        let at = blocker.0 as usize;
        match self.opaque_mesh(at) {
            Some(mesh) => {
                let part = blocker.1 as usize..blocker.2 as usize;
                !part.is_empty() && mesh.packs_block(part, ray, t_max)
            }
            None => self.leaf_stops_noted(at, ray, t_max, &mut 1.0, blocker),
        }
    }

    /// [`World::leaf_stops`], noting in `blocker` what stops the light: the entry, and
    /// for an opaque mesh the leaf of its tree, which is tried first when `blocker`
    /// names this entry already (the same answer: the mesh lets nothing through
    /// wherever a triangle of it lies across the segment). The mixed scene's torus
    /// shadows the floor: a leaf of four to eight triangles in place of a walk.
    #[inline(always)]
    pub(super) fn leaf_stops_noted(
        &self,
        at: usize,
        ray: &Ray,
        t_max: f32,
        light: &mut f64,
        blocker: &mut LastBlocker,
    ) -> bool {
        let stops = match self.opaque_mesh(at) {
            Some(mesh) => {
                let part = blocker.1 as usize..blocker.2 as usize;
                if blocker.0 as usize == at && !part.is_empty() && mesh.packs_block(part, ray, t_max) {
                    *light = 0.0;
                    return true;
                }
                let part = mesh.occluded_in(ray, 0.0, t_max);
                if let Some(part) = &part {
                    (blocker.1, blocker.2) = (part.start as u32, part.end as u32);
                    *light = 0.0;
                }
                part.is_some()
            }
            None => {
                let stops = self.leaf_stops(at, ray, t_max, light);
                if stops {
                    (blocker.1, blocker.2) = (0, 0);
                }
                stops
            }
        };
        if stops {
            blocker.0 = at as u32;
        }
        stops
    }

    /// [`World::leaf_stops_noted`] for entry `at` of a light buffer's list, with one
    /// match on the entry's kind: a pack of eight spheres (most entries) tested there,
    /// and a flat object (a quad or a triangle) that the ray leaves, `leaving`, skipped,
    /// as a ray that leaves its surface on the side of its light stays on that side of
    /// its plane. Matched once, not in a test for the flat object, one for a mesh and one
    /// for the test: each such match is a branch the predictor misses where kinds mix.
    #[inline(always)]
    pub(super) fn entry_stops_noted(
        &self,
        at: usize,
        ray: &Ray,
        t_max: f32,
        light: &mut f64,
        blocker: &mut LastBlocker,
        leaving: u32,
    ) -> bool {
        let stops = match self.leaves[at] {
            LeafItem::Spheres8(ref pack) => self.pass_through(self.spheres8(pack, ray, 0.0, t_max).0, &pack.ids, light),
            LeafItem::Inline(Inline::Quad(_) | Inline::Triangle(_), i) if i == leaving => return false,
            _ => return self.leaf_stops_noted(at, ray, t_max, light, blocker),
        };
        if stops {
            *blocker = LastBlocker(at as u32, 0, 0);
        }
        stops
    }

    /// The tree of leaf entry `at` where that is one opaque mesh, untransformed.
    #[inline(always)]
    pub(super) fn opaque_mesh(&self, at: usize) -> Option<&super::mesh_bvh::MeshBvh> {
        match self.leaves[at] {
            LeafItem::Other(i) => self.opaque_object_mesh(i as usize),
            _ => None,
        }
    }

    /// Multiplies into `light` the transmission of the objects of leaf entry `at` that
    /// lie across the segment; `true` once the light is gone.
    #[inline(always)]
    pub(super) fn leaf_stops(&self, at: usize, ray: &Ray, t_max: f32, light: &mut f64) -> bool {
        match self.leaves[at] {
            LeafItem::Spheres(ref pack) => {
                self.pass_through(pack.intersect(&Ray4::new(ray), 0.0, t_max).0, &pack.ids, light)
            }
            LeafItem::Spheres8(ref pack) => self.pass_through(self.spheres8(pack, ray, 0.0, t_max).0, &pack.ids, light),
            LeafItem::Inline(ref shape, i) => {
                self.pass_through(shape.intersect(ray, 0.0, t_max).is_some() as u32, &[i], light)
            }
            LeafItem::Other(i) => self.pass_through(self.blocks(i as usize, ray, t_max) as u32, &[i], light),
            LeafItem::Piece(i, start, end) => {
                // Of an opaque mesh.
                let mesh = self.meshes[i as usize].as_deref().expect("a piece's mesh has a tree");
                let stops = mesh.packs_block(start as usize..end as usize, ray, t_max);
                if stops {
                    *light = 0.0;
                }
                stops
            }
        }
    }

    /// Multiplies into `light` the transmission of the objects `ids` in the lanes of
    /// `blocked` (a pack's hits); `true` once the light is gone.
    #[inline(always)]
    fn pass_through(&self, mut blocked: u32, ids: &[u32], light: &mut f64) -> bool {
        while blocked != 0 {
            let lane = blocked.trailing_zeros() as usize;
            blocked &= blocked - 1;
            *light *= self.transmission[ids[lane] as usize] as f64;
            if *light == 0.0 {
                return true;
            }
        }
        false
    }
}
