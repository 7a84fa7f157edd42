//! The README is what a new user follows: every scene it names must exist and render,
//! every picture it shows must exist, and every `bench --scene` name it lists must be
//! accepted.

mod common;

use common::{manifest, whitted};
use std::collections::BTreeSet;

fn readme() -> String {
    std::fs::read_to_string(manifest("README.md")).unwrap()
}

/// Every `prefix...` path in the text ending in one of `exts`.
fn paths(text: &str, prefix: &str, exts: &[&str]) -> BTreeSet<String> {
    let mut found = BTreeSet::new();
    for (i, _) in text.match_indices(prefix) {
        let rest = &text[i..];
        let end = rest.find(|c: char| !(c.is_ascii_alphanumeric() || "/._-".contains(c))).unwrap_or(rest.len());
        let p = rest[..end].trim_end_matches('.');
        if exts.iter().any(|e| p.ends_with(e)) && !p.contains("NAME") {
            found.insert(p.to_owned());
        }
    }
    found
}

#[test]
fn every_scene_the_readme_names_exists_and_renders() {
    let text = readme();
    let scenes = paths(&text, "scenes/", &[".toml", ".nff", ".obj", ".glb", ".gltf"]);
    assert!(scenes.len() >= 6, "too few scenes found: {scenes:?}");
    let tmp = tempfile::tempdir().unwrap();
    for s in &scenes {
        let path = manifest(s);
        assert!(path.is_file(), "README names {s}, which does not exist");
        let png = tmp.path().join("out.png");
        let out = whitted(&["render", path.to_str().unwrap(), "--width", "32", "-q", "-o", png.to_str().unwrap()]);
        assert!(out.status.success(), "{s}: {}", String::from_utf8_lossy(&out.stderr));
        assert_eq!(image::open(&png).unwrap().width(), 32, "{s}");
    }
    for p in paths(&text, "docs/", &[".png", ".md"]) {
        assert!(manifest(&p).is_file(), "README links {p}, which does not exist");
    }
    assert!(!text.contains("../"), "README refers to a path outside the repository");
}

#[test]
fn every_bench_scene_the_readme_lists_is_accepted() {
    let text = readme();
    let start = text.find("`--scene` takes").expect("README lists the bench scenes");
    let list = &text[start..start + text[start..].find(";").unwrap()];
    let names: Vec<&str> = list.split('`').skip(3).step_by(2).collect();
    assert!(names.len() >= 6, "{names:?}");
    for n in names {
        // Building each case takes seconds (the 10M mesh a minute): ask the command line,
        // which checks every name before measuring, with a nonexistent mesh so that it
        // stops right after the names.
        let out = whitted(&["bench", "--scene", n, "--mesh", "/nonexistent.obj"]);
        let e = String::from_utf8_lossy(&out.stderr);
        assert!(e.contains("--mesh /nonexistent.obj: no such file"), "README lists bench scene {n}: {e}");
    }
    // And a wrong name is refused, so the check above can fail.
    let out = whitted(&["bench", "--scene", "spheres-10648", "--mesh", "/nonexistent.obj"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("no such built-in scene"));
}

#[test]
fn the_first_scene_in_the_readme_is_the_file() {
    let text = readme();
    let start = text.find("```toml\n# A first scene").expect("first scene block") + "```toml\n".len();
    let block = &text[start..start + text[start..].find("```").unwrap()];
    assert_eq!(block, std::fs::read_to_string(manifest("scenes/first.toml")).unwrap());
    assert!(block.lines().count() <= 30);
}
