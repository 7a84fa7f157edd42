//! Light buffers (Haines and Greenberg, 1986): for a light with a position, a cube of
//! direction cells around it, each listing the leaf entries of the tree that may lie in
//! its directions, nearest the light first (an opaque mesh not whole but by the leaves
//! of its own tree, [`super::LeafItem::Piece`]). A shadow ray from a point towards the light
//! can meet only what lies in the directions of that point as seen from the light, and
//! nearer the light than the point: it tests that cell's short list, stopping at the
//! first entry farther than the point, in place of a walk from the root of the tree.
//!
//! Every entry that may lie along the segment is in the list (the cells an entry's box
//! covers are worked out conservatively), and each is tested as the walk tests it
//! ([`World::leaf_stops`]), so the answer is the walk's. Where spheres are small beside
//! the cells, a cell lists packs of its own spheres in place of the tree's ([`regroup`]).

mod regroup;

pub(super) use regroup::{Members, Plan};

use super::{LastBlocker, NONE, ShadowLanes, World};
use crate::light::Light;
use crate::math::{Aabb, Ray, Vec3};

/// The cube of cells round one light.
#[derive(Debug)]
pub(super) struct LightBuffer {
    at: Vec3,
    /// Cells along a face's side.
    n: usize,
    /// Per face of the cube, where its cells start in `cells` ([`EMPTY_FACE`] where no
    /// entry lies in its directions: it has no cells).
    faces: [u32; 6],
    /// Per cell of the faces that have them, row by row: where its list starts in
    /// `entries` (above [`LEN_BITS`]) and how long it is (below), [`CROWDED`] where more
    /// than [`MAX_LIST`] entries lie in its directions: its rays walk the tree instead.
    cells: Vec<u32>,
    /// The lists: (leaf entry, its box's distance from the light). The cells that list
    /// one entry alone share one place for it.
    entries: Vec<(u32, f32)>,
    /// Packs of spheres planned for this buffer's cells ([`regroup`]), until they join
    /// the world's leaf entries ([`LightBuffer::place_packs`]).
    packs: Plan,
    /// How many packs the buffer's cells regrouped spheres into (for the tests).
    #[cfg_attr(not(test), allow(dead_code))]
    made: usize,
}

/// Entries a cell lists at most: past that, a walk of the tree is the quicker test.
/// Lists this long still beat the walk, as most rays stop at the first entry farther
/// from the light than their origin (sphereflake, bench/tree_nff.py: docs/performance.md).
const MAX_LIST: u32 = 64;

/// A cell's length takes the low bits of its word, its start the others.
const LEN_BITS: u32 = 7;
const LEN_MASK: u32 = (1 << LEN_BITS) - 1;
const CROWDED: u32 = LEN_MASK;
const _: () = assert!(MAX_LIST < CROWDED);

const EMPTY_FACE: u32 = u32::MAX;

/// A cell's word, while its buffer is built, where it lists one entry alone.
const ALONE: u32 = u32::MAX << LEN_BITS;

/// Entries over all cells a light's buffer may hold, shared places included (eight
/// bytes each, 4 MiB): a light whose buffer would hold more has none. With
/// [`MAX_LIGHTS`], memory for buffers stays under 40 MiB however many lights a scene has
/// (52 MiB with the packs their cells make, [`regroup`]).
const MAX_ENTRIES: usize = 1 << 19;
const _: () = assert!(MAX_ENTRIES < 1 << (32 - LEN_BITS));

/// Lights that get a buffer at most (the first with a position); the others' shadow
/// rays walk the tree.
pub(super) const MAX_LIGHTS: usize = 8;

/// Relative margin on the distances compared, so that rounding never drops an entry.
const SLACK: f32 = 1e-4;

/// Margin on a face's coordinates (which run from -1 to 1), likewise.
const EDGE: f32 = 1e-4;

impl LightBuffer {
    /// Whether lights get buffers over a tree of `entries` leaf entries: not where there
    /// are so few that a walk is short. `WHITTED_LIGHT_BUFFERS=0` in the environment
    /// goes without, to compare.
    pub(super) fn wanted(entries: usize) -> bool {
        LightBuffer::side(entries) > 0 && std::env::var_os("WHITTED_LIGHT_BUFFERS").is_none_or(|v| v != "0")
    }

    /// Per light of `lights`, its buffer over entries with boxes `boxes` (empty boxes
    /// listed nowhere), `n` cells a side ([`LightBuffer::side`]), where it has one: the
    /// first [`MAX_LIGHTS`] with a position may, built in parallel.
    pub(super) fn for_lights(
        lights: &[Light],
        boxes: &[Aabb],
        n: usize,
        members: &Members,
    ) -> Vec<Option<LightBuffer>> {
        use rayon::prelude::*;
        let placed: Vec<usize> =
            (0..lights.len()).filter(|&k| lights[k].position().is_some()).take(MAX_LIGHTS).collect();
        let built: Vec<_> = match n {
            0 => vec![],
            _ => placed.par_iter().map(|&k| LightBuffer::build(lights[k].position()?, boxes, n, members)).collect(),
        };
        let mut buffers: Vec<_> = lights.iter().map(|_| None).collect();
        for (&k, buffer) in placed.iter().zip(built) {
            buffers[k] = buffer;
        }
        buffers
    }

    /// Cells along a face's side for a tree of `entries` leaf entries: none for so
    /// few that a walk is short.
    pub(super) fn side(entries: usize) -> usize {
        if entries < 64 {
            return 0;
        }
        ((4.0 * (entries as f64).sqrt()) as usize).next_power_of_two().clamp(16, 128)
    }

    /// The buffer of a light at `at` over leaf entries with boxes `boxes`, `n` cells a
    /// side; `None` where it would hold more than [`MAX_ENTRIES`] or where more of its
    /// cells would be crowded than listed.
    pub(super) fn build(at: Vec3, boxes: &[Aabb], n: usize, members: &Members) -> Option<LightBuffer> {
        // Shared places come after the lists: each start, up to MAX_ENTRIES plus one per
        // entry, fits its word below ALONE.
        if MAX_ENTRIES + boxes.len() >= (ALONE >> LEN_BITS) as usize {
            return None;
        }
        // Entries nearest the light first, so each cell's list comes out in that order.
        // Empty boxes (meshes listed by their pieces) are in no cell.
        let mut order: Vec<(f32, u32)> = boxes
            .iter()
            .enumerate()
            .filter(|(_, b)| !(b.min.x > b.max.x))
            .map(|(i, b)| (near_distance(at, b), i as u32))
            .collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        // Coarser where finer cells would list too much (objects round the light, in many
        // of its directions); crowded cells only get more so.
        let mut n = n;
        loop {
            match LightBuffer::with_cells(at, boxes, &order, n, members) {
                Err(Full) if n > 16 => n /= 2,
                Err(_) => return None,
                Ok(buffer) => return Some(buffer),
            }
        }
    }

    /// [`LightBuffer::build`] with `n` cells a side, given the entries in `order`.
    fn with_cells(
        at: Vec3,
        boxes: &[Aabb],
        order: &[(f32, u32)],
        n: usize,
        members: &Members,
    ) -> Result<LightBuffer, Unfit> {
        // Each entry's cells, face by face ([`Span`]), worked out once for the three
        // passes below (flake build 3.3 to 2.8 ms at 1 thread: docs/performance.md).
        // Only the faces something lies in front of get cells.
        let mut faces = [EMPTY_FACE; 6];
        let mut spans = Vec::with_capacity(order.len() * 2);
        for (k, &(_, i)) in order.iter().enumerate() {
            each_range(at, &boxes[i as usize], n, |face, us, vs| {
                faces[face] = 0;
                // Cells a side are at most 128 (`LightBuffer::side`), so indices fit a byte.
                let cell = |c: usize| u8::try_from(c).expect("at most 128 cells a side");
                spans.push(Span {
                    k: k as u32,
                    face: face as u8,
                    us: [cell(*us.start()), cell(*us.end())],
                    vs: [cell(*vs.start()), cell(*vs.end())],
                });
            });
        }
        let mut used = 0;
        for face in faces.iter_mut().filter(|f| **f == 0) {
            (*face, used) = (used, used + (n * n) as u32);
        }
        let cell_of = |face: usize, u: usize, v: usize| faces[face] as usize + u * n + v;
        // Count each cell's entries, then give each its place, in the same array (a
        // second one as big was a fifth of the buffers' fresh memory, each page of which
        // a new process pays a page fault for). An entry's rows are counted by their ends
        // (+1 at its first column, -1 past its last), so that a running sum along a row
        // gives each cell's count: a few words an entry rather than one a cell (a floor
        // covers whole faces).
        let mut cells = vec![0u32; used as usize];
        for span in &spans {
            let ([u0, u1], [v0, v1]) = (span.us.map(usize::from), span.vs.map(usize::from));
            if v0 > v1 {
                continue;
            }
            for u in u0..=u1 {
                let row = cell_of(span.face as usize, u, 0);
                cells[row + v0] = cells[row + v0].wrapping_add(1);
                if v1 + 1 < n {
                    cells[row + v1 + 1] = cells[row + v1 + 1].wrapping_sub(1);
                }
            }
        }
        // Cells that list one entry alone (a floor past everything else, as the light
        // sees it) are marked [`ALONE`] here and share one place per entry, given as the
        // lists are filled: one place for all of them, not a copy per cell.
        let (mut sum, mut crowded, mut listed) = (0usize, 0usize, 0usize);
        for row in cells.chunks_mut(n) {
            let mut count = 0u32;
            for cell in row {
                count = count.wrapping_add(*cell);
                *cell = match count {
                    _ if count > MAX_LIST => {
                        crowded += 1;
                        (sum as u32) << LEN_BITS | CROWDED
                    }
                    1 => {
                        listed += 1;
                        ALONE
                    }
                    _ => {
                        listed += (count != 0) as usize;
                        let start = sum as u32;
                        sum += count as usize;
                        start << LEN_BITS
                    }
                };
            }
        }
        // Too many entries, or too many crowded cells for the buffer to pay.
        if sum > MAX_ENTRIES {
            return Err(Full);
        }
        if crowded > listed {
            return Err(Unfit::Crowded);
        }
        let mut entries = vec![(0u32, 0f32); sum];
        // Room for the shared places, so that none moves the lists (for a big array the
        // room is only reserved address space until used).
        entries.reserve_exact(boxes.len());
        // Per entry, its shared place, once it has one.
        let mut alone: Vec<u32> = vec![];
        for span in &spans {
            let (near, i) = order[span.k as usize];
            let ([u0, u1], [v0, v1]) = (span.us.map(usize::from), span.vs.map(usize::from));
            each_of(u0..=u1, v0..=v1, |u, v| {
                let cell = &mut cells[cell_of(span.face as usize, u, v)];
                if *cell == ALONE {
                    if alone.is_empty() {
                        alone.resize(boxes.len(), ALONE);
                    }
                    if alone[i as usize] == ALONE {
                        alone[i as usize] = entries.len() as u32;
                        entries.push((i, near));
                    }
                    *cell = alone[i as usize] << LEN_BITS | 1;
                } else if *cell & LEN_MASK != CROWDED {
                    entries[((*cell >> LEN_BITS) + (*cell & LEN_MASK)) as usize] = (i, near);
                    *cell += 1;
                }
            });
        }
        // The shared places count against the same bound as the lists.
        if entries.len() > MAX_ENTRIES {
            return Err(Full);
        }
        let packs = regroup::regroup(at, n, &faces, &mut cells, &mut entries, order, members);
        entries.shrink_to_fit();
        let made = packs.len();
        Ok(LightBuffer { at, n, faces, cells, entries, packs, made })
    }

    /// How many packs were planned for this buffer's cells, not yet placed.
    pub(super) fn pack_count(&self) -> usize {
        self.packs.len()
    }

    /// How many packs the buffer's cells regrouped spheres into.
    #[cfg(test)]
    pub(super) fn made(&self) -> usize {
        self.made
    }

    /// The packs planned for this buffer's cells, to join the world's leaf entries from
    /// `base` on; the lists name them there from now on.
    pub(super) fn place_packs(&mut self, base: u32) -> Plan {
        for &(start, len) in &self.packs.lists {
            for (at, _) in &mut self.entries[start as usize..(start + len) as usize] {
                if *at & regroup::PACKED != 0 {
                    *at = base + (*at & !regroup::PACKED);
                }
            }
        }
        std::mem::take(&mut self.packs)
    }

    pub(super) fn memory_bytes(&self) -> usize {
        self.cells.capacity() * 4 + self.entries.capacity() * 8
    }

    /// The list of the cell holding the direction from the light to `p`; `None` where
    /// the cell is crowded or there is no direction (`p` at the light, or not finite).
    #[inline(always)]
    pub(super) fn cell_of(&self, p: Vec3) -> Option<&[(u32, f32)]> {
        self.list_of(self.word(self.place(p.to_array())))
    }

    /// [`LightBuffer::cell_of`] for eight points at once, as words ([`LightBuffer::word`]).
    /// The lanes are placed first, then their words read, so that the compiler works
    /// the placing of the eight together (`place` selects rather than branches; with
    /// branches it gained nothing: docs/performance.md).
    #[inline(always)]
    pub(super) fn words_of_lanes(&self, from: &[[f32; 8]; 3]) -> [u32; 8] {
        // Row by row, as the compiler can work them in vector registers.
        let (mut face, mut offset, mut valid) = ([0u32; 8], [0u32; 8], [false; 8]);
        for lane in 0..8 {
            (face[lane], offset[lane], valid[lane]) = self.place([from[0][lane], from[1][lane], from[2][lane]]);
        }
        let mut words = [NO_CELL; 8];
        for lane in 0..8 {
            words[lane] = self.word((face[lane], offset[lane], valid[lane]));
        }
        words
    }

    /// Where the direction from the light to `p` lies: its face, its cell's place
    /// among the face's cells, and whether it has one (not where `p` is the light or
    /// not finite). The one computation of a cell, for one point or eight side by side:
    /// written as selections, without a branch or a checked conversion, so that eight
    /// points' placing compiles to vector instructions (1.6 % of the sphereflake's
    /// instructions, where a lane at a time with `as u32` converted one by one).
    #[inline(always)]
    #[allow(unsafe_code)]
    fn place(&self, p: [f32; 3]) -> (u32, u32, bool) {
        let (n, half, top) = (self.n as u32, 0.5 * self.n as f32, (self.n - 1) as f32);
        let w = [p[0] - self.at.x, p[1] - self.at.y, p[2] - self.at.z];
        let a = w.map(f32::abs);
        let x_major = (a[0] >= a[1]) & (a[0] >= a[2]);
        let y_major = !x_major & (a[1] >= a[2]);
        let (z, along) = (pick(x_major, y_major, a), pick(x_major, y_major, w));
        let u = if x_major { w[1] } else { w[0] };
        let v = if x_major | y_major { w[2] } else { w[1] };
        let face = pick(x_major, y_major, [0, 2, 4]) + u32::from(along < 0.0);
        let scale = half / z;
        // Below 0 or NaN is the first cell, past the last is the last.
        // SAFETY: `max` turns NaN into 0 and `min` caps the value at `top`, so what is
        // converted is finite and in `0..=top`, and `top` (a face's cells a side, less
        // one: at most 127, `LightBuffer::side`) is far below `i32::MAX`.
        let cell = |s: f32| unsafe { (s * scale + half).max(0.0).min(top).to_int_unchecked::<i32>() } as u32;
        // Finite: a NaN compares false.
        let finite = (a[0] < f32::INFINITY) & (a[1] < f32::INFINITY) & (a[2] < f32::INFINITY);
        (face, cell(u) * n + cell(v), (z > 0.0) & finite)
    }

    /// The word of a cell [`LightBuffer::place`] found: its start and length (or
    /// [`CROWDED`]), [`NO_CELL`] where there is no direction, or [`NO_ENTRIES`] where no
    /// entry lies in its face's directions.
    #[inline(always)]
    fn word(&self, (face, offset, valid): (u32, u32, bool)) -> u32 {
        match (valid, self.faces[face as usize]) {
            (false, _) => NO_CELL,
            (true, EMPTY_FACE) => NO_ENTRIES,
            (true, base) => self.cells[base as usize + offset as usize],
        }
    }

    /// The list a word of [`LightBuffer::words_of_lanes`] stands for, as `cell_of`
    /// gives it.
    #[inline(always)]
    pub(super) fn list_of(&self, word: u32) -> Option<&[(u32, f32)]> {
        match word {
            NO_CELL => None,
            NO_ENTRIES => Some(&[]),
            word => {
                let (start, len) = ((word >> LEN_BITS) as usize, word & LEN_MASK);
                (len != CROWDED).then(|| &self.entries[start..start + len as usize])
            }
        }
    }
}

/// Words of [`LightBuffer::words_of_lanes`] that are not cells': no direction, and a
/// face without entries (a cell's word has a length of at most [`CROWDED`], and its
/// start is below [`MAX_ENTRIES`], so it is neither).
const NO_CELL: u32 = u32::MAX;
const NO_ENTRIES: u32 = u32::MAX - 1;
const _: () = assert!(((MAX_ENTRIES as u32) << LEN_BITS | CROWDED) < NO_ENTRIES);

/// The first of `xyz` where `x_major`, the second where `y_major`, else the third: an
/// axis's value chosen by selection, for [`LightBuffer::place`].
#[inline(always)]
fn pick<T>(x_major: bool, y_major: bool, [x, y, z]: [T; 3]) -> T {
    if x_major {
        x
    } else if y_major {
        y
    } else {
        z
    }
}

/// Why a buffer was not made with so many cells.
enum Unfit {
    /// It would hold more than [`MAX_ENTRIES`].
    Full,
    /// More of its cells would be crowded than listed.
    Crowded,
}
use Unfit::Full;

/// The distance from `p` to the nearest point of `b` (0 inside it).
fn near_distance(p: Vec3, b: &Aabb) -> f32 {
    (b.min - p).max(p - b.max).max(Vec3::ZERO).length()
}

/// Lane `lane` of three rows of eight (a point or direction of [`ShadowLanes`]).
#[inline(always)]
fn lane_of(rows: &[[f32; 8]; 3], lane: usize) -> Vec3 {
    Vec3::new(rows[0][lane], rows[1][lane], rows[2][lane])
}

/// Calls `f` with each cell (face, row, column) whose directions from `at` may meet
/// box `b`.
#[cfg(test)]
fn each_cell(at: Vec3, b: &Aabb, n: usize, mut f: impl FnMut(usize, usize, usize)) {
    each_range(at, b, n, |face, us, vs| each_of(us, vs, |u, v| f(face, u, v)));
}

/// Calls `f` with each (row, column) of the ranges.
#[inline(always)]
fn each_of(us: std::ops::RangeInclusive<usize>, vs: std::ops::RangeInclusive<usize>, mut f: impl FnMut(usize, usize)) {
    for u in us {
        for v in vs.clone() {
            f(u, v);
        }
    }
}

/// The cells of one face an entry's box may meet ([`each_range`]): rows `us` and
/// columns `vs`, both inclusive, for the entry `k` of the buffer's order.
struct Span {
    k: u32,
    face: u8,
    us: [u8; 2],
    vs: [u8; 2],
}

/// Calls `f` with each face whose directions from `at` may meet box `b`, and the
/// ranges of rows and columns of cells there that may.
fn each_range(
    at: Vec3,
    b: &Aabb,
    n: usize,
    mut f: impl FnMut(usize, std::ops::RangeInclusive<usize>, std::ops::RangeInclusive<usize>),
) {
    let (lo, hi) = (b.min - at, b.max - at);
    let unbounded = !(lo.is_finite() && hi.is_finite());
    // Per axis, the box's least distance from the light's plane across it. (As arrays:
    // a `Vec3` indexed by a variable takes a branch per read.)
    let least = lo.max(-hi).max(Vec3::ZERO).to_array();
    let (lo, hi) = (lo.to_array(), hi.to_array());
    // A box well inside one face's directions (|x| < z throughout, with a margin no
    // rounding crosses) is on that face alone: its ranges at once, not six faces' tests
    // (most of a sphereflake's spheres).
    let far: [f32; 3] = std::array::from_fn(|k| lo[k].abs().max(hi[k].abs()));
    let axis = if far[0] >= far[1] && far[0] >= far[2] {
        0
    } else if far[1] >= far[2] {
        1
    } else {
        2
    };
    let (ua, va) = [(1, 2), (0, 2), (0, 1)][axis];
    let (face, z0, z1) =
        if lo[axis] > 0.0 { (2 * axis, lo[axis], hi[axis]) } else { (2 * axis + 1, -hi[axis], -lo[axis]) };
    let within = z0 * (1.0 - 4.0 * EDGE);
    if !unbounded && z0 > 0.0 && far[ua] < within && far[va] < within {
        let range = |x0: f32, x1: f32| {
            let min = if x0 >= 0.0 { x0 / z1 } else { x0 / z0 };
            let max = if x1 <= 0.0 { x1 / z1 } else { x1 / z0 };
            (min - EDGE, max + EDGE)
        };
        let (u, v) = (range(lo[ua], hi[ua]), range(lo[va], hi[va]));
        let cell = |s: f32| (((s.clamp(-1.0, 1.0) + 1.0) * 0.5 * n as f32) as usize).min(n - 1);
        f(face, cell(u.0)..=cell(u.1), cell(v.0)..=cell(v.1));
        return;
    }
    for face in 0..6 {
        if unbounded {
            // In every cell.
            f(face, 0..=n - 1, 0..=n - 1);
            continue;
        }
        let axis = face / 2;
        let (ua, va) = [(1, 2), (0, 2), (0, 1)][axis];
        // How far along the face's axis the box reaches, facing that way.
        let (z0, z1) = if face % 2 == 0 { (lo[axis], hi[axis]) } else { (-hi[axis], -lo[axis]) };
        // Behind the light, or wholly past one of the face's edges (|x / z| > 1), as the
        // range below would find, cheaply first.
        let past = z1 * (1.0 + EDGE);
        if !(z1 > 0.0) || least[ua] > past || least[va] > past {
            continue;
        }
        // Over the box's points in front of the light along this axis (0 < z <= z1),
        // the range of x / z for x in [x0, x1]: the extremes come at the nearest or
        // farthest z, unbounded where the box reaches the light's plane.
        let range = |x0: f32, x1: f32| {
            let min = if x0 >= 0.0 {
                x0 / z1
            } else if z0 > 0.0 {
                x0 / z0
            } else {
                f32::NEG_INFINITY
            };
            let max = if x1 <= 0.0 {
                x1 / z1
            } else if z0 > 0.0 {
                x1 / z0
            } else {
                f32::INFINITY
            };
            (min - EDGE, max + EDGE)
        };
        let (u, v) = (range(lo[ua], hi[ua]), range(lo[va], hi[va]));
        // Not on this face where all of it lies past one of its edges: a small box off the
        // light's axes lies in front of three faces but on one (clamped to the edge, the
        // others listed it in their edge cells).
        if u.0 > 1.0 || u.1 < -1.0 || v.0 > 1.0 || v.1 < -1.0 {
            continue;
        }
        let cell = |s: f32| (((s.clamp(-1.0, 1.0) + 1.0) * 0.5 * n as f32) as usize).min(n - 1);
        f(face, cell(u.0)..=cell(u.1), cell(v.0)..=cell(v.1));
    }
}

impl World<'_> {
    /// [`World::transmittance_hinted`] for a shadow ray towards light `light` (its index
    /// in the scene), through that light's buffer where it has one.
    #[inline]
    pub fn transmittance_towards(&self, light: usize, ray: &Ray, t_max: f32, blocker: &mut LastBlocker) -> f32 {
        // One call of each path, so that the walk is inlined here once.
        let list = match self.light_buffers.get(light) {
            Some(Some(buffer)) if ray.origin.is_finite() && ray.dir.is_finite() => buffer.cell_of(ray.origin),
            _ => None,
        };
        match list {
            Some(list) => self.transmittance_listed(list, ray, t_max, blocker, NONE),
            None => self.transmittance_hinted(ray, t_max, blocker),
        }
    }

    /// [`World::transmittance_towards`] for eight shadow rays, one after another with
    /// `blocker` carried on: the same answers, with the lanes' cells found together
    /// ([`LightBuffer::words_of_lanes`]). A flat object is not tested against the rays
    /// that leave it (`rays.leaving`), as they cannot meet it (the SPD floor: nearly a
    /// fifth of the sphereflake's list tests).
    #[allow(unsafe_code)]
    #[inline]
    pub fn transmittance_towards_lanes(&self, light: usize, rays: &ShadowLanes, blocker: &mut LastBlocker) -> [f32; 8] {
        let ShadowLanes { from, dirs, t_max, live, .. } = *rays;
        let mut visible = [0.0; 8];
        let buffer = match self.light_buffers.get(light) {
            Some(Some(buffer)) => buffer,
            _ => {
                for lane in crate::math::lanes::set_lanes(live) {
                    let ray = Ray { origin: lane_of(from, lane), dir: lane_of(dirs, lane) };
                    visible[lane] = self.transmittance_hinted(&ray, t_max[lane], blocker);
                }
                return visible;
            }
        };
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only where the processor has AVX2.
            return unsafe { self.listed_lanes_avx2(buffer, rays, blocker) };
        }
        self.listed_lanes(buffer, rays, blocker)
    }

    /// [`World::listed_lanes`] built for AVX2: the cells' placing on eight lanes at
    /// once, and the sphere packs' AVX test inlined in the lists' walks.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn listed_lanes_avx2(&self, buffer: &LightBuffer, rays: &ShadowLanes, blocker: &mut LastBlocker) -> [f32; 8] {
        self.listed_lanes(buffer, rays, blocker)
    }

    /// The eight shadow rays through `buffer`, their cells found together. A lane
    /// whose origin has no cell (not finite, or at the light) walks the tree; every
    /// other lane's direction, from a finite point other than the light, is finite.
    #[inline(always)]
    fn listed_lanes(&self, buffer: &LightBuffer, rays: &ShadowLanes, blocker: &mut LastBlocker) -> [f32; 8] {
        let ShadowLanes { from, dirs, t_max, live, leaving } = *rays;
        let words = buffer.words_of_lanes(from);
        let mut visible = [0.0; 8];
        for lane in crate::math::lanes::set_lanes(live) {
            let ray = Ray { origin: lane_of(from, lane), dir: lane_of(dirs, lane) };
            visible[lane] = match buffer.list_of(words[lane]) {
                Some(list) => {
                    debug_assert!(ray.origin.is_finite() && ray.dir.is_finite(), "{ray:?}");
                    self.list(list, &ray, t_max[lane], blocker, leaving[lane])
                }
                None => self.transmittance_hinted(&ray, t_max[lane], blocker),
            };
        }
        visible
    }

    /// [`World::transmittance_hinted`] over the entries of a light buffer's cell `list`:
    /// the last blocker first, then the list.
    #[allow(unsafe_code)]
    #[inline]
    fn transmittance_listed(
        &self,
        list: &[(u32, f32)],
        ray: &Ray,
        t_max: f32,
        blocker: &mut LastBlocker,
        leaving: u32,
    ) -> f32 {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only where the processor has AVX2.
            return unsafe { self.list_avx2(list, ray, t_max, blocker, leaving) };
        }
        self.list(list, ray, t_max, blocker, leaving)
    }

    /// The last blocker, then the entries of a cell's `list` nearer the light than the
    /// ray's origin, against the ray, until one stops the light.
    #[inline(always)]
    fn list(&self, list: &[(u32, f32)], ray: &Ray, t_max: f32, blocker: &mut LastBlocker, leaving: u32) -> f32 {
        if blocker.0 != u32::MAX && self.hint_stops(ray, t_max, blocker) {
            return 0.0;
        }
        let limit = t_max * (1.0 + SLACK);
        let mut light = 1.0f64;
        for &(at, near) in list {
            if near > limit {
                break;
            }
            if self.entry_stops_noted(at as usize, ray, t_max, &mut light, blocker, leaving) {
                return 0.0;
            }
        }
        // The light got through: the next ray, likely from nearby, will too more often
        // than the old blocker stops it (sphereflake: of 518 k hints tried, 197 k
        // settled a ray; tried only after a blocked ray, 281 k and 183 k).
        if light == 1.0 {
            *blocker = LastBlocker::default();
        }
        light as f32
    }

    /// [`World::list`] built for AVX2, so that the sphere packs' AVX test is inlined as
    /// in the walk's leaves (sphereflake 1-2 % faster than a call per pack:
    /// docs/performance.md, "Light buffers"). `list` is the portable path.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn list_avx2(&self, list: &[(u32, f32)], ray: &Ray, t_max: f32, blocker: &mut LastBlocker, leaving: u32) -> f32 {
        self.list(list, ray, t_max, blocker, leaving)
    }
}

#[cfg(test)]
mod tests {
    use super::super::LeafItem;
    use super::*;

    /// Each cell lists what lies in its directions, nearest the light first, whether its
    /// list has a place of its own or shares one (a floor under a few boxes is alone in
    /// most of the cells below the light): the same lists as placing every entry in
    /// every cell it covers, one copy each, in far fewer entries.
    #[test]
    fn cells_list_their_entries_in_order_with_lone_entries_shared() {
        let at = Vec3::new(0.3, 0.2, 4.0);
        let mut boxes = vec![Aabb { min: Vec3::new(-20.0, -20.0, -0.5), max: Vec3::new(20.0, 20.0, -0.5) }];
        for k in 0..80 {
            let c = Vec3::new((k % 9) as f32 - 4.0, (k / 9) as f32 - 4.0, (k % 5) as f32 * 0.4);
            boxes.push(Aabb { min: c - Vec3::splat(0.2), max: c + Vec3::splat(0.2) });
        }
        let n = 32;
        let members = Members { ranges: &[], spheres: &[], width: 8, pack: |_| LeafItem::Other(0) };
        let buffer = LightBuffer::build(at, &boxes, n, &members).expect("a buffer");
        // The lists as placing each entry in each cell it covers makes them.
        let mut order: Vec<(f32, u32)> =
            boxes.iter().enumerate().map(|(i, b)| (near_distance(at, b), i as u32)).collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut want = vec![vec![]; 6 * n * n];
        for &(near, i) in &order {
            each_cell(at, &boxes[i as usize], n, |face, u, v| want[(face * n + u) * n + v].push((i, near)));
        }
        let (mut alone, mut copies) = (0, 0);
        for face in 0..6 {
            for cell in 0..n * n {
                let want = &want[face * n * n + cell];
                let got = match buffer.faces[face] {
                    EMPTY_FACE => &[][..],
                    base => buffer.list_of(buffer.cells[base as usize + cell]).expect("no crowded cell here"),
                };
                assert_eq!(got, &want[..], "face {face}, cell {cell}");
                alone += (want.len() == 1) as usize;
                copies += want.len();
            }
        }
        // Without sharing, the entries would be the copies.
        assert!(alone > 1000, "{alone} cells list one entry");
        assert!(buffer.entries.len() <= copies - alone + boxes.len(), "{} entries for {copies}", buffer.entries.len());
    }
}
