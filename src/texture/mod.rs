//! Textures: what colour a surface has at a hit point.
//!
//! [`Texture`] is a closed `enum`, like the shapes, so the shading hot path is one `match`
//! with no allocation and no virtual call. Solid-space patterns (stripes, checker) read the
//! world-space point; images read the surface's `uv`. [`planet`] makes the equirectangular
//! map for the demo scene's globe, since the Earth map of the original cannot be shipped.

mod image_map;
mod noise;
mod planet;

use std::fmt;
use std::sync::Arc;

pub use image_map::ImageMap;
pub use planet::planet;

use crate::math::{Color, Vec2, Vec3};

/// Memory one texture (an image file or a generated map) may take, counted as
/// [`TEXEL_BYTES`] a texel: 12 as linear colour plus up to 4 of decoded file. 1.25 GiB
/// allows 8192 x 8192 texels.
pub const MAX_TEXTURE_BYTES: u64 = 5 << 28;
/// Bytes per texel counted against [`MAX_TEXTURE_BYTES`].
pub const TEXEL_BYTES: u64 = 16;

/// How a surface's colour varies over it. Cheap to clone: images are shared.
#[derive(Clone, Debug)]
pub enum Texture {
    Solid(Color),
    /// Bands of `width` perpendicular to unit `axis`, in world space: even bands get
    /// `colors[0]`, odd ones `colors[1]`, counting from the plane through the origin.
    Stripes {
        axis: Vec3,
        width: f32,
        colors: [Color; 2],
    },
    /// 3-D checkerboard of cubes of edge `size`, shifted by `offset` (it looks up
    /// `p + offset`) so the squares can be lined up with a floor's edges.
    Checker {
        size: f32,
        offset: Vec3,
        colors: [Color; 2],
    },
    /// An image looked up at `uv * scale + offset`, repeated, filtered bilinearly.
    Image {
        map: Arc<ImageMap>,
        scale: Vec2,
        offset: Vec2,
    },
}

impl Texture {
    /// An image once over the surface: the common case, and the one the sphere's seam
    /// handling is written for.
    pub fn image(map: Arc<ImageMap>) -> Self {
        Texture::Image { map, scale: Vec2::ONE, offset: Vec2::ZERO }
    }

    /// Whether [`Texture::color`] reads its `uv`: the solid patterns do not, so the
    /// shading code need not compute it.
    #[inline]
    pub fn uses_uv(&self) -> bool {
        matches!(self, Texture::Image { .. })
    }

    /// Colour at world point `p` with surface coordinates `uv`. Total: any input, even
    /// NaN or infinite (a degenerate hit), gives some colour rather than a panic.
    ///
    /// Inlined into the shading: called, its point went through memory as 8 + 4 bytes
    /// and was read back across the two stores, which stalls store forwarding.
    #[inline(always)]
    pub fn color(&self, p: Vec3, uv: Vec2) -> Color {
        match self {
            Texture::Solid(c) => *c,
            Texture::Stripes { axis, width, colors } => colors[parity(p.dot(*axis) / *width)],
            Texture::Checker { size, offset, colors } => {
                let q = (p + *offset) / *size;
                colors[parity(q.x) ^ parity(q.y) ^ parity(q.z)]
            }
            Texture::Image { map, scale, offset } => {
                let uv = uv * *scale + *offset;
                map.sample(Vec2::new(wrap01(uv.x), wrap01(uv.y)))
            }
        }
    }
}

/// 0 if `floor(t)` is even, 1 if odd, also for negative `t` (where `%` would give -1).
/// The `as` cast saturates and maps NaN to 0, so no input panics.
///
/// The floor is taken by truncating and stepping down below zero: `f32::floor` is a
/// libm call on the baseline x86-64 target (no SSE4.1), and this is exact for every `t`.
#[inline]
fn parity(t: f32) -> usize {
    let i = t as i64;
    // `i` is exact whenever `t` has a fraction (|t| < 2²³), and then compares exactly.
    let floor = if (i as f32) > t { i.saturating_sub(1) } else { i };
    (floor & 1) as usize
}

/// `t` wrapped into [0, 1]; non-finite input goes to 0 so it cannot reach an index.
#[inline]
fn wrap01(t: f32) -> f32 {
    let f = t - t.floor();
    if f.is_finite() { f } else { 0.0 }
}

/// Why an image texture could not be loaded or saved. The messages leave out the file
/// name: the scene loader that called us knows it, and the line that named it.
#[derive(Debug)]
pub enum TextureError {
    /// No file at that path.
    NotFound(std::io::Error),
    /// The file exists but could not be read (permissions, a directory, an I/O fault).
    Unreadable(std::io::Error),
    /// Its content (or, failing that, its name) says neither PNG nor JPEG.
    Unsupported(image::ImageError),
    /// It claims to be PNG or JPEG but does not decode.
    Corrupt(image::ImageError),
    /// It decodes to no texels at all, which nothing could be sampled from.
    Empty { width: u32, height: u32 },
    /// Saving failed (a missing directory, a full disk).
    Write(image::ImageError),
    /// Decoding and storing it would need more than [`MAX_TEXTURE_BYTES`].
    TooLarge { width: u32, height: u32, bytes: u64 },
}

impl fmt::Display for TextureError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TextureError::NotFound(e) => write!(f, "image file not found: {e}"),
            TextureError::Unreadable(e) => write!(f, "cannot read image file: {e}"),
            TextureError::Unsupported(e) => {
                write!(f, "unsupported image format (PNG or JPEG expected): {e}")
            }
            TextureError::Corrupt(e) => write!(f, "corrupt or truncated image: {e}"),
            TextureError::Empty { width, height } => {
                write!(f, "image is empty ({width}x{height} texels)")
            }
            TextureError::Write(e) => write!(f, "cannot write image: {e}"),
            TextureError::TooLarge { width, height, bytes } => write!(
                f,
                "a {width}x{height} image needs about {:.1} GiB as a texture; the limit is {:.2} GiB \
                 (8192x8192 texels)",
                *bytes as f64 / (1u64 << 30) as f64,
                MAX_TEXTURE_BYTES as f64 / (1u64 << 30) as f64
            ),
        }
    }
}

impl std::error::Error for TextureError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            TextureError::NotFound(e) | TextureError::Unreadable(e) => Some(e),
            TextureError::Unsupported(e) | TextureError::Corrupt(e) | TextureError::Write(e) => Some(e),
            TextureError::Empty { .. } | TextureError::TooLarge { .. } => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const BLACK: Color = Color::ZERO;
    const WHITE: Color = Color::ONE;

    fn stripes() -> Texture {
        Texture::Stripes { axis: Vec3::X, width: 2.0, colors: [BLACK, WHITE] }
    }

    #[test]
    fn stripes_alternate_across_a_boundary() {
        let t = stripes();
        assert_eq!(t.color(Vec3::new(1.99, 5.0, -3.0), Vec2::ZERO), BLACK);
        assert_eq!(t.color(Vec3::new(2.01, 5.0, -3.0), Vec2::ZERO), WHITE);
        assert_eq!(t.color(Vec3::new(4.01, 5.0, -3.0), Vec2::ZERO), BLACK);
    }

    #[test]
    fn stripes_continue_the_pattern_at_negative_coordinates() {
        let t = stripes();
        // [-2, 0) is band -1 (odd), [-4, -2) band -2 (even): no double-width band at 0.
        assert_eq!(t.color(Vec3::new(0.01, 0.0, 0.0), Vec2::ZERO), BLACK);
        assert_eq!(t.color(Vec3::new(-0.01, 0.0, 0.0), Vec2::ZERO), WHITE);
        assert_eq!(t.color(Vec3::new(-2.01, 0.0, 0.0), Vec2::ZERO), BLACK);
        assert_eq!(t.color(Vec3::new(-4.01, 0.0, 0.0), Vec2::ZERO), WHITE);
    }

    #[test]
    fn stripes_follow_a_diagonal_axis() {
        let axis = Vec3::new(1.0, 1.0, 0.0).normalize();
        let t = Texture::Stripes { axis, width: 1.0, colors: [BLACK, WHITE] };
        assert_eq!(t.color(axis * 0.5, Vec2::ZERO), BLACK);
        assert_eq!(t.color(axis * 1.5, Vec2::ZERO), WHITE);
        // Moving along the band (perpendicular to the axis) keeps the colour.
        assert_eq!(t.color(axis * 1.5 + Vec3::new(7.0, -7.0, 3.0), Vec2::ZERO), WHITE);
    }

    #[test]
    fn checker_flips_parity_along_each_axis_with_offset() {
        let offset = Vec3::new(0.5, 0.25, -0.5);
        let t = Texture::Checker { size: 1.0, offset, colors: [BLACK, WHITE] };
        // Centre of the cube [0,1)^3 in shifted space is even.
        let base = Vec3::splat(0.5) - offset;
        assert_eq!(t.color(base, Vec2::ZERO), BLACK);
        for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
            assert_eq!(t.color(base + axis, Vec2::ZERO), WHITE, "+{axis}");
            assert_eq!(t.color(base - axis, Vec2::ZERO), WHITE, "-{axis}");
            assert_eq!(t.color(base + 2.0 * axis, Vec2::ZERO), BLACK, "+2 {axis}");
        }
        // Two steps on different axes cancel.
        assert_eq!(t.color(base + Vec3::X - Vec3::Z, Vec2::ZERO), BLACK);
        assert_eq!(t.color(base + Vec3::new(1.0, 1.0, 1.0), Vec2::ZERO), WHITE);
    }

    #[test]
    fn parity_matches_floor_everywhere() {
        let reference = |t: f32| (t.floor() as i64).rem_euclid(2) as usize;
        let special = [0.0, -0.0, 0.5, -0.5, 1.0, -1.0, 8388607.5, -8388607.5, 8388609.0, -8388609.0, 1e19, -1e19];
        let special = special.into_iter().chain([f32::NAN, f32::INFINITY, f32::NEG_INFINITY, f32::MAX, f32::MIN]);
        for t in special.chain((0..200_000u32).map(|i| f32::from_bits(i.wrapping_mul(2_654_435_761)))) {
            assert_eq!(parity(t), reference(t), "{t}");
            let below = f32::from_bits(t.to_bits().wrapping_sub(1));
            assert_eq!(parity(below), reference(below), "{below}");
        }
    }

    #[test]
    fn checker_respects_cube_size() {
        let t = Texture::Checker { size: 10.0, offset: Vec3::ZERO, colors: [BLACK, WHITE] };
        assert_eq!(t.color(Vec3::new(9.0, 1.0, 1.0), Vec2::ZERO), BLACK);
        assert_eq!(t.color(Vec3::new(11.0, 1.0, 1.0), Vec2::ZERO), WHITE);
        assert_eq!(t.color(Vec3::new(-1.0, 1.0, 1.0), Vec2::ZERO), WHITE);
    }

    fn two_by_two() -> Arc<ImageMap> {
        let texels = [Color::X, Color::Y, Color::Z, Color::ONE];
        Arc::new(ImageMap::from_fn(2, 2, |x, y| texels[(y * 2 + x) as usize]))
    }

    #[test]
    fn image_texture_scales_and_offsets_uv_and_repeats() {
        let map = two_by_two();
        let t = Texture::Image { map: map.clone(), scale: Vec2::splat(2.0), offset: Vec2::ZERO };
        // uv 0.125 -> 0.25: centre of texel (0, 0); uv 0.625 -> 1.25 -> 0.25 again.
        let a = t.color(Vec3::ZERO, Vec2::splat(0.125));
        let b = t.color(Vec3::ZERO, Vec2::splat(0.625));
        assert!((a - Color::X).abs().max_element() < 1e-5, "{a}");
        assert!((b - Color::X).abs().max_element() < 1e-5, "{b}");
        let shifted = Texture::Image { map, scale: Vec2::ONE, offset: Vec2::new(0.5, 0.0) };
        let c = shifted.color(Vec3::ZERO, Vec2::splat(0.25));
        assert!((c - Color::Y).abs().max_element() < 1e-5, "{c}");
    }

    #[test]
    fn no_input_panics_or_escapes_the_image() {
        let textures = [
            Texture::Solid(WHITE),
            stripes(),
            Texture::Stripes { axis: Vec3::X, width: 0.0, colors: [BLACK, WHITE] },
            Texture::Checker { size: 1.0, offset: Vec3::ZERO, colors: [BLACK, WHITE] },
            Texture::Checker { size: 0.0, offset: Vec3::ZERO, colors: [BLACK, WHITE] },
            Texture::image(two_by_two()),
            Texture::Image { map: two_by_two(), scale: Vec2::splat(1e30), offset: Vec2::NAN },
        ];
        let bad = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, f32::MAX, f32::MIN, -0.0, 1e-45];
        for t in &textures {
            for &a in &bad {
                for &b in &bad {
                    let c = t.color(Vec3::new(a, b, a), Vec2::new(a, b));
                    if let Texture::Image { .. } = t {
                        assert!(c.is_finite(), "{t:?} at ({a}, {b}) gave {c}");
                    }
                }
            }
        }
    }

    #[test]
    fn errors_describe_the_problem_and_keep_the_cause() {
        use std::error::Error;
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "no such file");
        let e = TextureError::NotFound(io);
        assert!(e.to_string().contains("not found"));
        assert!(e.to_string().contains("no such file"));
        assert!(e.source().is_some());
        let e = TextureError::Empty { width: 0, height: 3 };
        assert!(e.to_string().contains("empty"));
    }
}
