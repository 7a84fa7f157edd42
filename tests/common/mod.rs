//! Helpers shared by the command-line tests.
#![allow(dead_code)] // each test crate uses its own subset

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the `whitted` binary built for these tests.
pub fn whitted(args: &[&str]) -> Output {
    whitted_command().args(args).output().expect("run whitted")
}

/// The `whitted` binary built for these tests, as a command to add arguments to. Where
/// the tests run under an emulator (CI's aarch64 tests under qemu), the environment
/// variable `WHITTED_TEST_RUNNER` names it, with its arguments, and the binary runs
/// under it too.
pub fn whitted_command() -> Command {
    let exe = env!("CARGO_BIN_EXE_whitted");
    let runner = std::env::var("WHITTED_TEST_RUNNER").unwrap_or_default();
    let mut words = runner.split_whitespace();
    let Some(program) = words.next() else { return Command::new(exe) };
    let mut cmd = Command::new(program);
    cmd.args(words).arg(exe);
    cmd
}

/// A path inside the repository.
pub fn manifest(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// Reads `# expect-line: N` and `# expect-field: NAME` from the top of a bad input file.
pub fn expectation(path: &Path) -> (usize, String) {
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

/// The files with extension `ext` in the repository folder `dir`, sorted.
pub fn files_in(dir: &str, ext: &str) -> Vec<PathBuf> {
    let mut files: Vec<_> = std::fs::read_dir(manifest(dir))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == ext))
        .collect();
    files.sort();
    files
}
