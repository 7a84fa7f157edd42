//! Micro-benchmarks of the hot routines: each shape's intersection test, and BVH
//! traversal against testing every object. `cargo bench` runs them (divan); compare
//! figures from one run, the machines are shared.

use divan::{Bencher, black_box};
use whitted::accel::{AccelKind, World};
use whitted::geometry::{Cone, Cylinder, Polygon, Quad, Shape, Sphere, Triangle, intersect_triangle};
use whitted::math::{Ray, Vec3};
use whitted::sampler::Rng;
use whitted::scene::{self, Scene};

fn main() {
    divan::main();
}

/// 1024 rays from around the unit cube towards it, most of them hitting a shape there.
fn rays() -> Vec<Ray> {
    let mut r = Rng::new(7);
    let mut v = |s: f32| Vec3::new(r.next_f32() - 0.5, r.next_f32() - 0.5, r.next_f32() - 0.5) * s;
    (0..1024)
        .map(|_| {
            let origin = v(1.0).normalize_or(Vec3::Z) * 5.0;
            let target = v(1.5);
            Ray::new(origin, target - origin)
        })
        .collect()
}

fn shapes() -> Vec<(&'static str, Shape)> {
    let y = Vec3::Y;
    vec![
        ("sphere", Sphere::new(Vec3::ZERO, 0.8).into()),
        ("quad", Quad::new(Vec3::new(-1.0, -1.0, 0.0), Vec3::X * 2.0, Vec3::Y * 2.0).into()),
        (
            "polygon",
            Polygon::new(
                (0..6)
                    .map(|i| {
                        let a = i as f32 * std::f32::consts::TAU / 6.0;
                        Vec3::new(a.cos(), a.sin(), 0.0)
                    })
                    .collect(),
            )
            .unwrap()
            .into(),
        ),
        (
            "triangle",
            Triangle::new(Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(0.0, 1.0, 0.0)).into(),
        ),
        ("cylinder", Cylinder::new(Vec3::new(0.0, -0.8, 0.0), y, 0.6, 1.6, true).into()),
        ("cone", Cone::new(Vec3::new(0.0, -0.8, 0.0), y, 0.8, 1.6, true).into()),
    ]
}

#[divan::bench(args = ["sphere", "quad", "polygon", "triangle", "cylinder", "cone"])]
fn shape_intersect(bencher: Bencher, name: &str) {
    let shape = shapes().into_iter().find(|(n, _)| *n == name).unwrap().1;
    let rays = rays();
    bencher
        .counter(divan::counter::ItemsCount::new(rays.len()))
        .bench_local(|| rays.iter().filter(|r| black_box(&shape).intersect(r, 0.0, f32::INFINITY).is_some()).count());
}

#[divan::bench]
fn moller_trumbore(bencher: Bencher) {
    let rays = rays();
    let (v0, e1, e2) = (Vec3::new(-1.0, -1.0, 0.0), Vec3::new(2.0, 0.0, 0.0), Vec3::new(1.0, 2.0, 0.0));
    bencher.counter(divan::counter::ItemsCount::new(rays.len())).bench_local(|| {
        rays.iter().filter(|r| intersect_triangle(black_box(v0), e1, e2, r, 0.0, f32::INFINITY).is_some()).count()
    });
}

fn room() -> Scene {
    scene::load_str(scene::DEFAULT_SCENE, scene::DEFAULT_SCENE_NAME, std::path::Path::new("scenes")).unwrap()
}

/// Primary rays of the room at 64 x 64, closest hit, through the BVH and by testing
/// every object.
#[divan::bench(args = [AccelKind::Bvh, AccelKind::None])]
fn room_closest_hit(bencher: Bencher, accel: AccelKind) {
    let scene = room();
    let world = World::new(&scene, accel);
    let rig = scene.camera.rig().unwrap();
    let rays: Vec<Ray> =
        (0..64 * 64).map(|i| rig.ray((i % 64) as f32 * 12.5 + 6.0, (i / 64) as f32 * 12.5 + 6.0)).collect();
    bencher
        .counter(divan::counter::ItemsCount::new(rays.len()))
        .bench_local(|| rays.iter().filter(|r| world.closest(r, 0.0, f32::INFINITY).is_some()).count());
}

/// Closest hits on a 49,152-triangle bumpy sphere from random directions.
#[divan::bench]
fn mesh_bvh_closest_hit(bencher: Bencher) {
    let mut scene = Scene::new(whitted::camera::Camera::new(Vec3::Z * 5.0, Vec3::ZERO, Vec3::Y, 40.0, 8, 8));
    let m = scene.add_material(whitted::material::Material::default());
    scene.add(scene::generate::cube_sphere(64), m);
    let world = World::new(&scene, AccelKind::Bvh);
    let rays = rays();
    bencher
        .counter(divan::counter::ItemsCount::new(rays.len()))
        .bench_local(|| rays.iter().filter(|r| world.closest(r, 0.0, f32::INFINITY).is_some()).count());
}
