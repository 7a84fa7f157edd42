//! Every malformed scene under tests/scenes/bad/ must make `whitted render` fail cleanly:
//! non-zero exit, a message naming the file, line and field, no panic, and no output
//! file. Each scene states the line and field it expects in its first two lines.

mod common;

use common::{expectation, files_in, manifest, whitted};
use std::path::{Path, PathBuf};
use std::process::Output;

fn bad_dir() -> PathBuf {
    manifest("tests/scenes/bad")
}

fn assert_clean_failure(out: &Output, output_file: &Path, what: &str) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!out.status.success(), "{what}: exit status was success; stderr: {stderr}");
    assert_eq!(out.status.code(), Some(1), "{what}: expected exit code 1; stderr: {stderr}");
    assert!(!stderr.contains("panicked"), "{what}: panicked: {stderr}");
    assert!(stderr.starts_with("error: "), "{what}: message should start with 'error: ': {stderr}");
    assert!(!output_file.exists(), "{what}: output file was created");
    stderr
}

#[test]
fn every_bad_scene_fails_with_file_line_and_field() {
    let tmp = tempfile::tempdir().unwrap();
    let files = files_in("tests/scenes/bad", "toml");
    assert!(files.len() >= 20, "only {} bad scenes", files.len());
    let mut failures = Vec::new();
    for path in &files {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let (line, field) = expectation(path);
        let out_png = tmp.path().join(format!("{name}.png"));
        let out = whitted(&["render", path.to_str().unwrap(), "-o", out_png.to_str().unwrap(), "-q"]);
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        if out.status.code() != Some(1) || stderr.contains("panicked") || out_png.exists() {
            failures.push(format!("{name}: status {:?}, output exists {}: {stderr}", out.status, out_png.exists()));
            continue;
        }
        let location = format!("{}:{line}:", path.display());
        if !stderr.contains(&location) || !stderr.contains(&field) {
            failures.push(format!("{name}: expected '{location}' and field '{field}' in: {stderr}"));
        }
    }
    assert!(failures.is_empty(), "messages missing file:line or field:\n{}", failures.join("\n"));
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 0, "files left behind");
}

#[test]
fn missing_scene_file_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let out_png = tmp.path().join("x.png");
    let out = whitted(&["render", "no/such/scene.toml", "-o", out_png.to_str().unwrap()]);
    let stderr = assert_clean_failure(&out, &out_png, "missing scene");
    assert!(stderr.contains("no/such/scene.toml"), "{stderr}");
}

#[test]
fn unwritable_output_fails_before_rendering_and_keeps_old_image() {
    let tmp = tempfile::tempdir().unwrap();
    let missing_dir = tmp.path().join("no-dir/x.png");
    let out = whitted(&["render", "-o", missing_dir.to_str().unwrap(), "--width", "8", "--height", "8"]);
    let stderr = assert_clean_failure(&out, &missing_dir, "unwritable output");
    assert!(stderr.contains("no-dir/x.png"), "{stderr}");

    let unknown = tmp.path().join("x.tga");
    let out = whitted(&["render", "-o", unknown.to_str().unwrap(), "--width", "8", "--height", "8"]);
    let stderr = assert_clean_failure(&out, &unknown, "unknown output format");
    assert!(stderr.contains("x.tga: unknown image format"), "{stderr}");

    // A failing render must not touch an existing good image.
    let good = tmp.path().join("good.png");
    std::fs::write(&good, b"previous image").unwrap();
    let bad_scene = bad_dir().join("negative_radius.toml");
    let out = whitted(&["render", bad_scene.to_str().unwrap(), "-o", good.to_str().unwrap()]);
    assert!(!out.status.success());
    assert_eq!(std::fs::read(&good).unwrap(), b"previous image");
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 1, "temporary files left behind");
}

#[test]
fn bad_flags_are_usage_errors_not_panics() {
    for args in [
        &["render", "--spp", "0"][..],
        &["render", "--width", "0"],
        &["render", "--height", "20000"],
        &["render", "--threads", "zero"],
        &["render", "--depth=-1"],
        &["render", "--frobnicate"],
    ] {
        let out = whitted(args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
        let flag = args[1].split('=').next().unwrap();
        assert!(stderr.contains(flag), "{args:?} not named in: {stderr}");
    }
}

#[test]
fn scene_without_objects_or_lights_renders_with_warnings() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("empty.toml");
    std::fs::write(&scene, "[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, -1]\nfov = 40\nwidth = 8\nheight = 8\n")
        .unwrap();
    let out_png = tmp.path().join("empty.png");
    let out = whitted(&["render", scene.to_str().unwrap(), "-o", out_png.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("warning: the scene has no objects"), "{stderr}");
    assert!(stderr.contains("warning: the scene has no lights"), "{stderr}");
    assert!(out_png.exists());
    // -q silences warnings.
    let out = whitted(&["render", scene.to_str().unwrap(), "-o", out_png.to_str().unwrap(), "-q"]);
    assert!(out.status.success() && out.stderr.is_empty());
}

fn mesh_scene(dir: &Path, obj: &Path) -> PathBuf {
    let scene = dir.join("mesh.toml");
    let text = format!(
        "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\nfov = 40\nwidth = 16\nheight = 16\n\n\
         [[light]]\nposition = [5, 5, 5]\n\n[[mesh]]\nfile = {:?}\nmaterial = {{ color = [1, 1, 1] }}\n",
        obj.to_str().unwrap()
    );
    std::fs::write(&scene, text).unwrap();
    scene
}

/// Every malformed OBJ under tests/scenes/bad_obj/ fails like a bad scene, and the
/// message names the OBJ file and the line (line 0: a whole-file problem).
#[test]
fn every_bad_obj_fails_with_file_line_and_statement() {
    let tmp = tempfile::tempdir().unwrap();
    let files = files_in("tests/scenes/bad_obj", "obj");
    assert!(files.len() >= 6, "only {} bad OBJ files", files.len());
    let mut failures = Vec::new();
    for obj in &files {
        let name = obj.file_name().unwrap().to_string_lossy().into_owned();
        let (line, field) = expectation(obj);
        let scene = mesh_scene(tmp.path(), obj);
        let out_png = tmp.path().join("out.png");
        let out = whitted(&["render", scene.to_str().unwrap(), "-o", out_png.to_str().unwrap(), "-q"]);
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        if out.status.code() != Some(1) || stderr.contains("panicked") || out_png.exists() {
            failures.push(format!("{name}: status {:?}: {stderr}", out.status));
            continue;
        }
        let location = if line == 0 { format!("{}: ", obj.display()) } else { format!("{}:{line}:", obj.display()) };
        if !stderr.contains(&location) || !stderr.contains(&field) {
            failures.push(format!("{name}: expected '{location}' and '{field}' in: {stderr}"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn missing_obj_is_reported_where_the_scene_names_it() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = mesh_scene(tmp.path(), &tmp.path().join("no-such-mesh.obj"));
    let out_png = tmp.path().join("out.png");
    let out = whitted(&["render", scene.to_str().unwrap(), "-o", out_png.to_str().unwrap()]);
    let stderr = assert_clean_failure(&out, &out_png, "missing OBJ");
    assert!(stderr.contains(&format!("{}:12:", scene.display())), "{stderr}");
    assert!(stderr.contains("file") && stderr.contains("no-such-mesh.obj"), "{stderr}");
}
