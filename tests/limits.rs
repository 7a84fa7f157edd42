//! Inputs within the documented limits that used to crash: endless files, huge images
//! and maps, huge counts. Each must end in an error naming the file and line, quickly.

mod common;

use common::whitted;

const HEAD: &str = "[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, -1]\nfov = 40\nwidth = 8\nheight = 8\n";

fn fails_with(scene_text: &str, name: &str, expect: &[&str]) {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join(name);
    std::fs::write(&scene, scene_text).unwrap();
    let out = whitted(&["render", scene.to_str().unwrap(), "-o", tmp.path().join("x.png").to_str().unwrap()]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{name}: {e}");
    for x in expect {
        assert!(e.contains(x), "{name}: expected {x:?} in {e}");
    }
}

#[cfg(unix)]
#[test]
fn endless_and_device_files_are_refused() {
    let m = "material = { color = [1, 1, 1] }\n";
    fails_with(&format!("{HEAD}[[mesh]]\nfile = \"/dev/zero\"\n{m}"), "m.toml", &["/dev/zero", "not a regular file"]);
    let out = whitted(&["render", "/dev/zero", "--format", "nff", "-o", "/tmp/never-written.png"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("not a regular file"));
}

#[test]
fn long_lines_binary_data_and_huge_counts_are_located() {
    let tmp = tempfile::tempdir().unwrap();
    let obj = tmp.path().join("long.obj");
    std::fs::write(&obj, format!("v 0 0 0\n{}\n", "x".repeat(4_000_000))).unwrap();
    let m = "material = { color = [1, 1, 1] }\n";
    let scene = format!("{HEAD}[[mesh]]\nfile = \"{}\"\n{m}", obj.display());
    fails_with(&scene, "long.toml", &["long.obj:2:1", "longer than 1 MiB"]);
    std::fs::write(&obj, format!("v 0 0 0\n{} 1 2\n", "k".repeat(500_000))).unwrap();
    let scene_path = tmp.path().join("kw.toml");
    std::fs::write(&scene_path, &scene).unwrap();
    let out = whitted(&["render", scene_path.to_str().unwrap(), "-o", tmp.path().join("x.png").to_str().unwrap()]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("long.obj:2:1") && e.contains("unknown OBJ statement") && e.len() < 1000, "{}", &e[..300]);
    let mut bad = format!("{HEAD}\n").into_bytes();
    bad.extend_from_slice(b"b = \"\xff\xfe\"\n");
    let path = tmp.path().join("bin.toml");
    std::fs::write(&path, bad).unwrap();
    let out = whitted(&["render", path.to_str().unwrap(), "-o", tmp.path().join("x.png").to_str().unwrap()]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("bin.toml:8:6: text: not UTF-8"), "{e}");
    let view = "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 40\nhither 1\nresolution 8 8\n";
    fails_with(&format!("{view}p 4294967296\n"), "p.nff", &["p.nff:8:", "at most 1000000 (got 4294967296)"]);
    fails_with(&format!("{view}p 99999999999999999999999\n"), "q.nff", &["at most 1000000"]);
}

#[test]
fn huge_textures_and_maps_are_refused_up_front() {
    let tmp = tempfile::tempdir().unwrap();
    // 20000 x 20000 grey pixels compress to a few hundred KB.
    let png = tmp.path().join("big.png");
    {
        let file = std::io::BufWriter::new(std::fs::File::create(&png).unwrap());
        let mut enc = png::Encoder::new(file, 20000, 20000);
        enc.set_color(png::ColorType::Grayscale);
        let mut w = enc.write_header().unwrap().into_stream_writer().unwrap();
        let row = vec![128u8; 20000];
        for _ in 0..20000 {
            std::io::Write::write_all(&mut w, &row).unwrap();
        }
        w.finish().unwrap();
    }
    let material = format!("[material.m]\ntexture = {{ kind = \"image\", path = \"{}\" }}\n", png.display());
    fails_with(&format!("{HEAD}{material}"), "img.toml", &["img.toml:8:", "20000x20000", "GiB"]);
    let planet = "[material.p]\ntexture = { kind = \"planet\", resolution = [16384, 16384] }\n";
    fails_with(&format!("{HEAD}{planet}"), "planet.toml", &["planet.toml:8:", "resolution", "16384x16384"]);
}

#[test]
fn nesting_too_deep_is_located() {
    let keys: Vec<String> = (0..100).map(|i| format!("k{i}")).collect();
    fails_with(&format!("{HEAD}\n\na.{} = 1\n", keys.join(".")), "dotted.toml", &["dotted.toml:9:", "recursion"]);
    let deep = format!("x = {}1{}\n", "[".repeat(200), "]".repeat(200));
    fails_with(&format!("{HEAD}{deep}"), "deep.toml", &["deep.toml:7:"]);
}

#[test]
fn a_polygon_of_a_million_vertices_is_rendered_or_reported_never_dropped() {
    let view = "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 40\nhither 1\nresolution 8 8\nl 0 0 5\nf 1 0 0 1 0 0 0 0\n";
    let circle = |n: usize| {
        let mut s = format!("{view}p {n}\n");
        for i in 0..n {
            let a = i as f64 / n as f64 * std::f64::consts::TAU;
            s.push_str(&format!("{:.7} {:.7} 0\n", a.cos(), a.sin()));
        }
        s
    };
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("c.nff");
    std::fs::write(&scene, circle(1_000_000)).unwrap();
    let out =
        whitted(&["render", scene.to_str().unwrap(), "--stats", "-o", tmp.path().join("c.png").to_str().unwrap()]);
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "{stderr}");
    let triangles: usize = stdout
        .split(" triangles")
        .next()
        .and_then(|s| s.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{stdout}"));
    // Its fan is a million slivers, each tiny beside the whole polygon: they are kept
    // (up to those within rounding of v0's tangent), not dropped as zero-area.
    assert!(triangles > 800_000, "slivers dropped: {stdout} {stderr}");
    fails_with(&circle(1_000_001), "big.nff", &["big.nff:10:", "at most 1000000 (got 1000001)"]);
}
