//! Lights: point, directional and spot, each with its colour, and for those with a
//! position an optional falloff with distance.
//!
//! ```toml
//! [[light]]                 # kind = "point" is the default
//! position = [10, 30, -3]
//! color = [1, 1, 1]
//! intensity = 1.0
//! attenuation = [1, 0, 0.01]  # optional: 1 / (c + l*d + q*d²); default none
//!
//! [[light]]
//! kind = "directional"
//! direction = [0, -1, -0.3] # the way the light travels (need not be unit)
//!
//! [[light]]
//! kind = "spot"
//! position = [0, 5, 0]
//! direction = [0, -1, 0]    # the way the cone's axis points
//! inner_angle = 15          # degrees from the axis: full light inside
//! outer_angle = 25          # no light outside; a smooth falloff between
//! ```
//!
//! Shading asks a light only four things: [`Light::toward`] (where it is, seen from a
//! point), [`Light::falloff`] (how much of it arrives there, shadows aside),
//! [`Light::color`] and [`Light::position`] (for the culling that needs one point).

use crate::math::{Color, Vec3};

/// Falloff with distance `d`: `1 / (constant + linear·d + quadratic·d²)`. The default,
/// [`Attenuation::NONE`] (`[1, 0, 0]`), is no falloff at all, like the original and
/// POV-Ray's default.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Attenuation {
    pub constant: f32,
    pub linear: f32,
    pub quadratic: f32,
}

impl Attenuation {
    /// No falloff: [`Attenuation::factor`] is exactly 1.
    pub const NONE: Attenuation = Attenuation { constant: 1.0, linear: 0.0, quadratic: 0.0 };

    pub fn new(constant: f32, linear: f32, quadratic: f32) -> Self {
        Attenuation { constant, linear, quadratic }
    }

    pub fn is_none(&self) -> bool {
        *self == Self::NONE
    }

    /// The share of the light left at distance `d`. Exactly 1.0 for [`Attenuation::NONE`],
    /// without arithmetic, so that scenes without attenuation render bit for bit as
    /// before it existed.
    #[inline]
    pub fn factor(&self, d: f32) -> f32 {
        if self.is_none() {
            return 1.0;
        }
        1.0 / (self.constant + self.linear * d + self.quadratic * d * d)
    }
}

impl Default for Attenuation {
    fn default() -> Self {
        Attenuation::NONE
    }
}

/// A point light, shining equally in every direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointLight {
    pub position: Vec3,
    /// Colour already multiplied by intensity.
    pub color: Color,
    pub attenuation: Attenuation,
}

impl PointLight {
    /// Without attenuation.
    pub fn new(position: Vec3, color: Color) -> Self {
        PointLight { position, color, attenuation: Attenuation::NONE }
    }

    pub fn with_attenuation(mut self, attenuation: Attenuation) -> Self {
        self.attenuation = attenuation;
        self
    }
}

/// A light infinitely far away (the sun): parallel rays, no falloff, shadows along
/// `-direction` to infinity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectionalLight {
    /// Unit vector: the way the light travels.
    pub direction: Vec3,
    pub color: Color,
}

impl DirectionalLight {
    /// `direction` (the way the light travels) is normalised ([`unit()`]); it must not
    /// be zero.
    pub fn new(direction: Vec3, color: Color) -> Self {
        DirectionalLight { direction: unit(direction), color }
    }
}

/// `v` normalised, unless it is unit already to within f32 rounding: then `v` itself,
/// so that a direction written out and read back (`whitted convert`) is the same to the
/// bit (normalising a normalised vector again can move it by an ulp, back and forth).
pub fn unit(v: Vec3) -> Vec3 {
    if (v.length_squared() - 1.0).abs() <= 1e-6 { v } else { v.normalize() }
}

/// A point light shining into a cone: full light within `inner` of the axis, none past
/// `outer`, a smoothstep in the cosine between them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpotLight {
    pub position: Vec3,
    /// Unit vector: the axis of the cone, the way the light travels.
    pub direction: Vec3,
    /// The half-angles in degrees, as given (kept so the scene writes back as read);
    /// shading uses their cosines. Set them with [`SpotLight::new`].
    pub inner_angle: f32,
    pub outer_angle: f32,
    /// Cosine of the inner half-angle (full light within it).
    pub cos_inner: f32,
    /// Cosine of the outer half-angle (no light past it); at most `cos_inner`.
    pub cos_outer: f32,
    pub color: Color,
    pub attenuation: Attenuation,
}

impl SpotLight {
    /// Half-angles in degrees from the axis, `0 <= inner <= outer < 90` (the scene
    /// reader checks; here `outer` is raised to `inner` if below it). `direction` is
    /// normalised; it must not be zero. Without attenuation.
    pub fn new(position: Vec3, direction: Vec3, inner_deg: f32, outer_deg: f32, color: Color) -> Self {
        let outer_deg = outer_deg.max(inner_deg);
        let cos_inner = inner_deg.to_radians().cos();
        let cos_outer = outer_deg.to_radians().cos();
        SpotLight {
            position,
            direction: unit(direction),
            inner_angle: inner_deg,
            outer_angle: outer_deg,
            cos_inner,
            cos_outer,
            color,
            attenuation: Attenuation::NONE,
        }
    }

    pub fn with_attenuation(mut self, attenuation: Attenuation) -> Self {
        self.attenuation = attenuation;
        self
    }

    /// The cone's factor for light leaving along unit `dir` (from the light to the
    /// point): 1 within the inner cone, 0 outside the outer one, and between them
    /// `smoothstep(cos_outer, cos_inner, cos θ)`, rising monotonically.
    #[inline]
    pub fn cone(&self, dir: Vec3) -> f32 {
        let c = self.direction.dot(dir);
        if c >= self.cos_inner {
            1.0
        } else if c <= self.cos_outer {
            0.0
        } else {
            let t = (c - self.cos_outer) / (self.cos_inner - self.cos_outer);
            t * t * (3.0 - 2.0 * t)
        }
    }
}

/// Any light of a scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Light {
    Point(PointLight),
    Directional(DirectionalLight),
    Spot(SpotLight),
}

impl From<PointLight> for Light {
    fn from(l: PointLight) -> Self {
        Light::Point(l)
    }
}

impl From<DirectionalLight> for Light {
    fn from(l: DirectionalLight) -> Self {
        Light::Directional(l)
    }
}

impl From<SpotLight> for Light {
    fn from(l: SpotLight) -> Self {
        Light::Spot(l)
    }
}

impl Light {
    /// Seen from `from`: the unit direction towards the light and its distance
    /// (`f32::INFINITY` for a directional light), the length a shadow ray must travel.
    /// For a point or spot light the same operations as the renderer's own, so the
    /// result is bit for bit `((p - from) / |p - from|, |p - from|)`.
    #[inline]
    pub fn toward(&self, from: Vec3) -> (Vec3, f32) {
        match self {
            Light::Point(PointLight { position, .. }) | Light::Spot(SpotLight { position, .. }) => {
                let to = *position - from;
                let distance = to.length();
                (to / distance, distance)
            }
            Light::Directional(d) => (-d.direction, f32::INFINITY),
        }
    }

    /// The share of the light that reaches a point, shadows aside, given `l` and
    /// `distance` from [`Light::toward`]: the spot cone's factor times the attenuation.
    /// Exactly 1.0 for a point light without attenuation and for a directional light,
    /// so a renderer may multiply by it unconditionally without changing their images.
    #[inline]
    pub fn falloff(&self, l: Vec3, distance: f32) -> f32 {
        match self {
            Light::Point(p) => p.attenuation.factor(distance),
            Light::Directional(_) => 1.0,
            Light::Spot(s) => {
                let cone = s.cone(-l);
                if cone == 0.0 { 0.0 } else { cone * s.attenuation.factor(distance) }
            }
        }
    }

    /// Colour, intensity included.
    #[inline]
    pub fn color(&self) -> Color {
        match self {
            Light::Point(l) => l.color,
            Light::Directional(l) => l.color,
            Light::Spot(l) => l.color,
        }
    }

    /// Where the light is; `None` for a directional light.
    #[inline]
    pub fn position(&self) -> Option<Vec3> {
        match self {
            Light::Point(l) => Some(l.position),
            Light::Spot(l) => Some(l.position),
            Light::Directional(_) => None,
        }
    }

    /// The attenuation, for the lights that have one.
    pub fn attenuation(&self) -> Option<Attenuation> {
        match self {
            Light::Point(l) => Some(l.attenuation),
            Light::Spot(l) => Some(l.attenuation),
            Light::Directional(_) => None,
        }
    }

    /// The point light, if this is one.
    pub fn as_point(&self) -> Option<&PointLight> {
        match self {
            Light::Point(l) => Some(l),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A spot at the origin pointing down -y, 20° inner, 30° outer: the light falling on
    /// the plane y = -1 at distance `x` from the axis.
    fn spot_on_floor(x: f32) -> f32 {
        let spot = Light::from(SpotLight::new(Vec3::ZERO, Vec3::new(0.0, -2.0, 0.0), 20.0, 30.0, Color::ONE));
        let (l, d) = spot.toward(Vec3::new(x, -1.0, 0.0));
        spot.falloff(l, d)
    }

    #[test]
    fn a_spot_cone_edge_lands_where_the_geometry_puts_it() {
        // On the plane one unit below, the cones meet it at radius tan(angle).
        let (inner, outer) = (20f32.to_radians().tan(), 30f32.to_radians().tan());
        assert_eq!(spot_on_floor(0.0), 1.0);
        assert_eq!(spot_on_floor(inner * 0.999), 1.0);
        assert!(spot_on_floor(outer * 0.999) > 0.0, "just inside the outer cone");
        assert!(spot_on_floor(outer * 0.999) < 0.01, "just inside the outer cone is dim");
        assert_eq!(spot_on_floor(outer * 1.001), 0.0, "just outside the outer cone");
        assert_eq!(spot_on_floor(-outer * 1.001), 0.0);
        assert_eq!(spot_on_floor(5.0), 0.0);
        // Behind the light: nothing.
        let spot = Light::from(SpotLight::new(Vec3::ZERO, Vec3::NEG_Y, 20.0, 30.0, Color::ONE));
        let (l, d) = spot.toward(Vec3::new(0.0, 1.0, 0.0));
        assert_eq!(spot.falloff(l, d), 0.0);
        // Between the cones: falling monotonically and smoothly (no step bigger than a
        // straight line's slope times 1.5, the smoothstep's steepest).
        let n = 200;
        let mut last = 1.0;
        for i in 0..=n {
            let x = inner + (outer - inner) * i as f32 / n as f32;
            let f = spot_on_floor(x);
            assert!(f <= last, "not monotonic at {x}: {f} after {last}");
            assert!(last - f < 0.02, "a jump at {x}: {last} to {f}");
            last = f;
        }
        // Halfway in the cosine, the smoothstep is one half.
        let s = SpotLight::new(Vec3::ZERO, Vec3::NEG_Y, 20.0, 30.0, Color::ONE);
        let c = 0.5 * (s.cos_inner + s.cos_outer);
        let dir = Vec3::new((1.0 - c * c).sqrt(), -c, 0.0);
        assert!((s.cone(dir) - 0.5).abs() < 1e-3, "{}", s.cone(dir));
        assert_eq!((s.inner_angle, s.outer_angle), (20.0, 30.0));
        assert!((s.cos_inner.acos().to_degrees() - 20.0).abs() < 1e-3);
        assert!((s.cos_outer.acos().to_degrees() - 30.0).abs() < 1e-3);
    }

    #[test]
    fn a_spot_with_equal_angles_has_a_hard_edge() {
        let s = SpotLight::new(Vec3::ZERO, Vec3::NEG_Y, 10.0, 10.0, Color::ONE);
        let edge = 10f32.to_radians();
        let at = |a: f32| s.cone(Vec3::new(a.sin(), -a.cos(), 0.0));
        assert_eq!(at(edge * 0.99), 1.0);
        assert_eq!(at(edge * 1.01), 0.0);
    }

    #[test]
    fn attenuation_follows_its_formula_and_none_is_exactly_one() {
        assert_eq!(Attenuation::NONE.factor(12345.0), 1.0);
        assert_eq!(Attenuation::default(), Attenuation::NONE);
        let a = Attenuation::new(1.0, 0.5, 0.25);
        assert_eq!(a.factor(0.0), 1.0);
        assert_eq!(a.factor(2.0), 1.0 / (1.0 + 1.0 + 1.0));
        assert_eq!(Attenuation::new(0.0, 0.0, 1.0).factor(4.0), 1.0 / 16.0);
        let p = Light::from(PointLight::new(Vec3::new(0.0, 3.0, 4.0), Color::ONE).with_attenuation(a));
        let (l, d) = p.toward(Vec3::ZERO);
        assert_eq!(d, 5.0);
        assert!((p.falloff(l, d) - 1.0 / (1.0 + 2.5 + 6.25)).abs() < 1e-7);
        // A plain point light and a directional light: exactly 1, wherever.
        let plain = Light::from(PointLight::new(Vec3::new(0.0, 3.0, 4.0), Color::ONE));
        let (l, d) = plain.toward(Vec3::new(0.1, 0.2, 0.3));
        assert_eq!(plain.falloff(l, d), 1.0);
        // A spot's attenuation multiplies its cone.
        let s = Light::from(
            SpotLight::new(Vec3::new(0.0, 2.0, 0.0), Vec3::NEG_Y, 10.0, 20.0, Color::ONE).with_attenuation(a),
        );
        let (l, d) = s.toward(Vec3::ZERO);
        assert_eq!(s.falloff(l, d), a.factor(2.0));
    }

    #[test]
    fn directional_lights_point_back_along_their_direction_at_infinity() {
        let sun = Light::from(DirectionalLight::new(Vec3::new(0.0, -3.0, -4.0), Color::splat(0.5)));
        for from in [Vec3::ZERO, Vec3::new(100.0, -7.0, 3.0)] {
            let (l, d) = sun.toward(from);
            assert!((l - Vec3::new(0.0, 0.6, 0.8)).length() < 1e-6, "{l}");
            assert_eq!(d, f32::INFINITY);
            assert_eq!(sun.falloff(l, d), 1.0);
        }
        assert_eq!(sun.position(), None);
        assert_eq!(sun.color(), Color::splat(0.5));
        assert_eq!(sun.attenuation(), None);
    }

    #[test]
    fn unit_directions_normalise_again_to_themselves() {
        let mut seed = 12345u32;
        let mut r = || {
            seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
            (seed >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0
        };
        for _ in 0..10_000 {
            let v = Vec3::new(r(), r(), r()) * 7.0;
            if v.length_squared() < 1e-6 {
                continue;
            }
            let d = unit(v);
            assert_eq!(unit(d), d, "{v}");
            assert!((d.length() - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn point_lights_toward_is_the_renderers_own_arithmetic() {
        let p = Vec3::new(1.5, 7.25, -3.0);
        let light = Light::from(PointLight::new(p, Color::ONE));
        let from = Vec3::new(0.3, 0.1, 0.7);
        let (l, d) = light.toward(from);
        let to = p - from;
        assert_eq!((l, d), (to / to.length(), to.length()));
        assert_eq!(light.position(), Some(p));
    }
}
