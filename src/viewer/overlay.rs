//! Drawing into the window's framebuffer (`0x00RRGGBB` per pixel, row-major): the
//! rendered picture, scaled up by pixel replication, and text in an 8 × 8 bitmap font
//! that ships inside the binary, so no system fonts are needed.

use crate::film::Image;
use font8x8::legacy::BASIC_LEGACY;

pub const WHITE: u32 = 0x00ff_ffff;
pub const YELLOW: u32 = 0x00ff_e060;
pub const RED: u32 = 0x00ff_6060;
pub const GREY: u32 = 0x00b0_b0b0;

/// The same quantisation as [`Image::to_rgb8`], so the window shows what a PNG would.
fn pack(c: crate::math::Color) -> u32 {
    let q = |v: f32| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u32;
    q(c.x) << 16 | q(c.y) << 8 | q(c.z)
}

/// Draws `image` into a `width` × `height` framebuffer, each image pixel covering a
/// `scale` × `scale` block from the top-left corner. What the image does not cover is
/// black, and what does not fit is cut off: never stretched.
pub fn blit(image: &Image, scale: u32, fb: &mut [u32], width: usize, height: usize) {
    let scale = scale.max(1) as usize;
    let (iw, ih) = (image.width() as usize, image.height() as usize);
    for (y, row) in fb.chunks_exact_mut(width).take(height).enumerate() {
        let sy = y / scale;
        if sy >= ih {
            row.fill(0);
            continue;
        }
        let mut x = 0;
        for sx in 0..iw {
            if x >= width {
                break;
            }
            let c = pack(image.pixel(sx as u32, sy as u32));
            let end = (x + scale).min(width);
            row[x..end].fill(c);
            x = end;
        }
        row[x..].fill(0);
    }
}

/// `image` scaled up `scale` times by pixel replication (for saving a preview pass at
/// the window's size).
pub fn upscale(image: &Image, scale: u32, width: u32, height: u32) -> Image {
    let scale = scale.max(1);
    let mut out = Image::new(width, height);
    for y in 0..height {
        for x in 0..width {
            let sx = (x / scale).min(image.width() - 1);
            let sy = (y / scale).min(image.height() - 1);
            out.set(x, y, image.pixel(sx, sy));
        }
    }
    out
}

/// A line of overlay text and its colour.
pub type Line = (String, u32);

/// Glyph size in pixels at `scale`, with one pixel of spacing between lines.
pub fn line_height(scale: usize) -> usize {
    9 * scale
}

/// Text scale that stays legible without covering a small window.
pub fn text_scale(width: usize) -> usize {
    if width >= 640 { 2 } else { 1 }
}

/// A framebuffer to draw on: `width` × `height` pixels, row-major.
pub struct Canvas<'a> {
    pub pixels: &'a mut [u32],
    pub width: usize,
    pub height: usize,
}

impl Canvas<'_> {
    /// Draws one line of text with its top-left corner at (`x`, `y`), `scale` screen
    /// pixels per font pixel, clipped to the canvas. Characters outside ASCII show as `?`.
    pub fn text(&mut self, x: usize, y: usize, text: &str, color: u32, scale: usize) {
        let scale = scale.max(1);
        for (i, ch) in text.chars().enumerate() {
            let glyph = BASIC_LEGACY[if ch.is_ascii() { ch as usize } else { '?' as usize }];
            let gx = x + i * 8 * scale;
            if gx >= self.width {
                break;
            }
            for (row, bits) in glyph.iter().enumerate() {
                // Bit 0 is the leftmost pixel of the row.
                for col in (0..8).filter(|c| bits >> c & 1 == 1) {
                    let start = gx + col * scale;
                    if start >= self.width {
                        break;
                    }
                    let end = (start + scale).min(self.width);
                    for py in (y + row * scale..y + (row + 1) * scale).take_while(|&py| py < self.height) {
                        self.pixels[py * self.width + start..py * self.width + end].fill(color);
                    }
                }
            }
        }
    }

    /// Darkens a rectangle to half brightness, so text over it reads on any picture.
    pub fn shade(&mut self, x0: usize, y0: usize, w: usize, h: usize) {
        for y in y0..(y0 + h).min(self.height) {
            let row = &mut self.pixels[y * self.width..(y + 1) * self.width];
            for p in &mut row[x0.min(self.width)..(x0 + w).min(self.width)] {
                *p = (*p >> 1) & 0x007f_7f7f;
            }
        }
    }

    /// Draws `lines` in a shaded box at the top-left corner.
    pub fn panel(&mut self, lines: &[Line], scale: usize) {
        if lines.is_empty() {
            return;
        }
        let pad = 3 * scale;
        let chars = lines.iter().map(|(t, _)| t.chars().count()).max().unwrap_or(0);
        let w = chars * 8 * scale + 2 * pad;
        let h = lines.len() * line_height(scale) + 2 * pad - scale;
        self.shade(0, 0, w, h);
        for (i, (text, color)) in lines.iter().enumerate() {
            self.text(pad, pad + i * line_height(scale), text, *color, scale);
        }
    }
}

/// Splits `text` into lines of at most `max_chars` characters, breaking at spaces where
/// it can (long error messages must fit the window).
pub fn wrap(text: &str, max_chars: usize) -> Vec<String> {
    let max_chars = max_chars.max(8);
    let mut out = Vec::new();
    for para in text.lines() {
        let mut line = String::new();
        for word in para.split(' ') {
            let mut word = word.to_owned();
            while word.chars().count() > max_chars {
                if !line.is_empty() {
                    out.push(std::mem::take(&mut line));
                }
                let head: String = word.chars().take(max_chars).collect();
                word = word.chars().skip(max_chars).collect();
                out.push(head);
            }
            let needed = line.chars().count() + usize::from(!line.is_empty()) + word.chars().count();
            if needed > max_chars && !line.is_empty() {
                out.push(std::mem::take(&mut line));
            }
            if !line.is_empty() {
                line.push(' ');
            }
            line.push_str(&word);
        }
        out.push(line);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Color;

    #[test]
    fn blit_replicates_pixels_and_never_stretches() {
        let mut img = Image::new(2, 2);
        img.set(0, 0, Color::new(1.0, 0.0, 0.0));
        img.set(1, 1, Color::new(0.0, 0.0, 1.0));
        let (w, h) = (5, 6);
        let mut fb = vec![0x123456; w * h];
        blit(&img, 2, &mut fb, w, h);
        assert_eq!(fb[0], 0xff0000);
        assert_eq!(fb[w + 1], 0xff0000);
        assert_eq!(fb[2], 0);
        assert_eq!(fb[3 * w + 3], 0x0000ff);
        assert_eq!(fb[4], 0, "past the image: black");
        assert_eq!(fb[5 * w], 0, "below the image: black");
        // A bigger image than the window is cut, not squeezed.
        let mut fb = vec![0; 1];
        blit(&img, 1, &mut fb, 1, 1);
        assert_eq!(fb[0], 0xff0000);
    }

    #[test]
    fn upscale_matches_blit() {
        let mut img = Image::new(3, 2);
        img.set(2, 1, Color::new(0.0, 1.0, 0.0));
        let big = upscale(&img, 4, 10, 7);
        assert_eq!(big.pixel(9, 6), Color::new(0.0, 1.0, 0.0));
        assert_eq!(big.pixel(7, 3), Color::ZERO);
        assert_eq!(big.pixel(8, 4), Color::new(0.0, 1.0, 0.0));
    }

    #[test]
    fn text_draws_glyph_pixels_and_clips() {
        let (w, h) = (40, 12);
        let mut fb = vec![0; w * h];
        let mut c = Canvas { pixels: &mut fb, width: w, height: h };
        c.text(0, 0, "H", WHITE, 1);
        let lit = c.pixels.iter().filter(|&&p| p == WHITE).count();
        let glyph_bits: u32 = BASIC_LEGACY['H' as usize].iter().map(|r| r.count_ones()).sum();
        assert_eq!(lit as u32, glyph_bits);
        // Row 0 of "H" is 0x33: bits 0, 1, 4, 5 from the left.
        assert_eq!(&c.pixels[..6], &[WHITE, WHITE, 0, 0, WHITE, WHITE]);
        // Far off the edge, huge or non-ASCII: nothing panics.
        c.text(35, 10, "clipped ü", WHITE, 3);
        c.text(1000, 1000, "gone", WHITE, 1);
        c.panel(&[("a long line that does not fit".into(), RED)], 2);
    }

    #[test]
    fn wrap_keeps_lines_short() {
        let lines = wrap("scene.toml:12:5: radius: must be > 0 (got -1)", 20);
        assert!(lines.iter().all(|l| l.chars().count() <= 20), "{lines:?}");
        assert_eq!(lines.join(" "), "scene.toml:12:5: radius: must be > 0 (got -1)");
        let long = wrap(&"x".repeat(50), 20);
        assert_eq!(long.len(), 3);
    }
}
