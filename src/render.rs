//! Drives a render: splits the image into tiles, traces them on all cores, assembles the
//! film. Every pixel depends only on the scene, the settings and its own coordinates, so
//! the image is the same for any thread count.

use crate::accel::{AccelKind, World};
use crate::camera::{Camera, CameraError, CameraRig};
use crate::film::Image;
use crate::integrator::{Integrator, RayStats, WAVE_RAYS, Wave};
use crate::math::{Color, Ray, Vec2, Vec3};
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
    samples: Vec<Vec2>,
    /// Where a wave's camera rays go through the image, in pixels.
    points: Vec<Vec2>,
    rays: Vec<Ray>,
    colors: Vec<Color>,
    wave: Wave,
}

/// A pixel's samples summed as they come, in order, then averaged.
#[derive(Default)]
struct PixelSum {
    sum: Color,
    count: u32,
}

impl PixelSum {
    /// Adds the colours of consecutive samples; each pixel of `spp` samples completed
    /// goes to `pixels`, the mean of its samples (the sample itself when there is one).
    fn add(&mut self, colors: &[Color], spp: u32, pixels: &mut Vec<Color>) {
        for &c in colors {
            self.sum += c;
            self.count += 1;
            if self.count == spp {
                pixels.push(if spp == 1 { c } else { self.sum / spp as f32 });
                *self = PixelSum::default();
            }
        }
    }
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
    cutoff: f32,
    /// The rectangle to render, `(x0, y0, x1, y1)` exclusive; the whole image if `None`.
    region: Option<(u32, u32, u32, u32)>,
}

/// A region that is not a non-empty rectangle inside the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "region {x0},{y0},{x1},{y1} is not a non-empty rectangle inside the {width} x {height} image (need x0 < x1 <= width, y0 < y1 <= height)"
)]
pub struct RegionError {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
    pub width: u32,
    pub height: u32,
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
            cutoff: scene.settings.cutoff,
            region: None,
        })
    }

    /// Renders only the pixels `x0..x1` × `y0..y1` of the image (set its size first),
    /// into an image of the region's size. Each pixel is exactly what the full render
    /// gives it: tiles stay on the full image's grid, so a frame can be split across
    /// processes or machines and reassembled bit for bit.
    pub fn region(mut self, x0: u32, y0: u32, x1: u32, y1: u32) -> Result<Self, RegionError> {
        let (width, height) = (self.width, self.height);
        if !(x0 < x1 && x1 <= width && y0 < y1 && y1 <= height) {
            return Err(RegionError { x0, y0, x1, y1, width, height });
        }
        self.region = Some((x0, y0, x1, y1));
        Ok(self)
    }

    /// The rectangle rendered: the region, kept inside the image should the size have
    /// shrunk since, or the whole image.
    fn bounds(&self) -> (u32, u32, u32, u32) {
        let (w, h) = (self.width, self.height);
        match self.region {
            Some((x0, y0, x1, y1)) if x0 < w && y0 < h => (x0, y0, x1.min(w), y1.min(h)),
            _ => (0, 0, w, h),
        }
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
    /// reflection ray on total internal reflection; smooth patches; Phong highlights)
    /// are how this tracer always works, and its rule of no adaptive cut-off sets the
    /// cutoff to 0.
    pub fn spd_rules(self) -> Self {
        self.max_depth(5).corner_sampling(true).one_sided(true).cutoff(0.0)
    }

    /// A ray whose share of its pixel falls below `cutoff` is not followed (the
    /// scene's `cutoff` setting by default; 0 follows every ray to the depth limit).
    pub fn cutoff(mut self, cutoff: f32) -> Self {
        self.cutoff = cutoff;
        self
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

    /// [`Renderer::render_world`] with progress: the frames of an animation where only
    /// the camera moves share one acceleration structure.
    pub fn render_world_with_progress(&self, world: &World, progress: &(dyn Fn(usize, usize) + Sync)) -> RenderOutput {
        self.in_pool(|| self.render_tiles(world, progress, None)).expect("a render without a cancel flag completes")
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

    /// [`Renderer::render_with_progress`] that stops soon after `cancel` becomes true and
    /// then returns `None` (a binding polls for Ctrl-C while the render runs elsewhere).
    pub fn render_with_progress_cancellable(
        &self,
        progress: &(dyn Fn(usize, usize) + Sync),
        cancel: &AtomicBool,
    ) -> Option<RenderOutput> {
        self.in_pool(|| {
            let world = World::new(self.scene, self.accel);
            let mut out = self.render_tiles(&world, progress, Some(cancel))?;
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
        let integrator = Integrator::new(world, self.max_depth).one_sided(self.one_sided).cutoff(self.cutoff);
        if self.corners {
            return self.render_corners(&rig, &integrator, progress, cancel, start);
        }

        // The tiles of the full image's grid that meet the rendered rectangle; a tile is
        // traced whole and only its pixels inside the rectangle are kept.
        let (rx0, ry0, rx1, ry1) = self.bounds();
        let (tx0, ty0) = (rx0 / TILE, ry0 / TILE);
        let tiles_x = (rx1.div_ceil(TILE) - tx0) as usize;
        let total = tiles_x * (ry1.div_ceil(TILE) - ty0) as usize;
        let width = (rx1 - rx0) as usize;
        let done = AtomicUsize::new(0);
        let mut image = Image::new(rx1 - rx0, ry1 - ry0);
        let workers = rayon::current_num_threads().min(total);
        let queue = TileQueue::new(total, workers);
        // A tile writes its pixels into its band of up to TILE rows, locked only for the
        // copy; a worker keeps its buffers for all the tiles it takes.
        let mut bands: Vec<Mutex<&mut [Vec3]>> = Vec::new();
        let mut rest = image.pixels_mut();
        for ty in ty0..ry1.div_ceil(TILE) {
            let rows = ((ty + 1) * TILE).min(ry1) - (ty * TILE).max(ry0);
            let (band, tail) = rest.split_at_mut(rows as usize * width);
            bands.push(Mutex::new(band));
            rest = tail;
        }
        let per_worker: Vec<RayStats> = (0..workers)
            .into_par_iter()
            .with_max_len(1)
            .map(|worker| {
                let (mut tile, mut stats) = (TileBuffers::default(), RayStats::default());
                while let Some(i) = queue.take(worker) {
                    if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                        return None;
                    }
                    let (x0, y0) = ((tx0 + (i % tiles_x) as u32) * TILE, (ty0 + (i / tiles_x) as u32) * TILE);
                    let (x1, y1) = ((x0 + TILE).min(self.width), (y0 + TILE).min(self.height));
                    self.render_tile(&rig, &integrator, (x0, y0, x1, y1), &mut tile, &mut stats);
                    let (cx0, cx1, band_y) = (x0.max(rx0), x1.min(rx1), y0.max(ry0));
                    let mut rows = bands[i / tiles_x].lock().unwrap_or_else(|e| e.into_inner());
                    for y in band_y..y1.min(ry1) {
                        let from = (y - y0) as usize * (x1 - x0) as usize + (cx0 - x0) as usize;
                        let at = (y - band_y) as usize * width + (cx0 - rx0) as usize;
                        let n = (cx1 - cx0) as usize;
                        for (to, c) in rows[at..at + n].iter_mut().zip(&tile.pixels[from..from + n]) {
                            *to = (*c).into();
                        }
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
    /// `buf.pixels` row by row: their samples in reading order, in waves of at most
    /// [`WAVE_RAYS`] camera rays, each with the cone of the rows it covers.
    fn render_tile(
        &self,
        rig: &CameraRig,
        integrator: &Integrator,
        (x0, y0, x1, y1): (u32, u32, u32, u32),
        buf: &mut TileBuffers,
        stats: &mut RayStats,
    ) {
        let TileBuffers { pixels, samples, points, rays, colors, wave } = buf;
        pixels.clear();
        points.clear();
        let mut sum = PixelSum::default();
        // The first row of the wave being gathered.
        let mut top = y0;
        let mut trace = |points: &mut Vec<Vec2>, rows: (u32, u32), pixels: &mut Vec<Color>| {
            rays.clear();
            rig.rays(points, rays);
            let cone = rig.cone(x0 as f32, rows.0 as f32, x1 as f32, rows.1 as f32);
            wave.trace(integrator, rays, Some(cone), colors, stats);
            sum.add(colors, self.spp, pixels);
            points.clear();
        };
        for y in y0..y1 {
            if self.spp == 1 {
                // One sample needs no random numbers: it goes through the pixel centre,
                // and a row's samples go in as runs (one push per sample cost 3 % of a
                // room render).
                if samples.is_empty() {
                    pixel_samples(1, &mut Rng::for_pixel(x0, y, 0), samples);
                }
                let s = samples[0];
                let mut x = x0;
                while x < x1 {
                    let n = (WAVE_RAYS - points.len()).min((x1 - x) as usize) as u32;
                    points.extend((x..x + n).map(|x| Vec2::new(x as f32 + s.x, y as f32 + s.y)));
                    x += n;
                    if points.len() == WAVE_RAYS {
                        trace(points, (top, y + 1), pixels);
                        top = y;
                    }
                }
                continue;
            }
            for x in x0..x1 {
                if self.spp > 1 || samples.is_empty() {
                    pixel_samples(self.spp, &mut Rng::for_pixel(x, y, 0), samples);
                }
                for s in samples.iter() {
                    points.push(Vec2::new(x as f32 + s.x, y as f32 + s.y));
                    if points.len() == WAVE_RAYS {
                        trace(points, (top, y + 1), pixels);
                        top = y;
                    }
                }
            }
        }
        if !points.is_empty() {
            trace(points, (top, y1), pixels);
        }
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
        let (x0, y0, x1, y1) = self.bounds();
        let (w, h) = (x1 - x0, y1 - y0);
        let total = h as usize + 1;
        let done = std::sync::atomic::AtomicUsize::new(0);
        // Three floats a corner (not the four of a `Color`): the grid is image-sized.
        let rows: Vec<(Vec<Vec3>, RayStats)> = (y0..=y1)
            .into_par_iter()
            .map_init(
                || (Wave::default(), Vec::new(), Vec::new()),
                |(wave, rays, colors), y| {
                    if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                        return None;
                    }
                    let mut stats = RayStats::default();
                    let mut row = Vec::with_capacity(w as usize + 1);
                    for xs in (x0..=x1).collect::<Vec<_>>().chunks(WAVE_RAYS) {
                        rays.clear();
                        rays.extend(xs.iter().map(|&x| rig.ray(x as f32, y as f32)));
                        wave.trace(integrator, rays, None, colors, &mut stats);
                        row.extend(colors.iter().map(|&c| Vec3::from(c)));
                    }
                    progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
                    Some((row, stats))
                },
            )
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
                image.set(x as u32, y as u32, c.into());
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

    #[test]
    fn spd_rules_limit_the_depth_to_five() {
        let scene = ball();
        let r = Renderer::new(&scene).unwrap().spd_rules();
        assert_eq!((r.max_depth, r.corners, r.one_sided, r.cutoff), (5, true, true, 0.0));
    }
}
