//! Live reload: notices when the scene file, or a file it names (an image texture, a
//! mesh), changes on disk, and loads the new version. Polling a handful of file stamps a
//! few times a second costs nothing and needs no platform file-watching API.
//!
//! A broken edit keeps the last good scene and reports the loader's error, which names
//! the file, line, column and field; the next edit is tried again.

use crate::scene::{self, Scene};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime};

/// How often the files are looked at: well inside the half second a reload may take.
pub const POLL_INTERVAL: Duration = Duration::from_millis(150);

/// What identifies one version of a file. The length catches a second write within one
/// tick of a coarse file-system clock; `None` is a missing or unreadable file, so a
/// file that appears (or disappears) counts as a change too.
type Stamp = Option<(SystemTime, u64)>;

fn stamp(path: &Path) -> Stamp {
    let m = std::fs::metadata(path).ok()?;
    Some((m.modified().ok()?, m.len()))
}

/// The files a scene text refers to, resolved against `base_dir` like the loader does:
/// every string value of a key named `path` or `file`, at any depth. Texture `path`s are
/// the only ones today; `file` is there for meshes. Broken text names no files (the
/// loader's error says why), and the previous list is kept by the caller.
pub fn referenced_files(src: &str, base_dir: &Path) -> Option<Vec<PathBuf>> {
    fn walk(v: &toml::Value, base: &Path, out: &mut Vec<PathBuf>) {
        match v {
            toml::Value::Table(t) => {
                for (k, v) in t {
                    match v {
                        toml::Value::String(s) if k == "path" || k == "file" => out.push(base.join(s)),
                        _ => walk(v, base, out),
                    }
                }
            }
            toml::Value::Array(a) => a.iter().for_each(|v| walk(v, base, out)),
            _ => {}
        }
    }
    let doc: toml::Table = toml::from_str(src).ok()?;
    let mut out = Vec::new();
    walk(&toml::Value::Table(doc), base_dir, &mut out);
    out.sort();
    out.dedup();
    Some(out)
}

/// The outcome of a reload.
#[derive(Debug)]
pub enum Reload {
    Loaded(Arc<Scene>),
    /// The message to show: `file:line:column: field: message`.
    Failed(String),
}

/// Watches one scene file and the files it uses.
#[derive(Debug)]
pub struct Watcher {
    scene_path: PathBuf,
    /// Each watched file with its stamp when last loaded, the scene file first.
    files: Vec<(PathBuf, Stamp)>,
    last_poll: Option<Instant>,
}

impl Watcher {
    /// Loads the scene for the first time. There is no last good version to fall back
    /// on yet, so a broken file is an error for the caller.
    pub fn open(scene_path: &Path) -> Result<(Self, Arc<Scene>), String> {
        let mut w = Watcher::new(scene_path);
        match w.load() {
            Reload::Loaded(scene) => Ok((w, scene)),
            Reload::Failed(e) => Err(e),
        }
    }

    fn new(scene_path: &Path) -> Self {
        Watcher { scene_path: scene_path.to_owned(), files: vec![(scene_path.to_owned(), None)], last_poll: None }
    }

    pub fn files(&self) -> impl Iterator<Item = &Path> {
        self.files.iter().map(|(p, _)| p.as_path())
    }

    /// Whether any watched file changed since the last load.
    pub fn changed(&self) -> bool {
        self.files.iter().any(|(p, s)| stamp(p) != *s)
    }

    /// Reloads when a watched file changed and it is time to look again (every
    /// [`POLL_INTERVAL`]); `None` when there is nothing new.
    pub fn poll(&mut self, now: Instant) -> Option<Reload> {
        if self.last_poll.is_some_and(|t| now.duration_since(t) < POLL_INTERVAL) {
            return None;
        }
        self.last_poll = Some(now);
        self.changed().then(|| self.load())
    }

    /// Loads the scene now. The stamps are taken before reading, so a write that lands
    /// during the load is seen by the next poll and loaded then.
    pub fn load(&mut self) -> Reload {
        for (p, s) in &mut self.files {
            *s = stamp(p);
        }
        // NFF or TOML, by extension, as `whitted render` decides.
        let result = scene::load_path(&self.scene_path, scene::Format::of_path(&self.scene_path)).map(|l| l.scene);
        // Watch what the text names even when it fails to load: a missing texture is
        // fixed by creating the texture.
        if let Ok(src) = std::fs::read_to_string(&self.scene_path) {
            let base = self.scene_path.parent().unwrap_or(Path::new("."));
            if let Some(deps) = referenced_files(&src, base) {
                self.files.truncate(1);
                for d in deps {
                    if d != self.scene_path {
                        let s = stamp(&d);
                        self.files.push((d, s));
                    }
                }
            }
        }
        match result {
            Ok(scene) => Reload::Loaded(Arc::new(scene)),
            Err(e) => Reload::Failed(e.to_string()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::fs::File;

    pub(crate) const GOOD: &str = r#"
[camera]
position = [0, 0, 0]
look_at = [0, 0, -1]
fov = 45
width = 64
height = 48

[[sphere]]
center = [0, 0, -5]
radius = 1
material = { color = [1, 0, 0] }
"#;

    /// Writes `text` and moves the file's time forward, so the change shows whatever
    /// the file system's clock resolution.
    fn write(path: &Path, text: &str, tick: u64) {
        std::fs::write(path, text).unwrap();
        let t = SystemTime::UNIX_EPOCH + Duration::from_secs(1_000_000 + tick);
        File::options().write(true).open(path).unwrap().set_modified(t).unwrap();
    }

    fn sphere_radius(scene: &Scene) -> f32 {
        match &scene.objects[0].shape {
            crate::geometry::Shape::Sphere(s) => s.radius,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn reloads_a_good_edit_and_keeps_the_last_good_scene_on_a_bad_one() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.toml");
        write(&path, GOOD, 1);
        let (mut w, scene) = Watcher::open(&path).unwrap();
        assert_eq!(sphere_radius(&scene), 1.0);
        let t0 = Instant::now();
        assert!(w.poll(t0).is_none(), "nothing changed");

        write(&path, &GOOD.replace("radius = 1", "radius = 2"), 2);
        assert!(w.poll(t0 + Duration::from_millis(10)).is_none(), "too soon to look again");
        match w.poll(t0 + POLL_INTERVAL) {
            Some(Reload::Loaded(s)) => assert_eq!(sphere_radius(&s), 2.0),
            other => panic!("{other:?}"),
        }

        write(&path, &GOOD.replace("radius = 1", "radius = -3"), 3);
        match w.poll(t0 + 2 * POLL_INTERVAL) {
            Some(Reload::Failed(e)) => {
                assert!(e.contains("s.toml:11:"), "file and line: {e}");
                assert!(e.contains("radius"), "field: {e}");
            }
            other => panic!("{other:?}"),
        }
        assert!(w.poll(t0 + 3 * POLL_INTERVAL).is_none(), "a failed version is not retried until edited");

        write(&path, GOOD, 4);
        assert!(matches!(w.poll(t0 + 4 * POLL_INTERVAL), Some(Reload::Loaded(_))));
    }

    #[test]
    fn a_broken_first_version_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.toml");
        write(&path, "[camera]\nposition = [0, 0", 1);
        let e = Watcher::open(&path).unwrap_err();
        assert!(e.contains("s.toml:2:"), "{e}");
        assert!(Watcher::open(&dir.path().join("missing.toml")).is_err());
    }

    #[test]
    fn watches_the_files_the_scene_names() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.toml");
        let text = format!("{GOOD}\n[material.wood]\ntexture = {{ kind = \"image\", path = \"tex/wood.png\" }}\n");
        write(&path, &text, 1);
        // Whether or not the image loads, the file is watched, and creating (or
        // editing) it triggers a reload.
        let mut w = Watcher::new(&path);
        let _ = w.load();
        let tex = dir.path().join("tex/wood.png");
        assert!(w.files().any(|p| p == tex), "{:?}", w.files().collect::<Vec<_>>());
        let t0 = Instant::now();
        assert!(w.poll(t0).is_none());
        std::fs::create_dir(dir.path().join("tex")).unwrap();
        write(&tex, "not really a png", 5);
        assert!(w.poll(t0 + POLL_INTERVAL).is_some(), "the texture changed");
    }

    #[test]
    fn referenced_files_finds_paths_at_any_depth() {
        let src = r#"
[material.a]
texture = { kind = "image", path = "a.png" }
[[mesh]]
file = "sub/b.obj"
[[sphere]]
material = { texture = { kind = "image", path = "/abs/c.png" } }
"#;
        let base = Path::new("/scenes");
        assert_eq!(
            referenced_files(src, base).unwrap(),
            [PathBuf::from("/abs/c.png"), PathBuf::from("/scenes/a.png"), PathBuf::from("/scenes/sub/b.obj")]
        );
        assert!(referenced_files("[camera", base).is_none());
    }
}
