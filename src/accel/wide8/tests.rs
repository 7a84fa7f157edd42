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
                Ray::new(Vec3::new(f(0), f(16), f(32)) * 60.0 - 5.0, Vec3::new(f(8) - 0.5, f(24) - 0.5, f(40) - 0.5))
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
            let leaf = each_ray(|k, range, t| {
                assert!(live >> k & 1 != 0, "a dead lane's leaf");
                nearest(&rays[k], range, t, &mut got[k])
            });
            let walked = eight.nearest_packet(rays.each_ref(), live, 0.0, t_max, &[0u8; 0], leaf);
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
    assert!(overflowed > 100 && blocked_rays > 50 && passed_rays > 200, "{overflowed} {blocked_rays} {passed_rays}");
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
                Ray::new(Vec3::new(f(0), f(16), f(32)) * 60.0 - 5.0, Vec3::new(f(8) - 0.5, f(24) - 0.5, f(40) - 0.5))
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
            let ray =
                Ray::new(Vec3::new(f(0), f(16), f(32)) * 60.0 - 5.0, Vec3::new(f(8) - 0.5, f(24) - 0.5, f(40) - 0.5));
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
