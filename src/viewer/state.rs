//! What the viewer's input does, with no window in sight: keys become [`Action`]s,
//! actions change the [`ViewState`], and the state says whether the picture must be
//! rendered again. The progressive [`schedule`] and the camera [`Orbit`] live here too,
//! so all of it is tested without a display.

use crate::accel::AccelKind;
use crate::camera::Camera;
use crate::math::Vec3;
use std::f32::consts::{FRAC_PI_2, TAU};

/// A key, named the way the viewer cares about it (the window maps its own key codes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Key {
    Char(char),
    Left,
    Right,
    Up,
    Down,
    Escape,
}

/// Everything the user can ask for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Action {
    ToggleAa,
    CycleAccel,
    ToggleTime,
    ToggleStats,
    ToggleHelp,
    /// Turn the camera around its look-at point (radians; positive yaw turns the view
    /// to the right, positive pitch raises the camera).
    Orbit {
        yaw: f32,
        pitch: f32,
    },
    /// Multiply the distance to the look-at point by this factor.
    Dolly(f32),
    ResetCamera,
    Screenshot,
    Quit,
}

/// One arrow-key press: small enough to aim, big enough that a few presses show a side.
pub const ARROW_STEP: f32 = 5.0 * std::f32::consts::PI / 180.0;
/// One `+`/`-` press or wheel notch moves a tenth of the way in (or out).
pub const DOLLY_STEP: f32 = 0.9;
/// Mouse drag: radians per pixel, about a half turn across an 800-pixel window.
pub const DRAG_RADIANS_PER_PIXEL: f32 = 0.004;
/// Orbiting stops short of the poles, where "up" and the view direction would meet.
pub const PITCH_LIMIT: f32 = FRAC_PI_2 - 1.0 * std::f32::consts::PI / 180.0;
/// Dollying stays within this factor of the scene's own distance either way.
pub const DOLLY_RANGE: f32 = 1000.0;

impl Action {
    /// The action bound to a key, if any. `+` also answers to `=` (the same key without
    /// shift on most layouts).
    pub fn from_key(key: Key) -> Option<Action> {
        Some(match key {
            Key::Char('a') => Action::ToggleAa,
            Key::Char('b') => Action::CycleAccel,
            Key::Char('t') => Action::ToggleTime,
            Key::Char('d') => Action::ToggleStats,
            Key::Char('h') => Action::ToggleHelp,
            Key::Char('r') => Action::ResetCamera,
            Key::Char('p') => Action::Screenshot,
            Key::Char('+' | '=') => Action::Dolly(DOLLY_STEP),
            Key::Char('-') => Action::Dolly(1.0 / DOLLY_STEP),
            Key::Left => Action::Orbit { yaw: -ARROW_STEP, pitch: 0.0 },
            Key::Right => Action::Orbit { yaw: ARROW_STEP, pitch: 0.0 },
            Key::Up => Action::Orbit { yaw: 0.0, pitch: ARROW_STEP },
            Key::Down => Action::Orbit { yaw: 0.0, pitch: -ARROW_STEP },
            Key::Escape => Action::Quit,
            Key::Char(_) => return None,
        })
    }

    /// A mouse drag by (`dx`, `dy`) pixels: the scene follows the pointer, as if grabbed.
    pub fn drag(dx: f32, dy: f32) -> Action {
        Action::Orbit { yaw: -dx * DRAG_RADIANS_PER_PIXEL, pitch: dy * DRAG_RADIANS_PER_PIXEL }
    }

    /// Mouse wheel: away from the user (positive) moves in.
    pub fn wheel(notches: f32) -> Action {
        Action::Dolly(DOLLY_STEP.powf(notches))
    }

    /// The line of the help overlay for each binding.
    pub const HELP: &'static [&'static str] = &[
        "a        anti-aliasing on/off",
        "b        acceleration structure",
        "t        frame time",
        "d        ray statistics",
        "arrows   orbit (or drag)",
        "+ -      dolly (or wheel)",
        "r        reset camera",
        "p        save screenshot",
        "h        this help",
        "Esc      quit",
    ];
}

/// The camera as a point on a sphere around its look-at point: yaw and pitch in a frame
/// built from the scene camera's `up`, so orbiting never rolls the picture and the
/// distance only changes when the user dollies.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orbit {
    home: Camera,
    /// Unit vectors: `up`, and the horizontal direction from the look-at point towards
    /// the home position, and their cross product.
    up: Vec3,
    toward: Vec3,
    side: Vec3,
    home_pitch: f32,
    home_distance: f32,
    yaw: f32,
    pitch: f32,
    distance: f32,
}

impl Orbit {
    /// Starts at `home`, which must make rays (scene cameras do: the loader checks).
    pub fn new(home: Camera) -> Self {
        let up = home.up.normalize_or(Vec3::Y);
        let offset = home.position - home.look_at;
        let horizontal = offset - up * offset.dot(up);
        let toward = horizontal.normalize_or(up.any_orthonormal_vector());
        let home_pitch = offset.dot(up).atan2(offset.dot(toward));
        let home_distance = offset.length().max(f32::MIN_POSITIVE);
        Orbit {
            home,
            up,
            toward,
            side: up.cross(toward),
            home_pitch,
            home_distance,
            yaw: 0.0,
            pitch: home_pitch,
            distance: home_distance,
        }
    }

    pub fn home(&self) -> Camera {
        self.home
    }

    /// The camera now. Exactly the home camera until the user moves it (or after a
    /// reset), so an untouched view renders the same pixels as `whitted render`.
    pub fn camera(&self) -> Camera {
        if self.yaw == 0.0 && self.pitch == self.home_pitch && self.distance == self.home_distance {
            return self.home;
        }
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        let dir = cp * (cy * self.toward + sy * self.side) + sp * self.up;
        Camera { position: self.home.look_at + self.distance * dir, ..self.home }
    }

    pub fn distance(&self) -> f32 {
        self.distance
    }

    /// Returns whether the camera moved (not when the input is not a number, nor when
    /// pitch is already at its limit).
    pub fn orbit(&mut self, yaw: f32, pitch: f32) -> bool {
        if !(yaw.is_finite() && pitch.is_finite()) {
            return false;
        }
        let before = (self.yaw, self.pitch);
        // The home pitch may itself lie past the limit (a camera looking almost straight
        // down): never jump there, only refuse to go further.
        let lo = (-PITCH_LIMIT).min(self.pitch);
        let hi = PITCH_LIMIT.max(self.pitch);
        self.pitch = (self.pitch + pitch).clamp(lo, hi);
        self.yaw = (self.yaw + yaw).rem_euclid(TAU);
        (self.yaw, self.pitch) != before
    }

    /// Returns whether the camera moved.
    pub fn dolly(&mut self, factor: f32) -> bool {
        if !(factor.is_finite() && factor > 0.0) {
            return false;
        }
        let before = self.distance;
        let (lo, hi) = (self.home_distance / DOLLY_RANGE, self.home_distance * DOLLY_RANGE);
        self.distance = (self.distance * factor).clamp(lo, hi);
        self.distance != before
    }

    /// Returns whether the camera moved.
    pub fn reset(&mut self) -> bool {
        let moved = self.camera() != self.home;
        *self = Orbit::new(self.home);
        moved
    }
}

/// One step of progressive rendering: the image at 1/`divisor` of the window's size in
/// each direction (shown by pixel replication), with `spp` samples per pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Pass {
    pub divisor: u32,
    pub spp: u32,
}

impl Pass {
    /// The image size this pass renders for a `width` × `height` window.
    pub fn size(&self, width: u32, height: u32) -> (u32, u32) {
        (width.div_ceil(self.divisor).max(1), height.div_ceil(self.divisor).max(1))
    }
}

/// The passes that take a `width` × `height` view to `spp` samples per pixel:
/// - a coarse preview at 1 spp (1/8 of the size each way for a big window, 1/4 for a
///   middling one, none for a small one, which the next pass already draws at once);
/// - the full size at 1 spp;
/// - then 4, 16, 64... spp up to `spp`, ending exactly on it.
///
/// Every pass starts afresh rather than adding to the previous ones: that costs at most
/// a third more than the last pass alone, and keeps the final picture the same pixels as
/// `whitted render --spp N` gives.
pub fn schedule(width: u32, height: u32, spp: u32) -> Vec<Pass> {
    let longest = width.max(height);
    let mut passes = Vec::new();
    if longest >= 512 {
        passes.push(Pass { divisor: 8, spp: 1 });
    } else if longest >= 128 {
        passes.push(Pass { divisor: 4, spp: 1 });
    }
    passes.push(Pass { divisor: 1, spp: 1 });
    let mut s = 4;
    while s < spp {
        passes.push(Pass { divisor: 1, spp: s });
        s = s.saturating_mul(4);
    }
    if spp > 1 {
        passes.push(Pass { divisor: 1, spp });
    }
    passes
}

/// Samples per pixel with anti-aliasing on: the scene's own count, or 4 when the scene
/// asks for 1 (the original's `a` key smoothed edges whatever the scene said).
pub fn aa_samples(scene_samples: u32) -> u32 {
    if scene_samples > 1 { scene_samples } else { 4 }
}

/// What a change asks of the viewer.
#[derive(Clone, Debug, PartialEq)]
pub enum Effect {
    /// Nothing the user can see changed.
    Nothing,
    /// Only the overlay changed: redraw it over the picture already there.
    Redraw,
    /// The picture is stale: cancel the render in progress and start over.
    Restart,
    /// Show a message for a moment.
    Notice(String),
    Screenshot,
    Quit,
}

/// The viewer's settings and camera: everything that decides what is rendered, plus the
/// overlay's toggles.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewState {
    pub aa: bool,
    /// Index into [`AccelKind::ALL`].
    pub accel: usize,
    pub show_time: bool,
    pub show_stats: bool,
    pub show_help: bool,
    pub orbit: Orbit,
    pub width: u32,
    pub height: u32,
    /// The scene's `settings.samples`.
    pub scene_samples: u32,
}

/// What one render job depends on: when it changes, the picture on screen is stale.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderKey {
    pub camera: Camera,
    pub accel: AccelKind,
    pub width: u32,
    pub height: u32,
    pub passes: Vec<Pass>,
}

impl ViewState {
    /// Anti-aliasing starts on, so that a view left alone ends up smooth.
    pub fn new(camera: Camera, scene_samples: u32, width: u32, height: u32) -> Self {
        ViewState {
            aa: true,
            accel: 0,
            show_time: true,
            show_stats: false,
            show_help: false,
            orbit: Orbit::new(camera),
            width: width.max(1),
            height: height.max(1),
            scene_samples,
        }
    }

    pub fn accel_kind(&self) -> AccelKind {
        AccelKind::ALL.get(self.accel).copied().unwrap_or_default()
    }

    pub fn target_spp(&self) -> u32 {
        if self.aa { aa_samples(self.scene_samples) } else { 1 }
    }

    pub fn render_key(&self) -> RenderKey {
        RenderKey {
            camera: self.orbit.camera(),
            accel: self.accel_kind(),
            width: self.width,
            height: self.height,
            passes: schedule(self.width, self.height, self.target_spp()),
        }
    }

    pub fn apply(&mut self, action: Action) -> Effect {
        let restart_if = |moved: bool| if moved { Effect::Restart } else { Effect::Nothing };
        match action {
            Action::ToggleAa => {
                self.aa = !self.aa;
                Effect::Restart
            }
            Action::CycleAccel => {
                if AccelKind::ALL.len() < 2 {
                    return Effect::Notice("BVH: not available in this build yet".to_owned());
                }
                self.accel = (self.accel + 1) % AccelKind::ALL.len();
                Effect::Restart
            }
            Action::ToggleTime => {
                self.show_time = !self.show_time;
                Effect::Redraw
            }
            Action::ToggleStats => {
                self.show_stats = !self.show_stats;
                Effect::Redraw
            }
            Action::ToggleHelp => {
                self.show_help = !self.show_help;
                Effect::Redraw
            }
            Action::Orbit { yaw, pitch } => restart_if(self.orbit.orbit(yaw, pitch)),
            Action::Dolly(f) => restart_if(self.orbit.dolly(f)),
            Action::ResetCamera => restart_if(self.orbit.reset()),
            Action::Screenshot => Effect::Screenshot,
            Action::Quit => Effect::Quit,
        }
    }

    /// The window was resized. A zero size (a minimised window) keeps the old one.
    pub fn resize(&mut self, width: u32, height: u32) -> Effect {
        if width == 0 || height == 0 || (width, height) == (self.width, self.height) {
            return Effect::Nothing;
        }
        self.width = width;
        self.height = height;
        Effect::Restart
    }

    /// A new version of the scene was loaded. The user's view survives an edit that
    /// leaves the file's camera alone; an edited camera is what the user wants to see.
    pub fn scene_changed(&mut self, camera: Camera, scene_samples: u32) {
        if camera != self.orbit.home() {
            self.orbit = Orbit::new(camera);
        }
        self.scene_samples = scene_samples;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera::new(Vec3::new(0.0, 2.0, 10.0), Vec3::new(0.0, 0.0, 0.0), Vec3::Y, 40.0, 320, 240)
    }

    fn state() -> ViewState {
        ViewState::new(camera(), 1, 320, 240)
    }

    #[test]
    fn every_key_maps_to_its_action() {
        let cases = [
            (Key::Char('a'), Some(Action::ToggleAa)),
            (Key::Char('b'), Some(Action::CycleAccel)),
            (Key::Char('t'), Some(Action::ToggleTime)),
            (Key::Char('d'), Some(Action::ToggleStats)),
            (Key::Char('h'), Some(Action::ToggleHelp)),
            (Key::Char('r'), Some(Action::ResetCamera)),
            (Key::Char('p'), Some(Action::Screenshot)),
            (Key::Char('+'), Some(Action::Dolly(DOLLY_STEP))),
            (Key::Char('='), Some(Action::Dolly(DOLLY_STEP))),
            (Key::Char('-'), Some(Action::Dolly(1.0 / DOLLY_STEP))),
            (Key::Escape, Some(Action::Quit)),
            (Key::Char('z'), None),
        ];
        for (key, action) in cases {
            assert_eq!(Action::from_key(key), action, "{key:?}");
        }
        for key in [Key::Left, Key::Right, Key::Up, Key::Down] {
            assert!(matches!(Action::from_key(key), Some(Action::Orbit { .. })), "{key:?}");
        }
    }

    #[test]
    fn aa_key_toggles_and_changes_the_samples() {
        let mut s = state();
        assert!(s.aa);
        assert_eq!(s.target_spp(), 4, "a scene of 1 spp gets 4 with AA on");
        assert_eq!(s.apply(Action::ToggleAa), Effect::Restart);
        assert_eq!(s.target_spp(), 1);
        assert_eq!(s.render_key().passes.last(), Some(&Pass { divisor: 1, spp: 1 }));
        s.apply(Action::ToggleAa);
        assert_eq!(s.target_spp(), 4);
        s.scene_samples = 9;
        assert_eq!(s.target_spp(), 9, "the scene's own count wins when it has one");
    }

    #[test]
    fn accel_key_cycles_through_what_the_build_has() {
        let mut s = state();
        let effect = s.apply(Action::CycleAccel);
        if AccelKind::ALL.len() == 1 {
            assert!(matches!(&effect, Effect::Notice(m) if m.contains("not available")), "{effect:?}");
            assert_eq!(s.accel_kind(), AccelKind::ALL[0]);
        } else {
            assert_eq!(effect, Effect::Restart);
            assert_eq!(s.accel_kind(), AccelKind::ALL[1]);
            for _ in 1..AccelKind::ALL.len() {
                s.apply(Action::CycleAccel);
            }
            assert_eq!(s.accel_kind(), AccelKind::ALL[0], "cycles back to the first");
        }
    }

    #[test]
    fn overlay_keys_only_redraw() {
        let mut s = state();
        let key = s.render_key();
        assert_eq!(s.apply(Action::ToggleTime), Effect::Redraw);
        assert!(!s.show_time);
        assert_eq!(s.apply(Action::ToggleStats), Effect::Redraw);
        assert!(s.show_stats);
        assert_eq!(s.apply(Action::ToggleHelp), Effect::Redraw);
        assert!(s.show_help);
        assert_eq!(s.render_key(), key, "the picture itself is not stale");
        assert_eq!(s.apply(Action::Screenshot), Effect::Screenshot);
        assert_eq!(s.apply(Action::Quit), Effect::Quit);
    }

    #[test]
    fn arrows_orbit_around_the_look_at_point_at_constant_distance() {
        let mut s = state();
        let home = s.orbit.camera();
        assert_eq!(home, camera(), "untouched, the camera is the scene's own");
        let d0 = (home.position - home.look_at).length();
        for key in [Key::Right, Key::Right, Key::Up, Key::Left, Key::Down, Key::Down] {
            assert_eq!(s.apply(Action::from_key(key).unwrap()), Effect::Restart, "{key:?}");
            let c = s.orbit.camera();
            assert_eq!(c.look_at, home.look_at);
            assert_eq!(c.up, home.up);
            assert!(((c.position - c.look_at).length() - d0).abs() < 1e-4 * d0);
            assert!(c.rig().is_ok());
        }
        // Right moves the camera to the right of where it looked from.
        let mut s = state();
        s.apply(Action::from_key(Key::Right).unwrap());
        assert!(s.orbit.camera().position.x > 0.0);
    }

    #[test]
    fn pitch_stops_short_of_the_poles() {
        let mut s = state();
        for _ in 0..100 {
            s.apply(Action::from_key(Key::Up).unwrap());
        }
        let c = s.orbit.camera();
        assert!(c.rig().is_ok(), "camera never looks straight along up");
        let elevation = (c.position - c.look_at).normalize().dot(Vec3::Y).asin();
        assert!((elevation - PITCH_LIMIT).abs() < 1e-4, "{elevation}");
        assert_eq!(s.apply(Action::from_key(Key::Up).unwrap()), Effect::Nothing, "already at the limit");
        for _ in 0..200 {
            s.apply(Action::drag(0.0, -50.0));
        }
        assert!(s.orbit.camera().rig().is_ok());
    }

    #[test]
    fn dolly_keeps_a_sane_distance() {
        let mut s = state();
        let d0 = s.orbit.distance();
        assert_eq!(s.apply(Action::from_key(Key::Char('+')).unwrap()), Effect::Restart);
        assert!((s.orbit.distance() - d0 * DOLLY_STEP).abs() < 1e-4);
        s.apply(Action::from_key(Key::Char('-')).unwrap());
        assert!((s.orbit.distance() - d0).abs() < 1e-4);
        for _ in 0..1000 {
            s.apply(Action::wheel(3.0));
        }
        let d = s.orbit.distance();
        assert!(d > 0.0 && d >= d0 / DOLLY_RANGE * 0.999, "{d}");
        assert!(s.orbit.camera().rig().is_ok(), "never onto the look-at point");
        for _ in 0..1000 {
            s.apply(Action::wheel(-3.0));
        }
        assert!(s.orbit.distance() <= d0 * DOLLY_RANGE * 1.001);
        for bad in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            assert_eq!(s.apply(Action::Dolly(bad)), Effect::Nothing, "{bad}");
        }
        assert_eq!(s.apply(Action::Orbit { yaw: f32::NAN, pitch: 0.0 }), Effect::Nothing);
        assert!(s.orbit.distance().is_finite());
    }

    #[test]
    fn reset_returns_to_the_scene_camera_exactly() {
        let mut s = state();
        assert_eq!(s.apply(Action::ResetCamera), Effect::Nothing, "nothing to reset");
        s.apply(Action::drag(37.0, -12.0));
        s.apply(Action::wheel(2.0));
        assert_ne!(s.orbit.camera(), camera());
        assert_eq!(s.apply(Action::ResetCamera), Effect::Restart);
        assert_eq!(s.orbit.camera(), camera());
    }

    #[test]
    fn drag_follows_the_pointer() {
        let mut s = state();
        s.apply(Action::drag(-100.0, 0.0)); // grab and pull left: camera goes right
        assert!(s.orbit.camera().position.x > 0.0);
        let mut s = state();
        s.apply(Action::drag(0.0, 100.0)); // pull down: camera rises
        assert!(s.orbit.camera().position.y > camera().position.y);
    }

    #[test]
    fn a_camera_looking_down_from_past_the_limit_still_orbits() {
        let steep = Camera::new(Vec3::new(0.0, 10.0, 0.01), Vec3::ZERO, Vec3::Y, 40.0, 64, 64);
        let mut o = Orbit::new(steep);
        assert_eq!(o.camera(), steep);
        assert!(o.orbit(0.3, 0.0));
        assert!(o.camera().rig().is_ok());
        assert!(!o.orbit(0.0, 0.1), "no further up");
        assert!(o.orbit(0.0, -0.1));
    }

    #[test]
    fn schedule_starts_coarse_and_ends_at_the_target() {
        assert_eq!(
            schedule(800, 800, 4),
            vec![Pass { divisor: 8, spp: 1 }, Pass { divisor: 1, spp: 1 }, Pass { divisor: 1, spp: 4 }]
        );
        assert_eq!(schedule(320, 240, 1), vec![Pass { divisor: 4, spp: 1 }, Pass { divisor: 1, spp: 1 }]);
        assert_eq!(schedule(64, 48, 1), vec![Pass { divisor: 1, spp: 1 }]);
        let spps: Vec<u32> = schedule(800, 600, 100).iter().map(|p| p.spp).collect();
        assert_eq!(spps, [1, 1, 4, 16, 64, 100]);
        let spps: Vec<u32> = schedule(800, 600, 16).iter().map(|p| p.spp).collect();
        assert_eq!(spps, [1, 1, 4, 16]);
        let spps: Vec<u32> = schedule(800, 600, 2).iter().map(|p| p.spp).collect();
        assert_eq!(spps, [1, 1, 2]);
        assert_eq!(Pass { divisor: 8, spp: 1 }.size(801, 3), (101, 1));
    }

    #[test]
    fn resize_restarts_at_the_new_size() {
        let mut s = state();
        assert_eq!(s.resize(320, 240), Effect::Nothing);
        assert_eq!(s.resize(0, 100), Effect::Nothing, "minimised");
        assert_eq!(s.resize(640, 200), Effect::Restart);
        let key = s.render_key();
        assert_eq!((key.width, key.height), (640, 200));
        assert_eq!(key.passes[0], Pass { divisor: 8, spp: 1 });
    }

    #[test]
    fn a_reloaded_scene_keeps_the_view_unless_its_camera_changed() {
        let mut s = state();
        s.apply(Action::drag(50.0, 0.0));
        let moved = s.orbit.camera();
        s.scene_changed(camera(), 16);
        assert_eq!(s.orbit.camera(), moved);
        assert_eq!(s.target_spp(), 16);
        let mut edited = camera();
        edited.fov = 60.0;
        s.scene_changed(edited, 1);
        assert_eq!(s.orbit.camera(), edited);
    }
}
