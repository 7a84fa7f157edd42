//! Meshes from OBJ files in scenes: smooth shading, and identical images with and
//! without the BVH.

use std::path::Path;
use whitted::accel::AccelKind;
use whitted::prelude::*;
use whitted::scene::{self, generate, obj};

fn mesh_scene(dir: &Path, smooth: bool) -> Scene {
    let mut f = std::fs::File::create(dir.join("bumpy.obj")).unwrap();
    obj::write_obj(&generate::cube_sphere(24), &mut f).unwrap();
    let toml = format!(
        r#"
[camera]
position = [0, 0.6, 3.2]
look_at = [0, 0, 0]
fov = 40
width = 96
height = 96

[[light]]
position = [4, 5, 6]

[[mesh]]
file = "bumpy.obj"
smooth = {smooth}
material = {{ color = [0.9, 0.6, 0.3], shininess = 30 }}
transform = {{ rotate = [0, 30, 0], scale = 1.1 }}

[[quad]]
corner = [-4, -1.3, 4]
edge_u = [8, 0, 0]
edge_v = [0, 0, -8]
material = {{ color = [0.5, 0.5, 0.5], reflectivity = 0.3 }}
"#
    );
    let path = dir.join(format!("mesh-{smooth}.toml"));
    std::fs::write(&path, toml).unwrap();
    scene::load_file(&path).unwrap()
}

#[test]
fn mesh_scene_is_identical_with_and_without_bvh() {
    let dir = tempfile::tempdir().unwrap();
    for smooth in [false, true] {
        let scene = mesh_scene(dir.path(), smooth);
        let a = Renderer::new(&scene).unwrap().accel(AccelKind::Bvh).render();
        let b = Renderer::new(&scene).unwrap().accel(AccelKind::None).render();
        assert!(a == b, "smooth = {smooth}: BVH and brute force differ");
    }
}

#[test]
fn smooth_shading_removes_facet_edges() {
    // Neighbouring pixels on a flat-shaded mesh jump where facets meet; interpolated
    // normals make the shading vary smoothly, so the summed jumps drop.
    let dir = tempfile::tempdir().unwrap();
    let roughness = |smooth| {
        let img = Renderer::new(&mesh_scene(dir.path(), smooth)).unwrap().render();
        let mut sum = 0.0;
        for y in 30..66 {
            for x in 30..65 {
                sum += (img.pixel(x, y) - img.pixel(x + 1, y)).abs().element_sum();
            }
        }
        sum
    };
    let (flat, smooth) = (roughness(false), roughness(true));
    assert!(smooth < 0.8 * flat, "smooth {smooth} vs flat {flat}");
}
