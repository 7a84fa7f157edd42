//! An interrupted render (Ctrl-C or SIGTERM) removes its temporary file and leaves an
//! existing image of the same name untouched.
#![cfg(unix)]

mod common;

use std::path::Path;
use std::time::{Duration, Instant};

fn temp_files(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(".whitted-"))
        .collect()
}

fn interrupt_with(signal: i32) {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("room.png");
    std::fs::write(&out, b"the previous image").unwrap();
    // Long enough to be interrupted whatever the machine: 2000x2000 pixels, 64 samples.
    let mut child = common::whitted_command()
        .args(["render", "--width", "2000", "--height", "2000", "--spp", "64", "-q", "-o"])
        .arg(&out)
        .spawn()
        .unwrap();
    let start = Instant::now();
    while temp_files(tmp.path()).is_empty() {
        assert!(start.elapsed() < Duration::from_secs(60), "no temporary file appeared");
        assert!(child.try_wait().unwrap().is_none(), "the render ended before it was interrupted");
        std::thread::sleep(Duration::from_millis(10));
    }
    std::thread::sleep(Duration::from_millis(300)); // well into the render
    // SAFETY: kill(2) on our own child's pid has no memory-safety preconditions.
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, signal) }, 0);
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130), "signal {signal}: {status:?}");
    assert_eq!(temp_files(tmp.path()), Vec::<String>::new(), "signal {signal}: temporary file left behind");
    assert_eq!(std::fs::read(&out).unwrap(), b"the previous image", "signal {signal}: image touched");
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 1);
}

#[test]
fn sigint_removes_the_temporary_file() {
    interrupt_with(libc::SIGINT);
}

#[test]
fn sigterm_removes_the_temporary_file() {
    interrupt_with(libc::SIGTERM);
}

/// Interrupting `--frames` keeps the frames already written, whole, and leaves no part
/// of the one being rendered.
#[test]
fn an_interrupted_run_of_frames_keeps_the_finished_ones_whole() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/turntable.toml");
    let mut child = common::whitted_command()
        .args(["render", "--frames", "0..100", "--width", "300", "--spp", "16", "-q", "-o"])
        .arg(tmp.path().join("f-###.png"))
        .arg(&scene)
        .spawn()
        .unwrap();
    let start = Instant::now();
    while !tmp.path().join("f-000.png").exists() {
        assert!(start.elapsed() < Duration::from_secs(120), "no frame appeared");
        assert!(child.try_wait().unwrap().is_none(), "the run ended before it was interrupted");
        std::thread::sleep(Duration::from_millis(10));
    }
    std::thread::sleep(Duration::from_millis(50)); // into the next frame
    // SAFETY: kill(2) on our own child's pid has no memory-safety preconditions.
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) }, 0);
    assert_eq!(child.wait().unwrap().code(), Some(130));
    assert_eq!(temp_files(tmp.path()), Vec::<String>::new(), "temporary file left behind");
    let mut names: Vec<_> =
        std::fs::read_dir(tmp.path()).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
    names.sort();
    assert!(!names.is_empty() && names.len() < 101, "{names:?}");
    for (i, n) in names.iter().enumerate() {
        assert_eq!(n, &format!("f-{i:03}.png"), "frames in order");
        let image = image::open(tmp.path().join(n)).unwrap_or_else(|e| panic!("{n}: {e}"));
        assert_eq!(image.width(), 300);
    }
}
