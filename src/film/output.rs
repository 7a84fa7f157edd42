//! Image file formats: which one a path asks for, and the encoders.
//!
//! The extension decides: `.png` (8 or 16 bits per channel), `.jpg`/`.jpeg` (8 bits),
//! `.exr` (OpenEXR, linear half or full float) and `.hdr` (Radiance RGBE, linear).
//! Integer formats are written either as the renderer's values are (linear, the
//! default, which keeps the project's images as they always were) or sRGB-encoded,
//! which is what image viewers and glTF scenes assume. Float formats are always linear.

use super::Image;
use crate::math::Color;
use std::io::{Seek, Write};
use std::path::{Path, PathBuf};

/// How colours go into 8- and 16-bit files.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ColorEncoding {
    /// Values as they are, clamped to [0, 1] (0.5 becomes 128).
    #[default]
    Linear,
    /// The sRGB transfer curve (0.5 becomes 188).
    Srgb,
}

impl ColorEncoding {
    /// `"linear"` or `"srgb"`, as the scene file and the command line spell them.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "linear" => Some(ColorEncoding::Linear),
            "srgb" => Some(ColorEncoding::Srgb),
            _ => None,
        }
    }
}

/// The sRGB encoding of a linear value in [0, 1] (IEC 61966-2-1).
#[inline]
pub fn srgb_encode(v: f32) -> f32 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    if v <= 0.003_130_8 { 12.92 * v } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 }
}

/// The linear value of an sRGB-encoded one in [0, 1] (for sRGB image textures).
#[inline]
pub fn srgb_decode(v: f32) -> f32 {
    if v <= 0.040_45 { v / 12.92 } else { ((v + 0.055) / 1.055).powf(2.4) }
}

/// The file formats written, by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileFormat {
    Png,
    Jpeg,
    Exr,
    Hdr,
}

impl FileFormat {
    /// The format `path`'s extension names (any case).
    pub fn of_path(path: &Path) -> Option<FileFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Some(match ext.as_str() {
            "png" => FileFormat::Png,
            "jpg" | "jpeg" => FileFormat::Jpeg,
            "exr" => FileFormat::Exr,
            "hdr" => FileFormat::Hdr,
            _ => return None,
        })
    }

    /// The name messages use.
    pub fn name(self) -> &'static str {
        match self {
            FileFormat::Png => "PNG",
            FileFormat::Jpeg => "JPEG",
            FileFormat::Exr => "OpenEXR",
            FileFormat::Hdr => "Radiance HDR",
        }
    }

    /// Bits per channel it can hold, the default first.
    fn bits(self) -> &'static [u32] {
        match self {
            FileFormat::Png => &[8, 16],
            FileFormat::Jpeg => &[8],
            FileFormat::Exr => &[16, 32],
            FileFormat::Hdr => &[32],
        }
    }
}

/// What the user asked for: the colour encoding of integer formats and, optionally, the
/// bits per channel (PNG 8 or 16, EXR 16 for half floats or 32 for full ones).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OutputOptions {
    pub color: ColorEncoding,
    pub bits: Option<u32>,
}

/// A resolved encoding: the format, its bits per channel and the colour encoding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Encoding {
    pub format: FileFormat,
    pub bits: u32,
    pub color: ColorEncoding,
}

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("{path}: unknown image format (give the file a .png, .jpg, .jpeg, .exr or .hdr extension)")]
    UnknownFormat { path: PathBuf },
    #[error("{path}: {} files hold {allowed} bits per channel, not {bits}", format.name())]
    Bits { path: PathBuf, format: FileFormat, bits: u32, allowed: String },
    #[error("{path}: cannot write the image: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path}: cannot encode the image: {message}")]
    Encode { path: PathBuf, message: String },
}

impl Encoding {
    /// The encoding for `path` with `options`, or why there is none.
    pub fn for_path(path: &Path, options: OutputOptions) -> Result<Encoding, OutputError> {
        let format = FileFormat::of_path(path).ok_or_else(|| OutputError::UnknownFormat { path: path.to_owned() })?;
        let allowed = format.bits();
        let bits = options.bits.unwrap_or(allowed[0]);
        if !allowed.contains(&bits) {
            let allowed = allowed.iter().map(|b| b.to_string()).collect::<Vec<_>>().join(" or ");
            return Err(OutputError::Bits { path: path.to_owned(), format, bits, allowed });
        }
        Ok(Encoding { format, bits, color: options.color })
    }
}

impl Image {
    /// 8-bit RGB in the given encoding, clamped to [0, 1] and rounded.
    pub fn to_rgb8_as(&self, color: ColorEncoding) -> image::RgbImage {
        let bytes = rgb8_of(bytemuck::cast_slice(&self.pixels), color);
        image::RgbImage::from_raw(self.width, self.height, bytes).expect("three bytes per pixel")
    }

    /// 16-bit RGB in the given encoding, clamped to [0, 1] and rounded.
    pub fn to_rgb16_as(&self, color: ColorEncoding) -> image::ImageBuffer<image::Rgb<u16>, Vec<u16>> {
        let mut out = image::ImageBuffer::new(self.width, self.height);
        let q = |v: f32| (encode(v, color) * 65535.0 + 0.5) as u16;
        for (dst, c) in out.pixels_mut().zip(self.pixels.iter()) {
            *dst = image::Rgb([q(c.x), q(c.y), q(c.z)]);
        }
        out
    }
}

/// Linear float channels as 8-bit ones in the given encoding, clamped to [0, 1] and
/// rounded: what every 8-bit output writes ([`Image::to_rgb8_as`]), also for floats
/// that are not in an [`Image`] (a numpy array).
pub fn rgb8_of(floats: &[f32], color: ColorEncoding) -> Vec<u8> {
    floats.iter().map(|&v| (encode(v, color) * 255.0 + 0.5) as u8).collect()
}

/// `v` clamped to [0, 1] (NaN to 0) and encoded; linear is exactly the clamp the
/// original PNG writer did, so linear images are unchanged byte for byte.
#[inline]
fn encode(v: f32, color: ColorEncoding) -> f32 {
    match color {
        ColorEncoding::Linear => v.clamp(0.0, 1.0),
        ColorEncoding::Srgb => srgb_encode(v),
    }
}

/// Writes `image` to `w` in `enc`; errors are messages for [`OutputError::Encode`].
pub(super) fn encode_to(image: &Image, enc: Encoding, w: &mut (impl Write + Seek)) -> Result<(), String> {
    use image::ImageEncoder;
    let (width, height) = (image.width, image.height);
    match (enc.format, enc.bits) {
        (FileFormat::Png, 16) => {
            image.to_rgb16_as(enc.color).write_to(w, image::ImageFormat::Png).map_err(|e| e.to_string())
        }
        (FileFormat::Png, _) => {
            image.to_rgb8_as(enc.color).write_to(w, image::ImageFormat::Png).map_err(|e| e.to_string())
        }
        (FileFormat::Jpeg, _) => {
            let rgb = image.to_rgb8_as(enc.color);
            image::codecs::jpeg::JpegEncoder::new_with_quality(w, 95)
                .write_image(rgb.as_raw(), width, height, image::ExtendedColorType::Rgb8)
                .map_err(|e| e.to_string())
        }
        (FileFormat::Hdr, _) => {
            // RGBE holds no negative or non-finite values.
            let clean = |v: f32| if v.is_finite() { v.max(0.0) } else { 0.0 };
            let px: Vec<image::Rgb<f32>> =
                image.pixels.iter().map(|c| image::Rgb([clean(c.x), clean(c.y), clean(c.z)])).collect();
            image::codecs::hdr::HdrEncoder::new(w)
                .encode(&px, width as usize, height as usize)
                .map_err(|e| e.to_string())
        }
        (FileFormat::Exr, bits) => write_exr(image, bits == 16, w),
    }
}

/// OpenEXR with R, G and B channels, half or full float, losslessly compressed.
fn write_exr(image: &Image, half: bool, w: &mut (impl Write + Seek)) -> Result<(), String> {
    use exr::prelude::{self as x, WritableImage};
    let size = (image.width as usize, image.height as usize);
    let at = |p: x::Vec2<usize>| -> Color { image.pixels[p.y() * size.0 + p.x()].into() };
    let result = if half {
        let h = |v: f32| x::f16::from_f32(v);
        let channels = x::SpecificChannels::rgb(|p: x::Vec2<usize>| {
            let c = at(p);
            (h(c.x), h(c.y), h(c.z))
        });
        x::Image::from_channels(size, channels).write().to_buffered(w)
    } else {
        let channels = x::SpecificChannels::rgb(|p: x::Vec2<usize>| {
            let c = at(p);
            (c.x, c.y, c.z)
        });
        x::Image::from_channels(size, channels).write().to_buffered(w)
    };
    result.map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_encodes_known_values() {
        let img = {
            let mut i = Image::new(4, 1);
            for (x, v) in [0.0, 0.5, 1.0, 0.002].into_iter().enumerate() {
                i.set(x as u32, 0, Color::splat(v));
            }
            i
        };
        let s = img.to_rgb8_as(ColorEncoding::Srgb);
        assert_eq!([0, 1, 2, 3].map(|x| s.get_pixel(x, 0).0[0]), [0, 188, 255, 7]);
        let l = img.to_rgb8_as(ColorEncoding::Linear);
        assert_eq!([0, 1, 2, 3].map(|x| l.get_pixel(x, 0).0[0]), [0, 128, 255, 1]);
        assert_eq!(l, img.to_rgb8(), "linear is the historical 8-bit conversion");
        let s16 = img.to_rgb16_as(ColorEncoding::Srgb);
        assert_eq!(s16.get_pixel(1, 0).0[0], 48192); // 0.735357 * 65535
        for v in [0.0, 0.001, 0.2, 0.5, 0.9, 1.0] {
            assert!((srgb_decode(srgb_encode(v)) - v).abs() < 1e-5, "{v}");
        }
    }

    #[test]
    fn formats_follow_the_extension_and_bits_are_checked() {
        let enc = |p: &str, bits| Encoding::for_path(Path::new(p), OutputOptions { bits, ..Default::default() });
        assert_eq!(enc("a.PNG", None).unwrap().bits, 8);
        assert_eq!(enc("a.png", Some(16)).unwrap().bits, 16);
        assert_eq!(enc("a.jpeg", None).unwrap().format, FileFormat::Jpeg);
        assert_eq!(enc("a.exr", None).unwrap().bits, 16);
        assert_eq!(enc("a.exr", Some(32)).unwrap().bits, 32);
        assert_eq!(enc("a.hdr", None).unwrap().format, FileFormat::Hdr);
        assert!(matches!(enc("a.jpg", Some(16)), Err(OutputError::Bits { .. })));
        assert!(matches!(enc("a.png", Some(32)), Err(OutputError::Bits { .. })));
        let e = enc("a.tiff", None).unwrap_err();
        assert!(matches!(e, OutputError::UnknownFormat { .. }));
        assert!(e.to_string().contains("a.tiff: unknown image format"), "{e}");
        assert!(matches!(enc("noext", None), Err(OutputError::UnknownFormat { .. })));
    }
}
