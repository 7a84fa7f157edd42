//! Drives a render: splits the image into tiles, traces them on all cores, assembles the
//! film. Every pixel depends only on the scene, the settings and its own coordinates, so
//! the image is the same for any thread count.

use crate::accel::{AccelKind, Best8, World};
use crate::camera::{Camera, CameraError, CameraRig};
use crate::film::Image;
use crate::geometry::Hit;
use crate::integrator::{
    BlockKind, Integrator, LightFrames, Lit, MirrorBlock, NONE, PackedSurface, QuadBlock, RayStats, Traced,
};
use crate::math::{Aabb, Color, Ray, Vec2};
use crate::sampler::{Rng, pixel_samples};
use crate::scene::Scene;
use rayon::prelude::*;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// Tile edge in pixels: small enough to balance load across threads, big enough that
/// per-tile overhead vanishes.
const TILE: u32 = 16;

/// What a render task keeps from one tile to the next, so that tiles allocate nothing.
#[derive(Default)]
struct TileBuffers {
    pixels: Vec<Color>,
    /// Per node, the colour seen along its ray.
    colors: Vec<Color>,
    samples: Vec<Vec2>,
    /// Where the tile's camera rays go through the image, in pixels.
    points: Vec<Vec2>,
    /// The tile's rays and their hits: camera rays, then those sent on ([`Traced`]).
    found: Vec<(Ray, Option<(Hit, u32)>)>,
    next: Vec<[u32; 2]>,
    surfaces: Vec<PackedSurface>,
    seen: Vec<u32>,
    hits: Vec<(u32, Aabb)>,
    /// Per light, the objects that may shadow one level's hits.
    blockers: Vec<Option<Vec<u32>>>,
    /// Per node and light, the light seen from its hit ([`Traced`]).
    lit: Vec<Lit>,
    /// The hits of one level that may be lit, as the lights see them.
    frames: LightFrames,
    /// Rays sent on from one level: (leaving object, reflected 0 or transmitted 1),
    /// the node sending it, the ray.
    sent: Vec<((u32, u32), u32, Ray)>,
    /// Rays shaded in lanes, eight at a time ([`QuadBlock`]), not node by node.
    blocks: Vec<QuadBlock>,
    /// Per object, a box round the hit points of `blocks`.
    block_hits: Vec<(u32, Aabb)>,
    /// The colours of `blocks`, lane by lane.
    block_colors: Vec<[[f32; 8]; 3]>,
    /// Rays that hit a perfect mirror eight at a time, level by level ([`MirrorBlock`]).
    mirrors: Vec<MirrorBlock>,
}

/// The tiles of an image, in reading order, shared out among workers: each starts on a
/// run of its own and, when that is done, takes the back half (rounded up) of the longest
/// run left. So the workers finish within a tile of each other (with bands of tiles as
/// rayon tasks, one sat idle for up to a few bands at the end), and each works in its own
/// part of the image (taking the next tile in reading order from one counter, two
/// threads worked side by side in the same rows and were slower: best 30.2 vs 28.7 ms).
struct TileQueue {
    runs: Mutex<Vec<std::ops::Range<usize>>>,
}

impl TileQueue {
    fn new(tiles: usize, workers: usize) -> Self {
        let at = |w: usize| w * tiles / workers;
        TileQueue { runs: Mutex::new((0..workers).map(|w| at(w)..at(w + 1)).collect()) }
    }

    /// The next tile for `worker`, or `None` when every tile is taken.
    fn take(&self, worker: usize) -> Option<usize> {
        let mut runs = self.runs.lock().unwrap_or_else(|e| e.into_inner());
        if runs[worker].is_empty() {
            let (longest, len) = runs.iter().map(|r| r.len()).enumerate().max_by_key(|&(_, len)| len)?;
            if len == 0 {
                return None;
            }
            let split = runs[longest].end - len.div_ceil(2);
            runs[worker] = split..runs[longest].end;
            runs[longest].end = split;
        }
        runs[worker].next()
    }
}

/// The mean of each `n` colours in turn, appended to `pixels`: the samples of a pixel.
/// Apart from the tile's big loop, whose registers were all taken, so that the sums
/// went through memory.
#[inline(never)]
fn average(colors: &[Color], n: usize, pixels: &mut Vec<Color>) {
    pixels.extend(colors.chunks(n).map(|samples| samples.iter().fold(Color::ZERO, |sum, &c| sum + c) / n as f32));
}

/// Offers eight rays, nodes `first..first + 8`, and their hits to be handled as a block
/// ([`Integrator::mirror_block`], [`Integrator::quad_block`]). A block taken goes to
/// `mirrors` or `blocks`, and for the latter the box round its hit points to
/// `block_hits`.
#[inline(always)]
fn take_block(
    integrator: &Integrator,
    kinds: &[BlockKind],
    (blocks, block_hits, mirrors): (&mut Vec<QuadBlock>, &mut Vec<(u32, Aabb)>, &mut Vec<MirrorBlock>),
    first: usize,
    rays: &[(Ray, Option<(Hit, u32)>)],
    hits: &Best8,
) -> bool {
    if let Some(block) = integrator.mirror_block(first as u32, rays, hits, kinds) {
        mirrors.push(block);
        return true;
    }
    let Some((block, bounds)) = integrator.quad_block(first as u32, rays, hits, kinds) else {
        return false;
    };
    merge_box(block_hits, (block.object(), bounds));
    blocks.push(block);
    true
}

/// `run`, a box round hits on one object, merged into that object's box in `hits`.
fn merge_box(hits: &mut Vec<(u32, Aabb)>, (i, run): (u32, Aabb)) {
    if let Some((o, b)) = hits.last_mut()
        && *o == i
    {
        *b = b.union(run);
        return;
    }
    match hits.iter_mut().find(|(o, _)| *o == i) {
        Some((_, b)) => *b = b.union(run),
        None => hits.push((i, run)),
    }
}

/// The surfaces hit by the rays of `buf.found` from node `from` on, into `buf.surfaces`,
/// and, per object hit, a box round its hit points, into `buf.hits`.
#[inline(never)]
fn surfaces_hit(integrator: &Integrator, buf: &mut TileBuffers, from: usize) {
    let TileBuffers { found, surfaces, hits, .. } = buf;
    hits.clear();
    surfaces.resize(found.len(), PackedSurface::default());
    // Hits come in runs on one object: each run's box is grown on its own, then merged.
    let mut run: Option<(u32, Aabb)> = None;
    for (k, (ray, hit)) in found.iter().enumerate().skip(from) {
        if let Some((h, i)) = hit {
            surfaces[k] = integrator.surface(ray, h, *i);
            let p = ray.at(h.t);
            match &mut run {
                Some((o, b)) if o == i => *b = b.grow(p),
                _ => {
                    if let Some(done) = run.replace((*i, Aabb::EMPTY.grow(p))) {
                        merge_box(hits, done);
                    }
                }
            }
        }
    }
    if let Some(done) = run {
        merge_box(hits, done);
    }
}

/// A configured render of one scene. Settings start from the scene's own and can be
/// overridden one by one.
#[derive(Clone, Debug)]
pub struct Renderer<'s> {
    scene: &'s Scene,
    camera: Camera,
    width: u32,
    height: u32,
    spp: u32,
    max_depth: u32,
    threads: Option<usize>,
    accel: AccelKind,
    corners: bool,
    one_sided: bool,
}

/// What a render produced.
#[derive(Clone, Debug)]
pub struct RenderOutput {
    pub image: Image,
    pub stats: RayStats,
    /// Wall time of tracing (not of loading the scene, building the acceleration
    /// structure or writing the file).
    pub elapsed: Duration,
    /// Wall time of building the acceleration structure.
    pub build_time: Duration,
    /// Samples per pixel used (4 with corner sampling, where neighbours share them).
    pub spp: u32,
    /// Whether the pixel corners were sampled ([`Renderer::corner_sampling`]).
    pub corners: bool,
}

impl<'s> Renderer<'s> {
    /// Fails only if the scene's camera cannot make rays.
    pub fn new(scene: &'s Scene) -> Result<Self, CameraError> {
        scene.camera.rig()?;
        Ok(Renderer {
            scene,
            camera: scene.camera,
            width: scene.camera.width,
            height: scene.camera.height,
            spp: scene.settings.samples.max(1),
            max_depth: scene.settings.max_depth,
            threads: None,
            accel: AccelKind::default(),
            corners: false,
            one_sided: false,
        })
    }

    /// One ray through each pixel corner, (width + 1) × (height + 1) rays, and each pixel
    /// the mean of its four corners: the SPD benchmark's sampling (513 × 513 eye rays for
    /// its 512 × 512 images). Replaces the samples per pixel while on.
    pub fn corner_sampling(mut self, on: bool) -> Self {
        self.corners = on;
        self
    }

    /// Opaque surfaces shaded one-sided (see [`Integrator::one_sided`]).
    pub fn one_sided(mut self, on: bool) -> Self {
        self.one_sided = on;
        self
    }

    /// The testing procedure of Eric Haines' Standard Procedural Databases, so timings
    /// compare with those published for other tracers: maximum ray depth 5 (the eye ray
    /// is 1), corner sampling, one-sided opaque surfaces and no shadow ray towards a
    /// light the shading normal faces away from. The rest of its rules (a reflection ray
    /// from every reflective hit and a refraction ray from every transmitting one, or a
    /// reflection ray on total internal reflection, with no adaptive cut-off; smooth
    /// patches; Phong highlights) are how this tracer always works.
    pub fn spd_rules(self) -> Self {
        self.max_depth(5).corner_sampling(true).one_sided(true)
    }

    pub fn size(mut self, width: u32, height: u32) -> Self {
        self.width = width.max(1);
        self.height = height.max(1);
        self
    }

    /// Looks through `camera` instead of the scene's own (an interactive viewer moves it
    /// without copying the scene). Its width and height are ignored: see [`Self::size`].
    pub fn camera(mut self, camera: Camera) -> Result<Self, CameraError> {
        camera.rig()?;
        self.camera = camera;
        Ok(self)
    }

    /// Samples per pixel (see [`pixel_samples`] for their layout).
    pub fn spp(mut self, spp: u32) -> Self {
        self.spp = spp.max(1);
        self
    }

    pub fn max_depth(mut self, depth: u32) -> Self {
        self.max_depth = depth;
        self
    }

    /// Worker threads; all cores when not set.
    pub fn threads(mut self, threads: usize) -> Self {
        self.threads = Some(threads.max(1));
        self
    }

    pub fn accel(mut self, accel: AccelKind) -> Self {
        self.accel = accel;
        self
    }

    pub fn render(&self) -> Image {
        self.render_with_progress(&|_, _| {}).image
    }

    /// Renders, calling `progress(tiles_done, tiles_total)` as tiles complete (from
    /// worker threads, in no particular order).
    pub fn render_with_progress(&self, progress: &(dyn Fn(usize, usize) + Sync)) -> RenderOutput {
        self.in_pool(|| {
            let world = World::new(self.scene, self.accel);
            let mut out = self.render_tiles(&world, progress, None).expect("a render without a cancel flag completes");
            out.build_time = world.build_time();
            out
        })
    }

    /// Renders with an acceleration structure built beforehand (benchmarks time the two
    /// apart; the viewer builds once per scene). `world` must come from this scene.
    pub fn render_world(&self, world: &World) -> RenderOutput {
        self.in_pool(|| self.render_tiles(world, &|_, _| {}, None)).expect("a render without a cancel flag completes")
    }

    /// Renders unless `cancel` becomes true first, in which case it returns `None` soon
    /// after: the flag is checked before every tile, so a stale frame in an interactive
    /// viewer stops within one tile's time rather than one image's.
    pub fn render_cancellable(&self, cancel: &AtomicBool) -> Option<RenderOutput> {
        self.in_pool(|| {
            let world = World::new(self.scene, self.accel);
            let mut out = self.render_tiles(&world, &|_, _| {}, Some(cancel))?;
            out.build_time = world.build_time();
            Some(out)
        })
    }

    /// [`Renderer::render_cancellable`] with a prebuilt acceleration structure.
    pub fn render_world_cancellable(&self, world: &World, cancel: &AtomicBool) -> Option<RenderOutput> {
        self.in_pool(|| self.render_tiles(world, &|_, _| {}, Some(cancel)))
    }

    /// Runs `f` on this renderer's thread pool (or the global one).
    pub fn in_pool<T: Send>(&self, f: impl FnOnce() -> T + Send) -> T {
        match self.threads {
            Some(n) => rayon::ThreadPoolBuilder::new().num_threads(n).build().expect("thread pool").install(f),
            None => f(),
        }
    }

    fn render_tiles(
        &self,
        world: &World,
        progress: &(dyn Fn(usize, usize) + Sync),
        cancel: Option<&AtomicBool>,
    ) -> Option<RenderOutput> {
        let start = Instant::now();
        let mut camera = self.camera;
        camera.width = self.width;
        camera.height = self.height;
        let rig = camera.rig().expect("checked in Renderer::new and Renderer::camera");
        let integrator = Integrator::new(world, self.max_depth).one_sided(self.one_sided);
        if self.corners {
            return self.render_corners(&rig, &integrator, progress, cancel, start);
        }

        let (width, tiles_x) = (self.width as usize, self.width.div_ceil(TILE) as usize);
        let total = tiles_x * self.height.div_ceil(TILE) as usize;
        let done = AtomicUsize::new(0);
        let mut image = Image::new(self.width, self.height);
        let workers = rayon::current_num_threads().min(total);
        let queue = TileQueue::new(total, workers);
        let kinds: Vec<BlockKind> = (0..self.scene.objects.len() as u32).map(|i| integrator.block_kind(i)).collect();
        // A tile writes its pixels into its band of TILE rows, locked only for the copy;
        // a worker keeps its buffers for all the tiles it takes.
        let bands: Vec<Mutex<&mut [Color]>> =
            image.pixels_mut().chunks_mut(TILE as usize * width).map(Mutex::new).collect();
        let per_worker: Vec<RayStats> = (0..workers)
            .into_par_iter()
            .with_max_len(1)
            .map(|worker| {
                let (mut tile, mut stats) = (TileBuffers::default(), RayStats::default());
                while let Some(i) = queue.take(worker) {
                    if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                        return None;
                    }
                    let (x0, y0) = ((i % tiles_x) as u32 * TILE, (i / tiles_x) as u32 * TILE);
                    let (x1, y1) = ((x0 + TILE).min(self.width), (y0 + TILE).min(self.height));
                    self.render_tile(world, &rig, &integrator, &kinds, (x0, y0, x1, y1), &mut tile, &mut stats);
                    let mut rows = bands[i / tiles_x].lock().unwrap_or_else(|e| e.into_inner());
                    for (y, row) in tile.pixels.chunks((x1 - x0) as usize).enumerate() {
                        let at = y * width + x0 as usize;
                        rows[at..at + row.len()].copy_from_slice(row);
                    }
                    drop(rows);
                    progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
                }
                Some(stats)
            })
            .collect::<Option<_>>()?;
        let mut stats = RayStats::default();
        for s in per_worker {
            stats += s;
        }
        Some(RenderOutput {
            image,
            stats,
            elapsed: start.elapsed(),
            build_time: Duration::ZERO,
            spp: self.spp,
            corners: false,
        })
    }

    /// Traces the pixels of one tile, `(x0, y0)` to `(x1, y1)` exclusive, into
    /// `buf.pixels` row by row. Blocks of eight rays on one object of a kind in `kinds`
    /// ([`Integrator::block_kind`]) are handled together.
    #[allow(clippy::too_many_arguments)]
    fn render_tile(
        &self,
        world: &World,
        rig: &CameraRig,
        integrator: &Integrator,
        kinds: &[BlockKind],
        (x0, y0, x1, y1): (u32, u32, u32, u32),
        buf: &mut TileBuffers,
        stats: &mut RayStats,
    ) {
        let TileBuffers { pixels, samples, points, found, seen, blocks, block_hits, mirrors, .. } = buf;
        pixels.clear();
        found.clear();
        points.clear();
        for y in y0..y1 {
            for x in x0..x1 {
                // One sample needs no random numbers: it goes through the pixel centre.
                if self.spp > 1 || samples.is_empty() {
                    pixel_samples(self.spp, &mut Rng::for_pixel(x, y, 0), samples);
                }
                points.extend(samples.iter().map(|s| Vec2::new(x as f32 + s.x, y as f32 + s.y)));
            }
        }
        rig.rays(points, |ray| found.push((ray, None)));
        // In a small scene the tile's camera rays test only the objects its cone of
        // rays meets (samples stay inside their pixels), and their hits are all found
        // first, so that the shadow rays from them test only the objects that can stand
        // between those hits and each light.
        let (apex, edges) = rig.cone(x0 as f32, y0 as f32, x1 as f32, y1 as f32);
        let culled = world.seen_from(apex, edges, seen);
        let camera_rays = found.len();
        if culled {
            blocks.clear();
            block_hits.clear();
            mirrors.clear();
            world.closest_among_each_or(seen, found, |first, rays, hits| {
                take_block(integrator, kinds, (blocks, block_hits, mirrors), first, rays, hits)
            });
            self.trace_ahead(world, integrator, kinds, buf, stats);
        }
        let TileBuffers { pixels, samples, found, next, surfaces, lit, colors, blocks, block_colors, .. } = buf;
        let n = samples.len();
        if culled {
            let traced = Traced { nodes: found, surfaces, next, lit, blocks, block_colors };
            integrator.shade_traced(&traced, colors, stats);
            stats.primary += camera_rays as u64;
            if n == 1 {
                // Each pixel is its one sample: the camera rays' colours as they are.
                std::mem::swap(pixels, colors);
                pixels.truncate(camera_rays);
            } else {
                average(&colors[..camera_rays], n, pixels);
            }
        } else {
            colors.clear();
            colors.extend(found.iter().map(|(ray, _)| integrator.trace_primary(ray, stats)));
            average(colors, n, pixels);
        }
    }

    /// For a culled tile whose camera rays' hits are found (`buf.found`): level by level,
    /// the surfaces hit, the objects that may shadow them, the lights as they see them
    /// ([`Renderer::look_at_lights`]), and the rays they send on with what those hit
    /// ([`Renderer::send_on`]), until no rays are sent or the depth limit is reached.
    fn trace_ahead(
        &self,
        world: &World,
        integrator: &Integrator,
        kinds: &[BlockKind],
        buf: &mut TileBuffers,
        stats: &mut RayStats,
    ) {
        buf.next.clear();
        buf.next.resize(buf.found.len(), [NONE; 2]);
        buf.surfaces.clear();
        buf.lit.clear();
        // One-sided shading may send a shadow ray from a surface's back through the
        // surface itself, which the culling assumes it does not.
        let lights = if self.one_sided { &[][..] } else { &self.scene.lights[..] };
        buf.block_colors.clear();
        let (mut level, mut depth, mut mirrors_done) = (0..buf.found.len(), 1u32, 0);
        loop {
            // The level's mirror blocks, taken when its rays' hits were found.
            let mirrors = mirrors_done..buf.mirrors.len();
            mirrors_done = mirrors.end;
            surfaces_hit(integrator, buf, level.start);
            let TileBuffers { hits, blockers, blocks, block_hits, block_colors, .. } = &mut *buf;
            // The level's hits shaded in lanes may be shadowed by what the others may.
            for &run in &*block_hits {
                merge_box(hits, run);
            }
            block_hits.clear();
            // Kept from tile to tile, to allocate nothing.
            blockers.resize_with(lights.len(), || None);
            for (b, l) in blockers.iter_mut().zip(lights) {
                let mut few = b.take().unwrap_or_default();
                *b = world.may_shadow(hits, l.position, &mut few).then_some(few);
            }
            // The level's blocks: those after the ones shaded already.
            integrator.shade_blocks(&blocks[block_colors.len()..], blockers, block_colors, stats);
            self.look_at_lights(integrator, buf, level.clone());
            if depth >= self.max_depth {
                // The level's mirror blocks get their hits back; they send nothing on.
                let TileBuffers { found, sent, mirrors: taken, .. } = &mut *buf;
                for block in &taken[mirrors] {
                    integrator.mirror_rays(block, found, depth, sent, stats);
                }
                break;
            }
            match self.send_on(world, integrator, kinds, buf, (level, mirrors), depth, stats) {
                Some(next_level) => (level, depth) = (next_level, depth + 1),
                None => break,
            }
        }
    }

    /// Each light as the hits of nodes `level` see it, into `buf.lit`, the shadow rays
    /// to it tested together against the objects that may shadow them (`buf.blockers`).
    #[inline(never)]
    fn look_at_lights(&self, integrator: &Integrator, buf: &mut TileBuffers, level: std::ops::Range<usize>) {
        let TileBuffers { found, surfaces, blockers, lit, frames, .. } = buf;
        let lights = self.scene.lights.len();
        lit.resize(found.len() * lights, Lit::default());
        frames.clear();
        for k in level {
            if let (ray, Some((_, index))) = &found[k]
                && integrator.may_light(*index)
            {
                frames.push(k as u32, integrator.light_frame(ray, &surfaces[k].get(), *index));
            }
        }
        for i in 0..lights {
            integrator.look_at_light(frames, i, blockers.get(i).and_then(|b| b.as_deref()), lit);
        }
    }

    /// The rays the hits of nodes `level` (at `depth`) send on, appended to `buf.found`
    /// grouped by the object they leave and how (reflected or transmitted), linked by
    /// `buf.next` and counted in `stats`, with what they hit: a group of four or more
    /// tested only against what it may meet ([`World::seen_along`]), eight at a time,
    /// blocks of eight on one object of a kind in `kinds` taken to be handled together.
    /// The level's mirror blocks (`buf.mirrors[mirrors]`) get their hits back and send
    /// their rays with the rest. Returns the new nodes, if any.
    #[inline(never)]
    #[allow(clippy::too_many_arguments)]
    fn send_on(
        &self,
        world: &World,
        integrator: &Integrator,
        kinds: &[BlockKind],
        buf: &mut TileBuffers,
        (level, mirrors): (std::ops::Range<usize>, std::ops::Range<usize>),
        depth: u32,
        stats: &mut RayStats,
    ) -> Option<std::ops::Range<usize>> {
        let TileBuffers { found, next, surfaces, seen, sent, blocks, block_hits, mirrors: taken, .. } = buf;
        sent.clear();
        for k in level {
            if let (ray, Some((_, i))) = &found[k]
                && integrator.sends(*i, depth)
            {
                let rays = integrator.sent_on(ray, &surfaces[k].get(), *i, depth, stats);
                for (slot, r) in rays.into_iter().enumerate() {
                    if let Some(r) = r {
                        sent.push(((*i, slot as u32), k as u32, r));
                    }
                }
            }
        }
        for block in &taken[mirrors] {
            integrator.mirror_rays(block, found, depth, sent, stats);
        }
        if sent.is_empty() {
            return None;
        }
        sent.sort_by_key(|&(group, ..)| group);
        let start = found.len();
        for (j, &((_, slot), parent, ray)) in sent.iter().enumerate() {
            next[parent as usize][slot as usize] = (start + j) as u32;
            found.push((ray, None));
            next.push([NONE; 2]);
        }
        let mut at = start;
        for group in sent.chunk_by(|a, b| a.0 == b.0) {
            let (first, rays) = (at, &mut found[at..at + group.len()]);
            at += group.len();
            if rays.len() >= 4 && world.seen_along(rays, seen) {
                world.closest_among_each_or(seen, rays, |k, rays, hits| {
                    take_block(integrator, kinds, (blocks, block_hits, taken), first + k, rays, hits)
                });
            } else {
                for (ray, hit) in rays {
                    *hit = world.closest(ray, 0.0, f32::INFINITY);
                }
            }
        }
        Some(start..found.len())
    }

    /// Corner sampling: rows of corner rays traced in parallel, each ray once, then
    /// averaged four at a time. `progress` counts rows.
    fn render_corners(
        &self,
        rig: &CameraRig,
        integrator: &Integrator,
        progress: &(dyn Fn(usize, usize) + Sync),
        cancel: Option<&AtomicBool>,
        start: Instant,
    ) -> Option<RenderOutput> {
        let (w, h) = (self.width, self.height);
        let total = h as usize + 1;
        let done = std::sync::atomic::AtomicUsize::new(0);
        let rows: Vec<(Vec<Color>, RayStats)> = (0..=h)
            .into_par_iter()
            .map(|y| {
                if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                    return None;
                }
                let mut stats = RayStats::default();
                let row = (0..=w).map(|x| integrator.trace_primary(&rig.ray(x as f32, y as f32), &mut stats)).collect();
                progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
                Some((row, stats))
            })
            .collect::<Option<_>>()?;
        let mut image = Image::new(w, h);
        let mut stats = RayStats::default();
        for (_, s) in &rows {
            stats += *s;
        }
        for y in 0..h as usize {
            let (top, bottom) = (&rows[y].0, &rows[y + 1].0);
            for x in 0..w as usize {
                let c = (top[x] + top[x + 1] + bottom[x] + bottom[x + 1]) * 0.25;
                image.set(x as u32, y as u32, c);
            }
        }
        Some(RenderOutput { image, stats, elapsed: start.elapsed(), build_time: Duration::ZERO, spp: 4, corners: true })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::prelude::*;

    fn scene() -> Scene {
        let mut scene = Scene::new(Camera::new(Vec3::ZERO, Vec3::NEG_Z, Vec3::Y, 45.0, 48, 32));
        let red = scene.add_material(Material::color(Color::new(1.0, 0.0, 0.0)));
        scene.add(Sphere::new(Vec3::new(0.0, 0.0, -5.0), 1.0), red);
        scene.add_light(PointLight::new(Vec3::new(5.0, 5.0, 0.0), Color::ONE));
        scene
    }

    #[test]
    fn the_tile_queue_hands_out_every_tile_once_and_workers_steal_halves() {
        for (tiles, workers) in [(1, 1), (1, 2), (7, 3), (2500, 2), (2500, 5), (10, 16)] {
            let queue = TileQueue::new(tiles, workers.min(tiles));
            let mut got = Vec::new();
            // Worker 0 alone takes its own run, then the back half of the longest left,
            // and so on until nothing is left, as when the other workers never start.
            while let Some(i) = queue.take(0) {
                got.push(i);
            }
            got.sort_unstable();
            assert_eq!(got, (0..tiles).collect::<Vec<_>>(), "{tiles} tiles, {workers} workers");
        }
        // Two workers, taking turns: each starts on its own half of the image.
        let queue = TileQueue::new(10, 2);
        assert_eq!((queue.take(0), queue.take(1)), (Some(0), Some(5)));
        // Worker 1 finishes its run; then it steals the back half of worker 0's.
        for i in 6..10 {
            assert_eq!(queue.take(1), Some(i));
        }
        assert_eq!(queue.take(1), Some(3));
        assert_eq!((queue.take(0), queue.take(0), queue.take(1), queue.take(0)), (Some(1), Some(2), Some(4), None));
        assert_eq!(queue.take(1), None);
    }

    #[test]
    fn a_cancelled_render_returns_nothing() {
        let scene = scene();
        let r = Renderer::new(&scene).unwrap();
        assert!(r.render_cancellable(&AtomicBool::new(true)).is_none());
        let out = r.render_cancellable(&AtomicBool::new(false)).unwrap();
        assert_eq!(out.image, r.render());
    }

    #[test]
    fn a_camera_override_matches_the_scene_with_that_camera() {
        let mut moved = scene();
        moved.camera.position = Vec3::new(1.0, 0.5, 0.0);
        let base = scene();
        let via_override = Renderer::new(&base).unwrap().camera(moved.camera).unwrap().render();
        assert_eq!(via_override, Renderer::new(&moved).unwrap().render());
        assert_ne!(via_override, Renderer::new(&base).unwrap().render());
        let mut bad = moved.camera;
        bad.look_at = bad.position;
        assert!(Renderer::new(&base).unwrap().camera(bad).is_err());
    }

    fn ball() -> Scene {
        let mut s = Scene::new(Camera::new(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, Vec3::Y, 40.0, 12, 10));
        let m = s.add_material(Material::color(Color::new(1.0, 0.5, 0.2)).reflective(0.3));
        s.add(Sphere::new(Vec3::ZERO, 1.0), m);
        s.add_light(PointLight::new(Vec3::new(3.0, 3.0, 3.0), Color::ONE));
        s
    }

    #[test]
    fn corner_sampling_traces_each_corner_once_and_averages_four() {
        let scene = ball();
        let out = Renderer::new(&scene).unwrap().corner_sampling(true).threads(3).render_with_progress(&|_, _| {});
        assert_eq!(out.stats.primary, 13 * 11);
        assert!(out.corners && out.spp == 4);
        // Pixel (x, y) is the mean of the rays through (x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1).
        let world = World::new(&scene, AccelKind::Bvh);
        let rig = scene.camera.rig().unwrap();
        let integrator = Integrator::new(&world, scene.settings.max_depth);
        let at = |x: u32, y: u32| integrator.trace_primary(&rig.ray(x as f32, y as f32), &mut RayStats::default());
        for (x, y) in [(0, 0), (5, 4), (11, 9)] {
            let expected = (at(x, y) + at(x + 1, y) + at(x, y + 1) + at(x + 1, y + 1)) * 0.25;
            assert_eq!(out.image.pixel(x, y), expected, "({x}, {y})");
        }
        // The same with one thread.
        let one = Renderer::new(&scene).unwrap().corner_sampling(true).threads(1).render();
        assert!(one == out.image);
    }

    /// Every kind of shape, mirrors and glass (refracting, so rays bounce inside it),
    /// three lights: image tiles that find their rays' hits and shadows ahead, level by
    /// level, must shade what tracing ray by ray without a tree shades, counts included.
    #[test]
    fn tiles_traced_ahead_match_tracing_ray_by_ray() {
        use crate::geometry::{Cone, Cylinder, Mesh, Polygon, Triangle};
        let mut scene =
            Scene::new(Camera::new(Vec3::new(0.5, 1.0, 6.0), Vec3::new(0.0, 0.0, -2.0), Vec3::Y, 60.0, 96, 72));
        let mirror = scene.add_material(Material::color(Color::splat(0.4)).reflective(0.8));
        let glass = scene.add_material(Material::color(Color::new(0.2, 0.5, 0.9)).transparent(0.8, 1.5));
        let red = scene.add_material(Material::color(Color::new(0.9, 0.2, 0.1)).reflective(0.2));
        // A checkered floor: on its black squares `local` looks at no light, although
        // the tile found the lights there ahead.
        let squares =
            Texture::Checker { size: 0.5, offset: Vec3::new(0.0, 0.25, 0.0), colors: [Color::ZERO, Color::splat(0.8)] };
        let checker = scene.add_material(Material::textured(squares).matte());
        let floor = Quad::new(Vec3::new(-6.0, -1.0, 4.0), Vec3::new(12.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -12.0));
        scene.add(floor, checker);
        scene.add(Quad::new(Vec3::new(-6.0, -1.0, -8.0), Vec3::new(12.0, 0.0, 0.0), Vec3::new(0.0, 7.0, 0.0)), mirror);
        scene.add(Quad::new(Vec3::new(-6.0, -1.0, 7.0), Vec3::new(0.0, 7.0, 0.0), Vec3::new(12.0, 0.0, 0.0)), mirror);
        scene.add(Sphere::new(Vec3::new(-1.5, 0.2, -2.0), 1.2), glass);
        scene.add(Sphere::new(Vec3::new(1.8, 0.0, -3.0), 1.0), mirror);
        scene.add(Cylinder::new(Vec3::new(0.3, -1.0, -0.5), Vec3::Y, 0.5, 1.5, true), glass);
        scene.add(Cone::new(Vec3::new(2.5, -1.0, -0.5), Vec3::new(0.1, 1.0, 0.0), 0.7, 1.6, true), red);
        scene.add(Cone::truncated(Vec3::new(-2.8, -1.0, 0.0), Vec3::Y, 0.6, 0.3, 1.2, true, true), glass);
        let hexagon = (0..6).map(|i| {
            let a = i as f32 * std::f32::consts::TAU / 6.0;
            Vec3::new(-0.5 + 0.6 * a.cos(), 2.2 + 0.6 * a.sin(), -4.0)
        });
        scene.add(Polygon::new(hexagon.collect()).unwrap(), red);
        scene
            .add(Triangle::new(Vec3::new(3.0, 1.5, -4.0), Vec3::new(4.0, 1.5, -4.5), Vec3::new(3.5, 2.8, -4.2)), glass);
        let tetra = vec![
            Vec3::new(0.8, 1.6, -1.0),
            Vec3::new(1.6, 1.6, -1.4),
            Vec3::new(1.1, 2.5, -1.2),
            Vec3::new(1.2, 1.9, -0.4),
        ];
        scene.add(
            Mesh::new(tetra, vec![], vec![], vec![[0, 1, 2], [0, 3, 1], [1, 3, 2], [2, 3, 0]], false).unwrap(),
            mirror,
        );
        for (p, c) in
            [(Vec3::new(4.0, 5.0, 3.0), 0.6), (Vec3::new(-4.0, 4.0, 1.0), 0.4), (Vec3::new(0.0, 3.0, -6.0), 0.3)]
        {
            scene.add_light(PointLight::new(p, Color::splat(c)));
        }
        scene.settings.max_depth = 6;
        let render =
            |accel| Renderer::new(&scene).unwrap().spp(4).threads(2).accel(accel).render_with_progress(&|_, _| {});
        let (ahead, by_ray) = (render(AccelKind::Bvh), render(AccelKind::None));
        assert_eq!(ahead.stats, by_ray.stats);
        assert!(ahead.stats.reflection > 5_000 && ahead.stats.refraction > 2_000, "{:?}", ahead.stats);
        assert!(ahead.image == by_ray.image);
        // The tiles were culled and traced ahead: the camera sees few objects per tile.
        let world = World::new(&scene, AccelKind::Bvh);
        let (apex, edges) = scene.camera.rig().unwrap().cone(32.0, 32.0, 48.0, 48.0);
        assert!(world.seen_from(apex, edges, &mut Vec::new()));
    }

    /// A room of matte quads of every solid-space texture, seen straight and in a
    /// mirror, shadowed through glass, under two lights: blocks of eight hits on one
    /// quad are shaded in lanes, and must shade what tracing ray by ray does.
    #[test]
    fn blocks_shaded_in_lanes_match_tracing_ray_by_ray() {
        let mut scene =
            Scene::new(Camera::new(Vec3::new(0.3, 0.5, 4.0), Vec3::new(0.0, 0.0, -3.0), Vec3::Y, 70.0, 64, 48));
        let stripes = Texture::Stripes {
            axis: Vec3::Z,
            width: 0.7,
            colors: [Color::new(1.0, 1.0, 0.5), Color::new(0.0, 1.0, 0.0)],
        };
        let checker =
            Texture::Checker { size: 0.5, offset: Vec3::new(0.0, 0.25, 0.0), colors: [Color::ZERO, Color::splat(0.9)] };
        let floor = scene.add_material(Material::textured(stripes).matte());
        let back = scene.add_material(Material::textured(checker).matte());
        let side = scene.add_material(Material::color(Color::new(0.0, 0.5, 1.0)).matte());
        let mirror = scene.add_material(Material::color(Color::splat(0.5)).reflective(1.0).matte());
        let glass = scene.add_material(Material::color(Color::new(1.0, 0.2, 0.2)).transparent(0.7, 1.0));
        let quad = |c: [f32; 3], u: [f32; 3], v: [f32; 3]| Quad::new(Vec3::from(c), Vec3::from(u), Vec3::from(v));
        scene.add(quad([-4.0, -1.5, 5.0], [8.0, 0.0, 0.0], [0.0, 0.0, -11.0]), floor);
        scene.add(quad([-4.0, -1.5, -6.0], [8.0, 0.0, 0.0], [0.0, 6.0, 0.0]), back);
        scene.add(quad([-4.0, -1.5, -6.0], [0.0, 6.0, 0.0], [0.0, 0.0, 11.0]), side);
        scene.add(quad([4.0, -1.5, -6.0], [0.0, 0.0, 11.0], [0.0, 6.0, 0.0]), mirror);
        scene.add(Sphere::new(Vec3::new(-0.5, 0.0, -2.5), 1.0), glass);
        scene.add_light(PointLight::new(Vec3::new(1.0, 3.5, 0.0), Color::splat(0.7)));
        scene.add_light(PointLight::new(Vec3::new(-3.0, 2.0, 2.0), Color::new(0.3, 0.3, 0.2)));
        let render = |accel| Renderer::new(&scene).unwrap().threads(2).accel(accel).render_with_progress(&|_, _| {});
        let (lanes, by_ray) = (render(AccelKind::Bvh), render(AccelKind::None));
        assert_eq!(lanes.stats, by_ray.stats);
        assert!(lanes.image == by_ray.image);
        // Where the processor has AVX2, the tiles take camera rays as blocks of both kinds.
        let world = World::new(&scene, AccelKind::Bvh);
        let integrator = Integrator::new(&world, scene.settings.max_depth);
        let kinds: Vec<BlockKind> = (0..scene.objects.len() as u32).map(|i| integrator.block_kind(i)).collect();
        use BlockKind::{Matte, Mirror};
        assert_eq!(kinds, [Matte, Matte, Matte, Mirror, BlockKind::None]);
        let rig = scene.camera.rig().unwrap();
        let (mut blocks, mut boxes, mut mirrors, mut seen) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (x, y) in (0..3).flat_map(|y| (0..4).map(move |x| (16 * x, 16 * y))) {
            let (apex, edges) = rig.cone(x as f32, y as f32, (x + 16) as f32, (y + 16) as f32);
            assert!(world.seen_from(apex, edges, &mut seen));
            let mut found = Vec::new();
            let points: Vec<Vec2> =
                (y..y + 16).flat_map(|y| (x..x + 16).map(move |x| Vec2::new(x as f32 + 0.5, y as f32 + 0.5))).collect();
            rig.rays(&points, |ray| found.push((ray, None)));
            let (taken, mine) = (blocks.len() + mirrors.len(), blocks.len());
            world.closest_among_each_or(&seen, &mut found, |first, rays, hits| {
                take_block(&integrator, &kinds, (&mut blocks, &mut boxes, &mut mirrors), first, rays, hits)
            });
            // Blocks taken are left without hits (so are rays into the open).
            let left = found.iter().filter(|(_, hit)| hit.is_none()).count();
            assert!(left >= 8 * (blocks.len() + mirrors.len() - taken), "tile at ({x}, {y})");
            assert!(blocks[mine..].iter().all(|b| found[b.node()..b.node() + 8].iter().all(|(_, hit)| hit.is_none())));
        }
        if crate::accel::lanes::avx2() {
            assert!(blocks.len() >= 40 && mirrors.len() >= 4, "{} and {} blocks", blocks.len(), mirrors.len());
        }
    }

    #[test]
    fn spd_rules_limit_the_depth_to_five() {
        let scene = ball();
        let r = Renderer::new(&scene).unwrap().spd_rules();
        assert_eq!((r.max_depth, r.corners, r.one_sided), (5, true, true));
    }
}
