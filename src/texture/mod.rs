//! PLACEHOLDER until the texture module lands (being written in parallel).
use crate::math::{Color, Vec2, Vec3};
use std::sync::Arc;

#[derive(Clone, Debug)]
pub enum Texture {
    Solid(Color),
    Stripes { axis: Vec3, width: f32, colors: [Color; 2] },
    Checker { size: f32, offset: Vec3, colors: [Color; 2] },
    Image { map: Arc<ImageMap>, scale: Vec2, offset: Vec2 },
}
impl Texture {
    pub fn color(&self, p: Vec3, _uv: Vec2) -> Color {
        match self {
            Texture::Solid(c) => *c,
            Texture::Stripes { axis, width, colors } => {
                colors[((p.dot(*axis) / width).floor() as i64).rem_euclid(2) as usize]
            }
            Texture::Checker { size, offset, colors } => {
                let q = ((p + *offset) / *size).floor();
                colors[((q.x + q.y + q.z) as i64).rem_euclid(2) as usize]
            }
            Texture::Image { .. } => Color::ONE,
        }
    }
}
#[derive(Debug, Clone, PartialEq)]
pub struct ImageMap {
    width: u32,
    height: u32,
    texels: Vec<Color>,
}
#[derive(Debug)]
pub struct TextureError(pub String);
impl std::fmt::Display for TextureError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}
impl std::error::Error for TextureError {}
impl ImageMap {
    pub fn load(_p: &std::path::Path) -> Result<ImageMap, TextureError> {
        Err(TextureError("placeholder".into()))
    }
    pub fn width(&self) -> u32 {
        self.width
    }
    pub fn height(&self) -> u32 {
        self.height
    }
    pub fn save_png(&self, _p: &std::path::Path) -> Result<(), TextureError> {
        Ok(())
    }
}
pub fn planet(width: u32, height: u32, _seed: u64) -> ImageMap {
    ImageMap { width, height, texels: vec![Color::ONE; (width * height) as usize] }
}
