//! The 4-wide BVH that rays traverse, derived from the canonical binary tree by pulling
//! grandchildren up into their parents. Each node holds the boxes of up to four
//! children side by side (structure of arrays), so one node visit tests all four boxes
//! with 4-lane SIMD arithmetic, and the tree is about half as deep.

use super::bvh::{Bvh, Node};
use crate::math::{Ray, Vec3};
use glam::Vec4;

/// A node of up to four children: their boxes, lane by lane, and for each a packed
/// reference (see `pack` below) to an inner node or a leaf's run of primitives in leaf
/// order. An unused slot has an empty box, so rays never enter it. 128 bytes: two cache
/// lines.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct Node4 {
    min_x: Vec4,
    min_y: Vec4,
    min_z: Vec4,
    max_x: Vec4,
    max_y: Vec4,
    max_z: Vec4,
    packed: [u32; 4],
    _pad: [u32; 4],
}

const _: () = assert!(std::mem::size_of::<Node4>() == 128);

/// What a traversal closure tells the loop after handling a leaf.
pub use super::bvh::Visit;

/// A wide tree. Primitive positions are those of the binary tree it came from.
#[derive(Clone, Debug, Default)]
pub struct Bvh4 {
    nodes: Vec<Node4>,
}

impl Bvh4 {
    /// Collapses a binary tree: each wide node takes a binary node's children and keeps
    /// opening the inner child with the largest box until it has four.
    pub fn from_binary(bvh: &Bvh) -> Bvh4 {
        Bvh4 { nodes: collapse_tree(bvh) }
    }

    /// Rewrites every leaf's (first, count), in node order: lets a user re-lay out the
    /// primitives (triangles into packs of four) after the tree is built.
    pub fn map_leaves(&mut self, f: impl FnMut(u32, u32) -> (u32, u32)) {
        map_leaves(&mut self.nodes, f);
    }

    /// Calls `f` with each leaf's first primitive and count.
    pub fn each_leaf(&self, f: impl FnMut(u32, u32)) {
        each_leaf(&self.nodes, f);
    }

    pub fn memory_bytes(&self) -> usize {
        self.nodes.capacity() * std::mem::size_of::<Node4>()
    }

    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Visits the leaves the ray enters, nearest first, skipping any whose box starts
    /// beyond the closest hit so far; `leaf(range, t_max)` handles the primitives at
    /// `range` (positions in leaf order) and says how to go on.
    #[inline]
    pub fn traverse(&self, ray: &Ray, t_min: f32, t_max: f32, leaf: impl FnMut(std::ops::Range<usize>, f32) -> Visit) {
        self.start::<true, u8>(ray, t_min, t_max, &[], leaf);
    }

    /// Like [`Bvh4::traverse`] for queries that need any hit, not the nearest (shadow
    /// rays): children are visited in node order, which saves sorting them. Most shadow
    /// rays are not blocked and must visit every box they cross anyway.
    #[inline]
    pub fn traverse_any(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        leaf: impl FnMut(std::ops::Range<usize>, f32) -> Visit,
    ) {
        self.start::<false, u8>(ray, t_min, t_max, &[], leaf);
    }

    #[inline]
    pub(super) fn start<const ORDERED: bool, T>(
        &self,
        ray: &Ray,
        t_min: f32,
        mut t_max: f32,
        items: &[T],
        mut leaf: impl FnMut(std::ops::Range<usize>, f32) -> Visit,
    ) {
        self.walk::<ORDERED, T>(&WideRay::new(ray), (0, t_min), t_min, &mut t_max, items, &mut leaf);
    }

    /// Traverses from one stack entry; returns `false` when the closure said stop. The
    /// stack is small so that setting it up costs little per ray; a tree deep enough to
    /// fill it continues in a nested call.
    fn walk<const ORDERED: bool, T>(
        &self,
        r: &WideRay,
        start: (u32, f32),
        t_min: f32,
        t_max: &mut f32,
        items: &[T],
        leaf: &mut impl FnMut(std::ops::Range<usize>, f32) -> Visit,
    ) -> bool {
        // (packed child, entry distance): eight bytes, so the stack is cheap to set up.
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
                let (near, hit) = r.enter(n, t_min, *t_max);
                if hit != 0 {
                    // Go straight on into one child (the nearest when ordered) and stack
                    // the others, farthest first, so that the nearest is popped next.
                    let mut order = [(0f32, 0usize); 4];
                    let mut k = 0;
                    for lane in 0..4 {
                        if hit & (1 << lane) != 0 {
                            // Any-hit walks never cull by distance: no need to read it.
                            let d = if ORDERED { near[lane] } else { 0.0 };
                            let mut j = k;
                            if ORDERED {
                                while j > 0 && order[j - 1].0 < d {
                                    order[j] = order[j - 1];
                                    j -= 1;
                                }
                            }
                            order[j] = (d, lane);
                            k += 1;
                        }
                    }
                    for &(d, lane) in &order[..k - 1] {
                        let entry = (n.packed[lane], d);
                        match unpack(entry.0) {
                            // Popped later: start loading it now.
                            (child, 0) => prefetch(&self.nodes[child as usize]),
                            (first, _) => prefetch_items(items, first as usize),
                        }
                        if sp < STACK {
                            stack[sp] = entry;
                            sp += 1;
                        } else if !self.walk::<ORDERED, T>(r, entry, t_min, t_max, items, leaf) {
                            return false;
                        }
                    }
                    let (d, lane) = order[k - 1];
                    current = (n.packed[lane], d);
                    continue 'visit;
                }
            }
            // Pop the next entry still in front of the closest hit (any entry, when any
            // hit will do: then `t_max` never shrinks).
            loop {
                if sp == 0 {
                    return true;
                }
                sp -= 1;
                if !ORDERED || stack[sp].1 <= *t_max * ROBUST {
                    current = stack[sp];
                    continue 'visit;
                }
            }
        }
    }
}

/// The children of binary inner node `binary` in a `width`-wide node: its two children,
/// then, while there is room, the inner child with the largest surface area is replaced
/// by its own two.
pub(super) fn collapse(bvh: &Bvh, binary: usize, width: usize) -> Vec<usize> {
    let b = &bvh.nodes[binary];
    let mut kids: Vec<usize> = vec![b.first as usize, b.first as usize + 1];
    while kids.len() < width {
        let best = kids
            .iter()
            .enumerate()
            .filter(|(_, k)| !bvh.nodes[**k].is_leaf())
            .max_by(|(_, a), (_, c)| area(&bvh.nodes[**a]).total_cmp(&area(&bvh.nodes[**c])))
            .map(|(i, _)| i);
        let Some(i) = best else { break };
        let k = kids.swap_remove(i);
        let n = &bvh.nodes[k];
        kids.push(n.first as usize);
        kids.push(n.first as usize + 1);
    }
    kids
}

/// What building a wide tree needs of its node type (4 or 8 children).
pub(super) trait WideNode: Sized {
    const WIDTH: usize;
    /// A node whose slots all have empty boxes.
    fn empty() -> Self;
    /// Sets slot `lane` to binary node `b`'s box and a packed child reference.
    fn set_lane(&mut self, lane: usize, b: &Node, child: u32, count: u32);
    fn packed_mut(&mut self) -> &mut [u32];
    fn packed(&self) -> &[u32];
}

/// The wide nodes of a binary tree, root first.
pub(super) fn collapse_tree<N: WideNode>(bvh: &Bvh) -> Vec<N> {
    // Room for the most wide nodes there can be (one per binary inner node), on huge
    // pages; the unused end is never touched, and is given back below.
    let mut nodes = crate::pages::with_capacity(bvh.nodes.len() / 2 + 1);
    let root = &bvh.nodes[0];
    let mut n = N::empty();
    if root.is_leaf() || root.count == 0 && bvh.nodes.len() == 1 {
        // A single leaf (or nothing): one wide node holding it.
        if root.count > 0 {
            n.set_lane(0, root, root.first, root.count);
        }
        nodes.push(n);
        return nodes;
    }
    nodes.push(n);
    fill(&mut nodes, bvh, 0, 0);
    nodes.shrink_to_fit();
    nodes
}

/// Fills wide node `at` from binary inner node `binary`, then recurses.
fn fill<N: WideNode>(nodes: &mut Vec<N>, bvh: &Bvh, at: usize, binary: usize) {
    let kids = collapse(bvh, binary, N::WIDTH);
    let mut inner = Vec::new();
    for (lane, &k) in kids.iter().enumerate() {
        let n = &bvh.nodes[k];
        if n.is_leaf() {
            nodes[at].set_lane(lane, n, n.first, n.count);
        } else {
            let index = nodes.len() as u32;
            nodes.push(N::empty());
            nodes[at].set_lane(lane, n, index, 0);
            inner.push((index as usize, k));
        }
    }
    for (index, k) in inner {
        fill(nodes, bvh, index, k);
    }
}

/// Rewrites every leaf reference (first, count) with `f`, in node order.
pub(super) fn map_leaves<N: WideNode>(nodes: &mut [N], mut f: impl FnMut(u32, u32) -> (u32, u32)) {
    for n in nodes {
        for packed in n.packed_mut() {
            let (child, count) = unpack(*packed);
            if count > 0 {
                let (child, count) = f(child, count);
                *packed = pack(child, count);
            }
        }
    }
}

/// Calls `f` with each leaf's first primitive and count, node by node.
pub(super) fn each_leaf<N: WideNode>(nodes: &[N], mut f: impl FnMut(u32, u32)) {
    for n in nodes {
        for &packed in n.packed() {
            let (first, count) = unpack(packed);
            if count > 0 {
                f(first, count);
            }
        }
    }
}

/// A child reference in one u32: a node index (count 0) or a leaf's first primitive,
/// with the leaf's primitive count in the top four bits (leaves hold at most eight).
const COUNT_SHIFT: u32 = 28;

pub(super) fn pack(child: u32, count: u32) -> u32 {
    assert!(count < 1 << (32 - COUNT_SHIFT) && child < 1 << COUNT_SHIFT, "BVH too large for 32-bit child references");
    child | count << COUNT_SHIFT
}

#[inline(always)]
pub(super) fn unpack(packed: u32) -> (u32, u32) {
    (packed & ((1 << COUNT_SHIFT) - 1), packed >> COUNT_SHIFT)
}

/// Asks the processor to start loading both cache lines of a node.
#[inline(always)]
#[allow(unsafe_code)]
fn prefetch(node: &Node4) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let p = (node as *const Node4).cast::<i8>();
        // SAFETY: a prefetch is only a hint: it never faults, reads nothing into the
        // program and changes no memory, whatever the address; both addresses here lie
        // inside `node`, a live reference (the node is 128 bytes and 64-aligned).
        unsafe {
            _mm_prefetch::<_MM_HINT_T0>(p);
            _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64));
        }
    }
}

/// Asks the processor to start loading the first two cache lines of `items[first]`
/// (a leaf's first triangle pack or top-level entry), three if it is bigger.
#[inline(always)]
#[allow(unsafe_code)]
pub(super) fn prefetch_items<T>(items: &[T], first: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let p = items.as_ptr().wrapping_add(first).cast::<i8>();
        // SAFETY: a prefetch is only a hint: it never faults, reads nothing into the
        // program and changes no memory, whatever the address (even past the slice).
        unsafe {
            _mm_prefetch::<_MM_HINT_T0>(p);
            _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64));
            // A top-level entry holding eight spheres is 192 bytes.
            if std::mem::size_of::<T>() > 128 {
                _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(128));
            }
        }
    }
}

/// Slack on box exit distances. The slab arithmetic rounds, and a ray through the
/// line where two flat boxes meet (a room's wall and ceiling) could otherwise miss a box
/// whose primitive it hits, or cull the box of an equally distant one: the BVH would
/// then pick a different object than testing everything does. A few ulps (relative)
/// cover the error (pbrt multiplies by 1 + 2γ₃ for the same reason).
pub(super) const ROBUST: f32 = 1.0 + 8.0 * f32::EPSILON;

/// Traversal stack entries: enough for trees about ten wide levels deep (three entries a
/// level) before a nested call takes over.
pub(super) const STACK: usize = 32;

impl WideNode for Node4 {
    const WIDTH: usize = 4;

    fn empty() -> Node4 {
        let inf = Vec4::splat(f32::INFINITY);
        Node4 {
            min_x: inf,
            min_y: inf,
            min_z: inf,
            max_x: -inf,
            max_y: -inf,
            max_z: -inf,
            packed: [0; 4],
            _pad: [0; 4],
        }
    }

    fn set_lane(&mut self, lane: usize, b: &Node, child: u32, count: u32) {
        self.min_x[lane] = b.min[0];
        self.min_y[lane] = b.min[1];
        self.min_z[lane] = b.min[2];
        self.max_x[lane] = b.max[0];
        self.max_y[lane] = b.max[1];
        self.max_z[lane] = b.max[2];
        self.packed[lane] = pack(child, count);
    }

    fn packed_mut(&mut self) -> &mut [u32] {
        &mut self.packed
    }

    fn packed(&self) -> &[u32] {
        &self.packed
    }
}

fn area(n: &Node) -> f32 {
    let d = Vec3::from_array(n.max) - Vec3::from_array(n.min);
    d.x * d.y + d.y * d.z + d.z * d.x
}

/// A ray set up for 4-wide box tests: origin and reciprocal direction splatted across
/// lanes, and for each axis which box face it meets first.
struct WideRay {
    org: [Vec4; 3],
    inv: [Vec4; 3],
    /// Per axis, whether the ray runs towards negative coordinates (then it enters
    /// through the max face). Choosing faces by sign, rather than taking min and max of
    /// the two distances, also makes empty lanes (min > max) miss by construction.
    negative: [bool; 3],
}

impl WideRay {
    #[inline]
    fn new(ray: &Ray) -> Self {
        // A zero component would make 0 × ∞ = NaN at a face through the origin; a tiny
        // value of the same sign keeps the arithmetic finite and the answer the same.
        let safe = |d: f32| if d.abs() < 1e-30 { 1e-30f32.copysign(d) } else { d };
        let d = [safe(ray.dir.x), safe(ray.dir.y), safe(ray.dir.z)];
        WideRay {
            org: [Vec4::splat(ray.origin.x), Vec4::splat(ray.origin.y), Vec4::splat(ray.origin.z)],
            inv: d.map(|v| Vec4::splat(1.0 / v)),
            negative: d.map(|v| v < 0.0),
        }
    }

    /// Entry distances of the four boxes and a bit mask of those entered within
    /// `[t_min, t_max]`.
    #[inline(always)]
    fn enter(&self, n: &Node4, t_min: f32, t_max: f32) -> (Vec4, u32) {
        let axis = |lo: Vec4, hi: Vec4, i: usize| {
            let (near, far) = if self.negative[i] { (hi, lo) } else { (lo, hi) };
            ((near - self.org[i]) * self.inv[i], (far - self.org[i]) * self.inv[i])
        };
        let (nx, fx) = axis(n.min_x, n.max_x, 0);
        let (ny, fy) = axis(n.min_y, n.max_y, 1);
        let (nz, fz) = axis(n.min_z, n.max_z, 2);
        let near = nx.max(ny).max(nz.max(Vec4::splat(t_min)));
        let far = fx.min(fy).min(fz.min(Vec4::splat(t_max))) * Vec4::splat(ROBUST);
        (near, near.cmple(far).bitmask())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Aabb;

    fn boxes(n: usize) -> Vec<Aabb> {
        crate::accel::bvh::tests::boxes(n, 0x9e3779b97f4a7c15)
    }

    /// The leaves a wide traversal reaches are those the binary tree reaches.
    #[test]
    fn wide_and_binary_trees_visit_the_same_primitives() {
        for n in [1, 2, 5, 100, 5000] {
            let b = boxes(n);
            let bvh = Bvh::build(&b);
            let wide = Bvh4::from_binary(&bvh);
            let mut s = 7u64;
            for _ in 0..300 {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                let f = |k: u32| ((s >> k) & 0xffff) as f32 / 65535.0;
                let ray = Ray::new(
                    Vec3::new(f(0), f(16), f(32)) * 60.0 - 5.0,
                    Vec3::new(f(8) - 0.5, f(24) - 0.5, f(40) - 0.5),
                );
                let mut a = Vec::new();
                bvh.traverse(&ray, 0.0, f32::INFINITY, |p, t| {
                    a.push(p);
                    Visit::Continue(t)
                });
                let mut w = Vec::new();
                wide.traverse(&ray, 0.0, f32::INFINITY, |range, t| {
                    w.extend(range.map(|i| bvh.indices[i]));
                    Visit::Continue(t)
                });
                a.sort_unstable();
                w.sort_unstable();
                assert_eq!(a, w, "n = {n}");
            }
        }
    }

    #[test]
    fn collapsing_makes_fewer_nodes() {
        let b = boxes(10_000);
        let bvh = Bvh::build(&b);
        let wide = Bvh4::from_binary(&bvh);
        assert!(wide.node_count() * 2 < bvh.nodes.len(), "{} vs {}", wide.node_count(), bvh.nodes.len());
    }
}
