//! Point lights.
//!
//! ```toml
//! [[light]]
//! position = [10, 30, -3]
//! color = [1, 1, 1]
//! intensity = 1.0
//! ```

use crate::math::{Color, Vec3};

/// A point light: no falloff with distance, like the original and POV-Ray's default.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointLight {
    pub position: Vec3,
    /// Colour already multiplied by intensity.
    pub color: Color,
}

impl PointLight {
    pub fn new(position: Vec3, color: Color) -> Self {
        PointLight { position, color }
    }
}
