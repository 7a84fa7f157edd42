//! Every platform: a build without the `viewer` feature says so when asked for the
//! window.

mod common;

#[cfg(not(feature = "viewer"))]
#[test]
fn view_says_it_was_built_without_the_viewer() {
    let run = common::whitted_command().arg("view").output().expect("run whitted");
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success(), "whitted view succeeded without the viewer");
    assert!(err.contains("built without the viewer") && err.contains("--features viewer"), "{err}");
}
