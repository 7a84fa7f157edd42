//! Images as textures: loading, bilinear sampling, saving.

use std::io::Cursor;
use std::path::Path;

use image::{ImageError, ImageFormat, ImageReader};

use super::{TextureError, wrap01};
use crate::film::ColorEncoding;
use crate::film::output::srgb_decode;
use crate::math::{Color, Vec2, Vec3};

/// A grid of colours, row 0 at the top (as image files store them, and as `v = 0` means:
/// texture coordinates run right and down the image, as in glTF; the OBJ reader and the
/// shapes turn their own conventions into this one).
/// Never empty, so sampling needs no special case.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageMap {
    width: u32,
    height: u32,
    /// Three floats a texel, not the four of a [`Color`]: a map's memory is counted
    /// against [`super::MAX_TEXTURE_BYTES`].
    texels: Vec<Vec3>,
}

impl ImageMap {
    /// Builds a map texel by texel, `f(x, y)` with `y = 0` the top row.
    ///
    /// # Panics
    /// If either side is 0: sampling needs at least one texel (files are refused with
    /// [`TextureError::Empty`] instead).
    pub fn from_fn(width: u32, height: u32, f: impl Fn(u32, u32) -> Color) -> Self {
        let texels = (0..height).flat_map(|y| (0..width).map(move |x| (x, y)));
        Self::from_texels(width, height, texels.map(|(x, y)| f(x, y).into()).collect())
    }

    /// For producers that fill the texels themselves (in parallel, say).
    pub(crate) fn from_texels(width: u32, height: u32, texels: Vec<Vec3>) -> Self {
        assert!(width > 0 && height > 0, "image map must not be empty ({width}x{height})");
        assert_eq!(texels.len(), width as usize * height as usize);
        ImageMap { width, height, texels }
    }

    /// Reads a PNG or JPEG. Stored values are taken as they are, divided by the largest
    /// value (255 for 8-bit): no sRGB decoding, because the renderer writes its results
    /// without gamma too, as the program it replaces did, so a colour round-trips.
    pub fn load(path: &Path) -> Result<ImageMap, TextureError> {
        Self::load_as(path, ColorEncoding::Linear)
    }

    /// [`ImageMap::load`], decoding the stored values from `encoding`: sRGB for photos
    /// and painted textures (what glTF's colour textures are), linear (values as they
    /// are) for data and for the project's own round trips.
    pub fn load_as(path: &Path, encoding: ColorEncoding) -> Result<ImageMap, TextureError> {
        let bytes = std::fs::read(path).map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => TextureError::NotFound(e),
            _ => TextureError::Unreadable(e),
        })?;
        Self::decode(&bytes, ImageFormat::from_path(path).ok(), encoding)
    }

    /// An image file's bytes decoded, `hint` the format its name or MIME type gives:
    /// its size read from the header first (a small file can claim a huge image), then
    /// decoded within the texture budget and converted texel by texel, without a second
    /// full-size copy.
    pub fn decode(bytes: &[u8], hint: Option<ImageFormat>, encoding: ColorEncoding) -> Result<ImageMap, TextureError> {
        let reader = || -> Result<ImageReader<Cursor<&[u8]>>, TextureError> {
            let mut reader = ImageReader::new(Cursor::new(bytes));
            // The content decides and the name is only the fallback: a JPEG named .png
            // still loads, and garbage named .png is reported as a corrupt PNG.
            if let Some(format) = hint {
                reader.set_format(format);
            }
            reader.with_guessed_format().map_err(TextureError::Unreadable)
        };
        let (width, height) = reader()?.into_dimensions().map_err(|e| match e {
            ImageError::Unsupported(_) => TextureError::Unsupported(e),
            _ => TextureError::Corrupt(e),
        })?;
        let need = width as u64 * height as u64 * super::TEXEL_BYTES;
        if need > super::MAX_TEXTURE_BYTES {
            return Err(TextureError::TooLarge { width, height, bytes: need });
        }
        let mut reader = reader()?;
        let mut limits = image::Limits::default();
        limits.max_alloc = Some(super::MAX_TEXTURE_BYTES);
        reader.limits(limits);
        let image = reader.decode().map_err(|e| match e {
            ImageError::Unsupported(_) => TextureError::Unsupported(e),
            ImageError::Limits(_) => TextureError::TooLarge { width, height, bytes: need },
            _ => TextureError::Corrupt(e),
        })?;
        let (width, height) = (image.width(), image.height());
        if width == 0 || height == 0 {
            return Err(TextureError::Empty { width, height });
        }
        let texels = match &image {
            image::DynamicImage::ImageLuma8(b) => b.pixels().map(|p| Vec3::splat(p.0[0] as f32 / 255.0)).collect(),
            image::DynamicImage::ImageLumaA8(b) => b.pixels().map(|p| Vec3::splat(p.0[0] as f32 / 255.0)).collect(),
            image::DynamicImage::ImageRgb8(b) => {
                b.pixels().map(|p| Vec3::from(p.0.map(|c| c as f32 / 255.0))).collect()
            }
            image::DynamicImage::ImageRgba8(b) => {
                b.pixels().map(|p| Vec3::new(p.0[0] as f32, p.0[1] as f32, p.0[2] as f32) / 255.0).collect()
            }
            other => other.to_rgb32f().pixels().map(|p| Vec3::from(p.0)).collect(),
        };
        Ok(Self::from_texels(width, height, texels).decoded(encoding))
    }

    /// The map with its texels decoded from `encoding` to linear values.
    pub fn decoded(mut self, encoding: ColorEncoding) -> Self {
        if encoding == ColorEncoding::Srgb {
            for t in &mut self.texels {
                *t = Vec3::new(srgb_decode(t.x), srgb_decode(t.y), srgb_decode(t.z));
            }
        }
        self
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    /// Row-major, top row first.
    pub fn texels(&self) -> &[Vec3] {
        &self.texels
    }

    /// # Panics
    /// If `(x, y)` is outside the map.
    pub fn texel(&self, x: u32, y: u32) -> Color {
        assert!(x < self.width && y < self.height, "texel ({x}, {y}) outside the map");
        self.texels[y as usize * self.width as usize + x as usize].into()
    }

    /// Bilinear lookup with texel centres at `(i + 0.5) / width`. `u` wraps around, so on
    /// a sphere the last column blends into the first and the seam does not show; `v`
    /// clamps, since the top and bottom rows are the poles, not neighbours. Any input,
    /// NaN included, lands inside the map.
    // Inlined always: with `#[inline]` alone, the room's shading stopped inlining it
    // when other code grew (4 % of a room render: docs/performance.md, "Light buffers").
    #[inline(always)]
    pub fn sample(&self, uv: Vec2) -> Color {
        let (w, h) = (self.width as usize, self.height as usize);

        let x = wrap01(uv.x) * w as f32 - 0.5; // in [-0.5, w - 0.5]
        let x_floor = x.floor();
        let fx = x - x_floor;
        let x0 = (x_floor as i64).rem_euclid(w as i64) as usize;
        let x1 = if x0 + 1 == w { 0 } else { x0 + 1 };

        let v = if uv.y.is_nan() { 0.0 } else { uv.y.clamp(0.0, 1.0) };
        let y = (v * h as f32 - 0.5).clamp(0.0, (h - 1) as f32);
        let y_floor = y.floor();
        let fy = y - y_floor;
        let y0 = y_floor as usize;
        let y1 = (y0 + 1).min(h - 1);

        let row0 = &self.texels[y0 * w..(y0 + 1) * w];
        let row1 = &self.texels[y1 * w..(y1 + 1) * w];
        let at = |row: &[Vec3], x: usize| Color::from(row[x]);
        let top = at(row0, x0).lerp(at(row0, x1), fx);
        let bottom = at(row1, x0).lerp(at(row1, x1), fx);
        top.lerp(bottom, fy)
    }

    /// 8-bit copy for writing out; values are clamped to [0, 1] and rounded, with no
    /// gamma, matching [`ImageMap::load`].
    pub fn to_rgb8(&self) -> image::RgbImage {
        let to_u8 = |c: f32| (c.clamp(0.0, 1.0) * 255.0).round() as u8;
        image::RgbImage::from_fn(self.width, self.height, |x, y| {
            let c = self.texel(x, y);
            image::Rgb([to_u8(c.x), to_u8(c.y), to_u8(c.z)])
        })
    }

    pub fn save_png(&self, path: &Path) -> Result<(), TextureError> {
        self.to_rgb8().save_with_format(path, ImageFormat::Png).map_err(TextureError::Write)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Color, b: Color) -> bool {
        (a - b).abs().max_element() < 1e-5
    }

    /// 3 x 2 map with distinct, exactly representable texels.
    fn map() -> ImageMap {
        ImageMap::from_fn(3, 2, |x, y| Color::new(x as f32 / 4.0, y as f32 / 2.0, 0.25))
    }

    #[test]
    fn from_fn_stores_rows_top_first() {
        let m = map();
        assert_eq!((m.width(), m.height()), (3, 2));
        assert_eq!(m.texel(2, 0), Color::new(0.5, 0.0, 0.25));
        assert_eq!(m.texels()[3], Vec3::new(0.0, 0.5, 0.25));
    }

    #[test]
    #[should_panic(expected = "empty")]
    fn from_fn_refuses_an_empty_map() {
        let _ = ImageMap::from_fn(0, 4, |_, _| Color::ZERO);
    }

    #[test]
    fn sampling_at_texel_centres_is_exact() {
        let m = map();
        for y in 0..2 {
            for x in 0..3 {
                let uv = Vec2::new((x as f32 + 0.5) / 3.0, (y as f32 + 0.5) / 2.0);
                assert!(close(m.sample(uv), m.texel(x, y)), "texel ({x}, {y})");
            }
        }
    }

    #[test]
    fn sampling_between_centres_is_bilinear() {
        let m = map();
        // Midway between the four texels (0..1, 0..1).
        let c = m.sample(Vec2::new(1.0 / 3.0, 0.5));
        let expected = (m.texel(0, 0) + m.texel(1, 0) + m.texel(0, 1) + m.texel(1, 1)) / 4.0;
        assert!(close(c, expected), "{c} vs {expected}");
    }

    #[test]
    fn sampling_wraps_u_between_last_and_first_columns() {
        let m = map();
        let mid = (m.texel(2, 0) + m.texel(0, 0)) / 2.0;
        let v = 0.25; // centre of row 0
        for u in [0.0, 1.0, -1.0, 2.0] {
            assert!(close(m.sample(Vec2::new(u, v)), mid), "u = {u}");
        }
        // A quarter texel inside the right edge is still three quarters the last column.
        let c = m.sample(Vec2::new(1.0 - 0.25 / 3.0, v));
        assert!(close(c, m.texel(2, 0).lerp(m.texel(0, 0), 0.25)), "{c}");
    }

    #[test]
    fn sampling_clamps_v_at_top_and_bottom() {
        let m = map();
        let u = 0.5 / 3.0; // centre of column 0
        for v in [0.0, 0.1, -5.0, f32::NEG_INFINITY] {
            assert!(close(m.sample(Vec2::new(u, v)), m.texel(0, 0)), "v = {v}");
        }
        for v in [1.0, 0.9, 7.0, f32::INFINITY] {
            assert!(close(m.sample(Vec2::new(u, v)), m.texel(0, 1)), "v = {v}");
        }
    }

    #[test]
    fn sampling_nan_uv_does_not_panic() {
        let m = map();
        for uv in [Vec2::NAN, Vec2::new(f32::NAN, 0.5), Vec2::new(0.5, f32::NAN)] {
            assert!(m.sample(uv).is_finite());
        }
        let one = ImageMap::from_fn(1, 1, |_, _| Color::ONE);
        assert_eq!(one.sample(Vec2::NAN), Color::ONE);
        assert_eq!(one.sample(Vec2::new(0.3, 0.9)), Color::ONE);
    }

    #[test]
    fn png_round_trips_through_load_without_gamma() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("map.png");
        let m = ImageMap::from_fn(5, 3, |x, y| Color::new(x as f32 * 51.0, y as f32 * 100.0, 128.0) / 255.0);
        m.save_png(&path).unwrap();
        let loaded = ImageMap::load(&path).unwrap();
        assert_eq!((loaded.width(), loaded.height()), (5, 3));
        for (a, b) in loaded.texels().iter().zip(m.texels()) {
            assert!(close((*a).into(), (*b).into()), "{a} vs {b}");
        }
        // Mid-grey stays mid-grey: no sRGB decoding on the way in.
        assert!((loaded.texel(0, 0).z - 128.0 / 255.0).abs() < 1e-6);
    }

    #[test]
    fn jpeg_loads_by_content_even_under_a_png_name() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("grey.png");
        let grey = image::RgbImage::from_pixel(8, 8, image::Rgb([128, 128, 128]));
        let mut jpeg = Vec::new();
        grey.write_to(&mut Cursor::new(&mut jpeg), ImageFormat::Jpeg).unwrap();
        std::fs::write(&path, jpeg).unwrap();
        let loaded = ImageMap::load(&path).unwrap();
        assert_eq!((loaded.width(), loaded.height()), (8, 8));
        assert!((loaded.texel(3, 3) - Color::splat(128.0 / 255.0)).abs().max_element() < 0.02);
    }

    #[test]
    fn load_of_a_missing_file_says_not_found() {
        let dir = tempfile::tempdir().unwrap();
        let err = ImageMap::load(&dir.path().join("nope.png")).unwrap_err();
        assert!(matches!(err, TextureError::NotFound(_)), "{err:?}");
        assert!(err.to_string().contains("not found"), "{err}");
    }

    #[test]
    fn load_of_a_directory_says_unreadable() {
        let dir = tempfile::tempdir().unwrap();
        let err = ImageMap::load(dir.path()).unwrap_err();
        assert!(matches!(err, TextureError::Unreadable(_)), "{err:?}");
    }

    #[test]
    fn load_of_garbage_named_png_says_corrupt() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.png");
        std::fs::write(&path, b"this is not a picture, just some bytes\x00\x01\x02").unwrap();
        let err = ImageMap::load(&path).unwrap_err();
        assert!(matches!(err, TextureError::Corrupt(_)), "{err:?}");
        assert!(err.to_string().contains("corrupt"), "{err}");
    }

    #[test]
    fn load_of_a_truncated_png_says_corrupt() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cut.png");
        map().save_png(&path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
        let err = ImageMap::load(&path).unwrap_err();
        assert!(matches!(err, TextureError::Corrupt(_)), "{err:?}");
    }

    #[test]
    fn load_of_another_format_says_unsupported() {
        let dir = tempfile::tempdir().unwrap();
        // A GIF by its magic bytes (this build decodes PNG and JPEG only), and a file whose
        // content and name both say nothing.
        for (name, bytes) in [("a.gif", &b"GIF89a\x01\x00\x01\x00"[..]), ("notes.txt", b"hello")] {
            let path = dir.path().join(name);
            std::fs::write(&path, bytes).unwrap();
            let err = ImageMap::load(&path).unwrap_err();
            assert!(matches!(err, TextureError::Unsupported(_)), "{name}: {err:?}");
            assert!(err.to_string().contains("unsupported"), "{err}");
        }
    }

    #[test]
    fn save_into_a_missing_directory_fails_cleanly() {
        let dir = tempfile::tempdir().unwrap();
        let err = map().save_png(&dir.path().join("no/such/dir/x.png")).unwrap_err();
        assert!(matches!(err, TextureError::Write(_)), "{err:?}");
    }
}
