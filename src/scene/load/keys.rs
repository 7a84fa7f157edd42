//! Reading the `keys` arrays of the camera, the lights and the objects, and
//! `[settings] frames`, into an [`Animation`] (its evaluation lives there).
//!
//! ```toml
//! [settings]
//! frames = [0, 119]                 # the range `--frames` defaults to
//!
//! [camera]
//! position = [0, 0, 0]              # the value wherever no key says otherwise
//! look_at = [0, 0, -60]
//! fov = 40
//! interpolation = "smooth"          # or "linear" (the default)
//! keys = [
//!   { frame = 0, position = [0, 0, 0] },
//!   { frame = 60, position = [0, 10, -120], fov = 50 },
//! ]
//!
//! [[sphere]]
//! center = [0, 0, -60]
//! radius = 5
//! material = "red"
//! keys = [{ frame = 0, transform = { translate = [0, 0, 0] } },
//!         { frame = 119, transform = { translate = [0, 10, 0] } }]
//! ```
//!
//! Each field is its own track: a key sets only the fields it names, and a field no
//! key names keeps the table's value. Every frame a track passes through is checked
//! here (a camera looking at itself, a scale through zero), so rendering any frame
//! cannot fail.

use super::{CameraDesc, Ctx, R, S, Scale, SettingsDesc, TransformDesc, V3};
use crate::camera::{Camera, CameraError};
use crate::geometry::Shape;
use crate::light::Light;
use crate::math::Vec3;
use crate::scene::animation::{CameraKeys, Interpolation, LightKeys, MAX_FRAME, ObjectKeys, Part, Track};
use serde::Deserialize;

/// A key of the camera: any of its animated fields.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct CameraKey {
    frame: S<i64>,
    position: Option<S<V3>>,
    look_at: Option<S<V3>>,
    fov: Option<S<f32>>,
}

/// A key of a point or spot light.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct LightKey {
    frame: S<i64>,
    position: S<V3>,
}

/// A key of an object: its transform at that frame (the parts it names).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ObjectKey {
    frame: S<i64>,
    transform: S<TransformDesc>,
}

/// The `keys` and `interpolation` fields every animatable table has.
pub(super) type Keys<K> = Option<S<Vec<S<K>>>>;

/// Translate, rotate and scale as written (each `None` when not given).
pub(super) type Parts = [Option<Vec3>; 3];

impl Ctx<'_> {
    /// `[settings] frames = [first, last]`.
    pub(super) fn frame_range(&self, s: &SettingsDesc) -> R<Option<(u32, u32)>> {
        let Some(f) = &s.frames else { return Ok(None) };
        let [a, b] = *f.get_ref();
        if !(0..=MAX_FRAME as i64).contains(&a) || !(0..=MAX_FRAME as i64).contains(&b) || a > b {
            let message = format!("must be [first, last] with 0 <= first <= last <= {MAX_FRAME} (got [{a}, {b}])");
            return Err(self.err(f, "frames", message));
        }
        Ok(Some((a as u32, b as u32)))
    }

    pub(super) fn interpolation(&self, v: &Option<S<String>>) -> R<Interpolation> {
        match v.as_ref().map(|s| (s, s.get_ref().as_str())) {
            None | Some((_, "linear")) => Ok(Interpolation::Linear),
            Some((_, "smooth")) => Ok(Interpolation::Smooth),
            Some((s, other)) => {
                Err(self.err(s, "interpolation", format!("expected \"linear\" or \"smooth\", got {other:?}")))
            }
        }
    }

    /// The frames of `keys`, each checked: a whole number in range, later than the key
    /// before it.
    fn frames<K>(&self, keys: &[S<K>], frame: impl Fn(&K) -> &S<i64>, range: Option<(u32, u32)>) -> R<Vec<u32>> {
        let mut out: Vec<u32> = Vec::with_capacity(keys.len());
        for (i, k) in keys.iter().enumerate() {
            let f = frame(k.get_ref());
            let n = *f.get_ref();
            if !(0..=MAX_FRAME as i64).contains(&n) {
                return Err(self.err(f, "frame", format!("must be between 0 and {MAX_FRAME} (got {n})")));
            }
            if let Some((a, b)) = range
                && !(a as i64..=b as i64).contains(&n)
            {
                return Err(self.err(f, "frame", format!("{n} is outside [settings] frames = [{a}, {b}]")));
            }
            if let Some(&prev) = out.last()
                && n <= prev as i64
            {
                let message =
                    format!("keys must go forward in time: key {} is at frame {n}, after frame {prev}", i + 1);
                return Err(self.err(f, "frame", message));
            }
            out.push(n as u32);
        }
        Ok(out)
    }

    /// The track of the keys that set a field (`None` when none do).
    fn track(&self, frames: &[u32], values: Vec<Option<Vec3>>, i: Interpolation) -> Option<Track> {
        Track::new(frames.iter().zip(values).filter_map(|(&f, v)| Some((f, v?))).collect(), i)
    }

    /// The key at or after `frame` (the last one if none), to point at when a frame
    /// between keys goes wrong.
    fn key_near<'k, K>(keys: &'k [S<K>], frames: &[u32], frame: u32) -> &'k S<K> {
        let i = frames.partition_point(|&f| f < frame).min(keys.len() - 1);
        &keys[i]
    }

    pub(super) fn camera_keys(&self, d: &CameraDesc, camera: &Camera, range: Option<(u32, u32)>) -> R<CameraKeys> {
        let Some(keys) = d.keys.as_ref().map(|k| k.get_ref()).filter(|k| !k.is_empty()) else {
            return Ok(CameraKeys::default());
        };
        let i = self.interpolation(&d.interpolation)?;
        let frames = self.frames(keys, |k| &k.frame, range)?;
        let mut values = [vec![], vec![], vec![]];
        for k in keys {
            let k = k.get_ref();
            if k.position.is_none() && k.look_at.is_none() && k.fov.is_none() {
                return Err(self.err(&k.frame, "frame", "the key sets nothing (give position, look_at or fov)"));
            }
            values[0].push(k.position.as_ref().map(|v| self.vec3(v, "position")).transpose()?);
            values[1].push(k.look_at.as_ref().map(|v| self.vec3(v, "look_at")).transpose()?);
            values[2].push(k.fov.as_ref().map(|v| self.finite(v, "fov").map(|x| Vec3::new(x, 0.0, 0.0))).transpose()?);
        }
        let [p, l, f] = values;
        let out = CameraKeys {
            position: self.track(&frames, p, i),
            look_at: self.track(&frames, l, i),
            fov: self.track(&frames, f, i),
        };
        // Every frame the keys span must give a camera that can make rays.
        let anim = crate::scene::Animation { camera: out.clone(), ..Default::default() };
        let (first, last) = (frames[0], frames[frames.len() - 1]);
        for frame in first..=last {
            if let Err(e) = anim.camera_at(camera, frame).rig() {
                let field = match e {
                    CameraError::ZeroDirection => "look_at",
                    CameraError::BadUp => "position",
                    CameraError::BadFov => "fov",
                };
                let key = Self::key_near(keys, &frames, frame);
                return Err(self.err(key, field, format!("at frame {frame}: {e}")));
            }
        }
        Ok(out)
    }

    pub(super) fn light_keys(
        &self,
        index: usize,
        keys: &Keys<LightKey>,
        interpolation: &Option<S<String>>,
        light: &Light,
        range: Option<(u32, u32)>,
    ) -> R<Option<LightKeys>> {
        let Some(list) = keys else { return Ok(None) };
        if matches!(light, Light::Directional(_)) {
            return Err(self.err(list, "keys", "a directional light has no position to animate"));
        }
        let list = list.get_ref();
        let i = self.interpolation(interpolation)?;
        let frames = self.frames(list, |k| &k.frame, range)?;
        let values = list.iter().map(|k| self.vec3(&k.get_ref().position, "position").map(Some)).collect::<R<_>>()?;
        Ok(self.track(&frames, values, i).map(|position| LightKeys { index, position }))
    }

    /// Translate, rotate and scale as written, checked.
    pub(super) fn transform_parts(&self, t: &TransformDesc) -> R<Parts> {
        let translate = t.translate.as_ref().map(|v| self.vec3(v, "translate")).transpose()?;
        let rotate = t.rotate.as_ref().map(|v| self.vec3(v, "rotate")).transpose()?;
        let scale = match &t.scale {
            None => None,
            Some(s) => {
                let v = match s.get_ref() {
                    Scale::Uniform(k) => Vec3::splat(*k),
                    Scale::Axes(a) => Vec3::from_array(*a),
                };
                if !v.is_finite() || v.cmpeq(Vec3::ZERO).any() {
                    return Err(self.err(s, "scale", format!("must be finite and non-zero (got {v})")));
                }
                Some(v)
            }
        };
        Ok([translate, rotate, scale])
    }

    /// The keys of the object about to be added at `index`, whose shape before any
    /// transform is `base`.
    pub(super) fn object_keys(
        &self,
        index: usize,
        base: &Shape,
        transform: &Option<S<TransformDesc>>,
        keys: &Keys<ObjectKey>,
        interpolation: &Option<S<String>>,
        range: Option<(u32, u32)>,
    ) -> R<Option<ObjectKeys>> {
        let Some(list) = keys else { return Ok(None) };
        let list = list.get_ref();
        let i = self.interpolation(interpolation)?;
        let frames = self.frames(list, |k| &k.frame, range)?;
        let own = match transform {
            Some(t) => self.transform_parts(t.get_ref())?,
            None => [None; 3],
        };
        let mut values = [vec![], vec![], vec![]];
        for k in list {
            let parts = self.transform_parts(k.get_ref().transform.get_ref())?;
            for (v, p) in values.iter_mut().zip(parts) {
                v.push(p);
            }
        }
        let [t, r, s] = values;
        let [own_t, own_r, own_s] = own;
        let part = |v: Vec<Option<Vec3>>, own: Option<Vec3>, default: Vec3| {
            self.track(&frames, v, i).map_or(Part::Fixed(own.unwrap_or(default)), Part::Keyed)
        };
        let (translate, rotate, scale) =
            (part(t, own_t, Vec3::ZERO), part(r, own_r, Vec3::ZERO), part(s, own_s, Vec3::ONE));
        let keys = ObjectKeys { index, base: base.clone(), translate, rotate, scale };
        // Every frame between the keys must leave the shape a shape: no scale through
        // zero; a polygon (the one shape a transform can flatten) is rebuilt each frame.
        let Some((first, last)) = keys.span() else { return Ok(None) };
        let polygon = matches!(base, Shape::Polygon(_));
        for frame in first..=last {
            let s = keys.scale.at(frame);
            let bad = if !s.is_finite() || s.cmpeq(Vec3::ZERO).any() {
                Some(format!("at frame {frame} the scale is {s}: it flattens the shape"))
            } else if polygon {
                keys.shape_at(frame).err()
            } else {
                None
            };
            if let Some(message) = bad {
                let key = Self::key_near(list, &frames, frame);
                return Err(self.err(&key.get_ref().transform, "transform", message));
            }
        }
        Ok(Some(keys))
    }
}
