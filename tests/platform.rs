//! Every platform: the portable path (forced by `WHITTED_PORTABLE=1`; the only one where
//! the processor lacks AVX2 or is not x86-64) renders the same images, byte for byte, as
//! the eight-lane AVX2 path; and a build without the `viewer` feature says so when asked
//! for the window.

mod common;

use common::{manifest, whitted_command};
use std::path::Path;

/// Renders `args` with the portable path forced or not, and returns the PNG's bytes.
fn render(dir: &Path, name: &str, portable: bool, args: &[&str]) -> Vec<u8> {
    let out = dir.join(format!("{name}-{}.png", if portable { "portable" } else { "default" }));
    let mut cmd = whitted_command();
    cmd.args(["render", "-q", "-o", out.to_str().unwrap()]).args(args);
    if portable {
        cmd.env("WHITTED_PORTABLE", "1");
    } else {
        cmd.env_remove("WHITTED_PORTABLE");
    }
    let run = cmd.output().expect("run whitted");
    assert!(run.status.success(), "whitted render {args:?} failed: {}", String::from_utf8_lossy(&run.stderr));
    std::fs::read(&out).unwrap()
}

fn same_both_ways(dir: &Path, name: &str, args: &[&str]) {
    let (fast, portable) = (render(dir, name, false, args), render(dir, name, true, args));
    assert!(fast == portable, "{name}: the portable path's image differs from the default path's");
}

/// The room takes the tile path: eight-lane blocks of quads and mirrors with AVX2.
#[test]
fn room_is_identical_on_the_portable_path() {
    let dir = tempfile::tempdir().unwrap();
    let room = manifest("scenes/room.toml");
    same_both_ways(dir.path(), "room", &[room.to_str().unwrap(), "--width", "160", "--height", "160", "--spp", "2"]);
}

/// A sphereflake (91 spheres, packed four to a leaf) and a mesh with analytic shapes
/// beside it: the 8-wide trees and the paired triangle tests with AVX2.
#[test]
fn sphereflake_and_mesh_are_identical_on_the_portable_path() {
    let dir = tempfile::tempdir().unwrap();
    let flake = dir.path().join("flake.nff");
    let run = whitted_command()
        .args(["generate", "sphereflake", "--level", "2", "-o", flake.to_str().unwrap()])
        .output()
        .expect("run whitted");
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    same_both_ways(dir.path(), "flake", &[flake.to_str().unwrap(), "--width", "128", "--height", "128"]);

    let mut f = std::fs::File::create(dir.path().join("bumpy.obj")).unwrap();
    whitted::scene::obj::write_obj(&whitted::scene::generate::cube_sphere(24), &mut f).unwrap();
    let scene = dir.path().join("mesh.toml");
    std::fs::write(
        &scene,
        r#"
[camera]
position = [0, 0.6, 3.2]
look_at = [0, 0, 0]
fov = 40
width = 128
height = 128

[[light]]
position = [4, 5, 6]

[[mesh]]
file = "bumpy.obj"
smooth = true
material = { color = [0.9, 0.6, 0.3], shininess = 30 }

[[sphere]]
center = [1.2, 0.2, 0.3]
radius = 0.4
material = { color = [0.8, 0.8, 0.9], reflectivity = 0.5 }

[[quad]]
corner = [-4, -1.3, 4]
edge_u = [8, 0, 0]
edge_v = [0, 0, -8]
material = { color = [0.5, 0.5, 0.5], reflectivity = 0.3 }
"#,
    )
    .unwrap();
    same_both_ways(dir.path(), "mesh", &[scene.to_str().unwrap()]);
}

#[cfg(not(feature = "viewer"))]
#[test]
fn view_says_it_was_built_without_the_viewer() {
    let run = whitted_command().arg("view").output().expect("run whitted");
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success(), "whitted view succeeded without the viewer");
    assert!(err.contains("built without the viewer") && err.contains("--features viewer"), "{err}");
}

/// On every platform (aarch64 under qemu in CI included) the room is within one level
/// per channel of the reference image rendered on x86-64 (which it matches exactly
/// there). tests/render.rs allows more, for other compilers; this is the bound across
/// this project's platforms.
#[test]
fn room_is_within_one_level_of_the_x86_64_reference() {
    use whitted::prelude::*;
    let room = whitted::scene::load_file(&manifest("scenes/room.toml")).unwrap();
    let image = Renderer::new(&room).unwrap().size(200, 200).spp(4).render().to_rgb8();
    let reference = image::open(manifest("tests/reference/room-200-spp4.png")).unwrap().to_rgb8();
    assert_eq!(image.dimensions(), reference.dimensions());
    let worst = image.as_raw().iter().zip(reference.as_raw()).map(|(a, b)| a.abs_diff(*b)).max().unwrap();
    let off = image.pixels().zip(reference.pixels()).filter(|(a, b)| a != b).count();
    assert!(worst <= 1, "the room differs from the reference by up to {worst} levels ({off} pixels differ)");
    eprintln!("room vs the x86-64 reference: {off} pixels differ, by at most {worst} level");
}
