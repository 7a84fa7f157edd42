//! A field of one mesh placed many times, as instances or flattened into copies: prints
//! the triangle count, build and render times, the ray rate and the acceleration
//! structure's bytes, for docs/performance.md (peak memory from `/usr/bin/time -v`).
//!
//! cargo run --release --example instances -- COUNT [instances|copies|one] [MESH_N] [OUT.png]
//!
//! `copies`: each placement a mesh of its own; `one`: all placements flattened into
//! one mesh (one material then).
//!
//! The mesh is the bumpy cube-sphere of `whitted generate`'s benchmark, 12·N² triangles
//! (N = 91: 99,372).

use std::sync::Arc;
use std::time::Instant;
use whitted::accel::{AccelKind, World};
use whitted::geometry::{self, Mesh, Shape, affine};
use whitted::prelude::*;
use whitted::scene::generate;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let count: usize = args.first().and_then(|a| a.parse().ok()).unwrap_or(10_000);
    let mode = args.get(1).map_or("instances", String::as_str);
    let n: u32 = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(91);
    let mesh = Arc::new(generate::cube_sphere(n));
    let side = (count as f32).sqrt().ceil() as usize;
    let mut scene = Scene::new(Camera::new(
        Vec3::new(0.0, side as f32 * 0.9, side as f32 * 1.3),
        Vec3::ZERO,
        Vec3::Y,
        45.0,
        512,
        512,
    ));
    let colours = [Color::new(0.8, 0.3, 0.2), Color::new(0.3, 0.7, 0.3), Color::new(0.3, 0.4, 0.9)];
    let materials: Vec<_> =
        colours.iter().map(|&c| scene.add_material(Material::color(c).shininess(20.0).reflective(0.1))).collect();
    let floor = scene.add_material(Material::color(Color::splat(0.7)));
    let h = side as f32 * 1.2;
    scene.add(Quad::new(Vec3::new(-h, -0.5, h), Vec3::new(2.0 * h, 0.0, 0.0), Vec3::new(0.0, 0.0, -2.0 * h)), floor);
    let start = Instant::now();
    let (mut positions, mut triangles) = (Vec::new(), Vec::new());
    for k in 0..count {
        let (i, j) = ((k % side) as f32, (k / side) as f32);
        let at = Vec3::new(2.0 * i - side as f32, 0.0, 2.0 * j - side as f32);
        let m = affine(at, Vec3::new(0.0, (k * 37 % 360) as f32, 0.0), Vec3::splat(0.45 + 0.1 * (k % 4) as f32));
        match mode {
            "copies" => {
                scene.add(geometry::transform(Shape::Mesh(mesh.clone()), &m).expect("a mesh moves"), materials[k % 3]);
            }
            "one" => {
                let first = positions.len() as u32;
                positions.extend(mesh.positions().iter().map(|&p| m.transform_point3(p)));
                triangles.extend(mesh.triangles().iter().map(|t| t.map(|v| v + first)));
            }
            _ => {
                scene.add(geometry::instance(&mesh, &m), materials[k % 3]);
            }
        }
    }
    if mode == "one" {
        scene.add(Mesh::new(positions, vec![], vec![], triangles, false).expect("a mesh"), materials[0]);
    }
    scene.add_light(PointLight::new(Vec3::new(side as f32, 3.0 * side as f32, side as f32), Color::ONE));
    let placed = start.elapsed();
    // Measured on a world of its own, dropped before the render builds its own.
    let accel_bytes = World::new(&scene, AccelKind::Bvh).memory_bytes();
    let out = Renderer::new(&scene).expect("a camera").threads(2).render_with_progress(&|_, _| {});
    let rays = out.stats.total();
    println!(
        "{count} {} of {} triangles ({} in all): placed {:.2} s, build {:.2} s, render {:.2} s, {:.2} Mrays/s, \
         acceleration {:.1} MB",
        mode,
        mesh.triangle_count(),
        mesh.triangle_count() * count,
        placed.as_secs_f64(),
        out.build_time.as_secs_f64(),
        out.elapsed.as_secs_f64(),
        rays as f64 / out.elapsed.as_secs_f64() / 1e6,
        accel_bytes as f64 / 1e6,
    );
    if let Some(path) = args.get(3) {
        whitted::film::write_png(&out.image, std::path::Path::new(path)).expect("written");
    }
}
