//! `whitted bench`: ray rates, build time and memory on built-in scenes and on meshes,
//! measured on the same ray sets as the Embree comparison harness (`$WHITTED_TOOLS/embree-bench`, docs/performance.md) so the two compare ray
//! for ray:
//! - primary: one ray through each pixel centre of a camera; for meshes (and the other
//!   generated scenes) a 1024² pinhole at c + normalize(0.3, 0.35, 1)·R / sin 20°
//!   looking at c, up +y, vertical field of view 40°, where c and R are the centre and
//!   half-diagonal of the bounding box;
//! - shadow: from each primary hit, offset 1e-4·R along the normal facing the viewer, to
//!   a point light (at c + (1.5, 2.5, 1.8)·R for meshes), stopping just short of it;
//! - incoherent: 2²⁰ rays with origins uniform in the box and directions uniform on the
//!   sphere, from the same generator and seed as the Embree benchmark (mt19937-64, 12345).
//!
//! Rays are traced in batches, as the renderer traces a tile's rays against a mesh:
//! through a mesh eight at a time, as one packet where they head into one octant (camera
//! rays and shadow rays to one light, mostly), else several tree walks at a time,
//! interleaved ([`World::closest_each`], [`World::transmittance_each`]); elsewhere one
//! by one. So the primary and shadow rates are those of packets of eight neighbouring
//! rays, each ray finding what its own walk finds.

use crate::accel::{AccelKind, World};
use crate::camera::{Camera, CameraRig};
use crate::geometry::{Mesh, Sphere};
use crate::light::PointLight;
use crate::material::Material;
use crate::math::{Aabb, Color, Ray, Vec3};
use crate::render::Renderer;
use crate::scene::{self, Scene, SceneError};
use rayon::prelude::*;
use std::time::Instant;

/// How many incoherent rays each run traces.
pub const INCOHERENT_RAYS: usize = 1 << 20;

/// A scene to measure and how to aim rays at it.
pub struct BenchCase {
    pub name: String,
    pub scene: Scene,
    pub primitives: usize,
    rig: CameraRig,
    width: u32,
    height: u32,
    light: Vec3,
    bounds: Aabb,
    incoherent: usize,
}

/// One line of results. Rates are in millions of rays per second of wall time (median
/// of the runs) and per worker CPU-second (the best run).
#[derive(Clone, Debug, serde::Serialize)]
pub struct BenchRow {
    pub scene: String,
    pub primitives: usize,
    pub accel: &'static str,
    pub threads: usize,
    pub build_ms: f64,
    pub accel_bytes: usize,
    pub bytes_per_primitive: f64,
    pub primary_mrays: f64,
    pub shadow_mrays: f64,
    pub incoherent_mrays: f64,
    pub frame_ms: f64,
    /// The same rates per CPU-second the worker threads spent tracing (immune to other
    /// load on the machine; measured as the Embree benchmark measures its own).
    pub primary_mrays_per_cpu_s: f64,
    pub shadow_mrays_per_cpu_s: f64,
    pub incoherent_mrays_per_cpu_s: f64,
    /// CPU seconds of one build.
    pub build_cpu_s: f64,
    /// Share of primary rays that hit something (a check that the camera sees the scene).
    pub primary_hit_frac: f64,
    pub runs: usize,
}

/// The standard 64-bit Mersenne Twister (std::mt19937_64), so incoherent rays match the
/// C++ benchmark's bit for bit.
pub struct Mt19937_64 {
    state: [u64; 312],
    index: usize,
}

impl Mt19937_64 {
    pub fn new(seed: u64) -> Self {
        let mut state = [0u64; 312];
        state[0] = seed;
        for i in 1..312 {
            state[i] = 6364136223846793005u64.wrapping_mul(state[i - 1] ^ (state[i - 1] >> 62)).wrapping_add(i as u64);
        }
        Mt19937_64 { state, index: 312 }
    }

    pub fn next_u64(&mut self) -> u64 {
        const UPPER: u64 = 0xFFFF_FFFF_8000_0000;
        const LOWER: u64 = 0x7FFF_FFFF;
        if self.index >= 312 {
            for i in 0..312 {
                let x = (self.state[i] & UPPER) | (self.state[(i + 1) % 312] & LOWER);
                let mut xa = x >> 1;
                if x & 1 != 0 {
                    xa ^= 0xB502_6F5A_A966_19E9;
                }
                self.state[i] = self.state[(i + 156) % 312] ^ xa;
            }
            self.index = 0;
        }
        let mut y = self.state[self.index];
        self.index += 1;
        y ^= (y >> 29) & 0x5555_5555_5555_5555;
        y ^= (y << 17) & 0x71D6_7FFF_EDA6_0000;
        y ^= (y << 37) & 0xFFF7_EEE0_0000_0000;
        y ^ (y >> 43)
    }

    /// `std::uniform_real_distribution<float>(0, 1)` as libstdc++ computes it.
    pub fn uniform_f32(&mut self) -> f32 {
        let r = self.next_u64() as f32 / 18446744073709551616.0f32;
        if r >= 1.0 { 1.0f32.next_down() } else { r }
    }
}

/// The Embree benchmark's camera and light for a box: see the module docs.
fn framing(bounds: Aabb, size: u32) -> (Camera, Vec3, f32) {
    let c = bounds.center();
    let r = 0.5 * (bounds.max - bounds.min).length();
    let dist = r / 20f32.to_radians().sin();
    let eye = c + Vec3::new(0.3, 0.35, 1.0).normalize() * dist;
    (Camera::new(eye, c, Vec3::Y, 40.0, size, size), c + Vec3::new(1.5, 2.5, 1.8) * r, r)
}

fn scene_bounds(scene: &Scene) -> Aabb {
    scene.objects.iter().fold(Aabb::EMPTY, |b, o| b.union(o.shape.bounds()))
}

impl BenchCase {
    fn new(name: String, scene: Scene, primitives: usize, light: Vec3) -> BenchCase {
        let rig = scene.camera.rig().expect("bench cameras are valid");
        let bounds = scene_bounds(&scene);
        BenchCase {
            name,
            rig,
            width: scene.camera.width,
            height: scene.camera.height,
            light,
            bounds,
            primitives,
            scene,
            incoherent: INCOHERENT_RAYS,
        }
    }

    /// A scene of one mesh, framed and lit as the Embree benchmark does.
    pub fn mesh(name: String, mesh: Mesh) -> BenchCase {
        let (camera, light, _) = framing(mesh.bounds(), 1024);
        let primitives = mesh.triangle_count();
        let mut scene = Scene::new(camera);
        let clay = scene.add_material(Material::color(Color::new(0.8, 0.7, 0.6)));
        scene.add(mesh, clay);
        scene.add_light(PointLight::new(light, Color::ONE));
        BenchCase::new(name, scene, primitives, light)
    }

    /// The seed room from its own camera and light.
    pub fn room() -> BenchCase {
        let scene = scene::load_str(scene::DEFAULT_SCENE, scene::DEFAULT_SCENE_NAME, std::path::Path::new("scenes"))
            .expect("the built-in room loads");
        let light = scene.lights[0].position().expect("the room's light is a point light");
        let n = scene.objects.len();
        BenchCase::new("room".into(), scene, n, light)
    }

    /// `side`³ spheres on a unit grid, framed like a mesh.
    pub fn sphere_grid(side: u32) -> BenchCase {
        let bounds = Aabb { min: Vec3::splat(-0.5), max: Vec3::splat(side as f32 - 0.5) };
        let (camera, light, _) = framing(bounds, 1024);
        let mut scene = Scene::new(camera);
        let m = scene.add_material(Material::color(Color::new(0.3, 0.5, 0.9)));
        for i in 0..side.pow(3) {
            let p = Vec3::new((i % side) as f32, (i / side % side) as f32, (i / (side * side)) as f32);
            scene.add(Sphere::new(p, 0.35), m);
        }
        scene.add_light(PointLight::new(light, Color::ONE));
        let n = scene.objects.len();
        BenchCase::new(format!("spheres-{n}"), scene, n, light)
    }

    /// The Embree benchmark's sphere cloud (`--spheres N`): centres uniform in the unit
    /// cube from mt19937-64 seeded 777, seen face-on so the cube's front face fills a
    /// 40° view, light at (2, 3, 2.5). The radius is found as it is there: bisection in
    /// log r (14 steps in [1e-5, 0.3]) until half the rays of a 256² view hit.
    pub fn sphere_cloud(n: usize) -> BenchCase {
        let mut rng = Mt19937_64::new(777);
        let centres: Vec<Vec3> =
            (0..n).map(|_| Vec3::new(rng.uniform_f32(), rng.uniform_f32(), rng.uniform_f32())).collect();
        let dist = 0.5 / 20f32.to_radians().tan();
        let eye = Vec3::new(0.5, 0.5, 1.0 + dist);
        let at = Vec3::new(0.5, 0.5, 0.0);
        let light = Vec3::new(2.0, 3.0, 2.5);
        let make = |radius: f32, size: u32| {
            let mut scene = Scene::new(Camera::new(eye, at, Vec3::Y, 40.0, size, size));
            let m = scene.add_material(Material::color(Color::new(0.9, 0.6, 0.3)));
            for &c in &centres {
                scene.add(Sphere::new(c, radius), m);
            }
            scene.add_light(PointLight::new(light, Color::ONE));
            scene
        };
        let (mut lo, mut hi) = (1e-5f64.ln(), 0.3f64.ln());
        for _ in 0..14 {
            let mid = 0.5 * (lo + hi);
            let scene = make(mid.exp() as f32, 256);
            let world = World::new(&scene, AccelKind::Bvh);
            let rig = scene.camera.rig().expect("valid camera");
            let hits = (0..256 * 256u32)
                .into_par_iter()
                .filter(|i| {
                    world
                        .closest(&rig.ray((i % 256) as f32 + 0.5, (i / 256) as f32 + 0.5), 0.0, f32::INFINITY)
                        .is_some()
                })
                .count();
            if hits as f64 / 65536.0 > 0.5 {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        let scene = make((0.5 * (lo + hi)).exp() as f32, 1024);
        BenchCase::new(format!("sphere-cloud-{n}"), scene, n, light)
    }

    /// The displaced cube-sphere of the Embree benchmark, 12·n² triangles.
    pub fn cube_sphere(n: u32) -> BenchCase {
        let mesh = scene::generate::cube_sphere(n);
        BenchCase::mesh(format!("cubesphere-{}", mesh.triangle_count()), mesh)
    }

    /// An OBJ file, flat-shaded.
    pub fn obj(path: &std::path::Path) -> Result<BenchCase, SceneError> {
        let mesh = scene::obj::load_obj(path, false)?;
        Ok(BenchCase::mesh(path.display().to_string(), mesh))
    }

    /// The built-in cases by name: `room`, `spheres-1000` … `spheres-1000000`,
    /// `cubesphere-1M`; on request (they take a while) `cubesphere-10M` and
    /// `sphere-cloud-1M` (the Embree benchmark's `--spheres 1000000`).
    pub fn builtin(name: &str) -> Option<BenchCase> {
        Some(match name {
            "room" => BenchCase::room(),
            "spheres-1000" => BenchCase::sphere_grid(10),
            "spheres-10000" => BenchCase::sphere_grid(22),
            "spheres-100000" => BenchCase::sphere_grid(46),
            "spheres-1000000" => BenchCase::sphere_grid(100),
            "cubesphere-1M" => BenchCase::cube_sphere(289),
            "cubesphere-10M" => BenchCase::cube_sphere(913),
            "sphere-cloud-1M" => BenchCase::sphere_cloud(1_000_000),
            _ => return None,
        })
    }

    pub const BUILTIN: &'static [&'static str] =
        &["room", "spheres-1000", "spheres-10000", "spheres-100000", "spheres-1000000", "cubesphere-1M"];
    /// Built-in cases run only when named with `--scene`.
    pub const ON_REQUEST: &'static [&'static str] = &["cubesphere-10M", "sphere-cloud-1M"];

    /// A smaller version for quick checks: `size`² primary rays, `incoherent` random ones.
    pub fn reduced(mut self, size: u32, incoherent: usize) -> BenchCase {
        self.scene.camera.width = size;
        self.scene.camera.height = size;
        self.rig = self.scene.camera.rig().expect("bench cameras are valid");
        (self.width, self.height, self.incoherent) = (size, size, incoherent);
        self
    }

    fn primary_rays(&self) -> Vec<Ray> {
        (0..self.height)
            .flat_map(|y| (0..self.width).map(move |x| (x, y)))
            .map(|(x, y)| self.rig.ray(x as f32 + 0.5, y as f32 + 0.5))
            .collect()
    }

    fn incoherent_rays(&self) -> Vec<Ray> {
        let (lo, hi) = (self.bounds.min, self.bounds.max);
        let mut rng = Mt19937_64::new(12345);
        (0..self.incoherent)
            .map(|_| {
                let o = Vec3::new(
                    lo.x + rng.uniform_f32() * (hi.x - lo.x),
                    lo.y + rng.uniform_f32() * (hi.y - lo.y),
                    lo.z + rng.uniform_f32() * (hi.z - lo.z),
                );
                let z = 2.0 * rng.uniform_f32() - 1.0;
                let ph = 2.0 * std::f32::consts::PI * rng.uniform_f32();
                let rr = (1.0 - z * z).max(0.0).sqrt();
                Ray { origin: o, dir: Vec3::new(rr * ph.cos(), rr * ph.sin(), z) }
            })
            .collect()
    }

    /// Shadow rays from the primary hits towards the light, with their lengths.
    fn shadow_rays(&self, world: &World, primary: &[Ray]) -> Vec<(Ray, f32)> {
        let eps = 1e-4 * 0.5 * (self.bounds.max - self.bounds.min).length();
        primary
            .par_iter()
            .filter_map(|ray| {
                let (hit, i) = world.closest(ray, 0.0, f32::INFINITY)?;
                let s = self.scene.objects[i as usize].shape.surface(ray, &hit);
                let n = if s.normal.dot(ray.dir) > 0.0 { -s.normal } else { s.normal };
                let p = ray.at(hit.t) + n * eps;
                let to_light = self.light - p;
                let dist = to_light.length();
                Some((Ray { origin: p, dir: to_light / dist }, dist * (1.0 - 1e-4)))
            })
            .collect()
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// CPU time (user + system) used so far by all threads of this process, in seconds.
/// Rates per CPU-second stay comparable when other programs share the machine.
/// (`clock_gettime` on Unix, `GetProcessTimes` on Windows; 0 if the system cannot
/// tell, which it always can on Linux, macOS and Windows.)
pub fn process_cpu_seconds() -> f64 {
    cpu_time::ProcessTime::try_now().map_or(0.0, |t| t.as_duration().as_secs_f64())
}

/// CPU time used so far by the calling thread, in seconds (`clock_gettime` on Unix,
/// `GetThreadTimes` on Windows; 0 if the system cannot tell).
fn thread_cpu_seconds() -> f64 {
    cpu_time::ThreadTime::try_now().map_or(0.0, |t| t.as_duration().as_secs_f64())
}

/// Wall and CPU seconds of a timed case: wall is the median of the runs; CPU is the
/// smallest over the runs, as the Embree benchmark reports it.
#[derive(Clone, Copy)]
struct Timing {
    wall: f64,
    cpu: f64,
}

/// Builds and frames: CPU is that of the whole process (median of the runs).
fn timed(runs: usize, mut f: impl FnMut()) -> Timing {
    let (mut wall, mut cpu) = (Vec::new(), Vec::new());
    for _ in 0..runs {
        let (t, c) = (Instant::now(), process_cpu_seconds());
        f();
        wall.push(t.elapsed().as_secs_f64());
        cpu.push(process_cpu_seconds() - c);
    }
    Timing { wall: median(wall), cpu: median(cpu) }
}

/// Ray cases, measured as the Embree comparison harness (`$WHITTED_TOOLS/embree-bench`, docs/performance.md) measures its own: one warm-up
/// run, then `runs` timed runs; CPU is the worker threads' CPU time spent tracing (summed
/// over chunks by `f`, which returns it), the smallest of the runs, so idle workers
/// waiting for work and other programs on the machine do not count.
fn timed_rays(runs: usize, mut f: impl FnMut() -> f64) -> Timing {
    f();
    let (mut wall, mut cpu) = (Vec::new(), f64::INFINITY);
    for _ in 0..runs {
        let t = Instant::now();
        let c = f();
        wall.push(t.elapsed().as_secs_f64());
        cpu = cpu.min(c);
    }
    Timing { wall: median(wall), cpu }
}

/// Runs `work` on each chunk of `items` in parallel; returns the sum of its results and
/// the worker CPU seconds spent in it.
fn par_chunks_timed<T: Sync>(items: &[T], work: impl Fn(&[T]) -> usize + Sync) -> (usize, f64) {
    items
        .par_chunks(CHUNK)
        .map(|c| {
            let start = thread_cpu_seconds();
            let n = work(c);
            (n, thread_cpu_seconds() - start)
        })
        .reduce(|| (0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1))
}

/// Rays a parallel worker takes at a time.
const CHUNK: usize = 4096;

/// Measures one case with one acceleration structure on `threads` threads.
pub fn run(case: &BenchCase, accel: AccelKind, runs: usize, threads: usize) -> BenchRow {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
    pool.install(|| {
        let runs = runs.max(1);
        let mut worlds = Vec::new();
        let build_s = timed(runs, || worlds.push(World::new(&case.scene, accel)));
        let world = worlds.pop().expect("at least one run");
        drop(worlds);

        let primary = case.primary_rays();
        let hits = |rays: &[Ray]| {
            par_chunks_timed(rays, |c| {
                let mut found = vec![None; c.len()];
                world.closest_each(c, 0.0, f32::INFINITY, &mut found);
                found.iter().filter(|h| h.is_some()).count()
            })
        };
        let mut primary_hits = 0;
        let primary_s = timed_rays(runs, || {
            let (n, cpu) = hits(&primary);
            primary_hits = n;
            cpu
        });
        let shadow = case.shadow_rays(&world, &primary);
        let shadow_s = timed_rays(runs, || {
            let (lit, cpu) = par_chunks_timed(&shadow, |c| {
                let mut light = vec![0.0; c.len()];
                world.transmittance_each(c, &mut light);
                light.iter().filter(|&&l| l > 0.0).count()
            });
            std::hint::black_box(lit);
            cpu
        });
        let incoherent = case.incoherent_rays();
        let incoherent_s = timed_rays(runs, || {
            let (n, cpu) = hits(&incoherent);
            std::hint::black_box(n);
            cpu
        });
        let renderer = Renderer::new(&case.scene).expect("bench cameras are valid").spp(1).accel(accel);
        let frame_s = timed(runs, || {
            std::hint::black_box(renderer.render_world(&world));
        });

        let mrays = |n: usize, s: f64| n as f64 / s / 1e6;
        let (build_s, primary_s, shadow_s, incoherent_s, frame_s) =
            (build_s, primary_s, shadow_s, incoherent_s, frame_s);
        let bytes = world.memory_bytes();
        BenchRow {
            scene: case.name.clone(),
            primitives: case.primitives,
            accel: accel.name(),
            threads,
            build_ms: build_s.wall * 1e3,
            build_cpu_s: build_s.cpu,
            accel_bytes: bytes,
            bytes_per_primitive: bytes as f64 / case.primitives.max(1) as f64,
            primary_mrays: mrays(primary.len(), primary_s.wall),
            shadow_mrays: mrays(shadow.len(), shadow_s.wall),
            incoherent_mrays: mrays(incoherent.len(), incoherent_s.wall),
            frame_ms: frame_s.wall * 1e3,
            primary_mrays_per_cpu_s: mrays(primary.len(), primary_s.cpu),
            shadow_mrays_per_cpu_s: mrays(shadow.len(), shadow_s.cpu),
            incoherent_mrays_per_cpu_s: mrays(incoherent.len(), incoherent_s.cpu),
            primary_hit_frac: primary_hits as f64 / primary.len() as f64,
            runs,
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mersenne_twister_matches_the_cpp_standard() {
        // The C++ standard requires the 10000th output of a default-seeded mt19937_64.
        let mut r = Mt19937_64::new(5489);
        let first = r.next_u64();
        assert_eq!(first, 14514284786278117030);
        let mut last = 0;
        for _ in 1..10000 {
            last = r.next_u64();
        }
        assert_eq!(last, 9981545732273789042);
    }

    #[test]
    fn bench_runs_on_a_small_mesh_and_agrees_across_structures() {
        let case = BenchCase::cube_sphere(8).reduced(64, 4096);
        let a = run(&case, AccelKind::Bvh, 1, 2);
        let b = run(&case, AccelKind::None, 1, 2);
        assert_eq!(a.primitives, 768);
        assert!(a.primary_hit_frac > 0.2 && a.primary_hit_frac < 0.9, "{}", a.primary_hit_frac);
        assert_eq!(a.primary_hit_frac, b.primary_hit_frac);
        assert!(a.accel_bytes > 0 && b.accel_bytes == 0);
        assert!(a.primary_mrays > 0.0 && a.shadow_mrays > 0.0 && a.incoherent_mrays > 0.0 && a.frame_ms > 0.0);
    }
}
