//! Eight rays down the 8-wide tree as one packet: camera rays, and shadow rays from
//! neighbouring points, share most of their node visits.

use super::*;

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
    /// another order). A leaf goes to `leaf(rays, range, t_max)` once, with the rays (a
    /// bit each) that reach it, whose bounds in `t_max` it lowers: a leaf entry with an
    /// eight-lane test takes them together, and [`each_ray`] makes a closure for one ray
    /// at a time. It must not depend on the order, as a nearest hit with ties to the lower
    /// id does not. Where neighbouring camera rays share most of their nodes, or all leave
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
        mut leaf: impl FnMut(u32, std::ops::Range<usize>, &mut [f32; 8]),
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
        leaf: &mut impl FnMut(u32, std::ops::Range<usize>, &mut [f32; 8]),
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
                leaf(mask, first..first + count as usize, &mut t_max);
            } else {
                let n = &self.nodes[index as usize];
                let bound = load(&t_max);
                // Hit children, nearest last, by the entry distance of their first ray.
                let mut order = [(0f32, 0u32, 0u32); 8];
                let mut near = [[0f32; 8]; 8];
                let mut m = 0;
                // Only the children the packet as a whole may enter are tested ray by ray.
                let mut maybe = may_enter!(p, n, t_min, farthest(bound, mask));
                while maybe != 0 {
                    let c = maybe.trailing_zeros() as usize;
                    maybe &= maybe - 1;
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
                                let mut go_on = |range, t| {
                                    let mut bound = t_max;
                                    bound[k] = t;
                                    leaf(1 << k, range, &mut bound);
                                    Visit::Continue(bound[k])
                                };
                                let entry = (n.packed[c], near[c][k]);
                                let mut t = t_max[k];
                                self.walk::<true, T>(rays[k], entry, t_min, &mut t, items, &mut go_on);
                                t_max[k] = t;
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
                let mut maybe = may_enter!(p, n, t_min, farthest(bound, mask));
                while maybe != 0 {
                    let c = maybe.trailing_zeros() as usize;
                    maybe &= maybe - 1;
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
    /// Per axis, for [`may_enter!`]: the live rays' origin that enters a box last and the
    /// one that leaves it first (the greatest and the least where the rays head up the
    /// axis, else the other way round), and their least and greatest inverse direction.
    /// Meaningless unless `spanned`.
    span: [[f32; 4]; 3],
    /// Whether every live ray's origin is finite, which `span` needs.
    spanned: bool,
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
        let inv = d.map(|d| _mm256_div_ps(one, d));
        let chosen = _mm256_castsi256_ps(lanes_of(live));
        // x - x is 0 for a finite x, NaN for an infinite or NaN one.
        let finite = |v: __m256| {
            _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_EQ_OQ>(_mm256_sub_ps(v, v), _mm256_setzero_ps())) as u32
        };
        let spanned = finite(org[0]) & finite(org[1]) & finite(org[2]) & live == live;
        let range = |v: __m256| {
            let lo = _mm256_blendv_ps(_mm256_set1_ps(f32::INFINITY), v, chosen);
            let hi = _mm256_blendv_ps(_mm256_set1_ps(f32::NEG_INFINITY), v, chosen);
            let lo = _mm256_cvtss_f32(everywhere(lo, |a, b| _mm256_min_ps(a, b)));
            (lo, _mm256_cvtss_f32(everywhere(hi, |a, b| _mm256_max_ps(a, b))))
        };
        let span = [0, 1, 2].map(|i| {
            let ((o_lo, o_hi), (i_lo, i_hi)) = (range(org[i]), range(inv[i]));
            if neg[i] == 0 { [o_hi, o_lo, i_lo, i_hi] } else { [o_lo, o_hi, i_lo, i_hi] }
        });
        Some(Packet8 { org, inv, near_row: [0, 1, 2].map(|i| if neg[i] != 0 { 3 + i } else { i }), span, spanned })
    }
}

/// A bit for each child of node `$n` that some ray of packet `$p` may enter within
/// `[t_min, t_far]` (`$t_far` in every lane, at least each ray's bound), all eight
/// children in lanes: the packet's pretest, so that the children it misses as a whole
/// cost no test ray by ray. Conservative: a ray's `enter_packet!` entry distance on an
/// axis is `(bound - origin) · inverse`, two rounded operations, each monotone in each
/// operand (rounding is monotone); a packet's inverses on an axis share one sign, so the
/// difference is least, where they are positive, for the greatest origin, and the
/// product then least at one end of the inverses' range; the exit distance likewise
/// greatest. With finite origins no value is NaN (an inverse is finite and not 0), so
/// every child a ray enters gets its bit. A macro, as `enter_packet!` is.
macro_rules! may_enter {
    ($p:expr, $n:expr, $t_min:expr, $t_far:expr) => {{
        let (p, n): (&Packet8, &Node8) = ($p, $n);
        if !p.spanned {
            0xff
        } else {
            let axis = |i: usize| {
                let [o_enter, o_leave, i_lo, i_hi] = p.span[i].map(|x| _mm256_set1_ps(x));
                let row = p.near_row[i];
                let far_row = if row >= 3 { row - 3 } else { row + 3 };
                let a = _mm256_sub_ps(load(&n.bounds[row]), o_enter);
                let b = _mm256_sub_ps(load(&n.bounds[far_row]), o_leave);
                let least = _mm256_min_ps(_mm256_mul_ps(a, i_lo), _mm256_mul_ps(a, i_hi));
                (least, _mm256_max_ps(_mm256_mul_ps(b, i_lo), _mm256_mul_ps(b, i_hi)))
            };
            let (nx, fx) = axis(0);
            let (ny, fy) = axis(1);
            let (nz, fz) = axis(2);
            let near = _mm256_max_ps(_mm256_max_ps(nx, ny), _mm256_max_ps(nz, _mm256_set1_ps($t_min)));
            let far =
                _mm256_mul_ps(_mm256_min_ps(_mm256_min_ps(fx, fy), _mm256_min_ps(fz, $t_far)), _mm256_set1_ps(ROBUST));
            _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_NGT_UQ>(near, far)) as u32
        }
    }};
}
use may_enter;

/// All-ones in the lanes of `mask` (a bit each), zero in the others.
#[target_feature(enable = "avx2")]
#[inline]
fn lanes_of(mask: u32) -> __m256i {
    let bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(mask as i32), bits), bits)
}

/// `f` (a lane-wise minimum or maximum) over all eight lanes of `v`, in every lane.
#[target_feature(enable = "avx2")]
#[inline]
fn everywhere(v: __m256, f: impl Fn(__m256, __m256) -> __m256) -> __m256 {
    let v = f(v, _mm256_permute2f128_ps::<1>(v, v));
    let v = f(v, _mm256_permute_ps::<0b01_00_11_10>(v));
    f(v, _mm256_permute_ps::<0b10_11_00_01>(v))
}

/// The greatest of `bound`'s lanes of `mask` (a bit each), in every lane. A NaN lane is
/// left out: its ray enters nothing (`enter_packet!`'s compare fails), and `maxps`
/// would let it hide the other lanes.
#[target_feature(enable = "avx2")]
#[inline]
fn farthest(bound: __m256, mask: u32) -> __m256 {
    let chosen = _mm256_and_ps(_mm256_castsi256_ps(lanes_of(mask)), _mm256_cmp_ps::<_CMP_ORD_Q>(bound, bound));
    everywhere(_mm256_blendv_ps(_mm256_set1_ps(f32::NEG_INFINITY), bound, chosen), |a, b| _mm256_max_ps(a, b))
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

/// A [`Bvh8::nearest_packet`] leaf closure from one for a ray at a time: `leaf(k, range,
/// t_max)`, ray `k`'s leaf, returning its new bound.
#[inline(always)]
pub fn each_ray(
    mut leaf: impl FnMut(usize, std::ops::Range<usize>, f32) -> f32,
) -> impl FnMut(u32, std::ops::Range<usize>, &mut [f32; 8]) {
    move |mut rays, range, t_max| {
        while rays != 0 {
            let k = rays.trailing_zeros() as usize;
            rays &= rays - 1;
            t_max[k] = leaf(k, range.clone(), t_max[k]);
        }
    }
}

#[cfg(test)]
mod pretest {
    use super::*;
    use glam::Vec3;

    /// The packet's pretest never leaves out a child that one of its live rays enters
    /// (`enter_packet!`, the test each ray's walk makes): packets from one origin and
    /// from scattered origins (reflection rays), directions with zero components, rays
    /// that start inside boxes, flat and empty boxes, bounds that differ by lane, dead
    /// lanes holding NaN rays. It must also leave out most of what no ray enters, or it
    /// would not pay.
    #[test]
    #[allow(unsafe_code)]
    fn packet_pretest_keeps_every_child_a_ray_enters() {
        if !std::is_x86_feature_detected!("avx2") {
            eprintln!("no AVX2 here: the packet pretest is not tested");
            return;
        }
        // SAFETY: AVX2 is present (checked above), all `check` needs.
        let (entered, missed, left_out) = unsafe { check() };
        assert!(entered > 10_000 && missed > 20_000, "{entered} {missed}");
        assert!(left_out * 2 > missed, "the pretest left out {left_out} of {missed} children no ray enters");
    }

    #[target_feature(enable = "avx2")]
    fn check() -> (u32, u32, u32) {
        let mut s = 11u64;
        let mut next = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 40) as f32 / (1u64 << 24) as f32
        };
        let (mut entered, mut missed, mut left_out) = (0, 0, 0);
        for round in 0..20_000 {
            let origin = Vec3::new(next(), next(), next()) * 20.0 - 10.0;
            let scatter = [0.0, 0.05, 2.0][round % 3];
            let dir = Vec3::new(next(), next(), next()) - 0.5;
            let live = if round % 4 == 0 { 0xff } else { (next() * 256.0) as u32 | 1 };
            let rays: [Ray; 8] = std::array::from_fn(|k| {
                if live >> k & 1 == 0 && round % 8 == 1 {
                    return Ray { origin: Vec3::NAN, dir: Vec3::NAN };
                }
                let o = origin + (Vec3::new(next(), next(), next()) - 0.5) * scatter;
                let mut d = (dir.abs() + Vec3::new(next(), next(), next()) * 0.1).copysign(dir);
                if round % 5 == 2 && k == 3 {
                    d.y = 0.0f32.copysign(dir.y);
                }
                Ray::new(o, d)
            });
            let Some(p) = Packet8::new(&rays.each_ref(), live) else { continue };
            let mut n = Node8::empty();
            for c in 0..7 {
                // Near the packet's path, or anywhere.
                let jitter = (Vec3::new(next(), next(), next()) - 0.5) * 6.0;
                let along = origin + dir.normalize() * (next() * 30.0 - 5.0);
                let center = if c < 4 { along + jitter } else { Vec3::new(next(), next(), next()) * 24.0 - 12.0 };
                let mut half = Vec3::new(next(), next(), next()) * [0.2, 1.0, 4.0][c % 3];
                if c == 5 {
                    half.z = 0.0;
                }
                for axis in 0..3 {
                    n.bounds[axis][c] = center[axis] - half[axis];
                    n.bounds[3 + axis][c] = center[axis] + half[axis];
                }
                n.packed[c] = 1 + c as u32;
            }
            let t_max: [f32; 8] = std::array::from_fn(|k| [f32::INFINITY, 8.0, 30.0, 0.5][(k + round) % 4]);
            let bound = load(&t_max);
            let maybe = may_enter!(&p, &n, 0.0, farthest(bound, live));
            for c in 0..8 {
                let hit = enter_packet!(&p, &n, c, 0.0, bound).1 & live;
                assert!(hit == 0 || maybe >> c & 1 != 0, "round {round}: child {c} entered by {hit:#b}, left out");
                if hit != 0 {
                    entered += 1;
                } else {
                    missed += 1;
                    left_out += (maybe >> c & 1 == 0) as u32;
                }
            }
        }
        (entered, missed, left_out)
    }
}
