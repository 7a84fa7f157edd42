//! The README's turntable strip: six frames of `scenes/turntable.toml`, evenly spaced
//! over its loop, rendered small and set side by side in one PNG.
//!
//!     cargo run --release --example turntable_strip -- docs/turntable-strip.png

use std::path::Path;
use whitted::render::Renderer;
use whitted::scene::load_animated_file;

/// Side of each frame in the strip, in pixels.
const SIDE: u32 = 200;
const FRAMES: u32 = 6;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args().nth(1).unwrap_or_else(|| "turntable-strip.png".into());
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/turntable.toml");
    let (scene, anim, _) = load_animated_file(&path)?;
    // The last frame of the file's range is the first again: spread six over the loop.
    let step = (anim.last - anim.first) / FRAMES;
    let mut strip = image::RgbImage::new(SIDE * FRAMES, SIDE);
    for i in 0..FRAMES {
        let frame = anim.first + i * step;
        let at = anim.scene_at(&scene, frame)?;
        let image = Renderer::new(&at)?.size(SIDE, SIDE).spp(4).render();
        let rgb = image.to_rgb8_as(at.settings.color);
        image::imageops::replace(&mut strip, &rgb, (i * SIDE) as i64, 0);
        eprintln!("frame {frame}");
    }
    strip.save(&out)?;
    eprintln!("wrote {out}");
    Ok(())
}
