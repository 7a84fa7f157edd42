//! NFF scenes through the command line: malformed files fail cleanly, naming the file,
//! line and command.

mod common;

use common::{expectation, files_in, manifest, whitted};
use std::path::{Path, PathBuf};

/// Every malformed file under tests/scenes/bad_nff/ makes `render` and `convert` fail:
/// exit code 1, no panic, `error: FILE:LINE:COL: COMMAND: ...`, and no output file.
#[test]
fn every_bad_nff_fails_with_file_line_and_command() {
    let tmp = tempfile::tempdir().unwrap();
    let files = files_in("tests/scenes/bad_nff", "nff");
    assert!(files.len() >= 12, "only {} bad NFF files", files.len());
    let mut failures = Vec::new();
    for path in &files {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let (line, field) = expectation(path);
        let png = tmp.path().join(format!("{name}.png"));
        let toml = tmp.path().join(format!("{name}.toml"));
        let runs = [
            (png.clone(), whitted(&["render", path.to_str().unwrap(), "-o", png.to_str().unwrap(), "-q"])),
            (toml.clone(), whitted(&["convert", path.to_str().unwrap(), toml.to_str().unwrap(), "-q"])),
        ];
        for (output, out) in runs {
            let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
            if out.status.code() != Some(1) || stderr.contains("panicked") || output.exists() {
                failures.push(format!("{name}: status {:?}, output exists {}: {stderr}", out.status, output.exists()));
                continue;
            }
            let location = format!("error: {}:{line}:", path.display());
            if !stderr.starts_with(&location) || !stderr.contains(&format!(": {field}: ")) {
                failures.push(format!("{name}: expected '{location}' and command '{field}' in: {stderr}"));
            }
        }
    }
    assert!(failures.is_empty(), "{} failures:\n{}", failures.len(), failures.join("\n"));
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 0, "files left behind");
}

#[test]
fn missing_nff_file_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let png = tmp.path().join("x.png");
    let out = whitted(&["render", "no/such/scene.nff", "-o", png.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("no/such/scene.nff"), "{stderr}");
    assert!(!png.exists());
}

#[test]
fn format_flag_overrides_the_extension() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("scene.txt");
    std::fs::write(&scene, "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 40\nresolution 8 8\nl 0 5 5\ns 0 0 0 1\n")
        .unwrap();
    let png = tmp.path().join("x.png");
    // As TOML (by the extension) it is a syntax error; as NFF it renders.
    let out = whitted(&["render", scene.to_str().unwrap(), "-o", png.to_str().unwrap(), "-q"]);
    assert_eq!(out.status.code(), Some(1));
    let out = whitted(&["render", scene.to_str().unwrap(), "--format", "nff", "-o", png.to_str().unwrap(), "-q"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(image::open(&png).unwrap().width(), 8);
}

// ---- rendering NFF scenes made here ----------------------------------------------------

/// Runs whitted and insists it succeeds; returns stdout and stderr.
fn ok(args: &[&str]) -> (String, String) {
    let out = whitted(args);
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "whitted {args:?} failed: {stderr}");
    (stdout.into_owned(), stderr.into_owned())
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn render(scene: &Path, png: &Path, extra: &[&str]) -> image::RgbImage {
    ok(&[&["render", scene.to_str().unwrap(), "-o", png.to_str().unwrap(), "-q"], extra].concat());
    image::open(png).unwrap().to_rgb8()
}

/// Every NFF entity, in the SPD's order, with comments, a colourless and a coloured
/// light, a multi-line `c`, convex and concave polygons and a patch.
fn every_command() -> String {
    "# every NFF entity\n\
     b 0.1 0.2 0.3\n\
     v\nfrom 0 2 9\nat 0 0 0\nup 0 1 0\nangle 40\nhither 0.01\nresolution 48 40\n\
     l 5 5 5\n\
     l -5 5 5 0.5 0.4 0.3   # coloured\n\
     f 0.9 0.9 0.9 0.8 0 100000 0 1\n\
     p 4\n-6 -1 6\n6 -1 6\n6 -1 -6\n-6 -1 -6\n\
     f 1 0.2 0.2 0.6 0.4 20 0 0\n\
     s -2 0 0 1\n\
     c 0 -1 0 1\n  0 1 0 0.5\n\
     c 2 -1 0 0.6 2 1 0 0.6\n\
     c 2 -1 2 0.6 2 1 2 0\n\
     f 0.2 0.9 0.2 0.7 0.1 30 0 0\n\
     p 6\n-3 1.5 -2\n-1 1.5 -2\n-1 2 -2\n-2 1.75 -2\n-3 2 -2\n-3 1.75 -2\n\
     pp 3\n1 1.5 -2 0 0 1\n3 1.5 -2 0 0 1\n2 2.5 -2 0.6 0 0.8\n\
     f 1 1 1 0.1 0.1 50 0.8 1.5\n\
     s 0 0 3 0.7\n"
        .to_owned()
}

#[test]
fn every_command_is_parsed_and_rendered() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = write(tmp.path(), "every.nff", &every_command());
    let png = tmp.path().join("every.png");
    let (stdout, stderr) = ok(&["render", scene.to_str().unwrap(), "-o", png.to_str().unwrap(), "--stats"]);
    assert!(!stderr.contains("warning"), "no warnings expected: {stderr}");
    assert!(stdout.contains("nff         37 lines, 0.0 MB, "), "{stdout}");
    // The concave hexagon has three vertices in a line: 3 triangles, not 4; the floor,
    // a rectangle, is one parallelogram.
    assert!(
        stdout
            .contains("2 spheres, 3 cones and cylinders, 2 polygons and 1 patches as 4 triangles and 1 parallelograms"),
        "{stdout}"
    );
    let img = image::open(&png).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (48, 40), "the file's resolution");
    // The background is the file's `b`; the floor in front is not.
    assert_eq!(img.get_pixel(24, 0).0, [26, 51, 77]);
    assert_ne!(img.get_pixel(24, 39).0, [26, 51, 77]);
    // --width/--height override the file.
    assert_eq!(render(&scene, &png, &["--width", "20", "--height", "10"]).dimensions(), (20, 10));
}

/// A sphere of radius 1 at the origin as `n` × 2n latitude-longitude triangles: `pp`
/// with the sphere's normals, or flat `p`.
fn faceted_ball(smooth: bool, n: usize) -> String {
    let mut s = String::from(
        "v\nfrom 0 0.5 4\nat 0 0 0\nup 0 1 0\nangle 40\nresolution 96 96\nl 3 4 5\nf 0.9 0.6 0.3 0.9 0 30 0 0\n",
    );
    let point = |i: usize, j: usize| {
        let (theta, phi) = (std::f64::consts::PI * i as f64 / n as f64, std::f64::consts::PI * j as f64 / n as f64);
        [theta.sin() * phi.cos(), theta.cos(), -theta.sin() * phi.sin()]
    };
    let mut tri = |a: [f64; 3], b: [f64; 3], c: [f64; 3]| {
        s.push_str(if smooth { "pp 3\n" } else { "p 3\n" });
        for v in [a, b, c] {
            if smooth {
                s.push_str(&format!("{} {} {} {} {} {}\n", v[0], v[1], v[2], v[0], v[1], v[2]));
            } else {
                s.push_str(&format!("{} {} {}\n", v[0], v[1], v[2]));
            }
        }
    };
    for i in 0..n {
        for j in 0..2 * n {
            let (a, b, c, d) = (point(i, j), point(i + 1, j), point(i + 1, j + 1), point(i, j + 1));
            if i > 0 {
                tri(a, b, d);
            }
            if i + 1 < n {
                tri(b, c, d);
            }
        }
    }
    s
}

#[test]
fn patches_render_smooth_where_polygons_show_facets() {
    let tmp = tempfile::tempdir().unwrap();
    let roughness = |smooth: bool| {
        let scene = write(tmp.path(), &format!("ball-{smooth}.nff"), &faceted_ball(smooth, 8));
        let img = render(&scene, &tmp.path().join("ball.png"), &[]);
        // Steps between neighbouring pixels inside the ball: facet edges make big ones,
        // interpolated normals only small ones.
        let mut steps = 0;
        for y in 30..66 {
            for x in 30..65 {
                let (a, b) = (img.get_pixel(x, y).0, img.get_pixel(x + 1, y).0);
                steps += (0..3).any(|c| a[c].abs_diff(b[c]) > 6) as u32;
            }
        }
        steps
    };
    let (flat, smooth) = (roughness(false), roughness(true));
    assert!(flat > 50 && smooth * 10 < flat, "steps: smooth {smooth} vs flat {flat}");
}

/// Width in pixels of what is not background in row `y`, from the leftmost to the
/// rightmost such pixel.
fn extent(img: &image::RgbImage, y: u32) -> u32 {
    let lit: Vec<u32> = (0..img.width()).filter(|&x| img.get_pixel(x, y).0 != [0, 0, 0]).collect();
    lit.last().map_or(0, |last| last - lit[0] + 1)
}

#[test]
fn a_cone_with_two_radii_renders_as_a_truncated_cone() {
    // Seen from the side and far away: the outline is a trapezoid, 2 units wide at the
    // bottom (y = -1) and 1 at the top (y = 1), in an image 3 units high.
    let tmp = tempfile::tempdir().unwrap();
    let view = "v\nfrom 0 0 40\nat 0 0 0\nup 0 1 0\nangle 4.29624\nresolution 96 96\nl 0 0 40\nf 1 1 1 1 0 0 0 0\n";
    let truncated = write(tmp.path(), "t.nff", &format!("{view}c 0 -1 0 1 0 1 0 0.5\n"));
    let pointed = write(tmp.path(), "p.nff", &format!("{view}c 0 -1 0 1 0 1 0 0\n"));
    let cylinder = write(tmp.path(), "c.nff", &format!("{view}c 0 -1 0 0.75 0 1 0 0.75\n"));
    let png = tmp.path().join("x.png");
    let px = 96.0 / 3.0; // pixels per unit
    // Rows at y = 0.95, 0, -0.95 (row 0 is y = 1.5).
    let rows = [(0.95f32, 17u32), (0.0, 48), (-0.95, 78)];
    let img = render(&truncated, &png, &[]);
    for (y, row) in rows {
        let expected = 2.0 * (0.75 - y / 4.0) * px;
        let got = extent(&img, row) as f32;
        assert!((got - expected).abs() <= 2.0, "y = {y}: {got} px wide, expected {expected}");
    }
    // Nothing above the top or below the base: it ends at both radii.
    assert_eq!(extent(&img, 14), 0);
    assert_eq!(extent(&img, 82), 0);
    // The pointed cone narrows to nothing at the top, the cylinder keeps its width.
    let img = render(&pointed, &png, &[]);
    assert!(extent(&img, 17) <= 4, "{}", extent(&img, 17));
    let img = render(&cylinder, &png, &[]);
    for (_, row) in rows {
        assert!((extent(&img, row) as f32 - 1.5 * px).abs() <= 2.0);
    }
}

#[test]
fn a_transparent_sphere_of_index_1_5_refracts() {
    // A red wall on the left, a blue one on the right, a glass ball in front: through
    // the ball's left half, glass of index 1.5 shows the right (an inverted image, as a
    // ball lens does); with index 1 the light goes straight through and it stays red.
    let tmp = tempfile::tempdir().unwrap();
    let scene = |ior: &str| {
        format!(
            "v\nfrom 0 0 10\nat 0 0 0\nup 0 1 0\nangle 20\nresolution 64 64\nl 0 0 10\n\
             f 1 0 0 1 0 0 0 0\np 4\n-20 -20 -6\n0 -20 -6\n0 20 -6\n-20 20 -6\n\
             f 0 0 1 1 0 0 0 0\np 4\n0 -20 -6\n20 -20 -6\n20 20 -6\n0 20 -6\n\
             f 1 1 1 0 0 100000 1 {ior}\ns 0 0 0 1.5\n"
        )
    };
    let png = tmp.path().join("x.png");
    let glass = render(&write(tmp.path(), "glass.nff", &scene("1.5")), &png, &[]);
    let air = render(&write(tmp.path(), "air.nff", &scene("1")), &png, &[]);
    let [r, _, b] = glass.get_pixel(24, 32).0;
    assert!(b > 2 * r.max(10), "index 1.5 inverts: {:?}", glass.get_pixel(24, 32).0);
    let [r, _, b] = air.get_pixel(24, 32).0;
    assert!(r > 2 * b.max(10), "index 1 goes straight: {:?}", air.get_pixel(24, 32).0);
    // Away from the ball both show the wall as it is.
    assert_eq!(glass.get_pixel(2, 2), air.get_pixel(2, 2));
    let [r, g, b] = glass.get_pixel(2, 2).0;
    assert!(r > 200 && g == 0 && b == 0, "{r} {g} {b}");
}

#[test]
fn converted_scenes_render_byte_identical() {
    let tmp = tempfile::tempdir().unwrap();
    let flake = tmp.path().join("flake.nff");
    ok(&["generate", "sphereflake", "--level", "2", "-o", flake.to_str().unwrap()]);
    let scenes = [
        write(tmp.path(), "every.nff", &every_command()),
        write(tmp.path(), "ball.nff", &faceted_ball(true, 6)),
        flake,
    ];
    for nff in &scenes {
        let toml = nff.with_extension("toml");
        ok(&["convert", nff.to_str().unwrap(), toml.to_str().unwrap()]);
        for extra in [&["--width", "64", "--height", "64"][..], &["--width", "32", "--height", "32", "--spd-rules"]] {
            let (a, b) = (tmp.path().join("a.png"), tmp.path().join("b.png"));
            render(nff, &a, extra);
            render(&toml, &b, extra);
            assert!(
                std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap(),
                "{} and its TOML differ ({extra:?})",
                nff.display()
            );
        }
    }
    // Converting the TOML again gives the same text (apart from the note naming the input).
    let toml = scenes[0].with_extension("toml");
    let again = tmp.path().join("again.toml");
    ok(&["convert", toml.to_str().unwrap(), again.to_str().unwrap()]);
    let body = |p: &Path| std::fs::read_to_string(p).unwrap().lines().skip(1).collect::<Vec<_>>().join("\n");
    assert_eq!(body(&toml), body(&again));
}

#[test]
fn convert_refuses_other_outputs_and_keeps_old_files() {
    let tmp = tempfile::tempdir().unwrap();
    let nff = write(tmp.path(), "every.nff", &every_command());
    let out = whitted(&["convert", nff.to_str().unwrap(), tmp.path().join("x.json").to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("TOML"));
    let bad = manifest("tests/scenes/bad_nff/unknown_command.nff");
    let old = write(tmp.path(), "old.toml", "previous");
    let out = whitted(&["convert", bad.to_str().unwrap(), old.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(std::fs::read_to_string(&old).unwrap(), "previous");
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 2, "temporary files left behind");
}

#[test]
fn spd_rules_trace_the_corner_pattern_to_depth_five() {
    let tmp = tempfile::tempdir().unwrap();
    let flake = tmp.path().join("flake.nff");
    ok(&["generate", "sphereflake", "--level", "1", "-o", flake.to_str().unwrap()]);
    let png = tmp.path().join("x.png");
    let args = ["render", flake.to_str().unwrap(), "-o", png.to_str().unwrap(), "--width", "40", "--height", "30"];
    let (stdout, _) = ok(&[&args[..], &["--stats", "--spd-rules"]].concat());
    assert!(stdout.contains("corner sampling (41 x 31 eye rays)"), "{stdout}");
    assert!(stdout.contains("primary 1271 "), "{stdout}");
    // --spd-rules sets the depth and the sampling itself.
    for clash in [&["--spd-rules", "--depth", "3"][..], &["--spd-rules", "--spp", "4"]] {
        let out = whitted(&[&args[..], clash].concat());
        assert_eq!(out.status.code(), Some(2), "{clash:?}");
    }
}

#[test]
fn a_file_without_lights_renders_with_ambient_light_and_a_warning() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = write(
        tmp.path(),
        "dark.nff",
        "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 40\nresolution 8 8\nf 1 1 1 1 0 0 0 0\ns 0 0 0 1\np 3 0 0 0 1 1 1 2 2 2\n",
    );
    let png = tmp.path().join("dark.png");
    let (_, stderr) = ok(&["render", scene.to_str().unwrap(), "-o", png.to_str().unwrap()]);
    assert!(stderr.contains("no lights: only ambient light will show"), "{stderr}");
    assert!(stderr.contains("1 zero-area polygon skipped (the first on line 9)"), "{stderr}");
    // Ambient 0.2 of white.
    assert_eq!(image::open(&png).unwrap().to_rgb8().get_pixel(4, 4).0, [51, 51, 51]);
}

#[test]
fn a_concave_polygon_covers_its_outline_and_not_its_notches() {
    // A comb facing the camera: three teeth 1 unit wide with notches between them, as
    // gears' 144-vertex faces need. 64 pixels span 8 units: 8 pixels a unit, x = -4 at 0.
    let tmp = tempfile::tempdir().unwrap();
    let scene = write(
        tmp.path(),
        "comb.nff",
        "v\nfrom 0 0 20\nat 0 0 0\nup 0 1 0\nangle 22.6199\nresolution 64 64\nl 0 0 20\nf 1 1 1 1 0 0 0 0\n\
         p 12\n-2.5 -2 0\n2.5 -2 0\n2.5 2 0\n1.5 2 0\n1.5 0 0\n0.5 0 0\n0.5 2 0\n-0.5 2 0\n-0.5 0 0\n-1.5 0 0\n\
         -1.5 2 0\n-2.5 2 0\n",
    );
    let img = render(&scene, &tmp.path().join("comb.png"), &[]);
    let lit = |x: f32, y: f32| img.get_pixel(((x + 4.0) * 8.0) as u32, ((4.0 - y) * 8.0) as u32).0 != [0, 0, 0];
    for x in [-2.0, 0.0, 2.0] {
        assert!(lit(x, 1.0), "tooth at x = {x}");
        assert!(lit(x, -1.0), "base at x = {x}");
    }
    for x in [-1.0, 1.0] {
        assert!(!lit(x, 1.0), "notch at x = {x}");
        assert!(lit(x, -1.0), "base under the notch at x = {x}");
    }
    assert!(!lit(3.0, 0.0) && !lit(0.0, 3.0));
}

/// A polygon of a million vertices on a circle: its fan's thinnest triangles are within
/// rounding of no area and are left out, and the file's reader says so.
#[test]
fn a_polygon_partly_left_uncovered_is_reported() {
    let tmp = tempfile::tempdir().unwrap();
    let n = 999_999;
    let mut text = String::from(
        "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 40\nhither 0.01\nresolution 8 8\nl 0 0 5\nf 1 1 1 1 0 1 0 1\n",
    );
    text += &format!("p {n}\n");
    for i in 0..n {
        let a = std::f64::consts::TAU * i as f64 / n as f64;
        text += &format!("{:.7} {:.7} 0\n", a.cos(), a.sin());
    }
    let nff = write(tmp.path(), "circle.nff", &text);
    let out = whitted(&["render", nff.to_str().unwrap(), "-o", tmp.path().join("c.png").to_str().unwrap()]);
    assert!(out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("1 polygon partly uncovered (slivers of too little area left out)"), "{stderr}");
}
