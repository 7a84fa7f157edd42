//! The viewer without a window: keys in, frames and files out.

use super::*;
use crate::viewer::state::Key;
use std::fs::File;
use std::sync::atomic::Ordering;
use std::time::SystemTime;

const SCENE: &str = r#"[camera]
position = [0, 0, 0]
look_at = [0, 0, -1]
fov = 45
width = 160
height = 120

[[light]]
position = [5, 5, 0]

[[sphere]]
center = [0, 0, -5]
radius = 1.5
material = { color = [1, 0, 0] }
"#;

/// Writes `text` with a distinct modification time, so the change is seen whatever the
/// file system's clock resolution.
fn write(path: &Path, text: &str, tick: u64) {
    std::fs::write(path, text).unwrap();
    let t = SystemTime::UNIX_EPOCH + Duration::from_secs(2_000_000 + tick);
    File::options().write(true).open(path).unwrap().set_modified(t).unwrap();
}

fn viewer_on(dir: &Path, text: &str) -> Viewer {
    let path = dir.join("ball.toml");
    write(&path, text, 0);
    Viewer::new(Options { scene: Some(path), screenshot_dir: dir.to_owned(), ..Options::default() }).unwrap()
}

/// Polls until `done` holds, for at most 20 s.
fn wait(v: &mut Viewer, what: &str, done: impl Fn(&Viewer) -> bool) {
    let deadline = Instant::now() + Duration::from_secs(20);
    while !done(v) {
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        v.poll();
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn full_quality(v: &Viewer) -> bool {
    v.shown().is_some_and(|f| f.job == v.job() && f.is_final())
}

fn centre(v: &Viewer) -> u32 {
    let (w, h) = v.size();
    v.framebuffer()[h / 2 * w + w / 2]
}

#[test]
fn shows_the_scene_progressively_up_to_full_quality() {
    let dir = tempfile::tempdir().unwrap();
    let mut v = viewer_on(dir.path(), SCENE);
    assert_eq!(v.title(), "whitted: ball");
    assert_eq!(v.size(), (160, 120));
    wait(&mut v, "full quality", full_quality);
    let f = v.shown().unwrap();
    assert_eq!((f.pass, f.passes, f.spp), (2, 3, 4), "preview, 1 spp, then 4 spp (AA on by default)");
    let c = centre(&v);
    assert!(c >> 16 & 0xff > 100 && c & 0xff < 40, "the red ball is in the middle: {c:06x}");
    assert!(v.take_dirty());
}

#[test]
fn toggling_aa_restarts_and_changes_the_picture() {
    let dir = tempfile::tempdir().unwrap();
    let mut v = viewer_on(dir.path(), SCENE);
    wait(&mut v, "full quality", full_quality);
    let smooth = v.shown().unwrap().image.clone();
    let job = v.job();
    assert_eq!(v.handle(Action::from_key(Key::Char('a')).unwrap()), Flow::Continue);
    assert!(v.job() > job, "a new job");
    wait(&mut v, "full quality without AA", full_quality);
    let f = v.shown().unwrap();
    assert_eq!(f.spp, 1);
    assert_ne!(f.image, smooth, "edges differ");
}

#[test]
fn a_camera_change_cancels_the_render_in_progress() {
    let dir = tempfile::tempdir().unwrap();
    // Big and slow enough (256 spp at 800 × 600) that the final pass cannot finish.
    let slow = format!("{SCENE}\n[settings]\nsamples = 256\n");
    let mut v = Viewer::new(Options {
        scene: Some({
            let p = dir.path().join("ball.toml");
            write(&p, &slow, 0);
            p
        }),
        size: Some((800, 600)),
        screenshot_dir: dir.path().to_owned(),
        ..Options::default()
    })
    .unwrap();
    assert_eq!(v.state().target_spp(), 256);
    wait(&mut v, "the preview", |v| v.shown().is_some());
    let old_job = v.job();
    let old_flag = v.worker().current_cancel_flag().unwrap();
    assert!(!old_flag.load(Ordering::Relaxed));

    let changed = Instant::now();
    v.handle(Action::from_key(Key::Left).unwrap());
    assert!(old_flag.load(Ordering::Relaxed), "the stale render was told to stop at once");
    assert!(v.job() > old_job);
    wait(&mut v, "the new job's preview", |v| v.shown().is_some_and(|f| f.job == v.job()));
    let f = v.shown().unwrap();
    assert_eq!((f.pass, f.divisor), (0, 8), "the new view starts with a coarse preview");
    assert!(changed.elapsed() < Duration::from_secs(5), "{:?}", changed.elapsed());
    // Keys that only touch the overlay leave the render alone.
    let job = v.job();
    let flag = v.worker().current_cancel_flag().unwrap();
    for c in ['t', 'd', 'h'] {
        v.handle(Action::from_key(Key::Char(c)).unwrap());
    }
    assert_eq!(v.job(), job);
    assert!(!flag.load(Ordering::Relaxed));
}

#[test]
fn reload_takes_a_good_edit_and_survives_a_bad_one() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ball.toml");
    let mut v = viewer_on(dir.path(), SCENE);
    wait(&mut v, "full quality", full_quality);
    assert!(centre(&v) >> 16 & 0xff > 100, "red first");

    // A good edit: the ball turns blue within half a second of polling.
    write(&path, &SCENE.replace("color = [1, 0, 0]", "color = [0, 0, 1]"), 1);
    let edited = Instant::now();
    let job = v.job();
    wait(&mut v, "the reload", |v| v.job() > job);
    assert!(edited.elapsed() < Duration::from_millis(500), "{:?}", edited.elapsed());
    wait(&mut v, "the new colour", full_quality);
    let c = centre(&v);
    assert!(c & 0xff > 100 && c >> 16 & 0xff < 40, "blue now: {c:06x}");
    assert!(v.error().is_none());
    let blue = v.shown().unwrap().image.clone();

    // A bad edit: the error names file, line and field; the blue ball stays.
    write(&path, &SCENE.replace("radius = 1.5", "radius = -2"), 2);
    wait(&mut v, "the error", |v| v.error().is_some());
    let e = v.error().unwrap().to_owned();
    assert!(e.contains("ball.toml:13:") && e.contains("radius"), "{e}");
    let job = v.job();
    v.poll();
    assert_eq!(v.job(), job, "no restart for a broken scene");
    assert_eq!(v.shown().unwrap().image, blue, "still the last good picture");
    // The camera still moves over the last good scene.
    v.handle(Action::from_key(Key::Right).unwrap());
    wait(&mut v, "a render of the last good scene", full_quality);

    // Fixed again: the error goes away.
    write(&path, SCENE, 3);
    wait(&mut v, "the fix", |v| v.error().is_none());
}

#[test]
fn screenshot_key_writes_numbered_pngs() {
    let dir = tempfile::tempdir().unwrap();
    let mut v = viewer_on(dir.path(), SCENE);
    wait(&mut v, "full quality", full_quality);
    v.handle(Action::from_key(Key::Char('p')).unwrap());
    v.handle(Action::from_key(Key::Char('p')).unwrap());
    for n in [1, 2] {
        let p = dir.path().join(format!("whitted-ball-{n}.png"));
        let img = image::open(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        assert_eq!((img.width(), img.height()), (160, 120));
    }
    // A screenshot of a preview is saved at the view's size too.
    v.handle(Action::from_key(Key::Char('-')).unwrap());
    wait(&mut v, "a preview", |v| v.shown().is_some_and(|f| f.job == v.job()));
    v.handle(Action::Screenshot);
    let img = image::open(dir.path().join("whitted-ball-3.png")).unwrap();
    assert_eq!((img.width(), img.height()), (160, 120));
}

#[test]
fn other_keys_and_resize() {
    let dir = tempfile::tempdir().unwrap();
    let mut v = viewer_on(dir.path(), SCENE);
    let job = v.job();
    v.handle(Action::CycleAccel);
    if crate::accel::AccelKind::ALL.len() < 2 {
        assert_eq!(v.job(), job, "nothing to switch to");
    } else {
        assert!(v.job() > job);
    }
    assert_eq!(v.handle(Action::from_key(Key::Escape).unwrap()), Flow::Quit);
    v.resize(200, 100);
    assert_eq!(v.size(), (200, 100));
    assert_eq!(v.framebuffer().len(), 200 * 100);
    wait(&mut v, "the new size", full_quality);
    assert_eq!(v.shown().unwrap().image.width(), 200);
    v.resize(0, 0);
    assert_eq!(v.size(), (200, 100), "a minimised window keeps its last size");
}

#[test]
fn the_built_in_room_opens_at_its_own_size() {
    let v = Viewer::new(Options::default()).unwrap();
    assert_eq!(v.size(), (800, 800));
    assert_eq!(v.title(), "whitted: room");
    assert_eq!(fit(3200, 1000, MAX_START_SIZE), (1600, 500));
}
