//! The window: minifb on X11. It only turns window input into [`Action`]s and puts
//! the [`Viewer`]'s framebuffer on screen; everything else is display-free.
//!
//! minifb opens the X11 libraries at run time, so building needs no system packages,
//! and its polling API suits a loop that must look at input every frame anyway.

use super::state::{Action, Key};
use super::{Flow, Options, Viewer};
use minifb::{InputCallback, MouseButton, MouseMode, ScaleMode, Window, WindowOptions};
use std::cell::RefCell;
use std::rc::Rc;
use std::time::{Duration, Instant};

/// The loop's pace: input is read every frame, far more often than the 50 ms a
/// responsive window needs, and a frame costs nearly nothing when nothing changed.
const FRAME: Duration = Duration::from_millis(16);
/// Even an unchanged picture is sent again now and then, in case the window system
/// lost it (an uncovered window without a compositor).
const REFRESH: Duration = Duration::from_millis(500);

fn key(k: minifb::Key) -> Option<Key> {
    use minifb::Key as K;
    Some(match k {
        K::A => Key::Char('a'),
        K::B => Key::Char('b'),
        K::D => Key::Char('d'),
        K::H => Key::Char('h'),
        K::P => Key::Char('p'),
        K::R => Key::Char('r'),
        K::T => Key::Char('t'),
        K::Equal | K::NumPadPlus => Key::Char('+'),
        K::Minus | K::NumPadMinus => Key::Char('-'),
        K::Left => Key::Left,
        K::Right => Key::Right,
        K::Up => Key::Up,
        K::Down => Key::Down,
        K::Escape => Key::Escape,
        _ => return None,
    })
}

/// Collects every key press as the window system reports it (auto-repeats included).
/// minifb's `get_keys_pressed` compares key states once a frame, so a press and release
/// that both land within one frame (a quick tap, or a test's `xdotool key`) are lost.
#[derive(Clone, Default)]
struct Presses(Rc<RefCell<Vec<minifb::Key>>>);

impl InputCallback for Presses {
    fn add_char(&mut self, _uni_char: u32) {}

    fn set_key_state(&mut self, key: minifb::Key, down: bool) {
        if down {
            self.0.borrow_mut().push(key);
        }
    }
}

/// Opens the window and runs until Esc or the window is closed.
pub fn run(options: Options) -> Result<(), String> {
    let timing = options.timing;
    let mut viewer = Viewer::new(options)?;
    let (w, h) = viewer.size();
    let mut window = Window::new(
        &viewer.title(),
        w,
        h,
        WindowOptions { resize: true, scale_mode: ScaleMode::UpperLeft, ..WindowOptions::default() },
    )
    .map_err(|e| format!("cannot open a window: {e} (is DISPLAY set to a running X server?)"))?;
    window.set_target_fps(1000 / FRAME.as_millis() as usize);
    let presses = Presses::default();
    window.set_input_callback(Box::new(presses.clone()));
    viewer.log_timing("window open");
    if timing {
        eprintln!("timing: input is read every {} ms", FRAME.as_millis());
    }

    let mut last_push = Instant::now();
    let mut drag: Option<(f32, f32)> = None;
    let mut title = viewer.title();
    let mut first_frame_logged = false;
    // Evidence for responsiveness: the longest time between two looks at the input.
    let mut last_input = Instant::now();
    let mut longest_gap = Duration::ZERO;
    while window.is_open() {
        longest_gap = longest_gap.max(last_input.elapsed());
        last_input = Instant::now();
        if handle_input(&mut window, &presses, &mut drag, &mut viewer) == Flow::Quit {
            break;
        }
        viewer.poll();
        if viewer.title() != title {
            title = viewer.title();
            window.set_title(&title);
        }
        if viewer.take_dirty() || last_push.elapsed() > REFRESH {
            let (w, h) = viewer.size();
            window
                .update_with_buffer(viewer.framebuffer(), w, h)
                .map_err(|e| format!("cannot draw the window: {e}"))?;
            last_push = Instant::now();
            if !first_frame_logged && viewer.shown().is_some() {
                first_frame_logged = true;
                viewer.log_timing("first frame on screen");
            }
        } else {
            window.update();
        }
    }
    viewer.log_timing(&format!("longest time between two input checks: {:.0} ms", longest_gap.as_secs_f64() * 1e3));
    Ok(())
}

/// Feeds the keys, mouse and size since the last frame to the viewer.
fn handle_input(window: &mut Window, presses: &Presses, drag: &mut Option<(f32, f32)>, viewer: &mut Viewer) -> Flow {
    let keys = std::mem::take(&mut *presses.0.borrow_mut());
    for action in keys.into_iter().filter_map(|k| key(k).and_then(Action::from_key)) {
        if viewer.handle(action) == Flow::Quit {
            return Flow::Quit;
        }
    }
    if window.get_mouse_down(MouseButton::Left) {
        if let Some(pos) = window.get_mouse_pos(MouseMode::Pass) {
            if let Some(last) = *drag
                && last != pos
            {
                viewer.handle(Action::drag(pos.0 - last.0, pos.1 - last.1));
            }
            *drag = Some(pos);
        }
    } else {
        *drag = None;
    }
    if let Some((_, dy)) = window.get_scroll_wheel()
        && dy != 0.0
    {
        viewer.handle(Action::wheel(dy.signum()));
    }
    let size = window.get_size();
    if size != viewer.size() {
        viewer.resize(size.0, size.1);
    }
    Flow::Continue
}
