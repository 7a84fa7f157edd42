//! `[[light]]` tables ([`crate::light`]): `kind` (`"point"`, the default,
//! `"directional"` or `"spot"`) says which fields belong; a field of another kind is an
//! error rather than silently ignored.

use super::{Ctx, R, S, V3};
use crate::light::{Attenuation, DirectionalLight, Light, PointLight, SpotLight};
use crate::math::Color;
use serde::Deserialize;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct LightDesc {
    kind: Option<S<String>>,
    position: Option<S<V3>>,
    /// The way the light travels (directional) or the cone's axis points (spot).
    direction: Option<S<V3>>,
    /// Spot half-angles from the axis, in degrees.
    inner_angle: Option<S<f32>>,
    outer_angle: Option<S<f32>>,
    color: Option<S<V3>>,
    intensity: Option<S<f32>>,
    /// `[constant, linear, quadratic]`.
    attenuation: Option<S<V3>>,
    /// Keyframes of `position` (point and spot lights).
    pub(super) keys: super::Keys<super::LightKey>,
    pub(super) interpolation: Option<S<String>>,
}

#[derive(Clone, Copy, PartialEq)]
enum Kind {
    Point,
    Directional,
    Spot,
}

impl Ctx<'_> {
    pub(super) fn light(&self, desc: &S<LightDesc>) -> R<Light> {
        let l = desc.get_ref();
        let kind = match &l.kind {
            None => Kind::Point,
            Some(k) => match k.get_ref().as_str() {
                "point" => Kind::Point,
                "directional" => Kind::Directional,
                "spot" => Kind::Spot,
                other => {
                    return Err(self.err(
                        k,
                        "kind",
                        format!("unknown light kind {other:?} (point, directional, spot)"),
                    ));
                }
            },
        };
        let name = match kind {
            Kind::Point => "a point light",
            Kind::Directional => "a directional light",
            Kind::Spot => "a spot light",
        };
        // Fields that do not belong to the kind.
        let misplaced = |field: &str, at: Option<usize>, why: &str| -> R<()> {
            match at {
                Some(at) => Err(self.error_at(at, field, format!("{name} has no `{field}` ({why})"))),
                None => Ok(()),
            }
        };
        fn start<T>(v: &Option<S<T>>) -> Option<usize> {
            v.as_ref().map(|v| v.span().start)
        }
        if kind != Kind::Spot {
            let why = if kind == Kind::Point { "set kind = \"spot\" for a cone" } else { "it lights everything alike" };
            misplaced("inner_angle", start(&l.inner_angle), why)?;
            misplaced("outer_angle", start(&l.outer_angle), why)?;
        }
        if kind == Kind::Point {
            let why = "it shines every way: set kind = \"spot\" or \"directional\"";
            misplaced("direction", start(&l.direction), why)?;
        }
        if kind == Kind::Directional {
            let why = "it is infinitely far away";
            misplaced("position", start(&l.position), why)?;
            misplaced("attenuation", start(&l.attenuation), why)?;
        }
        let need = |v: &Option<S<V3>>, field: &str| -> R<()> {
            match v {
                Some(_) => Ok(()),
                None => Err(self.err(desc, field, format!("{name} needs a `{field}`"))),
            }
        };

        let color = l.color.as_ref().map_or(Ok(Color::ONE), |c| self.color(c, "color"))?;
        let intensity = l.intensity.as_ref().map_or(Ok(1.0), |i| self.non_negative(i, "intensity"))?;
        let color = color * intensity;
        let attenuation = l.attenuation.as_ref().map_or(Ok(Attenuation::NONE), |a| self.attenuation(a))?;
        Ok(match kind {
            Kind::Point => {
                need(&l.position, "position")?;
                let position = self.vec3(l.position.as_ref().expect("checked"), "position")?;
                PointLight::new(position, color).with_attenuation(attenuation).into()
            }
            Kind::Directional => {
                need(&l.direction, "direction")?;
                let direction = self.direction(l.direction.as_ref().expect("checked"), "direction")?;
                DirectionalLight::new(direction, color).into()
            }
            Kind::Spot => {
                need(&l.position, "position")?;
                need(&l.direction, "direction")?;
                let position = self.vec3(l.position.as_ref().expect("checked"), "position")?;
                let direction = self.direction(l.direction.as_ref().expect("checked"), "direction")?;
                let angle = |v: &Option<S<f32>>, field: &str| -> R<(f32, usize)> {
                    let Some(v) = v else {
                        return Err(self.err(desc, field, format!("{name} needs an `{field}` (degrees)")));
                    };
                    let a = self.finite(v, field)?;
                    if a > 0.0 && a < 90.0 {
                        Ok((a, v.span().start))
                    } else {
                        Err(self.err(v, field, format!("must be between 0 and 90 degrees, both excluded (got {a})")))
                    }
                };
                let (inner, at) = angle(&l.inner_angle, "inner_angle")?;
                let (outer, _) = angle(&l.outer_angle, "outer_angle")?;
                if inner > outer {
                    let message = format!("must be at most outer_angle (got {inner} > {outer})");
                    return Err(self.error_at(at, "inner_angle", message));
                }
                SpotLight::new(position, direction, inner, outer, color).with_attenuation(attenuation).into()
            }
        })
    }

    /// `[constant, linear, quadratic]`: finite, non-negative, not all zero.
    fn attenuation(&self, v: &S<V3>) -> R<Attenuation> {
        let [c, l, q] = *v.get_ref();
        if ![c, l, q].iter().all(|x| x.is_finite() && *x >= 0.0) {
            return Err(self.err(v, "attenuation", format!("must be three finite numbers >= 0 (got [{c}, {l}, {q}])")));
        }
        if c == 0.0 && l == 0.0 && q == 0.0 {
            return Err(self.err(v, "attenuation", "must not be all zero (1 / 0 light); [1, 0, 0] is none"));
        }
        Ok(Attenuation::new(c, l, q))
    }
}

#[cfg(test)]
mod tests {
    use super::super::load_str;
    use crate::light::Light;
    use crate::math::{Color, Vec3};
    use crate::scene::{Scene, SceneError};
    use std::path::Path;

    const CAMERA: &str = "[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, -1]\nfov = 40\n";

    fn load(body: &str) -> Result<Scene, SceneError> {
        load_str(&format!("{CAMERA}{body}"), "t.toml", Path::new("."))
    }

    /// The line (counted in the whole file, camera included) and field of an error.
    fn fault(body: &str) -> (usize, String, String) {
        match load(body).unwrap_err() {
            SceneError::At { line, field, message, .. } => (line, field, message),
            e => panic!("{e}"),
        }
    }

    #[test]
    fn each_kind_loads_with_its_fields() {
        let s = load(
            "[[light]]\nposition = [1, 2, 3]\n\n\
             [[light]]\nkind = \"point\"\nposition = [1, 2, 3]\ncolor = [1, 0.5, 0]\nintensity = 2\nattenuation = [1, 0.5, 0.25]\n\n\
             [[light]]\nkind = \"directional\"\ndirection = [0, -2, 0]\ncolor = [0.5, 0.5, 0.5]\n\n\
             [[light]]\nkind = \"spot\"\nposition = [0, 5, 0]\ndirection = [0, -1, 0]\ninner_angle = 15\nouter_angle = 25\nattenuation = [0, 0, 1]\n",
        )
        .unwrap();
        assert_eq!(s.lights.len(), 4);
        let Light::Point(p) = s.lights[0] else { panic!("{:?}", s.lights[0]) };
        assert!(p.attenuation.is_none());
        let Light::Point(p) = s.lights[1] else { panic!("{:?}", s.lights[1]) };
        assert_eq!(p.color, Color::new(2.0, 1.0, 0.0));
        assert_eq!((p.attenuation.constant, p.attenuation.linear, p.attenuation.quadratic), (1.0, 0.5, 0.25));
        let Light::Directional(d) = s.lights[2] else { panic!("{:?}", s.lights[2]) };
        assert_eq!(d.direction, Vec3::NEG_Y);
        let Light::Spot(sp) = s.lights[3] else { panic!("{:?}", s.lights[3]) };
        assert_eq!((sp.inner_angle, sp.outer_angle), (15.0, 25.0));
        assert_eq!(sp.cos_inner, 15f32.to_radians().cos());
        assert_eq!(sp.attenuation.quadratic, 1.0);
    }

    /// The example scenes load, hold what their comments say, render (every light kind
    /// through today's core, shadows of a directional light to infinity), and write
    /// back to TOML that reads as the same scene.
    #[test]
    fn example_scenes_load_render_and_write_back() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
        for name in ["scenes/lights.toml", "scenes/fresnel.toml"] {
            let scene = crate::scene::load_file(&dir.join(name)).unwrap_or_else(|e| panic!("{e}"));
            let mut text = Vec::new();
            crate::scene::save::write_toml(&scene, name, &mut text).unwrap();
            let back = load_str(std::str::from_utf8(&text).unwrap(), name, dir).unwrap();
            assert_eq!(back.lights, scene.lights, "{name}");
            assert_eq!(format!("{:?}", back.materials), format!("{:?}", scene.materials), "{name}");
            let image = crate::render::Renderer::new(&scene).unwrap().size(64, 48).render();
            let mut lit = 0;
            for y in 0..48 {
                for x in 0..64 {
                    let c = image.pixel(x, y);
                    assert!(c.is_finite() && c.min_element() >= 0.0, "{name} ({x}, {y}): {c}");
                    lit += (c.max_element() > 0.1) as u32;
                }
            }
            assert!(lit > 64 * 48 / 2, "{name}: only {lit} pixels lit");
        }
        let lights = crate::scene::load_file(&dir.join("scenes/lights.toml")).unwrap();
        let kinds: Vec<_> = lights.lights.iter().map(std::mem::discriminant).collect();
        assert_eq!(kinds.len(), 3);
        assert!(kinds[0] != kinds[1] && kinds[1] != kinds[2] && kinds[0] != kinds[2]);
        let spot = lights.lights.iter().find(|l| matches!(l, Light::Spot(_))).unwrap();
        // Its cone meets the floor (y = 0) at 6·tan 20° from the point below it.
        let below = spot.position().unwrap() * Vec3::new(1.0, 0.0, 1.0);
        let on_floor = |r: f32| {
            let (l, d) = spot.toward(below + Vec3::new(r, 0.0, 0.0));
            spot.falloff(l, d)
        };
        let edge = 6.0 * 20f32.to_radians().tan();
        assert_eq!(on_floor(0.0), 1.0);
        assert!(on_floor(edge * 0.99) > 0.0 && on_floor(edge * 1.01) == 0.0);
        let glass = crate::scene::load_file(&dir.join("scenes/fresnel.toml")).unwrap();
        assert!(glass.materials.iter().any(|m| m.fresnel && m.absorbs() && m.transparency > 0.0));
    }

    #[test]
    fn bad_lights_are_located() {
        // The camera takes lines 1-4; `[[light]]` is line 5.
        let f = |body: &str| {
            let (line, field, _) = fault(body);
            (line, field)
        };
        assert_eq!(f("[[light]]\nkind = \"laser\"\nposition = [0, 0, 0]\n"), (6, "kind".into()));
        assert_eq!(f("[[light]]\nposition = [0, 0, 0]\ndirection = [0, -1, 0]\n"), (7, "direction".into()));
        assert_eq!(f("[[light]]\nposition = [0, 0, 0]\nouter_angle = 20\n"), (7, "outer_angle".into()));
        assert_eq!(
            f("[[light]]\nkind = \"directional\"\nposition = [0, 0, 0]\ndirection = [0, -1, 0]\n"),
            (7, "position".into())
        );
        assert_eq!(
            f("[[light]]\nkind = \"directional\"\ndirection = [0, -1, 0]\nattenuation = [1, 0, 0]\n"),
            (8, "attenuation".into())
        );
        assert_eq!(f("[[light]]\nkind = \"directional\"\ndirection = [0, 0, 0]\n"), (7, "direction".into()));
        assert_eq!(f("[[light]]\nkind = \"directional\"\ncolor = [1, 1, 1]\n").1, "direction");
        assert_eq!(f("[[light]]\ncolor = [1, 1, 1]\n").1, "position");
        let spot = "[[light]]\nkind = \"spot\"\nposition = [0, 5, 0]\ndirection = [0, -1, 0]\n";
        assert_eq!(f(&format!("{spot}inner_angle = 10\n")).1, "outer_angle");
        assert_eq!(f(&format!("{spot}outer_angle = 10\n")).1, "inner_angle");
        assert_eq!(f(&format!("{spot}inner_angle = 0\nouter_angle = 10\n")), (9, "inner_angle".into()));
        assert_eq!(f(&format!("{spot}inner_angle = 10\nouter_angle = 90\n")), (10, "outer_angle".into()));
        assert_eq!(f(&format!("{spot}inner_angle = 30\nouter_angle = 20\n")), (9, "inner_angle".into()));
        assert_eq!(f(&format!("{spot}inner_angle = nan\nouter_angle = 20\n")), (9, "inner_angle".into()));
        let ok = format!("{spot}inner_angle = 20\nouter_angle = 20\n");
        assert!(load(&ok).is_ok());
        assert_eq!(f(&format!("{ok}attenuation = [0, 0, 0]\n")), (11, "attenuation".into()));
        assert_eq!(f(&format!("{ok}attenuation = [1, -1, 0]\n")), (11, "attenuation".into()));
        assert_eq!(f(&format!("{ok}attenuation = [1, 0]\n")).1, "attenuation");
        let (_, _, message) = fault(&format!("{ok}attenuation = [0, 0, 0]\n"));
        assert!(message.contains("all zero"), "{message}");
    }
}
