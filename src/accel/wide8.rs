//! The 8-wide BVH, for processors with AVX2: one node visit tests eight boxes with
//! 8-lane arithmetic, as cheap as four with SSE, and the tree is a third shallower than
//! the 4-wide one, so long rays (shadows, incoherent bounces) visit fewer nodes. Built
//! and traversed like [`super::Bvh4`]; the box arithmetic is the same operation for
//! operation, so both trees reach the same leaves and images do not depend on the width.
//!
//! It exists only where the processor has AVX2 ([`Bvh8::from_binary`] checks at run
//! time), which is what makes calling its `avx2` traversal sound.

use super::bvh::{Bvh, Node, Visit};
use super::wide::{ROBUST, STACK, WideNode, collapse_tree, map_leaves, pack, unpack};
use crate::math::Ray;
use std::arch::x86_64::*;

/// A node of up to eight children: their boxes lane by lane (min x, y, z, then max x,
/// y, z) and packed child references as in the 4-wide tree. Unused slots have empty
/// boxes. 256 bytes: four cache lines, the boxes in the first three.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct Node8 {
    bounds: [[f32; 8]; 6],
    packed: [u32; 8],
    _pad: [u32; 8],
}

const _: () = assert!(std::mem::size_of::<Node8>() == 256);

/// An 8-wide tree. Primitive positions are those of the binary tree it came from.
#[derive(Clone, Debug)]
pub struct Bvh8 {
    nodes: Vec<Node8>,
}

impl Bvh8 {
    /// Collapses a binary tree into 8-wide nodes, or `None` if this processor lacks AVX2.
    pub fn from_binary(bvh: &Bvh) -> Option<Bvh8> {
        std::is_x86_feature_detected!("avx2").then(|| Bvh8 { nodes: collapse_tree(bvh) })
    }

    /// See [`super::Bvh4::map_leaves`].
    pub fn map_leaves(&mut self, f: impl FnMut(u32, u32) -> (u32, u32)) {
        map_leaves(&mut self.nodes, f);
    }

    pub fn memory_bytes(&self) -> usize {
        self.nodes.capacity() * std::mem::size_of::<Node8>()
    }

    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// See [`super::Bvh4::traverse`] (`ORDERED`) and [`super::Bvh4::traverse_any`].
    #[inline]
    #[allow(unsafe_code)]
    pub fn start<const ORDERED: bool, T>(
        &self,
        ray: &Ray,
        t_min: f32,
        mut t_max: f32,
        items: &[T],
        mut leaf: impl FnMut(std::ops::Range<usize>, f32) -> Visit,
    ) {
        // SAFETY: `walk` only needs AVX2 to be present, and a `Bvh8` exists only if
        // `from_binary` found it on this processor.
        unsafe { self.walk::<ORDERED, T>(ray, (0, t_min), t_min, &mut t_max, items, &mut leaf) };
    }

    /// The 4-wide tree's walk, eight lanes at a time.
    #[target_feature(enable = "avx2")]
    fn walk<const ORDERED: bool, T>(
        &self,
        ray: &Ray,
        start: (u32, f32),
        t_min: f32,
        t_max: &mut f32,
        items: &[T],
        leaf: &mut impl FnMut(std::ops::Range<usize>, f32) -> Visit,
    ) -> bool {
        let r = WideRay8::new(ray);
        let mut stack = [(0u32, 0f32); STACK];
        let mut sp = 0;
        let mut current = start;
        'visit: loop {
            let (index, count) = unpack(current.0);
            if count > 0 {
                let first = index as usize;
                match leaf(first..first + count as usize, *t_max) {
                    Visit::Continue(t) => *t_max = t,
                    Visit::Stop => return false,
                }
            } else {
                let n = &self.nodes[index as usize];
                // Starts loading child `lane` (a node's box lines, or a leaf's first items).
                macro_rules! load_child {
                    ($lane:expr) => {
                        prefetch_child(&self.nodes, items, n.packed[$lane])
                    };
                }
                // Stacks child `lane`, entered at distance `d` (a nested walk takes it
                // when the stack is full).
                macro_rules! stack_child {
                    ($lane:expr, $d:expr) => {
                        let entry = (n.packed[$lane], $d);
                        if sp < STACK {
                            stack[sp] = entry;
                            sp += 1;
                        } else if !self.walk::<ORDERED, T>(ray, entry, t_min, t_max, items, leaf) {
                            return false;
                        }
                    };
                }
                let (near, mut hit) = enter!(&r, n, t_min, *t_max);
                if !ORDERED && hit != 0 {
                    // Any hit will do: no order to keep, and `t_max` never shrinks, so
                    // no stacked child is culled by its distance. Go on into the last
                    // child, stack the others, without their distances: reading those
                    // back from the stored vector cost 6 % of a shadow ray.
                    let last = 31 - hit.leading_zeros() as usize;
                    hit &= !(1 << last);
                    load_child!(last);
                    while hit != 0 {
                        let lane = hit.trailing_zeros() as usize;
                        hit &= hit - 1;
                        load_child!(lane);
                        stack_child!(lane, 0.0);
                    }
                    current = (n.packed[last], 0.0);
                    continue 'visit;
                }
                if hit != 0 {
                    // Nearest child next; the others stacked farthest first. All start
                    // loading before the sort, the nearest too.
                    let mut order = [(0f32, 0u32); 8];
                    let mut k = 0;
                    while hit != 0 {
                        let lane = hit.trailing_zeros() as usize;
                        hit &= hit - 1;
                        load_child!(lane);
                        let d = near[lane];
                        let mut j = k;
                        while j > 0 && order[j - 1].0 < d {
                            order[j] = order[j - 1];
                            j -= 1;
                        }
                        order[j] = (d, lane as u32);
                        k += 1;
                    }
                    for &(d, lane) in &order[..k - 1] {
                        stack_child!(lane as usize, d);
                    }
                    let (d, lane) = order[k - 1];
                    current = (n.packed[lane as usize], d);
                    continue 'visit;
                }
            }
            loop {
                if sp == 0 {
                    return true;
                }
                sp -= 1;
                // (Any entry, when any hit will do.)
                if !ORDERED || stack[sp].1 <= *t_max * ROBUST {
                    current = stack[sp];
                    continue 'visit;
                }
            }
        }
    }
}

/// Entries of each stack of an interleaved walk ([`Bvh8::any_hits`]); a walk that
/// would overflow it goes on in a nested [`Bvh8::start`]-style walk. Small in tests, so
/// that they cover that path. The stacks are zeroed at every call: at 64 entries that
/// was a `memset` call of 1 KiB per pair of camera rays, most of which leave the tree
/// after a node or two (7 % of a primary ray). No walk of the 1M- and 10M-triangle
/// benchmarks (5.5M walks each) overflowed 32 entries; 198 overflowed 16.
const DEEP: usize = if cfg!(test) { 3 } else { 32 };

impl Bvh8 {
    /// `N` any-hit walks (shadow rays) at once, interleaved node by node. One walk is a
    /// chain of dependent steps (load a node, test its boxes, pick a child) that keeps
    /// the processor waiting; stepping `N` independent walks in turn fills those waits.
    /// `leaf(k, range)` says whether ray `k` is blocked by the primitives at `range`
    /// (which then ends its walk). Returns which rays were blocked: the same answers,
    /// from the same leaves, as one unordered walk per ray.
    #[inline]
    #[allow(unsafe_code)]
    pub fn any_hits<T, const N: usize>(
        &self,
        rays: [&Ray; N],
        t_min: f32,
        t_max: [f32; N],
        items: &[T],
        mut leaf: impl FnMut(usize, std::ops::Range<usize>) -> bool,
    ) -> [bool; N] {
        // SAFETY: as in `start`: a `Bvh8` exists only where the processor has AVX2.
        unsafe { self.walk_any(rays, t_min, t_max, items, &mut leaf) }
    }

    #[target_feature(enable = "avx2")]
    fn walk_any<T, const N: usize>(
        &self,
        rays: [&Ray; N],
        t_min: f32,
        mut t_max: [f32; N],
        items: &[T],
        leaf: &mut impl FnMut(usize, std::ops::Range<usize>) -> bool,
    ) -> [bool; N] {
        let r = rays.map(|ray| WideRay8::new(ray));
        let mut stack = [[0u32; DEEP]; N];
        let mut sp = [0usize; N];
        // Each walk starts at the root, node 0.
        let mut current = [0u32; N];
        let mut live = (1u32 << N) - 1;
        let mut blocked = [false; N];
        // One step of walk `k`: a leaf tested, or a node's children entered (the last
        // next, the others stacked); then, if the walk goes on, its next entry.
        macro_rules! step {
            ($k:expr) => {{
                let k = $k;
                let (index, count) = unpack(current[k]);
                let mut next = None;
                if count > 0 {
                    let first = index as usize;
                    if leaf(k, first..first + count as usize) {
                        blocked[k] = true;
                        live &= !(1 << k);
                    }
                } else {
                    let n = &self.nodes[index as usize];
                    let (_, mut hit) = enter!(&r[k], n, t_min, t_max[k]);
                    if hit != 0 {
                        let last = 31 - hit.leading_zeros() as usize;
                        hit &= !(1 << last);
                        while hit != 0 {
                            let lane = hit.trailing_zeros() as usize;
                            hit &= hit - 1;
                            let entry = n.packed[lane];
                            prefetch_child(&self.nodes, items, entry);
                            if sp[k] < DEEP {
                                stack[k][sp[k]] = entry;
                                sp[k] += 1;
                            } else {
                                #[cfg(test)]
                                tests::OVERFLOWS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                                let mut stop = |range, t| if leaf(k, range) { Visit::Stop } else { Visit::Continue(t) };
                                if !self.walk::<false, T>(rays[k], (entry, 0.0), t_min, &mut t_max[k], items, &mut stop)
                                {
                                    blocked[k] = true;
                                    live &= !(1 << k);
                                    break;
                                }
                            }
                        }
                        prefetch_child(&self.nodes, items, n.packed[last]);
                        next = Some(n.packed[last]);
                    }
                }
                if live >> k & 1 != 0 {
                    match next {
                        Some(entry) => current[k] = entry,
                        None if sp[k] == 0 => live &= !(1 << k),
                        None => {
                            sp[k] -= 1;
                            current[k] = stack[k][sp[k]];
                        }
                    }
                }
            }};
        }
        in_turn!(N, live, step);
        blocked
    }
}

impl Bvh8 {
    /// `N` nearest-first walks (closest hits) at once, interleaved node by node, as
    /// [`Bvh8::any_hits`] does for any-hit walks (one function for both, with `walk`'s
    /// `ORDERED` switch, made shadow rays 7 % slower): each walk visits the leaves that
    /// [`Bvh8::start`] (ordered) visits, in the same order, and `leaf(k, range, t_max)`
    /// handles ray `k`'s and returns its new bound.
    #[inline]
    #[allow(unsafe_code)]
    pub fn nearest_hits<T, const N: usize>(
        &self,
        rays: [&Ray; N],
        t_min: f32,
        t_max: [f32; N],
        items: &[T],
        mut leaf: impl FnMut(usize, std::ops::Range<usize>, f32) -> f32,
    ) {
        // SAFETY: as in `start`: a `Bvh8` exists only where the processor has AVX2.
        unsafe { self.walk_nearest(rays, t_min, t_max, items, &mut leaf) }
    }

    #[target_feature(enable = "avx2")]
    fn walk_nearest<T, const N: usize>(
        &self,
        rays: [&Ray; N],
        t_min: f32,
        mut t_max: [f32; N],
        items: &[T],
        leaf: &mut impl FnMut(usize, std::ops::Range<usize>, f32) -> f32,
    ) {
        let r = rays.map(|ray| WideRay8::new(ray));
        let mut stack = [[(0u32, 0f32); DEEP]; N];
        let mut sp = [0usize; N];
        let mut current = [(0u32, t_min); N];
        let mut live = (1u32 << N) - 1;
        // One step of walk `k`: a leaf handled, or a node's children entered (the
        // nearest next, the others stacked farthest first); then, if the walk goes on,
        // its next entry still in front of the nearest hit.
        macro_rules! step {
            ($k:expr) => {{
                let k = $k;
                let (index, count) = unpack(current[k].0);
                let mut next = None;
                if count > 0 {
                    let first = index as usize;
                    t_max[k] = leaf(k, first..first + count as usize, t_max[k]);
                } else {
                    let n = &self.nodes[index as usize];
                    let (near, mut hit) = enter!(&r[k], n, t_min, t_max[k]);
                    if hit != 0 {
                        let mut order = [(0f32, 0u32); 8];
                        let mut m = 0;
                        while hit != 0 {
                            let lane = hit.trailing_zeros() as usize;
                            hit &= hit - 1;
                            prefetch_child(&self.nodes, items, n.packed[lane]);
                            let d = near[lane];
                            let mut j = m;
                            while j > 0 && order[j - 1].0 < d {
                                order[j] = order[j - 1];
                                j -= 1;
                            }
                            order[j] = (d, lane as u32);
                            m += 1;
                        }
                        for &(d, lane) in &order[..m - 1] {
                            let entry = (n.packed[lane as usize], d);
                            if sp[k] < DEEP {
                                stack[k][sp[k]] = entry;
                                sp[k] += 1;
                            } else {
                                #[cfg(test)]
                                tests::OVERFLOWS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                                let mut go_on = |range, t| Visit::Continue(leaf(k, range, t));
                                self.walk::<true, T>(rays[k], entry, t_min, &mut t_max[k], items, &mut go_on);
                            }
                        }
                        let (d, lane) = order[m - 1];
                        next = Some((n.packed[lane as usize], d));
                    }
                }
                match next {
                    Some(entry) => current[k] = entry,
                    None => loop {
                        if sp[k] == 0 {
                            live &= !(1 << k);
                            break;
                        }
                        sp[k] -= 1;
                        if stack[k][sp[k]].1 <= t_max[k] * ROBUST {
                            current[k] = stack[k][sp[k]];
                            break;
                        }
                    },
                }
            }};
        }
        in_turn!(N, live, step);
    }
}

/// Entries of a packet walk's stack ([`Bvh8::nearest_packet`]); a child that would
/// overflow it is walked ray by ray. Small in tests, so that they cover that path.
const PACKET_DEEP: usize = if cfg!(test) { 3 } else { 32 };

impl Bvh8 {
    /// Up to eight nearest-first walks as one, if the rays of `live` (a bit each) all
    /// head into one octant; `false`, and nothing done, if not (unrelated rays share
    /// few nodes: as a packet, random rays were 30 % slower than walks in pairs).
    ///
    /// The rays go down the tree together. At each node, each child is tested against
    /// every ray with the single walk's arithmetic lane by lane, and entered by the rays
    /// that pass; so a ray reaches the leaves its own walk reaches (and perhaps more, in
    /// another order), and `leaf(k, range, t_max)` (ray `k`'s leaf, returning its new
    /// bound) must not depend on the order, as a nearest hit with ties to the lower id
    /// does not. Where neighbouring camera rays share most of their nodes, or all leave
    /// the tree after a node or two, one node visit serves them all.
    #[inline]
    #[allow(unsafe_code)]
    pub fn nearest_packet<T>(
        &self,
        rays: [&Ray; 8],
        live: u32,
        t_min: f32,
        t_max: [f32; 8],
        items: &[T],
        mut leaf: impl FnMut(usize, std::ops::Range<usize>, f32) -> f32,
    ) -> bool {
        // SAFETY: as in `start`: a `Bvh8` exists only where the processor has AVX2.
        unsafe {
            let Some(p) = Packet8::new(&rays, live) else { return false };
            self.walk_packet(&p, rays, live, t_min, t_max, items, &mut leaf);
        }
        true
    }

    #[allow(clippy::too_many_arguments)]
    #[target_feature(enable = "avx2")]
    fn walk_packet<T>(
        &self,
        p: &Packet8,
        rays: [&Ray; 8],
        live: u32,
        t_min: f32,
        mut t_max: [f32; 8],
        items: &[T],
        leaf: &mut impl FnMut(usize, std::ops::Range<usize>, f32) -> f32,
    ) {
        // Per entry: the child, the rays that entered it, and their entry distances.
        let mut stack = [(0u32, 0u32); PACKET_DEEP];
        let mut stack_near = [[0f32; 8]; PACKET_DEEP];
        let mut sp = 0;
        let mut current = (0u32, live & 0xff);
        let robust = _mm256_set1_ps(ROBUST);
        'visit: loop {
            let (packed, mask) = current;
            let (index, count) = unpack(packed);
            if count > 0 {
                let first = index as usize;
                let mut m = mask;
                while m != 0 {
                    let k = m.trailing_zeros() as usize;
                    m &= m - 1;
                    t_max[k] = leaf(k, first..first + count as usize, t_max[k]);
                }
            } else {
                let n = &self.nodes[index as usize];
                let bound = load(&t_max);
                // Hit children, nearest last, by the entry distance of their first ray.
                let mut order = [(0f32, 0u32, 0u32); 8];
                let mut near = [[0f32; 8]; 8];
                let mut m = 0;
                for c in 0..8 {
                    if n.packed[c] == 0 {
                        continue; // an empty slot
                    }
                    let (d, hit) = enter_packet!(p, n, c, t_min, bound);
                    let hit = hit & mask;
                    if hit == 0 {
                        continue;
                    }
                    prefetch_child(&self.nodes, items, n.packed[c]);
                    near[c] = store(d);
                    let d = near[c][hit.trailing_zeros() as usize];
                    let mut j = m;
                    while j > 0 && order[j - 1].0 < d {
                        order[j] = order[j - 1];
                        j -= 1;
                    }
                    order[j] = (d, c as u32, hit);
                    m += 1;
                }
                if m > 0 {
                    for &(_, c, hit) in &order[..m - 1] {
                        let c = c as usize;
                        if sp < PACKET_DEEP {
                            (stack[sp], stack_near[sp]) = ((n.packed[c], hit), near[c]);
                            sp += 1;
                        } else {
                            #[cfg(test)]
                            tests::OVERFLOWS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                            let mut h = hit;
                            while h != 0 {
                                let k = h.trailing_zeros() as usize;
                                h &= h - 1;
                                let mut go_on = |range, t| Visit::Continue(leaf(k, range, t));
                                let entry = (n.packed[c], near[c][k]);
                                self.walk::<true, T>(rays[k], entry, t_min, &mut t_max[k], items, &mut go_on);
                            }
                        }
                    }
                    let (_, c, hit) = order[m - 1];
                    current = (n.packed[c as usize], hit);
                    continue 'visit;
                }
            }
            // The next stacked child, for the rays still in front of their nearest hit.
            let bound = _mm256_mul_ps(load(&t_max), robust);
            loop {
                if sp == 0 {
                    return;
                }
                sp -= 1;
                let ahead = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(load(&stack_near[sp]), bound)) as u32;
                let mask = stack[sp].1 & ahead;
                if mask != 0 {
                    current = (stack[sp].0, mask);
                    continue 'visit;
                }
            }
        }
    }
}

impl Bvh8 {
    /// Up to eight any-hit walks as one ([`Bvh8::nearest_packet`]'s, for shadow rays),
    /// under the same condition (`None` if not met): the rays of `live` go down the tree
    /// together, each child entered by the rays whose own box test passes, the last
    /// such child first and the others stacked, as in one walk. `leaf(k, range)` says
    /// whether ray `k` is blocked at `range`, which takes it out of the packet. Returns
    /// which rays were blocked: the same answers as one walk per ray, since each ray
    /// still reaches every leaf its own walk reaches until something blocks it.
    #[inline]
    #[allow(unsafe_code)]
    pub fn any_packet<T>(
        &self,
        rays: [&Ray; 8],
        live: u32,
        t_min: f32,
        t_max: [f32; 8],
        items: &[T],
        mut leaf: impl FnMut(usize, std::ops::Range<usize>) -> bool,
    ) -> Option<u32> {
        // SAFETY: as in `start`: a `Bvh8` exists only where the processor has AVX2.
        unsafe {
            let p = Packet8::new(&rays, live)?;
            Some(self.walk_any_packet(&p, rays, live, t_min, t_max, items, &mut leaf))
        }
    }

    #[allow(clippy::too_many_arguments)]
    #[target_feature(enable = "avx2")]
    fn walk_any_packet<T>(
        &self,
        p: &Packet8,
        rays: [&Ray; 8],
        mut live: u32,
        t_min: f32,
        mut t_max: [f32; 8],
        items: &[T],
        leaf: &mut impl FnMut(usize, std::ops::Range<usize>) -> bool,
    ) -> u32 {
        live &= 0xff;
        let bound = load(&t_max);
        let mut blocked = 0u32;
        let mut stack = [(0u32, 0u32); PACKET_DEEP];
        let mut sp = 0;
        let mut current = (0u32, live);
        'visit: loop {
            let (packed, mask) = (current.0, current.1 & live);
            let (index, count) = unpack(packed);
            if mask == 0 {
                // Every ray of this entry is blocked already.
            } else if count > 0 {
                let first = index as usize;
                let mut m = mask;
                while m != 0 {
                    let k = m.trailing_zeros() as usize;
                    m &= m - 1;
                    if leaf(k, first..first + count as usize) {
                        blocked |= 1 << k;
                        live &= !(1 << k);
                    }
                }
                if live == 0 {
                    return blocked;
                }
            } else {
                let n = &self.nodes[index as usize];
                let mut next = None;
                for c in 0..8 {
                    if n.packed[c] == 0 {
                        continue; // an empty slot
                    }
                    let hit = enter_packet!(p, n, c, t_min, bound).1 & mask;
                    if hit == 0 {
                        continue;
                    }
                    prefetch_child(&self.nodes, items, n.packed[c]);
                    // The last child hit goes next; those before it are stacked.
                    let Some((before, hit_before)) = next.replace((n.packed[c], hit)) else { continue };
                    if sp < PACKET_DEEP {
                        stack[sp] = (before, hit_before);
                        sp += 1;
                    } else {
                        #[cfg(test)]
                        tests::OVERFLOWS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let mut h = hit_before & live;
                        while h != 0 {
                            let k = h.trailing_zeros() as usize;
                            h &= h - 1;
                            let mut stop = |range, t| if leaf(k, range) { Visit::Stop } else { Visit::Continue(t) };
                            if !self.walk::<false, T>(rays[k], (before, 0.0), t_min, &mut t_max[k], items, &mut stop) {
                                blocked |= 1 << k;
                                live &= !(1 << k);
                            }
                        }
                        if live == 0 {
                            return blocked;
                        }
                    }
                }
                if let Some(entry) = next {
                    current = entry;
                    continue 'visit;
                }
            }
            loop {
                if sp == 0 {
                    return blocked;
                }
                sp -= 1;
                if stack[sp].1 & live != 0 {
                    current = stack[sp];
                    continue 'visit;
                }
            }
        }
    }
}

/// Eight rays side by side, lane `k` for ray `k`, that all head into one octant: what
/// [`WideRay8`] holds of one ray.
struct Packet8 {
    org: [__m256; 3],
    inv: [__m256; 3],
    /// Per axis, the row of `Node8::bounds` every ray enters through.
    near_row: [usize; 3],
}

impl Packet8 {
    /// The rays of `live`, if their directions all have the same signs (those of
    /// [`WideRay8::new`]'s directions); the other lanes' rays are carried along unused.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn new(rays: &[&Ray; 8], live: u32) -> Option<Self> {
        let lanes = |f: &dyn Fn(&Ray) -> f32| load(&rays.map(f));
        let org = [lanes(&|r| r.origin.x), lanes(&|r| r.origin.y), lanes(&|r| r.origin.z)];
        let dir = [lanes(&|r| r.dir.x), lanes(&|r| r.dir.y), lanes(&|r| r.dir.z)];
        // As `WideRay8::new`: a direction within 1e-30 of 0 becomes ±1e-30, its sign kept.
        let sign = _mm256_set1_ps(-0.0);
        let tiny = _mm256_set1_ps(1e-30);
        let safe = |d: __m256| {
            let small = _mm256_cmp_ps::<_CMP_LT_OQ>(_mm256_andnot_ps(sign, d), tiny);
            _mm256_blendv_ps(d, _mm256_or_ps(_mm256_and_ps(sign, d), tiny), small)
        };
        let d = dir.map(safe);
        let live = live & 0xff;
        let neg = d.map(|d| _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(d, _mm256_setzero_ps())) as u32 & live);
        if neg.iter().any(|&n| n != 0 && n != live) {
            return None;
        }
        let one = _mm256_set1_ps(1.0);
        Some(Packet8 {
            org,
            inv: d.map(|d| _mm256_div_ps(one, d)),
            near_row: [0, 1, 2].map(|i| if neg[i] != 0 { 3 + i } else { i }),
        })
    }
}

/// Entry distances of child `$c`'s box for the eight rays of packet `$p`, and a bit mask
/// of the rays that enter it within `[t_min, t_max]`: `enter!`'s operations, in its
/// order, with the box's bounds in every lane. A macro for the same reason as `enter!`
/// (as a function it was not inlined: 9 % of a camera ray).
macro_rules! enter_packet {
    ($p:expr, $n:expr, $c:expr, $t_min:expr, $t_max:expr) => {{
        let (p, n, c): (&Packet8, &Node8, usize) = ($p, $n, $c);
        let axis = |i: usize| {
            let row = p.near_row[i];
            let far_row = if row >= 3 { row - 3 } else { row + 3 };
            let (near, far) = (_mm256_set1_ps(n.bounds[row][c]), _mm256_set1_ps(n.bounds[far_row][c]));
            (
                _mm256_mul_ps(_mm256_sub_ps(near, p.org[i]), p.inv[i]),
                _mm256_mul_ps(_mm256_sub_ps(far, p.org[i]), p.inv[i]),
            )
        };
        let (nx, fx) = axis(0);
        let (ny, fy) = axis(1);
        let (nz, fz) = axis(2);
        let near = _mm256_max_ps(_mm256_max_ps(nx, ny), _mm256_max_ps(nz, _mm256_set1_ps($t_min)));
        let far =
            _mm256_mul_ps(_mm256_min_ps(_mm256_min_ps(fx, fy), _mm256_min_ps(fz, $t_max)), _mm256_set1_ps(ROBUST));
        (near, _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32)
    }};
}
use enter_packet;

/// Steps the walks of `live` (a bit each, up to four) in turn with `$step!(k)` until
/// none is left. With constant indices: a loop over `k` kept the walks' state in memory,
/// and was slower by a tenth.
macro_rules! in_turn {
    ($n:expr, $live:ident, $step:ident) => {
        const { assert!($n >= 1 && $n <= 4, "one to four walks at a time") };
        while $live != 0 {
            if $live & 1 != 0 {
                $step!(0);
            }
            if $n > 1 && $live & 2 != 0 {
                $step!(1.min($n - 1));
            }
            if $n > 2 && $live & 4 != 0 {
                $step!(2.min($n - 1));
            }
            if $n > 3 && $live & 8 != 0 {
                $step!(3.min($n - 1));
            }
        }
    };
}
use in_turn;

/// Starts loading a child: an inner node's box lines or a leaf's first items.
#[inline(always)]
fn prefetch_child<T>(nodes: &[Node8], items: &[T], packed: u32) {
    match unpack(packed) {
        (child, 0) => prefetch(&nodes[child as usize]),
        (first, _) => super::wide::prefetch_items(items, first as usize),
    }
}

/// Asks the processor to start loading a node's box lines.
#[inline(always)]
#[allow(unsafe_code)]
fn prefetch(node: &Node8) {
    let p = (node as *const Node8).cast::<i8>();
    // SAFETY: a prefetch is a hint that never faults or changes memory; the addresses
    // lie inside `node`, a live 256-byte reference.
    unsafe {
        _mm_prefetch::<_MM_HINT_T0>(p);
        _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64));
        _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(128));
        _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(192));
    }
}

impl WideNode for Node8 {
    const WIDTH: usize = 8;

    fn empty() -> Node8 {
        let (inf, neg) = ([f32::INFINITY; 8], [f32::NEG_INFINITY; 8]);
        Node8 { bounds: [inf, inf, inf, neg, neg, neg], packed: [0; 8], _pad: [0; 8] }
    }

    fn set_lane(&mut self, lane: usize, b: &Node, child: u32, count: u32) {
        for axis in 0..3 {
            self.bounds[axis][lane] = b.min[axis];
            self.bounds[3 + axis][lane] = b.max[axis];
        }
        self.packed[lane] = pack(child, count);
    }

    fn packed_mut(&mut self) -> &mut [u32] {
        &mut self.packed
    }
}

/// The ray splatted across eight lanes; as [`super::wide`]'s `WideRay`.
struct WideRay8 {
    org: [__m256; 3],
    inv: [__m256; 3],
    /// Per axis, the row of `Node8::bounds` the ray enters through (it leaves through the
    /// other of the pair, as `enter!` derives).
    near_row: [usize; 3],
}

impl WideRay8 {
    #[target_feature(enable = "avx2")]
    #[inline]
    fn new(ray: &Ray) -> Self {
        let safe = |d: f32| if d.abs() < 1e-30 { 1e-30f32.copysign(d) } else { d };
        let d = [safe(ray.dir.x), safe(ray.dir.y), safe(ray.dir.z)];
        let o = ray.origin.to_array();
        // One 4-lane division for the three reciprocals (each lane rounds as 1.0 / d).
        let inv = _mm_div_ps(_mm_set1_ps(1.0), _mm_setr_ps(d[0], d[1], d[2], 1.0));
        let splat = |x: __m128| _mm256_broadcastss_ps(x);
        WideRay8 {
            org: [_mm256_set1_ps(o[0]), _mm256_set1_ps(o[1]), _mm256_set1_ps(o[2])],
            inv: [
                splat(inv),
                splat(_mm_shuffle_ps::<0b01_01_01_01>(inv, inv)),
                splat(_mm_shuffle_ps::<0b10_10_10_10>(inv, inv)),
            ],
            near_row: [0, 1, 2].map(|i| if d[i] < 0.0 { 3 + i } else { i }),
        }
    }
}

/// Entry distances of the eight boxes and a bit mask of those entered within
/// `[t_min, t_max]`: the 4-wide test's operations in the same order. A macro, not a
/// function: LLVM did not inline the `avx2` function, and the call cost 10 %.
macro_rules! enter {
    ($r:expr, $n:expr, $t_min:expr, $t_max:expr) => {{
        let (r, n) = ($r, $n);
        let axis = |i: usize| {
            let row = r.near_row[i];
            let far_row = if row >= 3 { row - 3 } else { row + 3 };
            let near = _mm256_mul_ps(_mm256_sub_ps(load(&n.bounds[row]), r.org[i]), r.inv[i]);
            let far = _mm256_mul_ps(_mm256_sub_ps(load(&n.bounds[far_row]), r.org[i]), r.inv[i]);
            (near, far)
        };
        let (nx, fx) = axis(0);
        let (ny, fy) = axis(1);
        let (nz, fz) = axis(2);
        // glam's `a.max(b)` is `maxps a, b`; the same operand order keeps NaN handling equal.
        let near = _mm256_max_ps(_mm256_max_ps(nx, ny), _mm256_max_ps(nz, _mm256_set1_ps($t_min)));
        let far = _mm256_mul_ps(
            _mm256_min_ps(_mm256_min_ps(fx, fy), _mm256_min_ps(fz, _mm256_set1_ps($t_max))),
            _mm256_set1_ps(ROBUST),
        );
        let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
        (store(near), mask)
    }};
}
use enter;

#[target_feature(enable = "avx2")]
#[inline]
#[allow(unsafe_code)]
fn load(a: &[f32; 8]) -> __m256 {
    // SAFETY: reads eight f32s from a live `[f32; 8]`; the unaligned load has no
    // alignment requirement.
    unsafe { _mm256_loadu_ps(a.as_ptr()) }
}

#[target_feature(enable = "avx2")]
#[inline]
#[allow(unsafe_code)]
fn store(v: __m256) -> [f32; 8] {
    let mut a = [0f32; 8];
    // SAFETY: writes eight f32s into a local `[f32; 8]`, unaligned store.
    unsafe { _mm256_storeu_ps(a.as_mut_ptr(), v) };
    a
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Bvh4;
    use crate::math::Vec3;

    type LeafFn<'a> = dyn FnMut(std::ops::Range<usize>, f32) -> Visit + 'a;

    /// Interleaved walks that overflowed their stack (into a nested walk).
    pub(super) static OVERFLOWS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

    /// The nearest-hit leaf of the walk tests: a primitive is hit where the ray enters
    /// its box (of `boxes`, by `bvh`'s leaf order); the nearest wins, ties to the lower
    /// id. Returns the new bound.
    fn nearest_box(
        boxes: &[crate::math::Aabb],
        bvh: &Bvh,
        ray: &Ray,
        range: std::ops::Range<usize>,
        mut t: f32,
        best: &mut Option<(f32, u32)>,
    ) -> f32 {
        for id in range.map(|i| bvh.indices[i]) {
            let (near, far) = (0..3).fold((0.0f32, f32::INFINITY), |(near, far), axis| {
                let inv = 1.0 / ray.dir[axis];
                let (a, c) = (
                    (boxes[id as usize].min[axis] - ray.origin[axis]) * inv,
                    (boxes[id as usize].max[axis] - ray.origin[axis]) * inv,
                );
                (near.max(a.min(c)), far.min(a.max(c)))
            });
            if near <= far && (near < t || best.is_some_and(|(bt, bid)| near == bt && id < bid)) {
                (t, *best) = (near, Some((near, id)));
            }
        }
        t
    }

    /// Three interleaved nearest-first walks find the same nearest primitive as one
    /// walk per ray (a primitive's distance made up from its id), with stacks that
    /// overflow into nested walks.
    #[test]
    fn interleaved_nearest_walks_match_walks_one_by_one() {
        let (mut found, mut rays_run) = (0, 0);
        let before = OVERFLOWS.load(std::sync::atomic::Ordering::Relaxed);
        for n in [1, 2, 9, 100, 5000] {
            let b = crate::accel::bvh::tests::boxes(n, 0x2545f4914f6cdd1d);
            let bvh = Bvh::build(&b);
            let Some(eight) = Bvh8::from_binary(&bvh) else {
                eprintln!("no AVX2 here: the 8-wide tree is not tested");
                return;
            };
            let nearest = |ray: &Ray, range, t, best: &mut _| nearest_box(&b, &bvh, ray, range, t, best);
            let mut s = 5u64;
            for _ in 0..1500 {
                let rays: [Ray; 3] = std::array::from_fn(|_| {
                    s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                    let f = |k: u32| ((s >> k) & 0xffff) as f32 / 65535.0;
                    Ray::new(
                        Vec3::new(f(0), f(16), f(32)) * 60.0 - 5.0,
                        Vec3::new(f(8) - 0.5, f(24) - 0.5, f(40) - 0.5),
                    )
                });
                let t_max = [f32::INFINITY, 40.0, 80.0];
                let mut got = [None; 3];
                eight.nearest_hits([&rays[0], &rays[1], &rays[2]], 0.0, t_max, &[0u8; 0], |k, range, t| {
                    nearest(&rays[k], range, t, &mut got[k])
                });
                for k in 0..3 {
                    let mut want = None;
                    eight.start::<true, u8>(&rays[k], 0.0, t_max[k], &[], |range, t| {
                        Visit::Continue(nearest(&rays[k], range, t, &mut want))
                    });
                    assert_eq!(got[k], want, "n = {n}, ray {k}");
                    found += want.is_some() as u32;
                    rays_run += 1;
                }
            }
        }
        let overflowed = OVERFLOWS.load(std::sync::atomic::Ordering::Relaxed) - before;
        assert!(overflowed > 100 && found > 300 && found + 300 < rays_run, "{overflowed} {found} {rays_run}");
    }

    /// Packet walks find the same nearest primitive for each live ray as one walk per
    /// ray, for bundles of rays into one octant (with zero direction components among
    /// them), dead lanes, bounds that differ by lane, and stacks that overflow into walks
    /// ray by ray; unrelated rays are refused, unless they happen to share an octant.
    #[test]
    fn packet_walks_match_walks_one_by_one() {
        let (mut found, mut rays_run, mut packets) = (0, 0, 0);
        let before = OVERFLOWS.load(std::sync::atomic::Ordering::Relaxed);
        for n in [1, 2, 9, 100, 5000] {
            let b = crate::accel::bvh::tests::boxes(n, 0x2545f4914f6cdd1d);
            let bvh = Bvh::build(&b);
            let Some(eight) = Bvh8::from_binary(&bvh) else {
                eprintln!("no AVX2 here: the 8-wide tree is not tested");
                return;
            };
            let nearest = |ray: &Ray, range, t, best: &mut _| nearest_box(&b, &bvh, ray, range, t, best);
            let mut s = 5u64;
            let mut next = || {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                s
            };
            for round in 0..1000 {
                let rays = rays_for(round, &mut next);
                let t_max: [f32; 8] = std::array::from_fn(|k| [f32::INFINITY, 40.0, 80.0][k % 3]);
                let live = if round % 3 == 0 { 0xff } else { (next() & 0xff) as u32 };
                let mut got = [None; 8];
                let walked = eight.nearest_packet(rays.each_ref(), live, 0.0, t_max, &[0u8; 0], |k, range, t| {
                    assert!(live >> k & 1 != 0, "a dead lane's leaf");
                    nearest(&rays[k], range, t, &mut got[k])
                });
                assert!(walked || round % 2 == 1, "a bundle refused");
                if !walked {
                    assert_eq!(got, [None; 8]);
                    continue;
                }
                packets += 1;
                for k in 0..8 {
                    let mut want = None;
                    if live >> k & 1 != 0 {
                        eight.start::<true, u8>(&rays[k], 0.0, t_max[k], &[], |range, t| {
                            Visit::Continue(nearest(&rays[k], range, t, &mut want))
                        });
                        rays_run += 1;
                    }
                    assert_eq!(got[k], want, "n = {n}, round {round}, ray {k}");
                    found += want.is_some() as u32;
                }
            }
        }
        let overflowed = OVERFLOWS.load(std::sync::atomic::Ordering::Relaxed) - before;
        assert!(overflowed > 100 && found > 300 && found + 1000 < rays_run, "{overflowed} {found} {rays_run}");
        assert!(packets < 5 * 550, "{packets}: unrelated rays taken as packets");
    }

    /// Eight rays: in even rounds a bundle (one origin, directions a little apart in one
    /// octant, one lane with a zero component of that octant's sign, one along an axis),
    /// in odd rounds unrelated ones.
    fn rays_for(round: usize, next: &mut impl FnMut() -> u64) -> [Ray; 8] {
        let f = |s: u64, k: u32| ((s >> k) & 0xffff) as f32 / 65535.0;
        let s0 = next();
        let bundle = round.is_multiple_of(2);
        std::array::from_fn(|k| {
            let s = if bundle { s0 } else { next() };
            let origin = Vec3::new(f(s, 0), f(s, 16), f(s, 32)) * 60.0 - 5.0;
            let dir = Vec3::new(f(s, 8) - 0.5, f(s, 24) - 0.5, f(s, 40) - 0.5);
            if !bundle {
                return Ray::new(origin, dir);
            }
            let spread = (dir.abs() + 0.02 * k as f32).copysign(dir);
            let dir = match k {
                3 => Vec3::new(spread.x, 0.0f32.copysign(dir.y), spread.z),
                5 => Vec3::new(0.0f32.copysign(dir.x), 0.0f32.copysign(dir.y), dir.z),
                _ => spread,
            };
            Ray::new(origin, dir)
        })
    }

    /// Any-hit packet walks block the same rays as one walk per ray, and every leaf a
    /// ray's own walk reaches is reached for it where it is not blocked: bundles and
    /// unrelated rays, dead lanes, small stacks.
    #[test]
    fn any_hit_packet_walks_match_walks_one_by_one() {
        let (mut blocked_rays, mut passed_rays) = (0, 0);
        let before = OVERFLOWS.load(std::sync::atomic::Ordering::Relaxed);
        for n in [1, 2, 9, 100, 5000] {
            let b = crate::accel::bvh::tests::boxes(n, 0x9e3779b97f4a7c15);
            let bvh = Bvh::build(&b);
            let Some(eight) = Bvh8::from_binary(&bvh) else {
                eprintln!("no AVX2 here: the 8-wide tree is not tested");
                return;
            };
            let blocks =
                |every: u32, range: std::ops::Range<usize>| range.clone().any(|i| bvh.indices[i].is_multiple_of(every));
            let mut s = 7u64;
            let mut next = || {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                s
            };
            for round in 0..1000 {
                let rays = rays_for(round, &mut next);
                let s0 = next();
                let every: [u32; 8] =
                    std::array::from_fn(|k| [2 + (s0 % 5) as u32, 7919, 1 + (s0 >> 20) as u32 % 9][k % 3]);
                let t_max: [f32; 8] = std::array::from_fn(|k| [f32::INFINITY, 40.0, 80.0][k % 3]);
                let live = if round % 3 == 0 { 0xff } else { (next() & 0xff) as u32 };
                let mut seen: [Vec<u32>; 8] = Default::default();
                let got = eight.any_packet(rays.each_ref(), live, 0.0, t_max, &[0u8; 0], |k, range| {
                    assert!(live >> k & 1 != 0, "a dead lane's leaf");
                    seen[k].extend(range.clone().map(|i| bvh.indices[i]));
                    blocks(every[k], range)
                });
                assert!(got.is_some() || round % 2 == 1, "a bundle refused");
                let Some(got) = got else { continue };
                assert_eq!(got & !live, 0, "a dead lane blocked");
                for k in (0..8).filter(|k| live >> k & 1 != 0) {
                    let (mut one, mut blocked) = (Vec::new(), false);
                    eight.start::<false, u8>(&rays[k], 0.0, t_max[k], &[], |range, t| {
                        one.extend(range.clone().map(|i| bvh.indices[i]));
                        blocked = blocks(every[k], range);
                        if blocked { Visit::Stop } else { Visit::Continue(t) }
                    });
                    assert_eq!(got >> k & 1 != 0, blocked, "n = {n}, round {round}, ray {k}");
                    if !blocked {
                        seen[k].sort_unstable();
                        seen[k].dedup();
                        one.sort_unstable();
                        one.dedup();
                        assert!(one.iter().all(|id| seen[k].binary_search(id).is_ok()), "n = {n}, ray {k}");
                    }
                    blocked_rays += blocked as u32;
                    passed_rays += (!blocked && !one.is_empty()) as u32;
                }
            }
        }
        let overflowed = OVERFLOWS.load(std::sync::atomic::Ordering::Relaxed) - before;
        assert!(
            overflowed > 100 && blocked_rays > 50 && passed_rays > 200,
            "{overflowed} {blocked_rays} {passed_rays}"
        );
    }

    /// Three interleaved any-hit walks block the same rays, and reach the same leaves
    /// where not blocked, as one walk per ray; with the tests' small stacks, walks also
    /// overflow into nested ones.
    #[test]
    fn interleaved_walks_match_walks_one_by_one() {
        let (mut blocked_rays, mut passed_leaves) = (0, 0);
        for n in [1, 2, 9, 100, 5000] {
            let b = crate::accel::bvh::tests::boxes(n, 0x9e3779b97f4a7c15);
            let bvh = Bvh::build(&b);
            let Some(eight) = Bvh8::from_binary(&bvh) else {
                eprintln!("no AVX2 here: the 8-wide tree is not tested");
                return;
            };
            // A ray is blocked by primitives whose id is a multiple of `every` (per ray).
            let blocks =
                |every: u32, range: std::ops::Range<usize>| range.clone().any(|i| bvh.indices[i].is_multiple_of(every));
            let mut s = 7u64;
            for _ in 0..1500 {
                let rays: [Ray; 3] = std::array::from_fn(|_| {
                    s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                    let f = |k: u32| ((s >> k) & 0xffff) as f32 / 65535.0;
                    Ray::new(
                        Vec3::new(f(0), f(16), f(32)) * 60.0 - 5.0,
                        Vec3::new(f(8) - 0.5, f(24) - 0.5, f(40) - 0.5),
                    )
                });
                let every = [2 + (s % 5) as u32, 7919, 1 + (s >> 20) as u32 % 9];
                let t_max = [f32::INFINITY, 40.0, 80.0];
                let mut seen: [Vec<u32>; 3] = Default::default();
                let got = eight.any_hits([&rays[0], &rays[1], &rays[2]], 0.0, t_max, &[0u8; 0], |k, range| {
                    seen[k].extend(range.clone().map(|i| bvh.indices[i]));
                    blocks(every[k], range)
                });
                for k in 0..3 {
                    let (mut one, mut blocked) = (Vec::new(), false);
                    eight.start::<false, u8>(&rays[k], 0.0, t_max[k], &[], |range, t| {
                        one.extend(range.clone().map(|i| bvh.indices[i]));
                        blocked = blocks(every[k], range);
                        if blocked { Visit::Stop } else { Visit::Continue(t) }
                    });
                    assert_eq!(got[k], blocked, "n = {n}, ray {k}");
                    if !blocked {
                        seen[k].sort_unstable();
                        one.sort_unstable();
                        assert_eq!(seen[k], one, "n = {n}, ray {k}");
                    }
                    blocked_rays += blocked as u32;
                    passed_leaves += (!blocked && !one.is_empty()) as u32;
                }
            }
        }
        let overflowed = OVERFLOWS.load(std::sync::atomic::Ordering::Relaxed);
        assert!(
            overflowed > 500 && blocked_rays > 200 && passed_leaves > 600,
            "{overflowed} {blocked_rays} {passed_leaves}"
        );
    }

    /// Both widths reach the same primitives, in the same nearest-first order of leaves
    /// when ordered, and the same set when not.
    #[test]
    fn eight_wide_and_four_wide_trees_reach_the_same_leaves() {
        for n in [1, 2, 7, 9, 100, 5000] {
            let b = crate::accel::bvh::tests::boxes(n, 0x2545f4914f6cdd1d);
            let bvh = Bvh::build(&b);
            let Some(eight) = Bvh8::from_binary(&bvh) else {
                eprintln!("no AVX2 here: the 8-wide tree is not tested");
                return;
            };
            let four = Bvh4::from_binary(&bvh);
            let mut s = 11u64;
            for _ in 0..500 {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                let f = |k: u32| ((s >> k) & 0xffff) as f32 / 65535.0;
                let ray = Ray::new(
                    Vec3::new(f(0), f(16), f(32)) * 60.0 - 5.0,
                    Vec3::new(f(8) - 0.5, f(24) - 0.5, f(40) - 0.5),
                );
                for ordered in [true, false] {
                    let collect = |walk: &dyn Fn(&mut LeafFn)| {
                        let mut got = Vec::new();
                        walk(&mut |range, t| {
                            got.extend(range.map(|i| bvh.indices[i]));
                            Visit::Continue(t)
                        });
                        got.sort_unstable();
                        got
                    };
                    let a = collect(&|f| {
                        if ordered {
                            four.traverse(&ray, 0.0, f32::INFINITY, f)
                        } else {
                            four.traverse_any(&ray, 0.0, f32::INFINITY, f)
                        }
                    });
                    let b = collect(&|f| {
                        if ordered {
                            eight.start::<true, u8>(&ray, 0.0, f32::INFINITY, &[], f)
                        } else {
                            eight.start::<false, u8>(&ray, 0.0, f32::INFINITY, &[], f)
                        }
                    });
                    assert_eq!(a, b, "n = {n}");
                }
            }
            assert!(
                n < 5000 || eight.node_count() * 3 < four.node_count() * 2,
                "{} vs {}",
                eight.node_count(),
                four.node_count()
            );
        }
    }
}
