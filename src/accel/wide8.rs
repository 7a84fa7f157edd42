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

    /// Calls `f` with each leaf's first primitive and count.
    pub fn each_leaf(&self, f: impl FnMut(u32, u32)) {
        super::wide::each_leaf(&self.nodes, f);
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

/// Starts loading a child: an inner node's four lines or a leaf's first items (four
/// lines from there, a little more than the biggest entry needs). The address is
/// picked without a branch: whether a child is a leaf is a coin toss to the
/// predictor, and branching on it was a tenth of a sphereflake render's mispredicted
/// branches (callgrind's branch simulation).
#[inline(always)]
#[allow(unsafe_code)]
fn prefetch_child<T>(nodes: &[Node8], items: &[T], packed: u32) {
    let (index, count) = unpack(packed);
    let node = nodes.as_ptr().wrapping_add(index as usize).cast::<i8>();
    let item = items.as_ptr().wrapping_add(index as usize).cast::<i8>();
    let p = std::hint::select_unpredictable(count == 0, node, item);
    // SAFETY: a prefetch is only a hint: it never faults, reads nothing into the
    // program and changes no memory, whatever the address.
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

    fn packed(&self) -> &[u32] {
        &self.packed
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

mod packet;
pub use packet::each_ray;

#[cfg(test)]
mod tests;
