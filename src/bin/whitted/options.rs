//! Reading numbers from the command line in the user's terms, and working out the image
//! size from `--width`, `--height` and `--scale`.

/// A whole number from 1 to `MAX`. Negative numbers and zero get "must be at least 1"
/// rather than clap's own hint (`-4` would otherwise read as an unknown flag).
pub fn count<const MAX: u32>(text: &str) -> Result<u32, String> {
    let t = text.trim();
    match t.parse::<i128>() {
        Ok(n) if n < 1 => Err(format!("must be at least 1 (got {t})")),
        Ok(n) if n > MAX as i128 => Err(format!("must be at most {MAX} (got {t})")),
        Ok(n) => Ok(n as u32),
        Err(_) if t.parse::<f64>().is_ok() => Err(format!("must be a whole number from 1 to {MAX} (got {t})")),
        Err(_) => Err(format!("must be a whole number from 1 to {MAX} (got {t:?})")),
    }
}

/// A positive, finite scale factor such as 0.5.
pub fn scale(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
        Ok(_) => Err(format!("must be a number greater than 0 (got {})", text.trim())),
        Err(_) => Err(format!("must be a number such as 0.5 (got {text:?})")),
    }
}

/// The image size: the camera's, with `--width` or `--height` alone keeping its aspect
/// ratio, both given taken as they are, and then multiplied by `--scale`.
pub fn image_size(
    camera: (u32, u32),
    width: Option<u32>,
    height: Option<u32>,
    scale: Option<f64>,
    max: u32,
) -> Result<(u32, u32), String> {
    let (cw, ch) = (camera.0 as f64, camera.1 as f64);
    let (w, h) = match (width, height) {
        (Some(w), Some(h)) => (w as f64, h as f64),
        (Some(w), None) => (w as f64, (w as f64 * ch / cw).round().max(1.0)),
        (None, Some(h)) => ((h as f64 * cw / ch).round().max(1.0), h as f64),
        (None, None) => (cw, ch),
    };
    let k = scale.unwrap_or(1.0);
    let (w, h) = ((w * k).round(), (h * k).round());
    if w < 1.0 || h < 1.0 {
        return Err(format!("--scale {k}: the image would be {w}x{h} pixels: it needs at least 1x1"));
    }
    if w > max as f64 || h > max as f64 {
        let what = if scale.is_some() { format!("--scale {k}") } else { "--width/--height".to_owned() };
        return Err(format!("{what}: the image would be {w}x{h} pixels: each side must be at most {max}"));
    }
    Ok((w as u32, h as u32))
}

/// Memory an image of this size needs while rendering and writing: the film's linear
/// colours plus the 8-bit copy encoded to PNG.
pub fn image_bytes(width: u32, height: u32) -> u64 {
    width as u64 * height as u64 * (std::mem::size_of::<whitted::math::Vec3>() as u64 + 3)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_say_what_is_wrong() {
        assert_eq!(count::<100>("-4").unwrap_err(), "must be at least 1 (got -4)");
        assert_eq!(count::<100>("0").unwrap_err(), "must be at least 1 (got 0)");
        assert_eq!(count::<100>("101").unwrap_err(), "must be at most 100 (got 101)");
        assert!(count::<100>("2.5").unwrap_err().contains("whole number"));
        assert!(count::<100>("abc").unwrap_err().contains("whole number"));
        assert_eq!(count::<100>("100"), Ok(100));
    }

    #[test]
    fn one_side_keeps_the_aspect_ratio() {
        assert_eq!(image_size((800, 600), Some(320), None, None, 16384), Ok((320, 240)));
        assert_eq!(image_size((800, 600), None, Some(300), None, 16384), Ok((400, 300)));
        assert_eq!(image_size((800, 600), Some(10), Some(10), None, 16384), Ok((10, 10)));
        assert_eq!(image_size((800, 600), None, None, Some(0.5), 16384), Ok((400, 300)));
        assert_eq!(image_size((800, 600), Some(320), None, Some(0.5), 16384), Ok((160, 120)));
        assert_eq!(
            image_size((1, 1000), Some(20), None, None, 16384).unwrap_err(),
            "--width/--height: the image would be 20x20000 pixels: each side must be at most 16384"
        );
        assert!(image_size((800, 600), None, None, Some(0.0001), 16384).is_err());
    }
}
