//! Working memory does not grow with the depth limit or the samples per pixel: a
//! counting allocator measures the most bytes held at once during a render, beyond
//! what was held before it started.
//!
//! One test function: the counts are global, and tests in one binary run in parallel.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};
use whitted::prelude::*;

struct Counting;

static HELD: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every call is passed on to the system allocator unchanged, with the caller's
// layout and pointer; the counters only observe sizes, so the `GlobalAlloc` contract
// (memory valid for the layout, freed with the same layout) is the system's.
#[allow(unsafe_code)]
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let held = HELD.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
        PEAK.fetch_max(held, Ordering::Relaxed);
        // SAFETY: as above.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        HELD.fetch_sub(layout.size(), Ordering::Relaxed);
        // SAFETY: as above.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > layout.size() {
            let held = HELD.fetch_add(new_size - layout.size(), Ordering::Relaxed) + new_size - layout.size();
            PEAK.fetch_max(held, Ordering::Relaxed);
        } else {
            HELD.fetch_sub(layout.size() - new_size, Ordering::Relaxed);
        }
        // SAFETY: as above.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// The most bytes held at once while `f` runs, beyond those held when it started.
fn peak_during(f: impl FnOnce()) -> usize {
    let before = HELD.load(Ordering::Relaxed);
    PEAK.store(before, Ordering::Relaxed);
    f();
    PEAK.load(Ordering::Relaxed) - before
}

/// A box of glass that reflects 0.45 and transmits 0.45 inside a box of mirrors: every
/// hit on the glass sends two rays on, so a ray's tree doubles with each level.
fn glass_box(width: u32) -> Scene {
    let mut scene = Scene::new(Camera::new(Vec3::new(0.0, 0.3, 2.5), Vec3::ZERO, Vec3::Y, 60.0, width, width));
    let glass = scene.add_material(Material::color(Color::new(0.6, 0.8, 1.0)).reflective(0.45).transparent(0.45, 1.5));
    let mirror = scene.add_material(Material::color(Color::ONE).reflective(0.9).matte());
    // The six faces of the cube of half-size `h` round the origin, normals out (in
    // when `h` is negative: both edges flip, so their cross product does not).
    let mut cube = |h: f32, material| {
        let (x, y, z) = (Vec3::X * 2.0 * h, Vec3::Y * 2.0 * h, Vec3::Z * 2.0 * h);
        let c = Vec3::splat(-h);
        for (corner, u, v) in
            [(c + z, x, y), (c + x, -x, y), (c + x + z, -z, y), (c, z, y), (c + y + z, x, -z), (c, x, z)]
        {
            scene.add(Quad::new(corner, u, v), material);
        }
    };
    cube(1.0, glass);
    cube(-3.0, mirror);
    scene.add_light(PointLight::new(Vec3::new(0.5, 1.5, 2.0), Color::ONE));
    scene
}

#[test]
fn working_memory_does_not_grow_with_depth_or_samples() {
    let render = |scene: &Scene, depth: u32, spp: u32, cutoff: f32| {
        let r = Renderer::new(scene).unwrap().threads(1).max_depth(depth).spp(spp).cutoff(cutoff);
        let mut image = None;
        let peak = peak_during(|| image = Some(r.render()));
        (peak, image.unwrap())
    };
    let scene = glass_box(16);
    // With the default cutoff the glass box's rays fade out after a few levels; without
    // it every level doubles them, and the wave must send the excess depth first.
    let (shallow, _) = render(&scene, 10, 1, whitted::scene::DEFAULT_CUTOFF);
    let (deep, image) = render(&scene, 1000, 1, whitted::scene::DEFAULT_CUTOFF);
    assert!(image.pixel(8, 8) != Color::ZERO);
    eprintln!("glass box 16x16: depth 10 {shallow} bytes, depth 1000 {deep} bytes");
    assert!(deep < shallow + (256 << 10), "depth 1000 held {deep} bytes, depth 10 {shallow}");
    let small = glass_box(4);
    let (d6, _) = render(&small, 6, 1, 0.0);
    let (d13, _) = render(&small, 13, 1, 0.0);
    eprintln!("glass box 4x4 without cutoff: depth 6 {d6} bytes, depth 13 {d13} bytes");
    assert!(d13 < d6 + (256 << 10), "depth 13 held {d13} bytes, depth 6 {d6}");
    // Samples go through in waves of at most 1024 camera rays, each sample with at most
    // 16 rays in a level: the waves' buffers are bounded by that, whatever the samples
    // per pixel, but for the samples' positions in their pixel (8 bytes each).
    let (few, _) = render(&small, 4, 64, 0.0);
    let (many, _) = render(&small, 4, 4096, 0.0);
    eprintln!("glass box 4x4 depth 4: 64 spp {few} bytes, 4096 spp {many} bytes");
    let waves = 4 << 20;
    assert!(few < waves && many < waves + 4096 * 8, "64 spp held {few} bytes, 4096 spp {many}");
    // And all of it is small: the waves' buffers, not the rays' trees.
    assert!(deep < 16 << 20 && d13 < 16 << 20 && many < 16 << 20, "{deep} {d13} {many}");
}
