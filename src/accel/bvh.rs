//! A binary bounding volume hierarchy built with the binned surface area heuristic,
//! stored flat: 32-byte nodes, two per cache line, children side by side and found by
//! index, primitives reordered so every leaf is one contiguous range.
//!
//! The tree knows nothing of what its primitives are: it is built from their boxes and
//! traversed with a closure that tests one primitive. The closure is a generic
//! parameter, so each use is compiled into its own loop with no dynamic dispatch.

use crate::math::{Aabb, Ray, Vec3};
use glam::Vec3A;

/// A node: its box, and either its two children (`count == 0`; they sit at
/// `first` and `first + 1`) or a leaf's primitives (`indices[first..first + count]`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub struct Node {
    pub min: [f32; 3],
    pub first: u32,
    pub max: [f32; 3],
    pub count: u32,
}

const _: () = assert!(std::mem::size_of::<Node>() == 32);

impl Node {
    #[inline]
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }

    fn bounds(&self) -> Aabb {
        Aabb { min: Vec3::from_array(self.min), max: Vec3::from_array(self.max) }
    }
}

#[derive(Clone, Debug, Default)]
pub struct Bvh {
    /// Root first, then child pairs.
    pub nodes: Vec<Node>,
    /// Primitive ids in leaf order.
    pub indices: Vec<u32>,
}

/// Deepest tree the fixed traversal stack allows; the builder stops splitting there.
pub const MAX_DEPTH: usize = 64;
/// Largest leaf the SAH may choose to keep rather than split.
const MAX_LEAF: usize = 8;
const BINS: usize = 16;
/// SAH cost of visiting a node, relative to one primitive test, for packed primitives
/// (mesh triangles, sphere clouds). A split is costed by primitives and a leaf by packs,
/// so a node of at most [`MAX_LEAF`] primitives always becomes a leaf and this value
/// only shapes the upper tree. Costing splits by packs too was measured (node cost 0.5
/// to 4, cube-sphere 1M): ray rates within ±3 % of this, so it was not kept.
const MESH_TRAVERSAL_COST: f32 = 4.0;
/// Scene objects (quads, cylinders, cones) each cost several box tests, and a room's
/// walls have flat boxes that ordered traversal culls well: small leaves pay there.
const OBJECT_TRAVERSAL_COST: f32 = 0.5;
/// Subtrees smaller than this are built on the current thread. Scenes of a few thousand
/// objects split their top levels between threads too: at 8192 the sphereflake (7,382
/// objects) was built on one thread, 3.9 ms against 2.9 ms now (medians, 2 threads).
/// The tree is the same either way (a subtree's nodes are laid out as one thread would).
const PARALLEL_MIN: usize = 1024;

/// What a traversal closure tells the loop after testing a primitive.
pub enum Visit {
    /// Keep going; the closest hit so far is now at this distance.
    Continue(f32),
    /// Nothing more is needed (an opaque occluder was found).
    Stop,
}

/// A ray prepared for box tests: reciprocal direction computed once.
#[derive(Clone, Copy)]
struct RayBox {
    origin: Vec3A,
    inv_dir: Vec3A,
}

impl RayBox {
    #[inline]
    fn new(ray: &Ray) -> Self {
        RayBox { origin: ray.origin.into(), inv_dir: Vec3A::ONE / Vec3A::from(ray.dir) }
    }

    /// Entry distance into the node's box if the ray meets it within `(t_min, t_max)`.
    #[inline(always)]
    fn enter(&self, n: &Node, t_min: f32, t_max: f32) -> Option<f32> {
        let t1 = (Vec3A::from_array(n.min) - self.origin) * self.inv_dir;
        let t2 = (Vec3A::from_array(n.max) - self.origin) * self.inv_dir;
        let near = t1.min(t2).max_element().max(t_min);
        let far = t1.max(t2).min_element().min(t_max) * (1.0 + 8.0 * f32::EPSILON);
        (near <= far).then_some(near)
    }
}

impl Bvh {
    /// Builds a tree over primitives given by their boxes. Deterministic: the same boxes
    /// give the same tree whatever the thread count.
    pub fn build(bounds: &[Aabb]) -> Bvh {
        Bvh::build_packed(bounds, 1)
    }

    /// Like [`Bvh::build`] for primitives that leaves will test `pack` at a time: the
    /// SAH costs a leaf by its number of packs, so leaves tend to fill them.
    pub fn build_packed(bounds: &[Aabb], pack: usize) -> Bvh {
        let mut indices: Vec<u32> = (0..bounds.len() as u32).collect();
        if bounds.is_empty() {
            return Bvh { nodes: vec![Node { min: [0.0; 3], first: 0, max: [0.0; 3], count: 0 }], indices };
        }
        let b = Builder::new(bounds, pack);
        let root = b.range(&indices);
        let nodes = b.subtree(&mut indices, root, 0, 0);
        Bvh { nodes, indices }
    }

    /// Bytes held by the tree (nodes and index list).
    pub fn memory_bytes(&self) -> usize {
        self.nodes.capacity() * std::mem::size_of::<Node>() + self.indices.capacity() * 4
    }

    pub fn bounds(&self) -> Aabb {
        self.nodes[0].bounds()
    }

    /// Visits, nearest box first, every leaf primitive whose box the ray enters before
    /// the closest hit so far; `test(primitive, t_max)` tests one and says how to go on.
    /// Renders traverse the 4-wide tree made from this one ([`super::Bvh4`]); this
    /// plain traversal is the reference the wide one is tested against.
    #[inline]
    pub fn traverse(&self, ray: &Ray, t_min: f32, t_max: f32, mut test: impl FnMut(u32, f32) -> Visit) {
        traverse_nodes(&self.nodes, ray, t_min, t_max, |range, mut t_cur| {
            for &prim in &self.indices[range] {
                match test(prim, t_cur) {
                    Visit::Continue(t) => t_cur = t,
                    Visit::Stop => return Visit::Stop,
                }
            }
            Visit::Continue(t_cur)
        })
    }
}

/// The traversal loop: nearest child first, the farther one pushed on a fixed stack
/// only if the ray enters it, boxes beyond the closest hit skipped. `leaf(range,
/// t_max)` handles the primitives `range` of a leaf (positions in leaf order).
#[inline]
fn traverse_nodes(
    nodes: &[Node],
    ray: &Ray,
    t_min: f32,
    mut t_max: f32,
    mut leaf: impl FnMut(std::ops::Range<usize>, f32) -> Visit,
) {
    let rb = RayBox::new(ray);
    if nodes.len() == 1 && nodes[0].count == 0 {
        return; // empty tree
    }
    if rb.enter(&nodes[0], t_min, t_max).is_none() {
        return;
    }
    let mut stack = [0u32; MAX_DEPTH];
    let mut sp = 0;
    let mut node = &nodes[0];
    loop {
        if node.is_leaf() {
            let first = node.first as usize;
            match leaf(first..first + node.count as usize, t_max) {
                Visit::Continue(t) => t_max = t,
                Visit::Stop => return,
            }
        } else {
            let (a, b) = (&nodes[node.first as usize], &nodes[node.first as usize + 1]);
            match (rb.enter(a, t_min, t_max), rb.enter(b, t_min, t_max)) {
                (Some(ta), Some(tb)) => {
                    let (near, far) = if ta <= tb { (a, node.first + 1) } else { (b, node.first) };
                    stack[sp] = far;
                    sp += 1;
                    node = near;
                    continue;
                }
                (Some(_), None) => {
                    node = a;
                    continue;
                }
                (None, Some(_)) => {
                    node = b;
                    continue;
                }
                (None, None) => {}
            }
        }
        // Pop the next node still in front of the closest hit.
        loop {
            if sp == 0 {
                return;
            }
            sp -= 1;
            let n = &nodes[stack[sp] as usize];
            if rb.enter(n, t_min, t_max).is_some() {
                node = n;
                break;
            }
        }
    }
}

/// A box in SIMD registers, for the builder's inner loops.
#[derive(Clone, Copy, Debug)]
struct Box3 {
    min: Vec3A,
    max: Vec3A,
}

impl Box3 {
    const EMPTY: Box3 = Box3 { min: Vec3A::splat(f32::INFINITY), max: Vec3A::splat(f32::NEG_INFINITY) };

    #[inline(always)]
    fn union(self, o: Box3) -> Box3 {
        Box3 { min: self.min.min(o.min), max: self.max.max(o.max) }
    }

    #[inline(always)]
    fn grow(self, p: Vec3A) -> Box3 {
        Box3 { min: self.min.min(p), max: self.max.max(p) }
    }

    #[inline(always)]
    fn area(&self) -> f32 {
        let d = (self.max - self.min).max(Vec3A::ZERO);
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }
}

struct Builder {
    bounds: Vec<Box3>,
    centroids: Vec<Vec3A>,
    /// Primitives a leaf tests at once.
    pack: usize,
    traversal_cost: f32,
}

/// What the builder knows of a range of primitives before deciding how to split it.
#[derive(Clone, Copy)]
struct Range {
    bounds: Box3,
    centroids: Box3,
}

/// A split found by the binned SAH, with the boxes of its two sides.
struct Split {
    axis: usize,
    /// Bins `< bin` go left.
    bin: usize,
    cost: f32,
    left: Box3,
    right: Box3,
    left_count: usize,
}

impl Builder {
    /// SAH cost of testing `n` primitives in a leaf.
    #[inline]
    fn leaf_cost(&self, n: usize) -> f32 {
        n.div_ceil(self.pack) as f32
    }

    fn new(bounds: &[Aabb], pack: usize) -> Builder {
        let bounds: Vec<Box3> = bounds.iter().map(|b| Box3 { min: b.min.into(), max: b.max.into() }).collect();
        let centroids = bounds.iter().map(|b| 0.5 * (b.min + b.max)).collect();
        let traversal_cost = if pack > 1 { MESH_TRAVERSAL_COST } else { OBJECT_TRAVERSAL_COST };
        Builder { bounds, centroids, pack: pack.max(1), traversal_cost }
    }

    fn range(&self, idx: &[u32]) -> Range {
        idx.iter().fold(Range { bounds: Box3::EMPTY, centroids: Box3::EMPTY }, |r, &i| Range {
            bounds: r.bounds.union(self.bounds[i as usize]),
            centroids: r.centroids.grow(self.centroids[i as usize]),
        })
    }

    fn node(r: &Range, first: usize, count: usize) -> Node {
        Node { min: r.bounds.min.to_array(), first: first as u32, max: r.bounds.max.to_array(), count: count as u32 }
    }

    /// Builds the subtree over `idx` (which starts at `offset` in the full index list)
    /// into a node list whose root is at 0.
    fn subtree(&self, idx: &mut [u32], r: Range, offset: usize, depth: usize) -> Vec<Node> {
        if idx.len() < PARALLEL_MIN {
            let mut nodes = Vec::with_capacity(idx.len());
            nodes.push(Builder::node(&r, offset, idx.len()));
            self.split_sequential(&mut nodes, 0, idx, r, offset, depth);
            return nodes;
        }
        let Some((mid, lr, rr)) = self.partition(idx, &r, depth) else {
            return vec![Builder::node(&r, offset, idx.len())];
        };
        let (l, rt) = idx.split_at_mut(mid);
        let (left, right) =
            rayon::join(|| self.subtree(l, lr, offset, depth + 1), || self.subtree(rt, rr, offset + mid, depth + 1));
        // Lay out: root, the two child roots, then the rest of each subtree.
        let mut nodes = Vec::with_capacity(1 + left.len() + right.len());
        nodes.push(Node { count: 0, ..Builder::node(&r, 1, 0) });
        let left_shift = 3 - 1;
        let right_shift = 3 + (left.len() - 1) - 1;
        let relink = |mut n: Node, shift: usize| {
            if !n.is_leaf() {
                n.first += shift as u32;
            }
            n
        };
        nodes.push(relink(left[0], left_shift));
        nodes.push(relink(right[0], right_shift));
        nodes.extend(left[1..].iter().map(|&n| relink(n, left_shift)));
        nodes.extend(right[1..].iter().map(|&n| relink(n, right_shift)));
        nodes
    }

    fn split_sequential(
        &self,
        nodes: &mut Vec<Node>,
        at: usize,
        idx: &mut [u32],
        r: Range,
        offset: usize,
        depth: usize,
    ) {
        let Some((mid, lr, rr)) = self.partition(idx, &r, depth) else {
            return;
        };
        let (l, rt) = idx.split_at_mut(mid);
        let first = nodes.len();
        nodes.push(Builder::node(&lr, offset, l.len()));
        nodes.push(Builder::node(&rr, offset + mid, rt.len()));
        nodes[at].first = first as u32;
        nodes[at].count = 0;
        self.split_sequential(nodes, first, l, lr, offset, depth + 1);
        self.split_sequential(nodes, first + 1, rt, rr, offset + mid, depth + 1);
    }

    /// Reorders `idx` into two non-empty halves and returns where the right one starts
    /// with what is known of each half, or `None` when a leaf is better (or the depth
    /// limit is reached).
    fn partition(&self, idx: &mut [u32], r: &Range, depth: usize) -> Option<(usize, Range, Range)> {
        let n = idx.len();
        if n <= 1 || depth + 1 >= MAX_DEPTH {
            return None;
        }
        // A split costs at least a node visit: where a leaf costs no more, it stays a
        // leaf whatever the bins say, so they need not be filled (most calls of a packed
        // build are such small ranges).
        if n <= MAX_LEAF && self.leaf_cost(n) <= self.traversal_cost {
            return None;
        }
        let split = self.best_split(idx, r);
        let mid = match &split {
            Some(s) if s.cost < self.leaf_cost(n) || n > MAX_LEAF => {
                let (lo, axis) = (r.centroids.min[s.axis], s.axis);
                let k = BINS as f32 / (r.centroids.max[axis] - lo);
                let bin_of = |i: u32| (((self.centroids[i as usize][axis] - lo) * k) as usize).min(BINS - 1);
                partition_in_place(idx, |&i| bin_of(i) < s.bin)
            }
            Some(_) => return None,
            // All centroids coincide: no plane separates them; split by count if too many.
            None if n > MAX_LEAF => n / 2,
            None => return None,
        };
        // Binning can round every centroid into one side; fall back to halves.
        let mid = if mid > 0 && mid < n {
            mid
        } else if n > MAX_LEAF {
            n / 2
        } else {
            return None;
        };
        let (l, rt) = idx.split_at(mid);
        // The SAH bins already give each side's box; only the centroid boxes need a pass.
        let centroids = |part: &[u32]| part.iter().fold(Box3::EMPTY, |b, &i| b.grow(self.centroids[i as usize]));
        match split {
            // The partition followed the bins, so their boxes describe the two sides.
            Some(s) if mid == s.left_count => Some((
                mid,
                Range { bounds: s.left, centroids: centroids(l) },
                Range { bounds: s.right, centroids: centroids(rt) },
            )),
            _ => Some((mid, self.range(l), self.range(rt))),
        }
    }

    /// Bins the centroids along all three axes in one pass and costs every plane
    /// between bins with the surface area heuristic.
    fn best_split(&self, idx: &[u32], r: &Range) -> Option<Split> {
        let extent = r.centroids.max - r.centroids.min;
        let k = Vec3A::splat(BINS as f32) / extent;
        let mut boxes = [[Box3::EMPTY; BINS]; 3];
        let mut counts = [[0u32; BINS]; 3];
        for &i in idx {
            let c = self.centroids[i as usize];
            let b = self.bounds[i as usize];
            // Clamped as floats, three axes at once, then cast to i32: the same bins as
            // clamping each axis's cast to usize, for 5 % fewer instructions a build. A
            // NaN (zero extent) casts to 0 whether or not the clamp kept it: bin 0.
            let f = ((c - r.centroids.min) * k).max(Vec3A::ZERO).min(Vec3A::splat((BINS - 1) as f32));
            let bins = f.as_ivec3().to_array();
            for axis in 0..3 {
                let bin = bins[axis] as usize;
                boxes[axis][bin] = boxes[axis][bin].union(b);
                counts[axis][bin] += 1;
            }
        }
        let parent_area = r.bounds.area().max(f32::MIN_POSITIVE);
        let mut best: Option<Split> = None;
        for axis in 0..3 {
            if !(extent[axis] > 0.0) {
                continue;
            }
            // Sweep from the right, then from the left, to cost each of the BINS-1 planes.
            let mut right_box = [Box3::EMPTY; BINS];
            let mut right_count = [0u32; BINS];
            let (mut acc, mut cnt) = (Box3::EMPTY, 0);
            for b in (1..BINS).rev() {
                acc = acc.union(boxes[axis][b]);
                cnt += counts[axis][b];
                right_box[b] = acc;
                right_count[b] = cnt;
            }
            let (mut acc, mut cnt) = (Box3::EMPTY, 0);
            for b in 1..BINS {
                // Past an empty bin the plane splits as the one before it, at the same
                // cost, which the strict comparison below would not take: skip it (most
                // planes of a small node).
                if counts[axis][b - 1] == 0 {
                    continue;
                }
                acc = acc.union(boxes[axis][b - 1]);
                cnt += counts[axis][b - 1];
                if cnt == 0 || right_count[b] == 0 {
                    continue;
                }
                let cost = self.traversal_cost
                    + (acc.area() * cnt as f32 + right_box[b].area() * right_count[b] as f32) / parent_area;
                if best.as_ref().is_none_or(|s| cost < s.cost) {
                    best = Some(Split { axis, bin: b, cost, left: acc, right: right_box[b], left_count: cnt as usize });
                }
            }
        }
        best
    }
}

/// Moves the elements for which `left` holds to the front; returns how many there are.
fn partition_in_place(v: &mut [u32], left: impl Fn(&u32) -> bool) -> usize {
    let mut i = 0;
    for j in 0..v.len() {
        if left(&v[j]) {
            v.swap(i, j);
            i += 1;
        }
    }
    i
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// `n` random boxes in a 100-unit cube.
    pub(crate) fn boxes(n: usize, seed: u64) -> Vec<Aabb> {
        let mut s = seed;
        let mut r = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 40) as f32 / (1u64 << 24) as f32
        };
        (0..n)
            .map(|_| {
                let c = Vec3::new(r(), r(), r()) * 100.0;
                let e = Vec3::new(r(), r(), r()) + Vec3::splat(0.01);
                Aabb { min: c - e, max: c + e }
            })
            .collect()
    }

    /// Every primitive appears once, and every node's box holds its subtree.
    fn check(bvh: &Bvh, bounds: &[Aabb]) {
        let mut seen = vec![false; bounds.len()];
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let n = &bvh.nodes[i];
            let nb = n.bounds();
            let inside = |b: &Aabb| nb.min.cmple(b.min).all() && nb.max.cmpge(b.max).all();
            if n.is_leaf() {
                for &p in &bvh.indices[n.first as usize..(n.first + n.count) as usize] {
                    assert!(!seen[p as usize], "primitive {p} twice");
                    seen[p as usize] = true;
                    assert!(inside(&bounds[p as usize]));
                }
            } else {
                for c in [n.first as usize, n.first as usize + 1] {
                    assert!(inside(&bvh.nodes[c].bounds()));
                    stack.push(c);
                }
            }
        }
        assert!(seen.iter().all(|&s| s), "a primitive is missing");
    }

    #[test]
    fn small_and_parallel_builds_are_complete_and_nested() {
        for n in [1, 2, 3, 17, 1000, 30_000] {
            let b = boxes(n, n as u64 + 1);
            check(&Bvh::build(&b), &b);
        }
    }

    #[test]
    fn identical_boxes_still_make_bounded_leaves() {
        let b = vec![Aabb { min: Vec3::ZERO, max: Vec3::ONE }; 100];
        let bvh = Bvh::build(&b);
        check(&bvh, &b);
        assert!(bvh.nodes.iter().all(|n| n.count as usize <= MAX_LEAF));
    }

    /// `partition` makes a range of at most `MAX_LEAF` a leaf without binning it when a
    /// leaf costs no more than a node visit: no split of such a range may cost less.
    #[test]
    fn small_ranges_left_unbinned_would_not_have_been_split() {
        let mut checked = 0;
        for pack in [1, 4, 8] {
            for seed in 0..300u64 {
                let b = boxes(2 + seed as usize % (MAX_LEAF - 1), seed * 7 + pack as u64);
                let builder = Builder::new(&b, pack);
                let idx: Vec<u32> = (0..b.len() as u32).collect();
                if builder.leaf_cost(idx.len()) > builder.traversal_cost {
                    continue;
                }
                checked += 1;
                if let Some(s) = builder.best_split(&idx, &builder.range(&idx)) {
                    assert!(
                        !(s.cost < builder.leaf_cost(idx.len())),
                        "pack {pack}, {} boxes: split cost {}",
                        b.len(),
                        s.cost
                    );
                }
            }
        }
        assert_eq!(checked, 600, "the packed builds' small ranges");
    }

    #[test]
    fn build_is_deterministic_across_thread_counts() {
        let b = boxes(50_000, 9);
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap().install(|| Bvh::build(&b));
        let four = rayon::ThreadPoolBuilder::new().num_threads(4).build().unwrap().install(|| Bvh::build(&b));
        assert_eq!(one.nodes, four.nodes);
        assert_eq!(one.indices, four.indices);
    }

    #[test]
    fn subtrees_built_on_other_threads_are_laid_out_as_one_thread_would() {
        for (n, pack) in [(3000, 1), (5000, 8), (PARALLEL_MIN, 1)] {
            let b = boxes(n, 4);
            let parallel = Bvh::build_packed(&b, pack);
            // The same build with every level split on this thread.
            let builder = Builder::new(&b, pack);
            let mut indices: Vec<u32> = (0..n as u32).collect();
            let root = builder.range(&indices);
            let mut nodes = vec![Builder::node(&root, 0, n)];
            builder.split_sequential(&mut nodes, 0, &mut indices, root, 0, 0);
            assert_eq!(parallel.nodes, nodes, "{n} boxes");
            assert_eq!(parallel.indices, indices, "{n} boxes");
        }
    }

    #[test]
    fn traversal_visits_every_box_the_ray_crosses() {
        let b = boxes(5000, 3);
        let bvh = Bvh::build(&b);
        let ray = Ray::new(Vec3::new(-10.0, 50.0, 50.0), Vec3::new(1.0, 0.05, -0.02));
        let rb = RayBox::new(&ray);
        let mut visited = vec![false; b.len()];
        bvh.traverse(&ray, 0.0, f32::INFINITY, |p, t| {
            visited[p as usize] = true;
            Visit::Continue(t)
        });
        for (i, bb) in b.iter().enumerate() {
            let n = Node { min: bb.min.to_array(), first: 0, max: bb.max.to_array(), count: 1 };
            if rb.enter(&n, 0.0, f32::INFINITY).is_some() {
                assert!(visited[i], "box {i} crossed but not visited");
            }
        }
    }
}
