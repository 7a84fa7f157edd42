//! A batch of camera rays traced level by level, the way every ray of a render goes.
//!
//! Each level's rays ask the [`World`] for their hits together, grouped by where they
//! come from (the camera, or the object and side they leave), so that the acceleration
//! structure can answer a coherent group at once: in a small scene it tests only the
//! objects the group may meet, eight rays at a time; in a large one it walks its tree.
//! Then every light is looked at from all of the level's hits together (its shadow rays
//! tested as a batch too), the hits' own colours are added to their samples, weighted,
//! and the rays they send on make the next level.
//!
//! Memory is bounded by the batch, not by depth or samples per pixel: a wave takes at
//! most [`WAVE_RAYS`] camera rays, and each sample may have at most [`PER_SAMPLE`] rays
//! in a level; rays past that are traced at once, depth first, by
//! [`Integrator::trace_path`]. Whether a ray goes on in the wave or depth first depends
//! only on its own sample, and each sample adds its colours in an order fixed by its own
//! rays, so a pixel's colour does not depend on which other pixels share its wave.

use super::{
    FrameBlock, Integrator, LightFrames, PackedSurface, Path, RayStats, Shading, lane_of, towards_light_lanes,
};
use crate::accel::{LastBlocker, NONE, ShadowLanes, World};
use crate::geometry::Hit;
use crate::math::{Aabb, Color, Ray, Vec3};
use glam::Vec3A;

/// Camera rays in one wave at most: callers split larger batches.
pub const WAVE_RAYS: usize = 1024;

/// Rays one sample may have in one level of a wave; the rest go depth first.
pub const PER_SAMPLE: u16 = 16;

// A level's rays are told apart by 16 bits in their sort keys (`Wave::send_on`).
const _: () = assert!(WAVE_RAYS * PER_SAMPLE as usize <= 1 << 16);

/// A ray found by [`World::closest`] and friends: the hit and the object's index.
type Found = (Ray, Option<(Hit, u32)>);

/// The buffers of a wave, kept from one batch to the next so that tracing allocates
/// nothing once they have grown.
#[derive(Default)]
pub struct Wave {
    /// The level's rays and what they hit.
    level: Vec<Found>,
    /// Per ray of the level: its weight and its sample (index into the colours).
    paths: Vec<(Color, u32)>,
    surfaces: Vec<PackedSurface>,
    shading: Vec<Shading>,
    /// Per object hit where lights may change the colour, a box round the points those
    /// hits send their shadow rays from.
    boxes: Vec<(u32, Aabb)>,
    frames: LightFrames,
    /// Objects that may shadow the level's hits from one light.
    blockers: Vec<u32>,
    /// Objects a group of rays may meet.
    seen: Vec<u32>,
    /// Rays sent on from the level: (object left, 0 reflected or 1 transmitted), the
    /// ray, its weight and its sample.
    sent: Vec<((u32, u32), Ray, Color, u32)>,
    /// The sent rays in the order they make the next level, as [`group_key`]s with
    /// their place in `sent` in the low 16 bits.
    order: Vec<u64>,
    /// Per sample, its rays in the next level.
    budget: Vec<u16>,
    /// Rays waiting in [`Integrator::trace_path`].
    stack: Vec<Path>,
}

impl Wave {
    /// The colours seen along camera rays `rays` (at most [`WAVE_RAYS`]), into `colors`,
    /// one per ray. `cone`, the apex and edge directions of a cone that holds every ray
    /// ([`crate::camera::CameraRig::cone`]), lets a small scene test only what it sees.
    pub fn trace(
        &mut self,
        integrator: &Integrator,
        rays: &[Ray],
        cone: Option<(Vec3, [Vec3; 4])>,
        colors: &mut Vec<Color>,
        stats: &mut RayStats,
    ) {
        debug_assert!(rays.len() <= WAVE_RAYS);
        let world = integrator.world();
        // Filled by the first level's shading, not zeroed first (up to 16 KiB a wave:
        // `memset`, mostly this one, was 1.6 % of the room's time in `perf`).
        colors.clear();
        self.level.clear();
        self.paths.clear();
        self.level.extend(rays.iter().map(|&ray| (ray, None)));
        self.paths.extend((0..rays.len() as u32).map(|sample| (Color::ONE, sample)));
        stats.primary += rays.len() as u64;
        match cone {
            Some((apex, edges)) if world.seen_from(apex, edges, &mut self.seen) => {
                world.closest_among_each(&self.seen, &mut self.level)
            }
            _ => find_hits(world, &mut self.level, &mut self.seen),
        }
        let mut depth = 1;
        loop {
            self.shade_level(integrator, colors, depth == 1, stats);
            if depth >= integrator.max_depth || !self.send_on(integrator, depth, colors, stats) {
                break;
            }
            depth += 1;
        }
    }

    /// The level's hits shaded: surfaces, every light looked at from all of them, and
    /// each ray's colour (its hit's own, or the background) added to its sample; on the
    /// `first` level (the camera rays, one a sample, in order) `colors` is filled.
    fn shade_level(&mut self, integrator: &Integrator, colors: &mut Vec<Color>, first: bool, stats: &mut RayStats) {
        let Wave { level, paths, surfaces, shading, boxes, frames, blockers, .. } = self;
        debug_assert_eq!(level.len(), paths.len());
        let world = integrator.world();
        surfaces.clear();
        shading.clear();
        boxes.clear();
        frames.clear();
        // Boxes round the hits only where the world can use them to cull shadow rays.
        let culls = world.culls() && !integrator.one_sided;
        let absorbs = world.absorbs();
        // Hits come in runs on one object: each run's box is grown on its own, then merged.
        // (Its corners as Vec3A: one instruction for each of min and max, not three.)
        let mut run: Option<(u32, Vec3A, Vec3A)> = None;
        for (k, (ray, found)) in level.iter().enumerate() {
            let Some((hit, index)) = found else {
                surfaces.push(PackedSurface::default());
                shading.push(Shading::default());
                continue;
            };
            let surface = integrator.surface(ray, hit, *index);
            surfaces.push(surface);
            let surface = surface.get();
            if absorbs {
                paths[k].0 = integrator.arriving(paths[k].0, ray, hit.t, &surface, *index);
            }
            let s = integrator.shading(ray, &surface, *index);
            shading.push(s);
            if !s.lit {
                continue;
            }
            frames.push(k as u32, *index, (s.from, s.n));
            if !culls {
                continue;
            }
            // The box holds where the shadow rays start.
            let p = Vec3A::from(s.from);
            match &mut run {
                Some((o, lo, hi)) if o == index => (*lo, *hi) = (lo.min(p), hi.max(p)),
                _ => {
                    if let Some(done) = run.replace((*index, p, p)) {
                        merge_box(boxes, done);
                    }
                }
            }
        }
        if let Some(done) = run {
            merge_box(boxes, done);
        }
        for (index, light) in world.scene().lights.iter().enumerate() {
            // One-sided shading may send a shadow ray from a surface's back through the
            // surface itself, which the culling assumes it does not.
            // A light without a position (directional) is tested against everything.
            let culled = culls && light.position().is_some_and(|p| world.may_shadow(boxes, p, blockers));
            let blockers = culled.then_some(&blockers[..]);
            // What blocked the last of this light's shadow rays, to try first.
            let mut last = LastBlocker::default();
            let color = light.color();
            for FrameBlock { nodes, lanes, objects, from, normal } in frames.blocks() {
                let seen = towards_light_lanes(light, from, normal);
                // Every lane's falloff, then those of the lanes lit from the front (the
                // others' is 0): without a branch a lane, for the lanes to go together.
                let falloff: [f32; 8] = std::array::from_fn(|lane| {
                    let falloff = light.falloff(lane_of(&seen.l, lane), seen.distance[lane]);
                    let front = (seen.n_dot_l[lane] > 0.0) & (lane < *lanes);
                    std::hint::select_unpredictable(front, falloff, 0.0)
                });
                let live = (0..8).fold(0u32, |live, lane| live | ((falloff[lane] > 0.0) as u32) << lane);
                // The objects the rays leave, on the light's side where shading is two-sided.
                let leaving = if integrator.one_sided { [NONE; 8] } else { *objects };
                let rays = ShadowLanes { from, dirs: &seen.l, t_max: seen.distance, live, leaving };
                let visible = visible_lanes(world, index, blockers, &rays, &mut last);
                stats.shadow += u64::from(live.count_ones());
                // The lanes lit: not those behind their surfaces, nor those past the block.
                for lane in crate::math::lanes::set_lanes(live) {
                    let k = nodes[lane];
                    let material = integrator.material(objects[lane]);
                    let l = lane_of(&seen.l, lane);
                    // Through absorbing glass the light takes its colour, ray by ray.
                    let visible = match world.absorbs() {
                        false => Color::splat(visible[lane]),
                        true => {
                            world.transmittance_color(&Ray { origin: lane_of(from, lane), dir: l }, seen.distance[lane])
                        }
                    };
                    let lit = (l, seen.n_dot_l[lane], visible * falloff[lane]);
                    integrator.add_light(&mut shading[k as usize], material, level[k as usize].0.dir, lit, color);
                }
            }
        }
        let seen = level.iter().zip(paths.iter()).zip(shading.iter()).map(|(((_, found), &(weight, sample)), s)| {
            let color = match found {
                None => integrator.background(),
                Some((_, index)) => integrator.own_color(s, integrator.material(*index)),
            };
            (sample, weight * color)
        });
        debug_assert!(!first || (colors.is_empty() && paths.iter().enumerate().all(|(k, p)| p.1 as usize == k)));
        match first {
            // (Added to zero as on the other levels, so that the sums are the same.)
            true => colors.extend(seen.map(|(_, color)| Color::ZERO + color)),
            false => seen.for_each(|(sample, color)| colors[sample as usize] += color),
        }
    }

    /// The rays the level's hits (the `depth`-th rays of their chains) send on become
    /// the next level, grouped by the object they leave and how, with their hits found;
    /// a sample's rays past its budget are traced depth first at once, into `colors`.
    /// `false` when no ray goes on in the wave.
    fn send_on(&mut self, integrator: &Integrator, depth: u32, colors: &mut [Color], stats: &mut RayStats) -> bool {
        let Wave { level, paths, surfaces, seen, sent, order, budget, stack, .. } = self;
        sent.clear();
        budget.clear();
        budget.resize(colors.len(), 0);
        for (k, (ray, found)) in level.iter().enumerate() {
            let Some((_, index)) = found else { continue };
            // Most hits (matte walls) send nothing: skip them before building a Path and
            // calling `scatter`, whose two-slot answer is costly to copy back.
            if !integrator.sends(*index, depth) {
                continue;
            }
            let (weight, sample) = paths[k];
            let path = Path { ray: *ray, weight, depth };
            for (slot, child) in integrator.scatter(&path, &surfaces[k].get(), *index).into_iter().enumerate() {
                let Some((child, kind)) = child else { continue };
                stats.count(kind);
                let rays = &mut budget[sample as usize];
                if *rays < PER_SAMPLE {
                    *rays += 1;
                    sent.push(((*index, slot as u32), child.ray, child.weight, sample));
                } else {
                    colors[sample as usize] += integrator.trace_path(child, stack, stats);
                }
            }
        }
        if sent.is_empty() {
            return false;
        }
        // The next level: the sent rays grouped, in a stable order (within a group each
        // sample's rays keep theirs). Where they are not grouped already, by sorting keys
        // (group, place in `sent`), not the 48-byte rays themselves: a stable sort of
        // those was 5 % of a render of the tree of cones (bench/tree_nff.py).
        level.clear();
        paths.clear();
        order.clear();
        let grouped = sent.is_sorted_by_key(|&(group, ..)| group);
        if grouped {
            level.extend(sent.iter().map(|&(_, ray, ..)| (ray, None)));
            paths.extend(sent.iter().map(|&(_, _, weight, sample)| (weight, sample)));
        } else {
            order.extend(sent.iter().enumerate().map(|(k, &(group, ..))| group_key(group) | k as u64));
            order.sort_unstable();
            for &key in order.iter() {
                let (_, ray, weight, sample) = sent[(key & 0xffff) as usize];
                level.push((ray, None));
                paths.push((weight, sample));
            }
        }
        let world = integrator.world();
        let mut at = 0;
        let mut hits = |n: usize| {
            find_hits(world, &mut level[at..at + n], seen);
            at += n;
        };
        match grouped {
            true => sent.chunk_by(|a, b| a.0 == b.0).for_each(|g| hits(g.len())),
            false => order.chunk_by(|a, b| a >> 16 == b >> 16).for_each(|g| hits(g.len())),
        }
        true
    }
}

/// The hits of a group of rays that leave from nearby points in nearby directions:
/// among the few objects they may meet where the world can tell
/// ([`World::seen_along`]), else through the tree ray by ray. The same answers.
fn find_hits(world: &World, rays: &mut [Found], seen: &mut Vec<u32>) {
    if rays.len() >= 4 && world.seen_along(rays, seen) {
        world.closest_among_each(seen, rays);
    } else {
        world.closest_found(rays);
    }
}

/// What eight shadow rays towards light `light` (its index) let through: tested together against
/// objects `blockers` only where given ([`World::may_shadow`]), else against the whole
/// world (through the light's buffer where it has one), each trying first what blocked
/// the light's last ray (`last`, carried on).
#[inline(always)]
fn visible_lanes(
    world: &World,
    light: usize,
    blockers: Option<&[u32]>,
    rays: &ShadowLanes,
    last: &mut LastBlocker,
) -> [f32; 8] {
    let ShadowLanes { from, dirs, t_max, live, .. } = *rays;
    match blockers {
        Some(ids) => world.transmittance_among_lanes(ids, from, dirs, t_max, live),
        // One walk a lane, each as it is taken: with the last blocker tried first, this
        // beat gathering the rays first (sphereflake, docs/performance.md).
        None if !world.packs_shadow_rays() => world.transmittance_towards_lanes(light, rays, last),
        None => {
            // The live lanes' rays, side by side, then their answers back in lane.
            let (mut packed, mut n) = ([(Ray { origin: Vec3::ZERO, dir: Vec3::Z }, 0.0); 8], 0);
            for lane in crate::math::lanes::set_lanes(live) {
                let shadow = Ray { origin: lane_of(from, lane), dir: lane_of(dirs, lane) };
                (packed[n], n) = ((shadow, t_max[lane]), n + 1);
            }
            let mut light = [0.0; 8];
            world.transmittance_each(&packed[..n], &mut light[..n]);
            let mut visible = [0.0; 8];
            for (lane, light) in crate::math::lanes::set_lanes(live).zip(light) {
                visible[lane] = light;
            }
            visible
        }
    }
}

/// A group of sent rays (object left, 0 reflected or 1 transmitted) as a sort key
/// above 16 bits: ordered as the pairs are.
#[inline(always)]
fn group_key((object, slot): (u32, u32)) -> u64 {
    (u64::from(object) << 1 | u64::from(slot)) << 16
}

/// `run`, a box round hits on one object, merged into that object's box in `boxes`.
fn merge_box(boxes: &mut Vec<(u32, Aabb)>, (i, lo, hi): (u32, Vec3A, Vec3A)) {
    let run = Aabb { min: lo.into(), max: hi.into() };
    if let Some((o, b)) = boxes.last_mut()
        && *o == i
    {
        *b = b.union(run);
        return;
    }
    match boxes.iter_mut().find(|(o, _)| *o == i) {
        Some((_, b)) => *b = b.union(run),
        None => boxes.push((i, run)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::AccelKind;
    use crate::prelude::*;

    /// Glass that reflects and transmits, between two mirrors: without a cutoff every
    /// glass hit sends two rays, so samples overrun their budget and go depth first.
    fn branchy() -> Scene {
        let mut scene = Scene::new(Camera::new(Vec3::new(0.0, 0.5, 2.5), Vec3::ZERO, Vec3::Y, 60.0, 8, 8));
        let glass =
            scene.add_material(Material::color(Color::new(0.6, 0.8, 1.0)).reflective(0.45).transparent(0.45, 1.5));
        let mirror = scene.add_material(Material::color(Color::ONE).reflective(0.9));
        scene.add(Sphere::new(Vec3::ZERO, 1.0), glass);
        scene.add(Sphere::new(Vec3::new(0.9, 0.8, -0.5), 0.6), glass);
        // A box of mirrors round it all, normals in: every ray hits something.
        let (h, x, y, z) = (3.0, Vec3::X * 6.0, Vec3::Y * 6.0, Vec3::Z * 6.0);
        let c = Vec3::splat(-h);
        for (corner, u, v) in [(c + z, y, x), (c, x, y), (c + x, z, y), (c + z, -z, y), (c + y, x, z), (c, z, x)] {
            scene.add(Quad::new(corner, u, v), mirror);
        }
        scene.add_light(PointLight::new(Vec3::new(1.0, 2.5, 2.0), Color::ONE));
        scene.settings.cutoff = 0.0;
        scene
    }

    #[test]
    fn a_rays_colour_does_not_depend_on_the_others_in_its_wave() {
        let scene = branchy();
        for accel in [AccelKind::Bvh, AccelKind::None] {
            let world = World::new(&scene, accel);
            let integrator = Integrator::new(&world, 9);
            let rig = scene.camera.rig().unwrap();
            let rays: Vec<Ray> = (0..64).map(|i| rig.ray((i % 8) as f32 + 0.3, (i / 8) as f32 + 0.6)).collect();
            let (mut wave, mut all, mut stats) = (Wave::default(), Vec::new(), RayStats::default());
            wave.trace(&integrator, &rays, None, &mut all, &mut stats);
            // Some samples ran past their budget: more rays than the wave could hold.
            assert!(stats.reflection + stats.refraction > 64 * PER_SAMPLE as u64, "{stats:?}");
            let mut one = Vec::new();
            for (k, ray) in rays.iter().enumerate() {
                wave.trace(&integrator, std::slice::from_ref(ray), None, &mut one, &mut RayStats::default());
                assert_eq!(one[0].to_array().map(f32::to_bits), all[k].to_array().map(f32::to_bits), "ray {k}");
                // Depth first from the start: the same colour, summed in another order.
                let dfs = integrator.trace_primary(ray, &mut RayStats::default());
                assert!((dfs - all[k]).abs().max_element() <= 1e-5 * (1.0 + dfs.max_element()), "ray {k}");
            }
        }
    }

    #[test]
    fn the_cutoff_drops_rays_that_bring_little_and_changes_little() {
        let mut scene = branchy();
        let render = |scene: &Scene| Renderer::new(scene).unwrap().max_depth(12).render_with_progress(&|_, _| {});
        let all = render(&scene);
        scene.settings.cutoff = crate::scene::DEFAULT_CUTOFF;
        let cut = render(&scene);
        let sent = |s: &RayStats| s.reflection + s.refraction;
        assert!(sent(&cut.stats) * 2 < sent(&all.stats), "{:?} vs {:?}", cut.stats, all.stats);
        // Each ray dropped carried under 1/255 of its pixel, but what it would have seen
        // may be brighter than 1: a highlight at every bounce between mirrors of 0.9
        // adds up to 10. On average a pixel moves by less than a level.
        let (mut worst, mut sum) = (0f32, 0f32);
        for y in 0..8 {
            for x in 0..8 {
                let d = (cut.image.pixel(x, y) - all.image.pixel(x, y)).abs().max_element();
                (worst, sum) = (worst.max(d), sum + d);
            }
        }
        assert!(worst > 0.0 && worst < 10.0 / 255.0, "a pixel moved by {worst}");
        assert!(sum / 64.0 < 1.0 / 255.0, "pixels moved by {} on average", sum / 64.0);
    }
}
