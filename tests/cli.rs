//! The command line in a new user's first minutes: bad numbers, bad output paths, the
//! line printed on success, image sizes from one side or a scale, and the order in
//! which unknown keys are reported.

mod common;

use common::whitted;

fn stderr(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn negative_and_zero_numbers_must_be_at_least_one() {
    for (flag, value) in [("--spp", "-4"), ("--width", "0"), ("--depth", "-1"), ("--threads", "0"), ("--height", "-20")]
    {
        let out = whitted(&["render", flag, value, "-o", "never.png"]);
        let e = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{flag} {value}: {e}");
        assert!(e.contains("must be at least 1"), "{flag} {value}: {e}");
        assert!(!e.contains("-- "), "{flag} {value}: suggests the `--` form: {e}");
        assert!(e.contains(flag), "{flag} {value}: flag not named: {e}");
    }
    let out = whitted(&["bench", "--runs", "-3"]);
    assert!(stderr(&out).contains("must be at least 1"), "{}", stderr(&out));
    let out = whitted(&["render", "--scale", "-0.5", "-o", "never.png"]);
    assert!(stderr(&out).contains("greater than 0"), "{}", stderr(&out));
    assert!(!std::path::Path::new("never.png").exists());
}

#[test]
fn output_paths_are_explained_in_the_users_terms() {
    let tmp = tempfile::tempdir().unwrap();
    let missing = tmp.path().join("nodir/sub/out.png");
    let out = whitted(&["render", "-o", missing.to_str().unwrap(), "--width", "8", "-q"]);
    let e = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{e}");
    assert!(e.contains("nodir/sub/out.png") && e.contains("does not exist"), "{e}");
    assert!(!e.contains(".whitted-"), "temporary name shown: {e}");

    let folder = format!("{}/", tmp.path().display());
    let out = whitted(&["render", "-o", &folder, "--width", "8", "-q"]);
    let e = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{e}");
    assert!(e.contains("folder") && !e.contains("only PNG"), "{e}");
    let out = whitted(&["render", "-o", tmp.path().to_str().unwrap(), "--width", "8", "-q"]);
    assert!(stderr(&out).contains("is a folder"), "{}", stderr(&out));

    // convert names the path too.
    let src = tempfile::tempdir().unwrap();
    let scene = src.path().join("s.toml");
    std::fs::write(&scene, "[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, -1]\nfov = 40\n").unwrap();
    let out = whitted(&["convert", scene.to_str().unwrap(), missing.with_extension("toml").to_str().unwrap()]);
    let e = stderr(&out);
    assert!(e.contains("nodir/sub/out.toml") && e.contains("does not exist") && !e.contains(".whitted-"), "{e}");
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 0, "files left behind");
}

#[test]
fn success_prints_one_line_unless_quiet_and_one_side_keeps_the_aspect_ratio() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("wide.toml");
    std::fs::write(
        &scene,
        "[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, -1]\nfov = 40\nwidth = 400\nheight = 100\n\
         [[sphere]]\ncenter = [0, 0, -5]\nradius = 1\nmaterial = { color = [1, 0, 0] }\n\
         [[light]]\nposition = [5, 5, 0]\n",
    )
    .unwrap();
    let png = tmp.path().join("wide.png");
    let size = |args: &[&str], quiet: bool| {
        let mut all = vec!["render", scene.to_str().unwrap(), "-o", png.to_str().unwrap()];
        all.extend_from_slice(args);
        if quiet {
            all.push("-q");
        }
        let out = whitted(&all);
        assert!(out.status.success(), "{}", stderr(&out));
        let img = image::open(&png).unwrap();
        ((img.width(), img.height()), stderr(&out))
    };
    let ((w, h), e) = size(&["--width", "80"], false);
    assert_eq!((w, h), (80, 20));
    let line = e.lines().last().unwrap_or("");
    assert!(line.starts_with(&format!("wrote {}: 80x20, 1 spp, ", png.display())), "{e}");
    assert!(line.ends_with(" s"), "{e}");
    assert_eq!(size(&["--height", "30"], true), ((120, 30), String::new()));
    assert_eq!(size(&["--scale", "0.25"], true).0, (100, 25));
    assert_eq!(size(&["--width", "40", "--height", "40", "--scale", "0.5"], true).0, (20, 20));
}

#[test]
fn a_huge_image_is_announced_with_its_memory() {
    // Refused before rendering by the missing folder, after the warning.
    let out = whitted(&["render", "--width", "16384", "--height", "16384", "-o", "no/such/folder/x.png"]);
    let e = stderr(&out);
    // The output path is checked first, so nothing is rendered; ask for a real folder.
    assert!(!e.contains("GiB"), "{e}");
    let tmp = tempfile::tempdir().unwrap();
    let png = tmp.path().join("big.png");
    // Started as the other tests start it (under CI's emulator where there is one).
    let mut child = common::whitted_command()
        .args(["render", "--width", "16384", "--height", "16384", "--spp", "1", "-o", png.to_str().unwrap()])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Read the first line, then stop the render.
    use std::io::BufRead;
    let mut first = String::new();
    std::io::BufReader::new(child.stderr.take().unwrap()).read_line(&mut first).unwrap();
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(first.starts_with("warning: a 16384x16384 image needs about 3.8 GiB"), "{first}");
}

#[test]
fn the_first_unknown_key_in_the_file_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("typos.toml");
    std::fs::write(
        &scene,
        "[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, -1]\nfov = 40\n\
         [[sphere]]\ncenter = [0, 0, -5]\nzradius = 1\naradius = 2\nmaterial = { color = [1, 0, 0] }\n",
    )
    .unwrap();
    let out = whitted(&["render", scene.to_str().unwrap(), "-o", tmp.path().join("x.png").to_str().unwrap()]);
    let e = stderr(&out);
    assert!(e.contains("typos.toml:7:") && e.contains("zradius"), "{e}");
}

#[test]
fn convert_names_materials_and_objects_as_the_file_does() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out.toml");
    let room = common::manifest("scenes/room.toml");
    let run = whitted(&["convert", room.to_str().unwrap(), out.to_str().unwrap()]);
    let e = stderr(&run);
    let text = std::fs::read_to_string(&room).unwrap();
    let line = text.lines().position(|l| l.starts_with("[material.planet]")).unwrap() + 1;
    let named = format!("material \"planet\" (line {line})");
    assert!(e.contains(&named) && e.contains("planet texture is generated"), "{e}");

    let scene = tmp.path().join("s.toml");
    let body = "[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, -1]\nfov = 40\n\n\
                [[light]]\nposition = [5, 5, 0]\n\n\
                [material.plain]\ncolor = [1, 1, 1]\n\n\
                [material.\"red glass\"]\ncolor = [1, 0, 0]\ntransparency = 0.5\n\n\
                [[cone]]\nbase = [0, 0, -5]\naxis = [0, 1, 0]\nradius = 0.5\nheight = 1\nmaterial = \"red glass\"\n\n\
                [[sphere]]\ncenter = [0, 0, -5]\nradius = 0.5\nmaterial = \"plain\"\n\n\
                [[sphere]]\ncenter = [0, 0, -5]\nradius = 1\nmaterial = { color = [0.5, 0.5, 0.5] }\n";
    std::fs::write(&scene, body).unwrap();
    let run = whitted(&["convert", scene.to_str().unwrap(), out.to_str().unwrap()]);
    assert!(run.status.success(), "{}", stderr(&run));
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("[material.plain]") && text.contains("[material.\"red glass\"]"), "{text}");
    assert!(text.contains("material = \"red glass\"") && text.contains("transparency = 0.5\n"), "{text}");
    // Converted again, it is the same text but for the note.
    let again = tmp.path().join("again.toml");
    let run = whitted(&["convert", out.to_str().unwrap(), again.to_str().unwrap()]);
    assert!(run.status.success(), "{}", stderr(&run));
    let strip = |t: &str| t.lines().skip(1).collect::<Vec<_>>().join("\n");
    assert_eq!(strip(&std::fs::read_to_string(&again).unwrap()), strip(&text));

    let stretched = format!("{body}transform = {{ scale = [2, 1, 1] }}\n");
    std::fs::write(&scene, stretched).unwrap();
    let run = whitted(&["convert", scene.to_str().unwrap(), out.to_str().unwrap()]);
    let e = stderr(&run);
    assert!(e.contains("[[sphere]] 2 (line 28)") && e.contains("stretched"), "{e}");
}

#[test]
fn obj_and_gltf_files_convert_to_toml_that_renders_the_same() {
    let tmp = tempfile::tempdir().unwrap();
    for name in ["torus.obj", "model.glb"] {
        let input = common::manifest(&format!("scenes/{name}"));
        let toml = tmp.path().join(format!("{name}.toml"));
        // `-o`, as `render` and `generate` take their output.
        let run = whitted(&["convert", input.to_str().unwrap(), "-o", toml.to_str().unwrap(), "-q"]);
        assert!(run.status.success(), "{name}: {}", stderr(&run));
        let [a, b] = ["from-file.png", "from-toml.png"].map(|p| tmp.path().join(p));
        for (scene, png) in [(&input, &a), (&toml, &b)] {
            let size = ["--width", "96", "--height", "64"];
            let run =
                whitted(&[&["render", scene.to_str().unwrap(), "-q", "-o", png.to_str().unwrap()][..], &size].concat());
            assert!(run.status.success(), "{}: {}", scene.display(), stderr(&run));
        }
        assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap(), "{name}: the TOML renders otherwise");
    }
    // One output, given either way.
    let obj = common::manifest("scenes/torus.obj");
    let run = whitted(&["convert", obj.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(2), "{}", stderr(&run));
    let run = whitted(&["convert", obj.to_str().unwrap(), "a.toml", "-o", "b.toml"]);
    assert_eq!(run.status.code(), Some(2), "{}", stderr(&run));
}
