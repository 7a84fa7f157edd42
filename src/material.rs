//! Surface appearance: the original's Phong model plus how much of the colour comes from
//! mirror reflection and from transmission.
//!
//! ```toml
//! [material.glass]
//! color = [0, 1, 0]
//! specular = 0        # no highlight
//! transparency = 0.9  # 90 % of the colour is what is seen through it
//! ior = 1.1           # bent on the way (1.0 = straight through)
//!
//! [material.green_glass]
//! color = [1, 1, 1]
//! transparency = 0.9
//! ior = 1.5
//! fresnel = true                  # reflected/transmitted split by angle (see `split`)
//! absorption = [0.5, 0.05, 0.4]   # per unit length inside: thick parts are greener
//! ```

use crate::math::Color;
use crate::texture::Texture;

#[derive(Clone, Debug)]
pub struct Material {
    /// Where the surface colour comes from (a plain colour is `Texture::Solid`).
    pub texture: Texture,
    /// Weight of the Lambert term.
    pub diffuse: f32,
    /// Weight of the white Phong highlight; 0 switches it off.
    pub specular: f32,
    /// Phong exponent: larger is a smaller, sharper highlight.
    pub shininess: f32,
    /// Share of the colour that is the mirror image, in [0, 1].
    pub reflectivity: f32,
    /// Share of the colour that is what lies behind, in [0, 1]; with
    /// `reflectivity` it sums to at most 1, the rest is the surface's own shading.
    pub transparency: f32,
    /// Index of refraction of the material (the scene's medium is 1).
    pub ior: f32,
    /// Split the reflected and transmitted shares by the Fresnel equations at each hit
    /// ([`Material::split`]), as real glass does: more mirror at grazing angles. No
    /// effect without `transparency`.
    pub fresnel: bool,
    /// Absorption per unit length inside the object, per channel ([`beer_lambert`]):
    /// light travelling `d` inside keeps `exp(-absorption·d)`. Only meaningful with
    /// `transparency > 0`: the scene reader refuses it otherwise, since nothing would
    /// travel inside to be absorbed.
    pub absorption: Color,
}

impl Default for Material {
    fn default() -> Self {
        Material {
            texture: Texture::Solid(Color::ONE),
            diffuse: 1.0,
            specular: 1.0,
            shininess: 50.0,
            reflectivity: 0.0,
            transparency: 0.0,
            ior: 1.0,
            fresnel: false,
            absorption: Color::ZERO,
        }
    }
}

impl Material {
    /// A plain coloured surface with the default highlight.
    pub fn color(c: Color) -> Self {
        Material { texture: Texture::Solid(c), ..Default::default() }
    }

    pub fn textured(texture: Texture) -> Self {
        Material { texture, ..Default::default() }
    }

    /// Builder-style setters, for scenes written in code.
    pub fn reflective(mut self, reflectivity: f32) -> Self {
        self.reflectivity = reflectivity;
        self
    }

    pub fn transparent(mut self, transparency: f32, ior: f32) -> Self {
        self.transparency = transparency;
        self.ior = ior;
        self
    }

    pub fn shininess(mut self, shininess: f32) -> Self {
        self.shininess = shininess;
        self
    }

    /// No highlight (the original's walls and green sphere).
    pub fn matte(mut self) -> Self {
        self.specular = 0.0;
        self
    }

    /// Share of the colour that the surface's own shading provides.
    pub fn local_share(&self) -> f32 {
        1.0 - self.reflectivity - self.transparency
    }

    /// Fresnel glass: the reflected/transmitted split follows the angle.
    pub fn with_fresnel(mut self, on: bool) -> Self {
        self.fresnel = on;
        self
    }

    /// Coloured glass: absorption per unit length inside.
    pub fn absorbing(mut self, absorption: Color) -> Self {
        self.absorption = absorption;
        self
    }

    /// The shares `(reflected, transmitted)` of the colour at a hit, given the Fresnel
    /// reflectance `fresnel` there ([`fresnel_reflectance`]; ignored unless
    /// [`Material::fresnel`]). Without `fresnel`: `(reflectivity, transparency)`, as
    /// always. With it, the transmitted share is split by the angle: what the
    /// interface reflects joins the mirror share, `(reflectivity + transparency·F,
    /// transparency·(1 − F))`; the sum, and so the surface's own share, stays the same.
    /// Past the critical angle (F = 1) all of `transparency` is reflected.
    #[inline]
    pub fn split(&self, fresnel: f32) -> (f32, f32) {
        if self.fresnel {
            (self.reflectivity + self.transparency * fresnel, self.transparency * (1.0 - fresnel))
        } else {
            (self.reflectivity, self.transparency)
        }
    }

    /// Whether light inside this material is absorbed ([`Material::absorption`] not zero).
    pub fn absorbs(&self) -> bool {
        self.absorption != Color::ZERO
    }
}

/// Unpolarised Fresnel reflectance of a smooth interface, light arriving from index
/// `eta_i` into index `eta_t` at `cos_i` (cosine between the ray reversed and the
/// normal, its sign ignored): the mean of the s- and p-polarised reflectances from the
/// exact Fresnel equations. 1.0 past the critical angle (total internal reflection).
/// The same from either side of the interface for the same pair of angles.
pub fn fresnel_reflectance(cos_i: f32, eta_i: f32, eta_t: f32) -> f32 {
    let cos_i = cos_i.abs().min(1.0);
    let eta = eta_i / eta_t;
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_s = (eta_i * cos_i - eta_t * cos_t) / (eta_i * cos_i + eta_t * cos_t);
    let r_p = (eta_t * cos_i - eta_i * cos_t) / (eta_t * cos_i + eta_i * cos_t);
    (0.5 * (r_s * r_s + r_p * r_p)).min(1.0)
}

/// Beer–Lambert: the share of light per channel left after `distance` through a
/// medium absorbing `absorption` per unit length, `exp(-absorption·distance)`.
/// Exactly 1 in channels that absorb nothing.
pub fn beer_lambert(absorption: Color, distance: f32) -> Color {
    let f = |a: f32| if a == 0.0 { 1.0 } else { (-a * distance).exp() };
    Color::new(f(absorption.x), f(absorption.y), f(absorption.z))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_is_four_percent_head_on_for_glass_and_rises_to_one_at_grazing() {
        let r0 = fresnel_reflectance(1.0, 1.0, 1.5);
        assert!((r0 - 0.04).abs() < 1e-6, "{r0}");
        // The same from inside, head on: ((1.5 - 1) / (1.5 + 1))².
        assert!((fresnel_reflectance(1.0, 1.5, 1.0) - 0.04).abs() < 1e-6);
        // The sign of the cosine does not matter.
        assert_eq!(fresnel_reflectance(-0.3, 1.0, 1.5), fresnel_reflectance(0.3, 1.0, 1.5));
        // Rising monotonically to 1 at grazing, for both polarisations averaged (the
        // p-polarised part dips to 0 at Brewster's angle, the sum never falls).
        let mut last = r0;
        for i in (0..=1000).rev() {
            let cos_i = i as f32 / 1000.0;
            let r = fresnel_reflectance(cos_i, 1.0, 1.5);
            assert!(r >= last - 1e-6, "falls at cos {cos_i}: {r} after {last}");
            assert!((0.0..=1.0).contains(&r));
            last = r;
        }
        assert_eq!(fresnel_reflectance(0.0, 1.0, 1.5), 1.0);
        assert!(fresnel_reflectance(0.05, 1.0, 1.5) > 0.7);
        // A known value: 45° into glass, Rs = 0.0920, Rp = 0.0085, mean 0.0503.
        let r45 = fresnel_reflectance(45f32.to_radians().cos(), 1.0, 1.5);
        assert!((r45 - 0.05023).abs() < 2e-4, "{r45}");
        // No interface, no reflection.
        assert_eq!(fresnel_reflectance(0.7, 1.5, 1.5), 0.0);
    }

    #[test]
    fn fresnel_is_total_past_the_critical_angle_and_symmetric_across_the_interface() {
        // From glass (1.5) into air the critical angle is asin(1/1.5) = 41.81°.
        let critical = (1.0f32 / 1.5).asin();
        assert_eq!(fresnel_reflectance((critical + 0.01).cos(), 1.5, 1.0), 1.0);
        assert_eq!(fresnel_reflectance(0.2, 1.5, 1.0), 1.0);
        assert!(fresnel_reflectance((critical - 0.01).cos(), 1.5, 1.0) < 1.0);
        // Light entering at θi leaves at θt the way it came: the same reflectance
        // from inside at θt as from outside at θi.
        for deg in [0.0f32, 10.0, 30.0, 50.0, 70.0, 85.0] {
            let ti = deg.to_radians();
            let tt = (ti.sin() / 1.5).asin();
            let outside = fresnel_reflectance(ti.cos(), 1.0, 1.5);
            let inside = fresnel_reflectance(tt.cos(), 1.5, 1.0);
            assert!((outside - inside).abs() < 1e-5, "{deg}°: {outside} vs {inside}");
        }
    }

    #[test]
    fn beer_lambert_halves_red_over_one_unit_of_ln2() {
        let c = beer_lambert(Color::new(std::f32::consts::LN_2, 0.0, 0.0), 1.0);
        assert!((c.x - 0.5).abs() < 1e-6, "{c}");
        assert_eq!((c.y, c.z), (1.0, 1.0));
        // Twice the thickness, a quarter; no distance, nothing absorbed.
        let c = beer_lambert(Color::new(std::f32::consts::LN_2, 1.0, 0.0), 2.0);
        assert!((c.x - 0.25).abs() < 1e-6, "{c}");
        assert!((c.y - (-2.0f32).exp()).abs() < 1e-7);
        assert_eq!(beer_lambert(Color::splat(3.0), 0.0), Color::ONE);
        assert_eq!(beer_lambert(Color::ZERO, f32::INFINITY), Color::ONE);
    }

    #[test]
    fn split_keeps_todays_shares_without_fresnel_and_moves_transmission_to_reflection_with_it() {
        let glass = Material::default().reflective(0.1).transparent(0.8, 1.5);
        assert_eq!(glass.split(0.3), (0.1, 0.8));
        let fresnel = glass.clone().with_fresnel(true);
        let (r, t) = fresnel.split(0.25);
        assert!((r - 0.3).abs() < 1e-6 && (t - 0.6).abs() < 1e-6, "{r} {t}");
        let (r, t) = fresnel.split(1.0);
        assert!((r - 0.9).abs() < 1e-6 && t == 0.0, "{r} {t}");
        assert_eq!(fresnel.split(0.0), (0.1, 0.8));
        // The surface's own share does not move.
        assert!((1.0 - r - t - fresnel.local_share()).abs() < 1e-6);
    }
}
