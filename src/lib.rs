//! Whitted: a fast recursive ray tracer.
//!
//! Follow one ray: [`camera`] makes it, [`integrator`] traces it through the [`accel`]
//! structure over the [`geometry`], shades it with [`material`]s, [`texture`]s and
//! [`light`]s, and [`render`] gathers the pixels into the [`film`]. [`scene`] reads
//! scene files or lets you build a scene in code.

#![deny(unsafe_code)]
// `!(x > 0.0)` is how this code says "not positive, or NaN": the negation is the point.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod accel;
pub mod bench;
pub mod camera;
pub mod cleanup;
pub mod film;
pub mod geometry;
pub mod integrator;
pub mod light;
pub mod material;
pub mod math;
pub mod pages;
pub mod render;
pub mod sampler;
pub mod scene;
pub mod texture;
pub mod viewer;

/// Everything needed to build and render a scene in code.
pub mod prelude {
    pub use crate::camera::Camera;
    pub use crate::film::{Image, write_png};
    pub use crate::geometry::{Cone, Cylinder, Polygon, Quad, Shape, Sphere, Triangle};
    pub use crate::light::{Attenuation, DirectionalLight, Light, PointLight, SpotLight};
    pub use crate::material::Material;
    pub use crate::math::{Color, Vec2, Vec3};
    pub use crate::render::Renderer;
    pub use crate::scene::{MaterialId, Scene};
    pub use crate::texture::Texture;
}
