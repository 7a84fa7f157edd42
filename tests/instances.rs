//! Instances: one mesh placed many times shares one tree. They render as the mesh
//! copied into place would, the same with and without the acceleration structure, and
//! cost a transform each, not a mesh each.

use std::sync::Arc;
use whitted::accel::{AccelKind, World};
use whitted::geometry::{self, Mesh, Shape, affine};
use whitted::prelude::*;
use whitted::scene::generate;

/// A ring of `n` placements of one bumpy ball over a floor: turned, scaled (one
/// stretched along x), moved. As instances, or as copies moved vertex by vertex.
fn ring(mesh: &Arc<Mesh>, n: usize, instanced: bool) -> Scene {
    let mut scene = Scene::new(Camera::new(Vec3::new(0.0, 3.0, 7.0), Vec3::new(0.0, 0.3, 0.0), Vec3::Y, 50.0, 80, 60));
    let shiny = scene.add_material(Material::color(Color::new(0.9, 0.6, 0.3)).shininess(30.0).reflective(0.2));
    let floor = scene.add_material(Material::color(Color::splat(0.6)));
    scene.add(Quad::new(Vec3::new(-6.0, -0.8, 6.0), Vec3::new(12.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -12.0)), floor);
    for k in 0..n {
        let a = k as f32 / n as f32 * std::f32::consts::TAU;
        let scale = if k == 0 { Vec3::new(1.6, 0.8, 0.8) } else { Vec3::splat(0.5 + 0.1 * (k % 3) as f32) };
        let m = affine(
            Vec3::new(2.5 * a.cos(), 0.0, 2.5 * a.sin()),
            Vec3::new(10.0 * k as f32, 37.0 * k as f32, 0.0),
            scale,
        );
        let shape = if instanced {
            geometry::instance(mesh, &m)
        } else {
            geometry::transform(Shape::Mesh(mesh.clone()), &m).unwrap()
        };
        scene.add(shape, shiny);
    }
    scene.add_light(PointLight::new(Vec3::new(3.0, 6.0, 4.0), Color::ONE));
    scene
}

fn render(scene: &Scene, accel: AccelKind) -> Image {
    Renderer::new(scene).unwrap().accel(accel).threads(2).render()
}

#[test]
fn instances_render_as_copies_of_the_mesh_would() {
    let mesh = Arc::new(generate::cube_sphere(10));
    let (inst, copies) = (ring(&mesh, 7, true), ring(&mesh, 7, false));
    let a = render(&inst, AccelKind::Bvh);
    // With and without the trees: the same triangles met, bit for bit.
    let c = render(&inst, AccelKind::None);
    let bits = |i: &Image| -> Vec<u32> {
        (0..i.height())
            .flat_map(|y| (0..i.width()).map(move |x| (x, y)))
            .flat_map(|(x, y)| i.pixel(x, y).to_array().map(f32::to_bits))
            .collect()
    };
    assert!(bits(&a) == bits(&c), "instances differ with and without the BVH");
    // Against copies moved vertex by vertex the arithmetic differs (rays carried into
    // the mesh's space), so allow rounding at silhouettes: a few pixels, never many.
    let b = render(&copies, AccelKind::Bvh);
    let (w, h) = (a.width(), a.height());
    let (mut off, mut lit) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let (p, q) = (a.pixel(x, y), b.pixel(x, y));
            off += ((p - q).abs().max_element() > 2.0 / 255.0) as usize;
            lit += (p.max_element() > 0.05) as usize;
        }
    }
    assert!(lit > (w * h / 2) as usize, "the scene is mostly dark: {lit} lit pixels");
    assert!(off * 200 < (w * h) as usize, "{off} of {} pixels differ by more than two levels", w * h);
}

#[test]
fn instances_share_one_tree() {
    let mesh = Arc::new(generate::cube_sphere(24));
    // The trees alone: the light's buffer grows with the objects round it, shared or not.
    let bytes = |n, instanced| {
        let scene = ring(&mesh, n, instanced);
        let world = World::new(&scene, AccelKind::Bvh);
        world.memory_bytes() - world.light_buffer_bytes()
    };
    let (one, many, copies) = (bytes(1, true), bytes(300, true), bytes(300, false));
    // 300 instances add their top-level entries, about 200 bytes each; 300 copies
    // add 299 trees of the mesh.
    assert!(many < one + 300 * 400, "one instance {one} bytes, 300 instances {many}");
    assert!(copies > one * 250, "one copy {one} bytes, 300 copies {copies}");
}

/// `[[instance]]` in a scene file: the named mesh placed again, with its material or
/// another, renders as the mesh written out again with that transform would.
#[test]
fn instances_in_a_scene_file_render_as_the_mesh_written_again() {
    let dir = tempfile::tempdir().unwrap();
    let mut f = std::fs::File::create(dir.path().join("ball.obj")).unwrap();
    whitted::scene::obj::write_obj(&generate::cube_sphere(8), &mut f).unwrap();
    let head = "[camera]\nposition = [0, 2, 6]\nlook_at = [0, 0, 0]\nfov = 50\nwidth = 64\nheight = 48\n\n\
                [[light]]\nposition = [3, 5, 4]\n\n[material.clay]\ncolor = [0.8, 0.5, 0.3]\n\n\
                [material.gold]\ncolor = [1, 0.8, 0.2]\nshininess = 40\n\n";
    let mesh = |name: &str, transform: &str, material: &str| {
        format!("[[mesh]]\n{name}file = \"ball.obj\"\nmaterial = \"{material}\"\ntransform = {transform}\n\n")
    };
    let (left, right, up) = (
        "{ translate = [-1.5, 0, 0], rotate = [0, 20, 0] }",
        "{ translate = [1.5, 0, 0], scale = 0.7 }",
        "{ translate = [0, 1.2, -1], scale = [1.5, 0.5, 1] }",
    );
    let instanced = format!(
        "{head}{}[[instance]]\nof = \"ball\"\ntransform = {right}\n\n[[instance]]\nof = \"ball\"\ntransform = {up}\nmaterial = \"gold\"\n",
        mesh("name = \"ball\"\n", left, "clay")
    );
    let written = format!("{head}{}{}{}", mesh("", left, "clay"), mesh("", right, "clay"), mesh("", up, "gold"));
    let load = |text: &str| whitted::scene::load_str(text, "test.toml", dir.path()).unwrap();
    let (a, b) = (load(&instanced), load(&written));
    assert_eq!(a.objects.len(), 3);
    assert!(matches!(a.objects[1].shape, Shape::Transformed(_)), "the instances share the mesh");
    let (a, b) = (render(&a, AccelKind::Bvh), render(&b, AccelKind::Bvh));
    let (mut off, mut lit) = (0, 0);
    for y in 0..a.height() {
        for x in 0..a.width() {
            off += ((a.pixel(x, y) - b.pixel(x, y)).abs().max_element() > 2.0 / 255.0) as u32;
            lit += (a.pixel(x, y).max_element() > 0.1) as u32;
        }
    }
    assert!(lit * 10 > a.width() * a.height(), "only {lit} pixels lit");
    assert!(off * 100 < a.width() * a.height(), "{off} pixels differ by more than two levels");
}

/// A named glTF asset placed again: each of its meshes comes again, shared, moved by the
/// instance's transform in place of the asset's.
#[test]
fn a_gltf_asset_placed_again_brings_each_of_its_meshes() {
    let model = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/model.glb");
    let text = format!(
        "[camera]\nposition = [0, 3, 12]\nlook_at = [0, 0, 0]\nfov = 50\nwidth = 64\nheight = 40\n\n\
         [[gltf]]\nname = \"still life\"\nfile = {:?}\ntransform = {{ translate = [-3, 0, 0] }}\n\n\
         [[instance]]\nof = \"still life\"\ntransform = {{ translate = [3, 0, 0] }}\n",
        model.display().to_string()
    );
    let dir = tempfile::tempdir().unwrap();
    let scene = whitted::scene::load_str(&text, "test.toml", dir.path()).unwrap();
    let meshes = scene.objects.iter().filter(|o| matches!(o.shape, Shape::Mesh(_))).count();
    let placed: Vec<_> = scene.objects.iter().filter(|o| matches!(o.shape, Shape::Transformed(_))).collect();
    assert!(meshes >= 4 && placed.len() == meshes, "{meshes} meshes, {} instances", placed.len());
    // Each instance lies 6 to the right of its mesh, wherever the node tree put it.
    for (o, i) in scene.objects.iter().take(meshes).zip(placed) {
        let (a, b) = (o.shape.bounds(), i.shape.bounds());
        let moved = (b.min - a.min).abs().max((b.max - a.max).abs());
        assert!((b.min.x - a.min.x - 6.0).abs() < 1e-3 && moved.y < 1e-3 && moved.z < 1e-3, "{a:?} -> {b:?}");
        assert_eq!(o.material, i.material, "an instance keeps the asset's materials");
    }
}

/// An instance with keys: its first and last frames are the scene with the keys'
/// transforms written in, and it stays an instance (shared triangles) in between.
#[test]
fn keyed_instances_move_as_their_keys_say() {
    let head = "[camera]\nposition = [0, 2, 8]\nlook_at = [0, 0, 0]\nfov = 50\nwidth = 48\nheight = 32\n\n\
                [[light]]\nposition = [3, 5, 4]\n\n[[mesh]]\nname = \"tri\"\n\
                positions = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]\n\
                triangles = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]\nsmooth = false\n\
                material = { color = [0.9, 0.6, 0.3] }\ntransform = { translate = [-2, 0, 0] }\n\n";
    // Each part named by both keys: a part one key leaves out holds the other key's value.
    let (a, b) = (
        "{ translate = [1, 0, 0], rotate = [0, 0, 0], scale = 1 }",
        "{ translate = [2, 1, 0], rotate = [0, 90, 0], scale = 1.5 }",
    );
    let keyed = format!(
        "{head}[[instance]]\nof = \"tri\"\ninterpolation = \"smooth\"\n\
         keys = [{{ frame = 0, transform = {a} }}, {{ frame = 5, transform = {b} }}]\n"
    );
    let fixed = |t: &str| format!("{head}[[instance]]\nof = \"tri\"\ntransform = {t}\n");
    let dir = std::path::Path::new(".");
    let (scene, anim, _) = whitted::scene::load_animated_str(&keyed, "keyed.toml", dir).unwrap();
    for (frame, t) in [(0, a), (5, b)] {
        let want = whitted::scene::load_str(&fixed(t), "fixed.toml", dir).unwrap();
        let got = anim.scene_at(&scene, frame).unwrap();
        assert_eq!(got.objects.len(), want.objects.len());
        for (x, y) in got.objects.iter().zip(&want.objects) {
            assert_eq!(x.shape, y.shape, "frame {frame}");
        }
    }
    let mid = anim.scene_at(&scene, 2).unwrap();
    assert!(matches!(mid.objects[1].shape, Shape::Transformed(_)), "{:?}", mid.objects[1].shape);
    assert!(anim.moves_geometry(0, 2), "the instance moves");
}
