//! The interactive viewer (`whitted view`): a window showing the scene rendered
//! progressively, a coarse preview first, then finer passes while nothing changes.
//!
//! Everything but the window itself is here and display-free: [`state`] turns keys into
//! changes, [`worker`] renders on its own thread and cancels stale work, [`reload`]
//! watches the scene's files, [`overlay`] draws the picture and the text. [`Viewer`]
//! ties them together behind a few calls that the window loop makes ([`window`]) and
//! that tests make without one. Only [`window`] needs the `viewer` cargo feature.

pub mod overlay;
pub mod reload;
pub mod state;
#[cfg(feature = "viewer")]
pub mod window;
pub mod worker;

use crate::film::write_png;
use crate::scene::{self, Scene};
use overlay::{GREY, Line, RED, WHITE, YELLOW};
use reload::{Reload, Watcher};
use state::{Action, Effect, ViewState, aa_samples};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};
use worker::{Frame, Job, Worker};

/// How long a notice (a saved screenshot, a missing feature) stays on screen.
const NOTICE_TIME: Duration = Duration::from_secs(3);
/// The window opens no larger than this, keeping the scene's aspect ratio.
const MAX_START_SIZE: (u32, u32) = (1600, 1000);

/// How the viewer starts.
#[derive(Clone, Debug, Default)]
pub struct Options {
    /// The scene file; the built-in room without one.
    pub scene: Option<PathBuf>,
    /// Window size; the scene camera's without one.
    pub size: Option<(u32, u32)>,
    /// Print when each pass appears and when full quality is reached, to stderr.
    pub timing: bool,
    /// Where screenshots go.
    pub screenshot_dir: PathBuf,
}

/// Whether the viewer goes on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Flow {
    Continue,
    Quit,
}

pub struct Viewer {
    name: String,
    scene: Arc<Scene>,
    watcher: Option<Watcher>,
    state: ViewState,
    worker: Worker,
    /// The job whose passes are wanted; frames of older ones are dropped.
    job: u64,
    /// The last pass shown, kept to redraw the overlay and for screenshots.
    shown: Option<Frame>,
    /// The last reload error, until a good version loads.
    error: Option<String>,
    notice: Option<(String, Instant)>,
    fb: Vec<u32>,
    dirty: bool,
    timing: bool,
    launched: Instant,
    screenshot_dir: PathBuf,
    screenshots: u32,
}

impl Viewer {
    /// Loads the scene and starts rendering. A scene that fails to load the first time
    /// is an error: there is no earlier version to show instead.
    pub fn new(options: Options) -> Result<Viewer, String> {
        let launched = Instant::now();
        let (name, scene, watcher) = match &options.scene {
            Some(path) => {
                let (watcher, scene) = Watcher::open(path)?;
                (scene_name(path), scene, Some(watcher))
            }
            None => {
                let scene = scene::load_str(scene::DEFAULT_SCENE, scene::DEFAULT_SCENE_NAME, Path::new("scenes"))
                    .map_err(|e| e.to_string())?;
                ("room".to_owned(), Arc::new(scene), None)
            }
        };
        let (width, height) =
            options.size.unwrap_or_else(|| fit(scene.camera.width, scene.camera.height, MAX_START_SIZE));
        let state = ViewState::new(scene.camera, scene.settings.samples, width, height);
        let mut viewer = Viewer {
            name,
            scene,
            watcher,
            state,
            worker: Worker::new(),
            job: 0,
            shown: None,
            error: None,
            notice: None,
            fb: vec![0; width as usize * height as usize],
            dirty: true,
            timing: options.timing,
            launched,
            screenshot_dir: options.screenshot_dir,
            screenshots: 0,
        };
        for w in viewer.scene.warnings() {
            eprintln!("warning: {w}");
        }
        viewer.restart();
        Ok(viewer)
    }

    pub fn title(&self) -> String {
        format!("whitted: {}", self.name)
    }

    pub fn size(&self) -> (usize, usize) {
        (self.state.width as usize, self.state.height as usize)
    }

    pub fn state(&self) -> &ViewState {
        &self.state
    }

    /// The current job's number (it changes whenever the picture goes stale).
    pub fn job(&self) -> u64 {
        self.job
    }

    pub fn shown(&self) -> Option<&Frame> {
        self.shown.as_ref()
    }

    pub fn error(&self) -> Option<&str> {
        self.error.as_deref()
    }

    pub fn worker(&self) -> &Worker {
        &self.worker
    }

    /// The picture with its overlay, `size()` pixels.
    pub fn framebuffer(&self) -> &[u32] {
        &self.fb
    }

    /// Whether the framebuffer changed since the last call.
    pub fn take_dirty(&mut self) -> bool {
        std::mem::take(&mut self.dirty)
    }

    /// Prints a timing line, measured from launch.
    pub fn log_timing(&self, what: &str) {
        if self.timing {
            eprintln!("timing: {:8.3} s: {what}", self.launched.elapsed().as_secs_f64());
        }
    }

    pub fn handle(&mut self, action: Action) -> Flow {
        let effect = self.state.apply(action);
        self.effect(effect)
    }

    pub fn resize(&mut self, width: usize, height: usize) {
        let (w, h) = (width.min(u32::MAX as usize) as u32, height.min(u32::MAX as usize) as u32);
        let effect = self.state.resize(w, h);
        if effect == Effect::Restart {
            self.fb = vec![0; width * height];
        }
        self.effect(effect);
    }

    fn effect(&mut self, effect: Effect) -> Flow {
        match effect {
            Effect::Nothing => {}
            Effect::Redraw => self.compose(),
            Effect::Restart => self.restart(),
            Effect::Notice(text) => self.notify(text),
            Effect::Screenshot => self.screenshot(),
            Effect::Quit => return Flow::Quit,
        }
        Flow::Continue
    }

    /// Takes in finished passes and file changes; call it every few milliseconds.
    pub fn poll(&mut self) {
        let now = Instant::now();
        let mut latest = None;
        while let Some(f) = self.worker.try_recv() {
            if f.job == self.job {
                latest = Some(f);
            }
        }
        if let Some(f) = latest {
            self.show(f);
        }
        if let Some(w) = &mut self.watcher
            && let Some(reload) = w.poll(now)
        {
            self.reloaded(reload);
        }
        if self.notice.as_ref().is_some_and(|(_, t)| now.duration_since(*t) > NOTICE_TIME) {
            self.notice = None;
            self.compose();
        }
    }

    fn show(&mut self, f: Frame) {
        let first = self.shown.is_none();
        let (w, h) = (f.image.width(), f.image.height());
        self.log_timing(&format!(
            "job {} pass {}/{} shown ({w}x{h}, {} spp, pass {:.0} ms, {:.0} ms after the change){}",
            f.job,
            f.pass + 1,
            f.passes,
            f.spp,
            f.elapsed.as_secs_f64() * 1e3,
            f.since_submit.as_secs_f64() * 1e3,
            if first { ", first frame" } else { "" },
        ));
        if f.is_final() {
            self.log_timing(&format!("job {} full quality", f.job));
        }
        if self.state.show_stats && f.is_final() {
            let s = f.stats;
            println!(
                "rays: primary {} shadow {} reflection {} refraction {} total {} ({:.2} Mrays/s)",
                s.primary,
                s.shadow,
                s.reflection,
                s.refraction,
                s.total(),
                mrays(&f)
            );
        }
        self.shown = Some(f);
        self.compose();
    }

    fn reloaded(&mut self, reload: Reload) {
        match reload {
            Reload::Loaded(scene) => {
                eprintln!("reloaded {}", self.name);
                self.state.scene_changed(scene.camera, scene.settings.samples);
                self.scene = scene;
                self.error = None;
                self.restart();
            }
            Reload::Failed(e) => {
                eprintln!("error: {e} (still showing the last good version)");
                self.error = Some(e);
                self.compose();
            }
        }
    }

    /// Cancels the render in progress and starts the passes of the current view. The
    /// old picture stays up until the new preview replaces it.
    fn restart(&mut self) {
        let key = self.state.render_key();
        self.job = self.worker.submit(Job {
            scene: self.scene.clone(),
            camera: key.camera,
            accel: key.accel,
            width: key.width,
            height: key.height,
            passes: key.passes,
        });
        self.compose();
    }

    fn notify(&mut self, text: String) {
        println!("{text}");
        self.notice = Some((text, Instant::now()));
        self.compose();
    }

    /// Saves the last pass shown, at the view's size, as `whitted-<scene>-<n>.png`
    /// with the first free `n`; the file appears whole or not at all.
    fn screenshot(&mut self) {
        let Some(f) = &self.shown else {
            self.notify("nothing rendered yet to save".to_owned());
            return;
        };
        let image =
            if f.divisor == 1 { f.image.clone() } else { overlay::upscale(&f.image, f.divisor, f.width, f.height) };
        let path = loop {
            self.screenshots += 1;
            let name = format!("whitted-{}-{}.png", self.name, self.screenshots);
            // Plain name for the current folder: that is what the user types next.
            let p = if self.screenshot_dir == Path::new(".") {
                PathBuf::from(name)
            } else {
                self.screenshot_dir.join(name)
            };
            if !p.exists() {
                break p;
            }
        };
        let text = match write_png(&image, &path) {
            Ok(()) => format!("saved {}", path.display()),
            Err(e) => format!("error: {e}"),
        };
        self.notify(text);
    }

    /// Redraws the framebuffer: the last pass, then the overlay.
    fn compose(&mut self) {
        let (w, h) = self.size();
        match &self.shown {
            Some(f) => overlay::blit(&f.image, f.divisor, &mut self.fb, w, h),
            None => self.fb.fill(0),
        }
        let scale = overlay::text_scale(w);
        let lines = self.overlay_lines((w / (8 * scale)).saturating_sub(1));
        overlay::Canvas { pixels: &mut self.fb, width: w, height: h }.panel(&lines, scale);
        self.dirty = true;
    }

    fn overlay_lines(&self, max_chars: usize) -> Vec<Line> {
        let s = &self.state;
        let mut lines = Vec::new();
        let current = self.shown.as_ref().filter(|f| f.job == self.job);
        let status = match (&self.shown, current) {
            (None, _) => "rendering...".to_owned(),
            (Some(_), None) => "rendering...".to_owned(),
            (Some(_), Some(f)) => {
                let res = if f.divisor > 1 { format!(" 1/{} res", f.divisor) } else { String::new() };
                let more = if f.is_final() { "" } else { " refining" };
                format!("{} spp{res}{more}", f.spp)
            }
        };
        lines.push((format!("{}  {status}", self.name), WHITE));
        if s.show_time
            && let Some(f) = &self.shown
        {
            lines.push((format!("frame {:.0} ms  {:.1} Mrays/s", f.elapsed.as_secs_f64() * 1e3, mrays(f)), WHITE));
        }
        if s.show_stats
            && let Some(f) = &self.shown
        {
            let st = f.stats;
            lines.push((format!("primary {}  shadow {}", st.primary, st.shadow), WHITE));
            lines.push((format!("reflect {}  refract {}", st.reflection, st.refraction), WHITE));
        }
        let aa = if s.aa { format!("on {}spp", aa_samples(s.scene_samples)) } else { "off".to_owned() };
        let accel = if crate::accel::AccelKind::ALL.len() < 2 {
            "BVH n/a".to_owned()
        } else {
            format!("accel {:?}", s.accel_kind())
        };
        lines.push((format!("AA {aa}  {accel}  h: keys"), GREY));
        if s.show_help {
            lines.extend(Action::HELP.iter().map(|l| (l.to_string(), YELLOW)));
        }
        if let Some((text, _)) = &self.notice {
            lines.extend(overlay::wrap(text, max_chars).into_iter().map(|l| (l, YELLOW)));
        }
        if let Some(e) = &self.error {
            lines.extend(overlay::wrap(e, max_chars).into_iter().map(|l| (l, RED)));
        }
        lines
    }
}

fn mrays(f: &Frame) -> f64 {
    f.stats.total() as f64 / f.elapsed.as_secs_f64().max(1e-9) / 1e6
}

/// The file name without its extension, for the title bar and screenshot names.
fn scene_name(path: &Path) -> String {
    path.file_stem().map_or_else(|| "scene".to_owned(), |s| s.to_string_lossy().into_owned())
}

/// `width` × `height` scaled down, if need be, to fit `max`, keeping the aspect ratio.
fn fit(width: u32, height: u32, max: (u32, u32)) -> (u32, u32) {
    let k = (max.0 as f64 / width as f64).min(max.1 as f64 / height as f64).min(1.0);
    (((width as f64 * k).round() as u32).max(1), ((height as f64 * k).round() as u32).max(1))
}

#[cfg(test)]
mod tests;
