//! Animation: a scene with keys, at its first and last frames, is the scene with those
//! keys' values written in; values between keys follow the interpolation; the command
//! line writes one file per frame; bad keys are reported by line and field.

mod common;

use common::whitted;
use std::path::Path;
use whitted::render::Renderer;
use whitted::scene::{Animation, Scene, SceneError, load_animated_str, load_str};

/// An animated scene: the camera, a point light and a sphere, a polygon and a mesh
/// keyed, with `{interp}` interpolation; keys at frames 0, 4 and 10.
fn animated(interp: &str) -> String {
    format!(
        r#"
[settings]
frames = [0, 10]

[camera]
position = [0, 1, 6]
look_at = [0, 0, 0]
fov = 40
width = 48
height = 36
interpolation = "{interp}"
keys = [
  {{ frame = 0, position = [0, 1, 6], look_at = [0, 0, 0], fov = 40 }},
  {{ frame = 4, position = [2, 2, 5] }},
  {{ frame = 10, position = [-3, 1.5, 5], look_at = [0.5, 0, 0], fov = 55 }},
]

[[light]]
position = [5, 5, 5]
interpolation = "{interp}"
keys = [{{ frame = 0, position = [5, 5, 5] }}, {{ frame = 10, position = [-5, 4, 3] }}]

[[light]]
position = [0, 8, 0]
color = [0.3, 0.3, 0.3]

[[sphere]]
center = [0, 0, 0]
radius = 1
material = {{ color = [1, 0.2, 0.2], reflectivity = 0.3 }}
transform = {{ scale = 0.8 }}
interpolation = "{interp}"
keys = [
  {{ frame = 0, transform = {{ translate = [-1, 0, 0], rotate = [0, 0, 0], scale = 0.8 }} }},
  {{ frame = 4, transform = {{ translate = [0, 1, 0], rotate = [0, 30, 0] }} }},
  {{ frame = 10, transform = {{ translate = [1, 0, -1], rotate = [0, 90, 0], scale = 1.2 }} }},
]

[[polygon]]
vertices = [[-4, -1, -4], [4, -1, -4], [4, -1, 4], [-4, -1, 4]]
material = {{ color = [0.8, 0.8, 0.8] }}

[[mesh]]
positions = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
triangles = [[0, 1, 2]]
material = {{ color = [0.2, 0.2, 1] }}
keys = [{{ frame = 0, transform = {{ translate = [1.5, 0, 0], rotate = [0, 0, 0] }} }}, {{ frame = 10, transform = {{ translate = [1.5, 0.5, 0], rotate = [0, 0, 45] }} }}]
"#
    )
}

/// The same scene with no keys, each keyed field written in with the given values.
fn fixed(camera: &str, light: &str, sphere: &str, mesh: &str) -> String {
    format!(
        r#"
[camera]
{camera}
width = 48
height = 36

[[light]]
position = {light}

[[light]]
position = [0, 8, 0]
color = [0.3, 0.3, 0.3]

[[sphere]]
center = [0, 0, 0]
radius = 1
material = {{ color = [1, 0.2, 0.2], reflectivity = 0.3 }}
transform = {sphere}

[[polygon]]
vertices = [[-4, -1, -4], [4, -1, -4], [4, -1, 4], [-4, -1, 4]]
material = {{ color = [0.8, 0.8, 0.8] }}

[[mesh]]
positions = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
triangles = [[0, 1, 2]]
material = {{ color = [0.2, 0.2, 1] }}
transform = {mesh}
"#
    )
}

fn first_fixed() -> String {
    fixed(
        "position = [0, 1, 6]\nlook_at = [0, 0, 0]\nfov = 40",
        "[5, 5, 5]",
        "{ translate = [-1, 0, 0], scale = 0.8 }",
        "{ translate = [1.5, 0, 0] }",
    )
}

fn last_fixed() -> String {
    fixed(
        "position = [-3, 1.5, 5]\nlook_at = [0.5, 0, 0]\nfov = 55",
        "[-5, 4, 3]",
        "{ translate = [1, 0, -1], rotate = [0, 90, 0], scale = 1.2 }",
        "{ translate = [1.5, 0.5, 0], rotate = [0, 0, 45] }",
    )
}

fn load_anim(src: &str) -> (Scene, Animation) {
    let (scene, anim, _) = load_animated_str(src, "anim.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"));
    (scene, anim)
}

fn pixels(scene: &Scene) -> Vec<[u32; 3]> {
    let image = Renderer::new(scene).unwrap().threads(2).render();
    let mut out = Vec::new();
    for y in 0..image.height() {
        for x in 0..image.width() {
            out.push(image.pixel(x, y).to_array().map(f32::to_bits));
        }
    }
    out
}

#[test]
fn first_and_last_frames_are_the_scene_with_the_key_values_written_in() {
    for interp in ["linear", "smooth"] {
        let (scene, anim) = load_anim(&animated(interp));
        assert_eq!((anim.first, anim.last), (0, 10));
        let first = load_str(&first_fixed(), "first.toml", Path::new(".")).unwrap();
        let last = load_str(&last_fixed(), "last.toml", Path::new(".")).unwrap();
        let at0 = anim.scene_at(&scene, 0).unwrap();
        let at10 = anim.scene_at(&scene, 10).unwrap();
        // What the loader gives is frame 0.
        assert_eq!(scene.camera, first.camera, "{interp}");
        for (a, b, what) in [(&at0, &first, "frame 0"), (&at10, &last, "frame 10")] {
            assert_eq!(a.camera, b.camera, "{interp} {what}");
            assert_eq!(a.lights, b.lights, "{interp} {what}");
            for (i, (x, y)) in a.objects.iter().zip(&b.objects).enumerate() {
                assert_eq!(x.shape, y.shape, "{interp} {what}: object {i}");
            }
            assert!(pixels(a) == pixels(b), "{interp} {what}: the images differ");
        }
        assert!(pixels(&at0) != pixels(&at10), "{interp}: the animation changes nothing");
        // Beyond the keys, values hold.
        assert_eq!(anim.scene_at(&scene, 25).unwrap().camera, last.camera);
    }
}

#[test]
fn linear_keys_give_the_midpoint_halfway() {
    let (scene, anim) = load_anim(&animated("linear"));
    // Keys at 4 and 10 for the camera's position: frame 7 is halfway.
    let c = anim.scene_at(&scene, 7).unwrap().camera;
    assert_eq!(c.position, whitted::math::Vec3::new(-0.5, 1.75, 5.0));
    // fov is keyed at 0 and 10 only: frame 5 is halfway, 47.5.
    assert_eq!(anim.scene_at(&scene, 5).unwrap().camera.fov, 47.5);
    // The light, keyed at 0 and 10.
    let l = anim.scene_at(&scene, 5).unwrap().lights[0].position().unwrap();
    assert_eq!(l, whitted::math::Vec3::new(0.0, 4.5, 4.0));
    // The mesh's transform at frame 5 is the one written halfway.
    let mid = fixed(
        "position = [0, 1, 6]\nlook_at = [0, 0, 0]\nfov = 40",
        "[0, 4.5, 4]",
        "{ scale = 0.8 }",
        "{ translate = [1.5, 0.25, 0], rotate = [0, 0, 22.5] }",
    );
    let mid = load_str(&mid, "mid.toml", Path::new(".")).unwrap();
    assert_eq!(anim.scene_at(&scene, 5).unwrap().objects[2].shape, mid.objects[2].shape);
}

#[test]
fn only_moving_objects_need_a_new_acceleration_structure() {
    let (_, anim) = load_anim(&animated("smooth"));
    assert!(anim.moves_geometry(0, 1) && anim.moves_geometry(9, 10));
    assert!(!anim.moves_geometry(10, 11) && !anim.moves_geometry(12, 40), "values hold after the last key");
    assert!(anim.moves_lights(0, 1) && !anim.moves_lights(10, 11));
    // Only a light moving: a new structure too (the world reads lights through its scene).
    let light_only = "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nfov = 40\n[[light]]\nposition = [0, 5, 0]\n\
         keys = [{ frame = 0, position = [0, 5, 0] }, { frame = 4, position = [2, 5, 0] }]\n";
    let (_, a) = load_anim(light_only);
    assert!(!a.moves_geometry(0, 1) && a.needs_new_world(0, 1) && !a.needs_new_world(4, 5));
    let camera_only = std::fs::read_to_string(common::manifest("scenes/turntable.toml")).unwrap();
    let (scene, anim) = load_anim(&camera_only);
    assert!(!anim.is_static() && anim.objects.is_empty() && anim.lights.is_empty());
    assert!((0..anim.last).all(|f| !anim.needs_new_world(f, f + 1)));
    assert!((0..anim.last).all(|f| anim.camera_at(&scene.camera, f) != anim.camera_at(&scene.camera, f + 1)));
    // The turntable starts on the room's own view, and comes back to it.
    let room = load_str(whitted::scene::DEFAULT_SCENE, "room.toml", Path::new("scenes")).unwrap();
    assert_eq!(scene.camera, room.camera);
    assert_eq!(anim.scene_at(&scene, 120).unwrap().camera, room.camera);
}

fn fault(src: &str) -> (usize, String, String) {
    match load_animated_str(src, "bad.toml", Path::new(".")).map(|_| ()).unwrap_err() {
        SceneError::At { line, field, message, .. } => (line, field, message),
        e => panic!("{e}"),
    }
}

#[test]
fn bad_keys_are_reported_by_line_and_field() {
    let cam = "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nfov = 40\n"; // lines 1-4
    let sphere = "[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = { color = [1, 1, 1] }\n"; // 1-4
    let cases: &[(String, usize, &str, &str)] = &[
        (format!("{cam}keys = [\n{{ frame = 5, fov = 30 }},\n{{ frame = 5, fov = 50 }},\n]\n"), 7, "frame", "forward"),
        (format!("{cam}keys = [\n{{ frame = 5, fov = 30 }},\n{{ frame = 2, fov = 50 }},\n]\n"), 7, "frame", "forward"),
        (format!("{cam}keys = [\n{{ frame = 0, zoom = 30 }},\n]\n"), 6, "zoom", "unknown field"),
        (format!("{cam}keys = [\n{{ frame = 0, fov = \"wide\" }},\n]\n"), 6, "fov", ""),
        (format!("{cam}keys = [\n{{ frame = 1.5, fov = 30 }},\n]\n"), 6, "frame", ""),
        (format!("{cam}keys = [\n{{ frame = -1, fov = 30 }},\n]\n"), 6, "frame", "between"),
        (format!("{cam}keys = [\n{{ frame = 3 }},\n]\n"), 6, "frame", "sets nothing"),
        (format!("{cam}interpolation = \"cubic\"\nkeys = [{{ frame = 0, fov = 30 }}]\n"), 5, "interpolation", "smooth"),
        (
            format!(
                "[settings]\nframes = [0, 10]\n{cam}keys = [\n{{ frame = 0, fov = 30 }},\n{{ frame = 11, fov = 50 }},\n]\n"
            ),
            9,
            "frame",
            "outside",
        ),
        (format!("[settings]\nframes = [10, 0]\n{cam}"), 2, "frames", "first <= last"),
        // The camera passes through its look_at at frame 5.
        (
            format!(
                "{cam}keys = [\n{{ frame = 0, position = [-1, 0, 0] }},\n{{ frame = 10, position = [1, 0, 0] }},\n]\n"
            ),
            7,
            "look_at",
            "frame 5",
        ),
        (format!("{cam}keys = [\n{{ frame = 0, fov = 30 }},\n{{ frame = 10, fov = 190 }},\n]\n"), 7, "fov", "frame"),
        (
            format!(
                "{cam}[[light]]\nkind = \"directional\"\ndirection = [0, -1, 0]\nkeys = [{{ frame = 0, position = [0, 1, 0] }}]\n"
            ),
            8,
            "keys",
            "directional",
        ),
        (format!("{cam}[[light]]\nposition = [0, 5, 0]\nkeys = [\n{{ frame = 0 }},\n]\n"), 8, "position", "missing"),
        (
            format!("{cam}[[light]]\nposition = [0, 5, 0]\nkeys = [\n{{ frame = 0, position = [1, 2] }},\n]\n"),
            8,
            "position",
            "",
        ),
        (
            format!("{cam}{sphere}keys = [\n{{ frame = 0, transform = {{ spin = 3 }} }},\n]\n"),
            10,
            "spin",
            "unknown field",
        ),
        (format!("{cam}{sphere}keys = [\n{{ frame = 0, transform = {{ scale = 0 }} }},\n]\n"), 10, "scale", "non-zero"),
        // A scale from 1 to -1 passes through 0 at frame 5.
        (
            format!(
                "{cam}{sphere}keys = [\n{{ frame = 0, transform = {{ scale = 1 }} }},\n{{ frame = 10, transform = {{ scale = -1 }} }},\n]\n"
            ),
            11,
            "transform",
            "frame 5",
        ),
        (format!("{cam}{sphere}keys = [\n{{ frame = 0 }},\n]\n"), 10, "transform", "missing"),
    ];
    for (src, line, field, words) in cases {
        let (l, f, m) = fault(src);
        assert_eq!((l, f.as_str()), (*line, *field), "{src}\n{m}");
        assert!(m.contains(words), "{src}\nmessage: {m}");
    }
    // Empty key lists animate nothing.
    let empty = format!("{cam}keys = []\n[[light]]\nposition = [0, 5, 0]\nkeys = []\n{sphere}keys = []\n");
    let (_, anim, _) = load_animated_str(&empty, "empty.toml", Path::new(".")).unwrap();
    assert!(anim.is_static());
    // A polygon that a key's rotation turns edge-on is fine (it only turns); one that
    // a per-axis scale flattens is not.
    let poly =
        "[[polygon]]\nvertices = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]\nmaterial = { color = [1, 1, 1] }\n";
    assert!(load_animated_str(
        &format!("{cam}{poly}keys = [{{ frame = 0, transform = {{ rotate = [0, 0, 0] }} }}, {{ frame = 9, transform = {{ rotate = [0, 90, 0] }} }}]\n"),
        "ok.toml",
        Path::new(".")
    )
    .is_ok());
}

#[test]
fn the_command_line_writes_one_file_per_frame() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("anim.toml");
    std::fs::write(&scene, animated("smooth")).unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let pattern = out.join("frame-####.png");
    let s = scene.to_str().unwrap();
    let r = whitted(&["render", s, "--frames", "0..2", "-o", pattern.to_str().unwrap(), "--threads", "2"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let mut names: Vec<_> =
        std::fs::read_dir(&out).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
    names.sort();
    assert_eq!(names, ["frame-0000.png", "frame-0001.png", "frame-0002.png"]);
    let e = String::from_utf8_lossy(&r.stderr);
    assert!(e.contains("wrote 3 frames"), "{e}");
    // Every frame moves an object, so each gets its own acceleration structure; the
    // turntable moves only its camera, so its frames share one.
    let stats = |scene: &str, pattern: &Path| {
        let r = whitted(&[
            "render",
            scene,
            "--frames",
            "0..2",
            "--width",
            "16",
            "-q",
            "--stats",
            "-o",
            pattern.to_str().unwrap(),
        ]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        String::from_utf8_lossy(&r.stdout).into_owned()
    };
    let elsewhere = dir.path().join("stats");
    std::fs::create_dir(&elsewhere).unwrap();
    let out_stats = stats(s, &elsewhere.join("a-#.png"));
    assert!(out_stats.contains("acceleration structures built: 3"), "{out_stats}");
    let turntable = common::manifest("scenes/turntable.toml");
    let out_stats = stats(turntable.to_str().unwrap(), &elsewhere.join("t-#.png"));
    assert!(out_stats.contains("acceleration structures built: 1"), "{out_stats}");
    // Each file is the frame rendered alone; they differ from each other.
    let one = dir.path().join("one.png");
    let r = whitted(&["render", s, "--frame", "1", "-o", one.to_str().unwrap(), "-q"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let frame1 = std::fs::read(out.join("frame-0001.png")).unwrap();
    assert_eq!(std::fs::read(&one).unwrap(), frame1);
    assert_ne!(std::fs::read(out.join("frame-0000.png")).unwrap(), frame1);
    // The last frame by the command line is the static file with its values.
    let fixed_path = dir.path().join("last.toml");
    std::fs::write(&fixed_path, last_fixed()).unwrap();
    let (a, b) = (dir.path().join("a.png"), dir.path().join("b.png"));
    assert!(whitted(&["render", s, "--frame", "10", "-o", a.to_str().unwrap(), "-q"]).status.success());
    assert!(whitted(&["render", fixed_path.to_str().unwrap(), "-o", b.to_str().unwrap(), "-q"]).status.success());
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap(), "frame 10 and the static scene");

    // No run of # with --frames: a usage error, nothing written.
    let plain = out.join("frame.png");
    let r = whitted(&["render", s, "--frames", "0..2", "-o", plain.to_str().unwrap()]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("run of #"), "{}", String::from_utf8_lossy(&r.stderr));
    // A folder that does not exist is named before anything renders.
    let missing = dir.path().join("nowhere/f-##.png");
    let r = whitted(&["render", s, "--frames", "0..2", "-o", missing.to_str().unwrap()]);
    let e = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{e}");
    assert!(e.contains("nowhere") && e.contains("does not exist"), "{e}");
    let r = whitted(&["render", s, "--frames", "3..1", "-o", pattern.to_str().unwrap()]);
    assert_eq!(r.status.code(), Some(2));
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 3, "nothing but the three frames");
}
