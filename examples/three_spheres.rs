//! Builds a small scene in code and renders it: three spheres, one glass, one mirror,
//! on a checkered floor.
//!
//!     cargo run --release --example three_spheres -- out.png

use whitted::prelude::*;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args().nth(1).unwrap_or_else(|| "three_spheres.png".into());

    let camera = Camera::new(Vec3::new(0.0, 2.0, 6.0), Vec3::new(0.0, 0.5, 0.0), Vec3::Y, 40.0, 640, 400);
    let mut scene = Scene::new(camera);
    scene.settings.background = Color::new(0.1, 0.12, 0.2);

    let floor = scene.add_material(
        Material::textured(Texture::Checker {
            size: 1.0,
            offset: Vec3::new(0.0, 0.5, 0.0),
            colors: [Color::splat(0.9), Color::splat(0.2)],
        })
        .matte(),
    );
    let red = scene.add_material(Material::color(Color::new(0.9, 0.1, 0.1)).shininess(80.0));
    let glass = scene.add_material(Material::color(Color::new(0.8, 1.0, 0.9)).transparent(0.9, 1.5));
    let mirror = scene.add_material(Material::color(Color::splat(0.8)).reflective(0.8));

    scene
        .add(Quad::new(Vec3::new(-10.0, 0.0, 10.0), Vec3::new(20.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -20.0)), floor)
        .add(Sphere::new(Vec3::new(-1.6, 0.8, 0.0), 0.8), red)
        .add(Sphere::new(Vec3::new(0.0, 0.8, 1.0), 0.8), glass)
        .add(Sphere::new(Vec3::new(1.6, 0.8, 0.0), 0.8), mirror)
        .add_light(PointLight::new(Vec3::new(-4.0, 8.0, 6.0), Color::splat(0.8)))
        .add_light(PointLight::new(Vec3::new(5.0, 6.0, 2.0), Color::splat(0.4)));

    let image = Renderer::new(&scene)?.spp(16).render();
    write_png(&image, std::path::Path::new(&out))?;
    println!("wrote {out}");
    Ok(())
}
