//! The image being made, and writing it out (formats in [`output`]).

pub mod output;

pub use output::{ColorEncoding, Encoding, FileFormat, OutputError, OutputOptions, rgb8_of};

use crate::math::{Color, Vec3};
use std::io::Write;
use std::path::{Path, PathBuf};

/// A rendered picture in linear colour, row-major from the top-left pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    width: u32,
    height: u32,
    /// Three floats a pixel (not the four of [`Color`]): for memory, and so that the
    /// pixels can be handed over as they are ([`Image::into_floats`]).
    pixels: crate::pages::Zeroed<Vec3>,
}

impl Image {
    pub fn new(width: u32, height: u32) -> Self {
        Image { width, height, pixels: crate::pages::zeroed(width as usize * height as usize) }
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    pub fn pixel(&self, x: u32, y: u32) -> Color {
        self.pixels[y as usize * self.width as usize + x as usize].into()
    }

    pub fn set(&mut self, x: u32, y: u32, c: Color) {
        self.pixels[y as usize * self.width as usize + x as usize] = c.into();
    }

    /// All pixels, row after row: renderers fill tiles of rows in parallel.
    pub fn pixels_mut(&mut self) -> &mut [Vec3] {
        &mut self.pixels
    }

    /// The pixels as floats, three per pixel, row after row, from the returned index
    /// on: the film's own memory, not a copy, so a binding can hand a big image over
    /// (to numpy) without writing it twice. (A copy only if the cast is refused.)
    pub fn into_floats(self) -> (Vec<f32>, usize) {
        let (buf, start) = self.pixels.into_parts();
        match bytemuck::allocation::try_cast_vec::<Vec3, f32>(buf) {
            Ok(floats) => (floats, start * 3),
            Err((_, buf)) => (bytemuck::cast_slice(&buf[start..]).to_vec(), 0),
        }
    }

    /// 8-bit RGB, clamped, without gamma: the original wrote its colours to the screen
    /// as they were, and the POV-Ray reference does the same (`File_Gamma=1.0`).
    pub fn to_rgb8(&self) -> image::RgbImage {
        self.to_rgb8_as(ColorEncoding::Linear)
    }
}

/// An image file written whole or not at all: the data goes to a temporary file beside the
/// target, which is renamed over it only once complete, so a failed or interrupted
/// render never leaves a half-written image or clobbers a good one (the temporary file
/// is removed when this is dropped uncommitted).
pub struct PendingOutput {
    path: PathBuf,
    encoding: Encoding,
    temp: tempfile::NamedTempFile,
}

impl PendingOutput {
    /// Checks up front that `path` names a known format and can be written (before
    /// spending time rendering); default options (8-bit or half float, linear).
    pub fn create(path: &Path) -> Result<Self, OutputError> {
        Self::create_with(path, OutputOptions::default())
    }

    /// [`PendingOutput::create`] with the colour encoding and bits per channel chosen.
    pub fn create_with(path: &Path, options: OutputOptions) -> Result<Self, OutputError> {
        check_target(path).map_err(|source| OutputError::Io { path: path.to_owned(), source })?;
        let encoding = Encoding::for_path(path, options)?;
        let temp = temp_file_beside(path).map_err(|source| OutputError::Io { path: path.to_owned(), source })?;
        Ok(PendingOutput { path: path.to_owned(), encoding, temp })
    }

    /// The format, bits and colour encoding the file will get.
    pub fn encoding(&self) -> Encoding {
        self.encoding
    }

    /// Encodes `image` into the temporary file, syncs it and renames it into place.
    pub fn commit(mut self, image: &Image) -> Result<(), OutputError> {
        let path = self.path;
        let io_err = |source| OutputError::Io { path: path.clone(), source };
        {
            let mut w = std::io::BufWriter::new(self.temp.as_file_mut());
            output::encode_to(image, self.encoding, &mut w)
                .map_err(|message| OutputError::Encode { path: path.clone(), message })?;
            w.flush().map_err(io_err)?;
        }
        self.temp.as_file().sync_all().map_err(io_err)?;
        let temp_path = self.temp.path().to_owned();
        let result = self.temp.persist(&path);
        crate::cleanup::forget(&temp_path);
        result.map_err(|e| io_err(e.error))?;
        Ok(())
    }
}

/// A temporary file in the folder of `path`, to be renamed over it once complete (a
/// rename within one file system is atomic). It gets an ordinary file's permissions
/// (what the umask allows), not the owner-only mode temporary files get by default,
/// since it becomes the user's output.
pub fn temp_file_beside(path: &Path) -> std::io::Result<tempfile::NamedTempFile> {
    check_target(path)?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let mut builder = tempfile::Builder::new();
    builder.prefix(".whitted-").suffix(".tmp");
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
    // The temporary name means nothing to the user: errors keep only their kind.
    let temp = builder.tempfile_in(dir).map_err(|e| std::io::Error::from(e.kind()))?;
    // Listed so that an interrupted run removes it (see `crate::cleanup`).
    crate::cleanup::register(temp.path());
    Ok(temp)
}

/// Whether `path` can be an output file, in terms of that path: not a folder, and in a
/// folder that exists.
pub fn check_target(path: &Path) -> std::io::Result<()> {
    use std::io::{Error, ErrorKind};
    let text = path.as_os_str().to_string_lossy();
    if path.is_dir() || text.ends_with('/') || text.ends_with(std::path::MAIN_SEPARATOR) {
        let example = path.join("room.png");
        return Err(Error::new(
            ErrorKind::InvalidInput,
            format!("this is a folder; give a file name, such as {}", example.display()),
        ));
    }
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty())
        && !dir.is_dir()
    {
        let what = if dir.exists() { "is not a folder" } else { "does not exist" };
        return Err(Error::new(ErrorKind::NotFound, format!("the folder {} {what}", dir.display())));
    }
    Ok(())
}

/// Writes `image` to `path` atomically, in the format its extension names (default
/// options: the name is historical).
pub fn write_png(image: &Image, path: &Path) -> Result<(), OutputError> {
    PendingOutput::create(path)?.commit(image)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floats_are_the_pixels_in_order_small_and_big() {
        // 1000x1000 is big enough for the film to start past a huge-page boundary.
        for (w, h) in [(3, 2), (1000, 1000)] {
            let mut img = Image::new(w, h);
            img.set(0, 0, Color::new(0.1, 0.2, 0.3));
            img.set(w - 1, h - 1, Color::new(4.0, -1.0, f32::NAN));
            img.set(1, 1, Color::new(0.5, 0.6, 0.7));
            let expect: Vec<u32> = (0..h)
                .flat_map(|y| (0..w).map(move |x| (x, y)))
                .flat_map(|(x, y)| img.pixel(x, y).to_array())
                .map(f32::to_bits)
                .collect();
            let rgb8 = img.to_rgb8();
            let (floats, start) = img.into_floats();
            let got: Vec<u32> = floats[start..start + (w * h * 3) as usize].iter().map(|v| v.to_bits()).collect();
            assert_eq!(got, expect, "{w}x{h}");
            // The 8-bit quantisation of the same floats, as the PNG writer does it.
            let quantised = rgb8_of(&floats[start..start + (w * h * 3) as usize], ColorEncoding::Linear);
            assert_eq!(quantised, rgb8.into_raw());
            assert_eq!(&quantised[quantised.len() - 3..], &[255, 0, 0]);
        }
    }

    #[test]
    fn write_is_atomic_and_leaves_no_temp_files() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("a.png");
        let mut img = Image::new(4, 3);
        img.set(1, 1, Color::new(1.0, 0.5, 0.0));
        write_png(&img, &out).unwrap();
        let back = image::open(&out).unwrap().to_rgb8();
        assert_eq!(back.get_pixel(1, 1).0, [255, 128, 0]);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn abandoned_output_removes_its_temp_and_keeps_the_old_file() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("keep.png");
        std::fs::write(&out, b"good").unwrap();
        let pending = PendingOutput::create(&out).unwrap();
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
        drop(pending); // the render failed
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        assert_eq!(std::fs::read(&out).unwrap(), b"good");
    }

    #[test]
    fn unwritable_and_unknown_paths_are_refused_up_front() {
        assert!(matches!(PendingOutput::create(Path::new("/nonexistent-dir/x.png")), Err(OutputError::Io { .. })));
        assert!(matches!(PendingOutput::create(Path::new("x.tga")), Err(OutputError::UnknownFormat { .. })));
    }
}
