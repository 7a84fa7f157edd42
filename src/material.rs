//! Surface appearance: the original's Phong model plus how much of the colour comes from
//! mirror reflection and from transmission.
//!
//! ```toml
//! [material.glass]
//! color = [0, 1, 0]
//! specular = 0        # no highlight
//! transparency = 0.9  # 90 % of the colour is what is seen through it
//! ior = 1.1           # bent on the way (1.0 = straight through)
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
}
