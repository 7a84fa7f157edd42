//! Spheres regrouped by cell. The tree packs spheres that lie near each other, but a
//! pack's box spans more of a light's directions than most of its spheres do: of the
//! packs a sphereflake's cell lists, about two spheres of eight lie in the cell. Where a
//! cell's own spheres, packed anew (roughly nearest the light first), make fewer packs
//! than the tree's packs it lists, the cell lists those new packs instead (sphereflake:
//! 9 % fewer instructions a render; docs/performance.md, stop 58).

use super::{CROWDED, EMPTY_FACE, LEN_BITS, LEN_MASK, Span, each_range, near_distance};
use crate::accel::LeafItem;
use crate::geometry::Sphere;
use crate::math::Vec3;

/// The spheres of the tree's packs, for [`regroup`].
pub(in crate::accel) struct Members<'a> {
    /// Per leaf entry, the range of its spheres in `spheres`; none past the end, or
    /// an empty range, where the entry is not a pack of spheres.
    pub ranges: &'a [(u32, u32)],
    /// Each sphere with its object index.
    pub spheres: &'a [(Sphere, u32)],
    /// Spheres a pack holds at most.
    pub width: usize,
    /// A pack of up to `width` spheres, as a leaf entry.
    pub pack: fn(&[(Sphere, u32)]) -> LeafItem,
}

impl Members<'_> {
    /// Whether leaf entry `at` is a pack of spheres.
    fn is_pack(&self, at: u32) -> bool {
        self.range(at).is_some()
    }

    /// The range of leaf entry `at`'s spheres in `spheres`, where it is a pack of them.
    fn range(&self, at: u32) -> Option<(u32, u32)> {
        self.ranges.get(at as usize).copied().filter(|&(start, end)| start < end)
    }
}

/// The packs a buffer's cells regroup spheres into, each a run of places in
/// [`Members::spheres`], made into leaf entries only as they join the world's (each
/// made once, where it stays: 0.4 MiB a sphereflake's light, fresh memory that a new
/// process faults in page by page).
#[derive(Debug, Default)]
pub(in crate::accel) struct Plan {
    spheres: Vec<u32>,
    /// Where each pack's run ends in `spheres`.
    ends: Vec<u32>,
    /// The lists that name packs: (start, length) in the buffer's entries.
    pub(super) lists: Vec<(u32, u32)>,
}

impl Plan {
    pub(in crate::accel) fn len(&self) -> usize {
        self.ends.len()
    }

    /// Pack `k`, made of `members`' spheres.
    pub(in crate::accel) fn pack(&self, k: usize, members: &Members) -> LeafItem {
        let from = if k == 0 { 0 } else { self.ends[k - 1] as usize };
        let run = &self.spheres[from..self.ends[k] as usize];
        // (A run holds at most `members.width` spheres, 4 or 8.)
        let mut pack = [members.spheres[0]; 8];
        for (slot, &i) in pack.iter_mut().zip(run) {
            *slot = members.spheres[i as usize];
        }
        (members.pack)(&pack[..run.len()])
    }
}

/// A list entry that names one of the light's new packs (by its place among them) until
/// they join the world's leaf entries ([`super::LightBuffer::place_packs`]).
pub(super) const PACKED: u32 = 1 << 31;

/// New packs a light makes at most (192 bytes each, 1.5 MiB): past that, cells keep
/// the tree's packs.
const MAX_PACKS: usize = 1 << 13;

/// Cells a sphere lies in, on average, at most for a light's cells to be regrouped.
const MAX_CELLS_A_SPHERE: usize = 4;

/// A cell that is not regrouped, in the counts below.
const SKIP: u32 = u32::MAX;

/// Regroups the spheres of the cells where that makes fewer packs: rewrites those
/// cells' lists in place (each only gets shorter), with entries [`PACKED`] for the new
/// packs, whose plan it returns. `cells` and `entries` are a buffer's, for a light at `at`
/// with `n` cells a side and faces `faces`.
pub(super) fn regroup(
    at: Vec3,
    n: usize,
    faces: &[u32; 6],
    cells: &mut [u32],
    entries: &mut [(u32, f32)],
    order: &[(f32, u32)],
    members: &Members,
) -> Plan {
    let spheres = members.spheres;
    if spheres.is_empty() {
        return Plan::default();
    }
    // A first look at the spheres' size beside the cells, from at most 1,024 of them (the
    // test below, on the spheres that matter, comes after a pass over every cell).
    let (step, mut looked, mut pairs) = (spheres.len().div_ceil(1024), 0, 0);
    for (sphere, _) in spheres.iter().step_by(step) {
        looked += 1;
        each_range(at, &sphere.bounds(), n, |_, us, vs| pairs += us.count() * vs.count());
    }
    if pairs > MAX_CELLS_A_SPHERE * looked {
        return Plan::default();
    }
    // The cells that may be regrouped: those listing two entries or more, one of them a
    // pack, in order, with where each row's start among them (counted below by their
    // place here, not in an array as big as the cells: 1.2 MB for a sphereflake's three
    // lights, which a new process faults in page by page). Only the spheres of the
    // packs they list are placed below (a sphereflake of 66 k spheres lists most of them
    // in crowded cells, whose rays walk the tree).
    let mut candidates: Vec<u32> = vec![];
    let mut wanted = vec![false; members.ranges.len()];
    let mut rows = vec![0u32; cells.len() / n + 1];
    for (row, words) in cells.chunks(n).enumerate() {
        rows[row] = candidates.len() as u32;
        for (v, &word) in words.iter().enumerate() {
            let (start, len) = ((word >> LEN_BITS) as usize, word & LEN_MASK);
            if len < 2 || len == CROWDED {
                continue;
            }
            let list = &entries[start..start + len as usize];
            if list.iter().any(|&(i, _)| members.is_pack(i)) {
                candidates.push((row * n + v) as u32);
                for &(i, _) in list {
                    if let Some(wanted) = wanted.get_mut(i as usize) {
                        *wanted = true;
                    }
                }
            }
        }
    }
    rows[cells.len() / n] = candidates.len() as u32;
    // Each sphere's distance from the light and its cells, pack by pack in the order of
    // the packs' distances (`order`, the buffer's), so that each cell's spheres come
    // roughly nearest first (sorting them all was a sixth of this work). Most spheres
    // lie on one face: room for an eighth more (a sphereflake's then stays under the
    // size for which glibc maps fresh memory and unmaps it after).
    let mut near = vec![0f32; spheres.len()];
    let mut spans = Vec::with_capacity(spheres.len() + spheres.len() / 8);
    let mut placed = 0;
    for &(_, i) in order {
        let Some((start, end)) = members.range(i).filter(|_| wanted[i as usize]) else { continue };
        placed += (end - start) as usize;
        for k in start..end {
            let b = spheres[k as usize].0.bounds();
            near[k as usize] = near_distance(at, &b);
            each_range(at, &b, n, |face, us, vs| {
                // A sphere's pack's box holds its box, so its faces have cells.
                if faces[face] == EMPTY_FACE {
                    return;
                }
                let cell = |c: usize| u8::try_from(c).expect("at most 128 cells a side");
                spans.push(Span {
                    k,
                    face: face as u8,
                    us: [cell(*us.start()), cell(*us.end())],
                    vs: [cell(*vs.start()), cell(*vs.end())],
                });
            });
        }
    }
    // Regrouping pays where spheres are small beside the cells, each in a few (a pack of
    // them then spans many more cells than each sphere): not where they cover many
    // cells each, whose regrouping costs the build more than it saves the render
    // (bench/mixed_nff.py: 1,001 spheres in some 17 cells each, build +3.7 ms, render
    // -2.8; the sphereflake's in 2.3: docs/performance.md, stop 58).
    let pairs: usize =
        spans.iter().map(|s| (1 + usize::from(s.us[1] - s.us[0])) * (1 + usize::from(s.vs[1] - s.vs[0]))).sum();
    if pairs > MAX_CELLS_A_SPHERE * placed {
        return Plan::default();
    }
    // Each span's candidate cells (their places among the candidates), found once by a
    // search in each of its rows, for the count here and the slots below.
    let (mut met, mut ends) = (Vec::with_capacity(spans.len() * 2), Vec::with_capacity(spans.len()));
    for span in &spans {
        let ([u0, u1], [v0, v1]) = (span.us.map(u32::from), span.vs.map(u32::from));
        for u in u0..=u1 {
            let row = (faces[span.face as usize] / n as u32 + u) as usize;
            let (first, last) = (rows[row] as usize, rows[row + 1] as usize);
            let base = row as u32 * n as u32;
            let from = first + candidates[first..last].partition_point(|&c| c < base + v0);
            let within = candidates[from..last].iter().take_while(|&&c| c <= base + v1).count();
            met.extend(from as u32..(from + within) as u32);
        }
        ends.push(met.len() as u32);
    }
    // Each candidate's spheres counted.
    let mut count = vec![0u32; candidates.len()];
    for &k in &met {
        count[k as usize] += 1;
    }
    // The cells to regroup, each given its place among the spheres' slots.
    let (mut chosen, mut slots) = (Vec::with_capacity(candidates.len()), 0u32);
    for (k, &c) in candidates.iter().enumerate() {
        let (word, spheres) = (cells[c as usize], std::mem::replace(&mut count[k], SKIP));
        let (start, len) = ((word >> LEN_BITS) as usize, word & LEN_MASK);
        let listed = entries[start..start + len as usize].iter().filter(|&&(i, _)| members.is_pack(i)).count();
        if (spheres as usize).div_ceil(members.width) < listed {
            count[k] = slots;
            chosen.push((c, slots, spheres, k as u32));
            slots += spheres;
        }
    }
    let mut slot = vec![0u32; slots as usize];
    let mut from = 0;
    for (span, &end) in spans.iter().zip(&ends) {
        for &k in &met[from..end as usize] {
            let k = k as usize;
            if count[k] != SKIP {
                slot[count[k] as usize] = span.k;
                count[k] += 1;
            }
        }
        from = end as usize;
    }
    // Each chosen cell's spheres packed. A cell with the same spheres as the chosen cell
    // before it in its row, or above it, shares its packs (large spheres cover many
    // cells alike: bench/mixed_nff.py). Its other entries are merged in by distance.
    for (at, &(.., k)) in chosen.iter().enumerate() {
        count[k as usize] = at as u32;
    }
    let chosen_at = |c: usize| match candidates.binary_search(&(c as u32)) {
        Ok(k) if count[k] != SKIP => Some(count[k] as usize),
        _ => None,
    };
    let mut packs = Plan::default();
    let mut firsts = vec![u32::MAX; chosen.len()];
    let mut list = Vec::with_capacity(64);
    let group_of = |&(_, from, count, _): &(u32, u32, u32, u32)| &slot[from as usize..(from + count) as usize];
    for (at, &(c, from, size, _)) in chosen.iter().enumerate() {
        let c = c as usize;
        let group = &slot[from as usize..(from + size) as usize];
        let (u, v) = (c % (n * n) / n, c % n);
        let shared = [(v > 0, c.wrapping_sub(1)), (u > 0, c.wrapping_sub(n))].into_iter().find_map(|(inside, c)| {
            let other = chosen_at(c).filter(|_| inside)?;
            (firsts[other] != u32::MAX && group_of(&chosen[other]) == group).then(|| firsts[other])
        });
        let first = match shared {
            Some(first) => first,
            None if packs.len() + group.len().div_ceil(members.width) > MAX_PACKS => break,
            None => {
                let first = packs.len() as u32;
                for chunk in group.chunks(members.width) {
                    packs.spheres.extend_from_slice(chunk);
                    packs.ends.push(packs.spheres.len() as u32);
                }
                first
            }
        };
        firsts[at] = first;
        let (start, len) = ((cells[c] >> LEN_BITS) as usize, (cells[c] & LEN_MASK) as usize);
        // The cell's other entries and its packs, by distance (a pack's is its nearest
        // sphere's).
        list.clear();
        list.extend(entries[start..start + len].iter().copied().filter(|&(i, _)| !members.is_pack(i)));
        for (k, chunk) in group.chunks(members.width).enumerate() {
            let d = chunk.iter().map(|&k| near[k as usize]).fold(f32::INFINITY, f32::min);
            list.push((PACKED | (first + k as u32), d));
        }
        list.sort_by(|a, b| a.1.total_cmp(&b.1));
        debug_assert!(list.len() < len);
        entries[start..start + list.len()].copy_from_slice(&list);
        cells[c] = (start as u32) << LEN_BITS | list.len() as u32;
        packs.lists.push((start as u32, list.len() as u32));
    }
    packs
}
