//! NFF scenes through the command line: malformed files fail cleanly, naming the file,
//! line and command.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn whitted(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_whitted")).args(args).output().expect("run whitted")
}

fn manifest(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// Reads `# expect-line: N` and `# expect-field: NAME` from the top of a bad file.
fn expectation(path: &Path) -> (usize, String) {
    let text = std::fs::read_to_string(path).unwrap();
    let value = |key: &str| {
        text.lines()
            .find_map(|l| l.strip_prefix(key))
            .unwrap_or_else(|| panic!("{} lacks '{key}'", path.display()))
            .trim()
            .to_owned()
    };
    (value("# expect-line:").parse().unwrap(), value("# expect-field:"))
}

/// Every malformed file under tests/scenes/bad_nff/ makes `render` and `convert` fail:
/// exit code 1, no panic, `error: FILE:LINE:COL: COMMAND: ...`, and no output file.
#[test]
fn every_bad_nff_fails_with_file_line_and_command() {
    let tmp = tempfile::tempdir().unwrap();
    let mut files: Vec<_> = std::fs::read_dir(manifest("tests/scenes/bad_nff"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "nff"))
        .collect();
    files.sort();
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
