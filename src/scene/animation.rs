//! Keyframed values of a scene file and the scene they give at each frame.
//!
//! The TOML reader ([`super::load_animated_file`]) turns the `keys` arrays of the
//! camera, the lights and the objects into an [`Animation`]: one [`Track`] per animated
//! field. [`Animation::scene_at`] writes a frame's values into a plain [`Scene`], so the
//! render core knows nothing of animation. A field no key sets keeps the value its
//! table gives; before a track's first key and after its last the value holds.

use super::{Scene, SceneError};
use crate::camera::Camera;
use crate::geometry::{self, Shape};
use crate::light::Light;
use crate::math::Vec3;

/// Frame numbers run from 0 to this: a million frames is over nine hours at 30 fps.
pub const MAX_FRAME: u32 = 1_000_000;

/// How a track goes from one key to the next.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Interpolation {
    /// Straight from key to key (`interpolation = "linear"`, the default).
    #[default]
    Linear,
    /// A Catmull–Rom curve through the keys (`"smooth"`): no corner at a key.
    Smooth,
}

/// The keys of one field, frames strictly increasing (the reader checks; scalar fields
/// use `x`).
#[derive(Clone, Debug, PartialEq)]
pub struct Track {
    keys: Vec<(u32, Vec3)>,
    interpolation: Interpolation,
}

impl Track {
    /// `None` unless `keys` is non-empty with frames strictly increasing.
    pub fn new(keys: Vec<(u32, Vec3)>, interpolation: Interpolation) -> Option<Track> {
        let increasing = keys.windows(2).all(|w| w[0].0 < w[1].0);
        (!keys.is_empty() && increasing).then_some(Track { keys, interpolation })
    }

    /// The frames of the first and last keys.
    pub fn span(&self) -> (u32, u32) {
        (self.keys[0].0, self.keys[self.keys.len() - 1].0)
    }

    /// The value at `frame`. A key's own frame gives its value exactly, so that a frame
    /// on a key renders as the scene with that value written in.
    pub fn at(&self, frame: u32) -> Vec3 {
        let k = &self.keys;
        let i = k.partition_point(|&(f, _)| f <= frame);
        if i == 0 {
            return k[0].1;
        }
        if i == k.len() || k[i - 1].0 == frame {
            return k[i - 1].1;
        }
        let ((t0, p0), (t1, p1)) = (k[i - 1], k[i]);
        let dt = (t1 - t0) as f64;
        let s = (frame - t0) as f64 / dt;
        let (p0d, p1d) = (p0.as_dvec3(), p1.as_dvec3());
        match self.interpolation {
            Interpolation::Linear => (p0d + (p1d - p0d) * s).as_vec3(),
            Interpolation::Smooth => {
                // Hermite form with Catmull–Rom tangents measured per frame, so keys
                // need not be evenly spaced; at the end keys the tangent is the slope
                // of the one segment there (clamped: no phantom key beyond the ends).
                let slope = |a: usize, b: usize| (k[b].1.as_dvec3() - k[a].1.as_dvec3()) / (k[b].0 - k[a].0) as f64;
                let m0 = slope(i.saturating_sub(2), i);
                let m1 = slope(i - 1, (i + 1).min(k.len() - 1));
                let (s2, s3) = (s * s, s * s * s);
                let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
                let h10 = s3 - 2.0 * s2 + s;
                let h01 = -2.0 * s3 + 3.0 * s2;
                let h11 = s3 - s2;
                (p0d * h00 + m0 * (h10 * dt) + p1d * h01 + m1 * (h11 * dt)).as_vec3()
            }
        }
    }
}

/// The animated fields of the camera.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CameraKeys {
    pub position: Option<Track>,
    pub look_at: Option<Track>,
    /// Degrees, in `x`.
    pub fov: Option<Track>,
}

/// The animated position of the light at `index` in [`Scene::lights`].
#[derive(Clone, Debug, PartialEq)]
pub struct LightKeys {
    pub index: usize,
    pub position: Track,
}

/// An object whose transform is keyed: its shape before any transform, and the parts
/// of the transform (each a track, or the table's own value).
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectKeys {
    /// In [`Scene::objects`].
    pub index: usize,
    pub base: Shape,
    pub translate: Part,
    /// Degrees about x, y and z.
    pub rotate: Part,
    pub scale: Part,
}

/// One part of a transform: fixed, or keyed.
#[derive(Clone, Debug, PartialEq)]
pub enum Part {
    Fixed(Vec3),
    Keyed(Track),
}

impl Part {
    pub fn at(&self, frame: u32) -> Vec3 {
        match self {
            Part::Fixed(v) => *v,
            Part::Keyed(t) => t.at(frame),
        }
    }

    fn span(&self) -> Option<(u32, u32)> {
        match self {
            Part::Fixed(_) => None,
            Part::Keyed(t) => Some(t.span()),
        }
    }
}

impl ObjectKeys {
    /// `(translate, rotate, scale)` at `frame`.
    pub fn transform_at(&self, frame: u32) -> [Vec3; 3] {
        [self.translate.at(frame), self.rotate.at(frame), self.scale.at(frame)]
    }

    /// The frames between its first and last key, the only ones whose transform can
    /// differ from its neighbour's.
    pub fn span(&self) -> Option<(u32, u32)> {
        [&self.translate, &self.rotate, &self.scale]
            .iter()
            .filter_map(|p| p.span())
            .reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)))
    }

    /// The object's shape at `frame`; fails only where the transform degenerates it.
    pub fn shape_at(&self, frame: u32) -> Result<Shape, String> {
        let [t, r, s] = self.transform_at(frame);
        if !s.is_finite() || s.cmpeq(Vec3::ZERO).any() {
            return Err(format!("the scale at frame {frame} is {s}: it flattens the shape"));
        }
        geometry::transform(self.base.clone(), &geometry::affine(t, r, s))
            .map_err(|e| format!("the transform at frame {frame} makes the polygon degenerate: {e}"))
    }
}

/// Everything that moves in a scene file, and the frames it is meant to be seen over.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Animation {
    /// The scene file, for messages.
    pub file: String,
    /// The file's `[settings] frames`, else 0 to the last key.
    pub first: u32,
    pub last: u32,
    pub camera: CameraKeys,
    pub lights: Vec<LightKeys>,
    pub objects: Vec<ObjectKeys>,
}

impl Animation {
    /// Whether nothing is keyed: every frame is the same scene.
    pub fn is_static(&self) -> bool {
        let c = &self.camera;
        c.position.is_none()
            && c.look_at.is_none()
            && c.fov.is_none()
            && self.lights.is_empty()
            && self.objects.is_empty()
    }

    /// `camera` with the keyed fields at `frame` written in.
    pub fn camera_at(&self, camera: &Camera, frame: u32) -> Camera {
        let mut c = *camera;
        if let Some(t) = &self.camera.position {
            c.position = t.at(frame);
        }
        if let Some(t) = &self.camera.look_at {
            c.look_at = t.at(frame);
        }
        if let Some(t) = &self.camera.fov {
            c.fov = t.at(frame).x;
        }
        c
    }

    /// The scene at `frame`: `scene` (the one the reader gave with this animation) with
    /// every keyed value of that frame written in. Frames outside [`Self::first`]..=
    /// [`Self::last`] are allowed: values hold beyond their keys.
    pub fn scene_at(&self, scene: &Scene, frame: u32) -> Result<Scene, SceneError> {
        let mut out = scene.clone();
        out.camera = self.camera_at(&scene.camera, frame);
        for l in &self.lights {
            match out.lights.get_mut(l.index) {
                Some(Light::Point(p)) => p.position = l.position.at(frame),
                Some(Light::Spot(s)) => s.position = l.position.at(frame),
                _ => {}
            }
        }
        for o in &self.objects {
            let shape = o.shape_at(frame).map_err(|message| SceneError::File {
                file: self.file.clone(),
                message: format!("{}: {message}", scene.object_label(o.index)),
            })?;
            if let Some(slot) = out.objects.get_mut(o.index) {
                slot.shape = shape;
            }
        }
        Ok(out)
    }

    /// Whether any object stands differently at frames `a` and `b`: only then must the
    /// acceleration structure be rebuilt between them.
    pub fn moves_geometry(&self, a: u32, b: u32) -> bool {
        self.objects.iter().any(|o| o.transform_at(a) != o.transform_at(b))
    }

    /// Whether any light stands differently at frames `a` and `b`. The acceleration
    /// structure reads the lights through the scene it was built over, so a frame whose
    /// lights moved gets a new one too (for a scene of a few objects, well under a
    /// millisecond); a frame where only the camera moved reuses it.
    pub fn moves_lights(&self, a: u32, b: u32) -> bool {
        self.lights.iter().any(|l| l.position.at(a) != l.position.at(b))
    }

    /// Whether frames `a` and `b` need separate acceleration structures.
    pub fn needs_new_world(&self, a: u32, b: u32) -> bool {
        self.moves_geometry(a, b) || self.moves_lights(a, b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn track(keys: &[(u32, f32)], i: Interpolation) -> Track {
        Track::new(keys.iter().map(|&(f, x)| (f, Vec3::new(x, 2.0 * x, -x))).collect(), i).unwrap()
    }

    #[test]
    fn tracks_need_keys_in_order() {
        assert!(Track::new(vec![], Interpolation::Linear).is_none());
        assert!(Track::new(vec![(3, Vec3::ZERO), (3, Vec3::ONE)], Interpolation::Linear).is_none());
        assert!(Track::new(vec![(4, Vec3::ZERO), (3, Vec3::ONE)], Interpolation::Smooth).is_none());
    }

    #[test]
    fn linear_goes_straight_and_holds_beyond_the_keys() {
        let t = track(&[(10, 0.0), (20, 4.0), (40, 0.0)], Interpolation::Linear);
        assert_eq!(t.at(15), Vec3::new(2.0, 4.0, -2.0), "midpoint");
        assert_eq!(t.at(30).x, 2.0);
        assert_eq!(t.at(0).x, 0.0);
        assert_eq!(t.at(10).x, 0.0);
        assert_eq!(t.at(20).x, 4.0);
        assert_eq!(t.at(40).x, 0.0);
        assert_eq!(t.at(1000).x, 0.0);
        assert_eq!(t.span(), (10, 40));
    }

    #[test]
    fn smooth_passes_through_its_keys_and_is_exact_on_a_line() {
        let keys = [(0, 1.5), (7, -3.25), (9, 8.0), (30, 0.1), (31, 2.0)];
        let t = track(&keys, Interpolation::Smooth);
        for (f, x) in keys {
            assert_eq!(t.at(f), Vec3::new(x, 2.0 * x, -x), "key at {f}");
        }
        // Between keys it is not the straight line: it bends towards the neighbours.
        let lin = track(&keys, Interpolation::Linear);
        assert_ne!(t.at(8), lin.at(8));
        // Evenly spaced keys on a line: the curve is the line itself, ends included.
        let even = track(&[(0, 0.0), (10, 5.0), (20, 10.0), (30, 15.0)], Interpolation::Smooth);
        for f in 0..=30 {
            let x = f as f32 * 0.5;
            let v = even.at(f);
            assert!((v - Vec3::new(x, 2.0 * x, -x)).abs().max_element() < 1e-5, "frame {f}: {v}");
        }
        // Two keys: no neighbours, so the curve is the straight line.
        let two = track(&[(0, 0.0), (4, 8.0)], Interpolation::Smooth);
        assert!((two.at(1).x - 2.0).abs() < 1e-6 && (two.at(3).x - 6.0).abs() < 1e-6);
    }

    #[test]
    fn smooth_turns_at_a_key_where_linear_has_a_corner() {
        let keys = [(0, 0.0), (10, 10.0), (20, 0.0), (30, 5.0)];
        // The change of slope over the frames either side of the key at 20.
        let kink = |t: &Track| (t.at(21).x - t.at(20).x) - (t.at(20).x - t.at(19).x);
        let (smooth, linear) = (kink(&track(&keys, Interpolation::Smooth)), kink(&track(&keys, Interpolation::Linear)));
        assert_eq!(linear, 1.5);
        assert!(smooth.abs() < linear / 3.0, "{smooth}");
    }
}
