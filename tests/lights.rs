//! The light kinds, attenuation, Fresnel glass and absorption, as rendered by the one
//! core: each checked against what the geometry or the physics says.

use whitted::accel::{AccelKind, World};
use whitted::integrator::{Integrator, Path, RayStats};
use whitted::light::{Attenuation, DirectionalLight, Light, PointLight, SpotLight};
use whitted::math::Ray;
use whitted::prelude::*;

/// A white matte floor at y = 0 lit by `light` alone, no ambient light.
fn floor(light: impl Into<Light>) -> Scene {
    let mut scene = Scene::new(Camera::new(Vec3::new(0.0, 5.0, 5.0), Vec3::ZERO, Vec3::Y, 40.0, 8, 8));
    scene.settings.ambient = 0.0;
    let white = scene.add_material(Material::color(Color::ONE).matte());
    scene.add(Quad::new(Vec3::new(-20.0, 0.0, 20.0), Vec3::new(40.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -40.0)), white);
    scene.add_light(light);
    scene
}

/// The colour seen looking straight down at floor point (x, 0, z), from both paths:
/// a wave of one ray, and depth first.
fn seen(scene: &Scene, x: f32, z: f32) -> Color {
    let world = World::new(scene, AccelKind::Bvh);
    let integrator = Integrator::new(&world, 5);
    let ray = Ray::new(Vec3::new(x, 0.5, z), Vec3::NEG_Y);
    let mut colors = Vec::new();
    whitted::integrator::Wave::default().trace(&integrator, &[ray], None, &mut colors, &mut RayStats::default());
    let deep = integrator.trace_primary(&ray, &mut RayStats::default());
    assert_eq!(colors[0], deep, "wave and depth first at ({x}, {z})");
    colors[0]
}

#[test]
fn a_spot_lights_its_cone_and_its_edge_lands_where_the_angles_put_it() {
    let (h, inner, outer) = (4.0f32, 10.0f32, 20.0f32);
    let scene = floor(SpotLight::new(Vec3::new(0.0, h, 0.0), Vec3::NEG_Y, inner, outer, Color::ONE));
    let (r_in, r_out) = (h * inner.to_radians().tan(), h * outer.to_radians().tan());
    // Full light inside the inner cone (the cosine of the angle at the floor).
    let centre = seen(&scene, 0.0, 0.0);
    assert!((centre.x - 1.0).abs() < 1e-5, "{centre}");
    let cos = |r: f32| h / (h * h + r * r).sqrt();
    let near_inner = seen(&scene, 0.98 * r_in, 0.0);
    assert!((near_inner.x - cos(0.98 * r_in)).abs() < 1e-4, "{near_inner}");
    // Some light just inside the outer edge, none just past it, less and less between.
    assert!(seen(&scene, 0.97 * r_out, 0.0).x > 0.0);
    assert_eq!(seen(&scene, 1.03 * r_out, 0.0), Color::ZERO);
    assert_eq!(seen(&scene, 0.0, -1.03 * r_out), Color::ZERO, "round the axis, not along x only");
    let steps: Vec<f32> = (0..20).map(|i| seen(&scene, r_in + (r_out - r_in) * i as f32 / 19.0, 0.0).x).collect();
    assert!(steps.windows(2).all(|w| w[1] <= w[0]), "{steps:?}");
}

#[test]
fn a_directional_light_lights_by_its_angle_and_casts_parallel_shadows() {
    let dir = Vec3::new(0.6, -0.8, 0.0);
    let mut scene = floor(DirectionalLight::new(dir, Color::ONE));
    let c = seen(&scene, 3.0, 7.0);
    assert!((c.x - 0.8).abs() < 1e-5, "cosine 0.8 everywhere: {c}");
    // A ball at height 4 shadows the floor 3 units further along x, wherever it stands.
    let opaque = scene.add_material(Material::color(Color::ONE));
    for x in [-6.0, 5.0] {
        scene.add(Sphere::new(Vec3::new(x, 4.0, 0.0), 0.5), opaque);
    }
    for x in [-6.0f32, 5.0] {
        assert_eq!(seen(&scene, x + 3.0, 0.0), Color::ZERO, "shadow at {}", x + 3.0);
        assert!(seen(&scene, x + 3.0, 1.0).x > 0.7, "lit beside it");
    }
}

#[test]
fn attenuation_divides_by_constant_linear_and_quadratic_terms() {
    let light = PointLight::new(Vec3::new(0.0, 2.0, 0.0), Color::ONE);
    let plain = seen(&floor(light), 0.0, 0.0).x;
    assert!((plain - 1.0).abs() < 1e-5);
    let faded = seen(&floor(light.with_attenuation(Attenuation::new(1.0, 0.5, 0.25))), 0.0, 0.0).x;
    // d = 2 (less the shadow ray's offset off the floor): 1 / (1 + 0.5·2 + 0.25·4) = 1/3.
    assert!((faded - 1.0 / 3.0).abs() < 1e-3, "{faded}");
}

/// A head-on camera ray into a pane of Fresnel glass of index 1.5 (transparency 1).
fn pane_shares(cos: f32) -> (f32, f32) {
    let mut scene = Scene::new(Camera::new(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 40.0, 8, 8));
    let glass = scene.add_material(Material::color(Color::ONE).transparent(1.0, 1.5).with_fresnel(true));
    scene.add(Quad::new(Vec3::new(-50.0, -50.0, 0.0), Vec3::new(100.0, 0.0, 0.0), Vec3::new(0.0, 100.0, 0.0)), glass);
    let world = World::new(&scene, AccelKind::Bvh);
    let integrator = Integrator::new(&world, 5).cutoff(0.0);
    let sin = (1.0 - cos * cos).sqrt();
    let ray = Ray::new(Vec3::new(0.0, -3.0 * sin / cos, 3.0), Vec3::new(0.0, sin, -cos));
    let (hit, index) = world.closest(&ray, 0.0, f32::INFINITY).unwrap();
    let surface = scene.objects[0].shape.surface(&ray, &hit);
    let [r, t] = integrator.scatter(&Path::camera(ray), &surface, index);
    (r.map_or(0.0, |(p, _)| p.weight.x), t.map_or(0.0, |(p, _)| p.weight.x))
}

#[test]
fn fresnel_glass_reflects_four_percent_head_on_and_nearly_all_at_grazing() {
    let (r, t) = pane_shares(1.0);
    assert!((r - 0.04).abs() < 1e-6 && (t - 0.96).abs() < 1e-6, "{r} {t}");
    let (r60, _) = pane_shares(60f32.to_radians().cos());
    let (r89, t89) = pane_shares(89.5f32.to_radians().cos());
    assert!(r < r60 && r60 < r89 && r89 > 0.9, "{r} {r60} {r89}");
    assert!((r89 + t89 - 1.0).abs() < 1e-6);
}

/// A block of clear glass one unit thick (z from -0.5 to 0.5) that absorbs
/// `absorption`, before a white background, lit from straight above.
fn block(absorption: Color) -> Scene {
    let mut scene = Scene::new(Camera::new(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 40.0, 8, 8));
    scene.settings.background = Color::ONE;
    scene.settings.ambient = 0.0;
    let glass = scene.add_material(Material::color(Color::ONE).transparent(1.0, 1.0).matte().absorbing(absorption));
    let (x, y, z) = (Vec3::X * 4.0, Vec3::Y * 4.0, Vec3::Z);
    let c = Vec3::new(-2.0, 1.0, -0.5);
    for (corner, u, v) in [(c + z, x, y), (c + x, -x, y), (c + x + z, -z, y), (c, z, y), (c + y + z, x, -z), (c, x, z)]
    {
        scene.add(Quad::new(corner, u, v), glass);
    }
    // A floor under it, lit through it from above.
    let white = scene.add_material(Material::color(Color::ONE).matte());
    scene.add(Quad::new(Vec3::new(-9.0, -3.0, 9.0), Vec3::new(18.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -18.0)), white);
    scene.add_light(DirectionalLight::new(Vec3::new(0.0, -1.0, 0.0), Color::ONE));
    scene
}

#[test]
fn absorption_of_ln2_per_unit_halves_red_through_one_unit_and_in_the_shadow() {
    let red = Color::new(std::f32::consts::LN_2, 0.0, 0.0);
    // Straight through the block's unit thickness (z), at the background.
    let scene = block(red);
    let world = World::new(&scene, AccelKind::Bvh);
    let through = Integrator::new(&world, 10)
        .trace_primary(&Ray::new(Vec3::new(0.0, 3.0, 5.0), Vec3::NEG_Z), &mut RayStats::default());
    // (The ray inside starts and ends a hair off each face: 1e-4 of the distance.)
    assert!((through - Color::new(0.5, 1.0, 1.0)).abs().max_element() < 1e-3, "{through}");
    // The floor under it is lit through its four units of height (y from 1 to 5):
    // red 1/16, others whole.
    let floor = Integrator::new(&world, 10)
        .trace_primary(&Ray::new(Vec3::new(0.0, -2.0, 3.0), Vec3::NEG_Y), &mut RayStats::default());
    assert!(floor.x > 0.0);
    let lit = Integrator::new(&world, 10)
        .trace_primary(&Ray::new(Vec3::new(0.0, -2.0, 0.0), Vec3::NEG_Y), &mut RayStats::default());
    assert!((lit - Color::new(1.0 / 16.0, 1.0, 1.0)).abs().max_element() < 1e-4, "{lit}");
    // Without absorption, all of it.
    let clear = block(Color::ZERO);
    let world = World::new(&clear, AccelKind::Bvh);
    let lit = Integrator::new(&world, 10)
        .trace_primary(&Ray::new(Vec3::new(0.0, -2.0, 0.0), Vec3::NEG_Y), &mut RayStats::default());
    assert!((lit - Color::ONE).abs().max_element() < 1e-5, "{lit}");
}
