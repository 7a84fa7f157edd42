//! Image files out: each format read back by a reader independent of the writer.

mod common;

use common::whitted;
use whitted::film::{ColorEncoding, Image, OutputOptions, PendingOutput};
use whitted::math::Color;

/// A small image with values beyond 1, small ones and exact binary fractions.
fn sample_image() -> Image {
    let mut img = Image::new(5, 3);
    let values = [
        Color::new(1.0, 0.5, 0.25),
        Color::new(3.0, 1.5, 0.75),
        Color::new(0.125, 0.0625, 0.03125),
        Color::new(12.0, 0.0, 6.0),
        Color::new(0.0, 0.0, 0.0),
    ];
    for y in 0..3 {
        for x in 0..5 {
            img.set(x, y, values[(x as usize + y as usize) % 5] * if y == 1 { 2.0 } else { 1.0 });
        }
    }
    img
}

fn write(img: &Image, path: &std::path::Path, bits: Option<u32>) {
    PendingOutput::create_with(path, OutputOptions { bits, color: ColorEncoding::Linear })
        .unwrap()
        .commit(img)
        .unwrap();
}

#[test]
fn exr_round_trips_in_half_and_full_float() {
    let dir = tempfile::tempdir().unwrap();
    // Written by the `exr` crate, read back by `image`'s decoder.
    for bits in [16, 32] {
        let path = dir.path().join(format!("f{bits}.exr"));
        let mut img = sample_image();
        if bits == 32 {
            img.set(2, 2, Color::new(0.1, 1.0 / 3.0, 1e-7)); // not representable in half
        }
        write(&img, &path, Some(bits));
        let back = image::open(&path).unwrap().to_rgb32f();
        assert_eq!((back.width(), back.height()), (5, 3));
        for y in 0..3 {
            for x in 0..5 {
                assert_eq!(back.get_pixel(x, y).0, img.pixel(x, y).to_array(), "{bits} bits, ({x}, {y})");
            }
        }
    }
    // Half floats round: 0.1 comes back as the nearest half, within 2^-11 relative.
    let path = dir.path().join("round.exr");
    let mut img = Image::new(1, 1);
    img.set(0, 0, Color::new(0.1, 1000.0, 1.0 / 3.0));
    write(&img, &path, None);
    let p = image::open(&path).unwrap().to_rgb32f().get_pixel(0, 0).0;
    assert_ne!(p[0], 0.1);
    for (a, b) in p.iter().zip([0.1, 1000.0, 1.0 / 3.0]) {
        assert!((a - b).abs() <= b * 2f32.powi(-11), "{a} vs {b}");
    }
}

/// A Radiance RGBE reader written from the format's description (flat and new-style
/// run-length scanlines), independent of the `image` crate that writes them.
fn read_hdr(bytes: &[u8]) -> (usize, usize, Vec<[f32; 3]>) {
    let mut pos = 0;
    let mut line = || {
        let end = pos + bytes[pos..].iter().position(|&b| b == b'\n').unwrap();
        let l = String::from_utf8_lossy(&bytes[pos..end]).into_owned();
        pos = end + 1;
        l
    };
    assert!(line().starts_with("#?"), "magic");
    let mut l = line();
    while !l.is_empty() {
        assert!(!l.starts_with("FORMAT=") || l == "FORMAT=32-bit_rle_rgbe", "{l}");
        l = line();
    }
    let res = line();
    let parts: Vec<&str> = res.split_whitespace().collect();
    assert_eq!((parts[0], parts[2]), ("-Y", "+X"), "{res}");
    let (h, w): (usize, usize) = (parts[1].parse().unwrap(), parts[3].parse().unwrap());
    let mut data = &bytes[pos..];
    let mut out = Vec::with_capacity(w * h);
    for _ in 0..h {
        let mut rgbe = vec![[0u8; 4]; w];
        if data[0] == 2 && data[1] == 2 && ((data[2] as usize) << 8 | data[3] as usize) == w {
            data = &data[4..];
            for c in 0..4 {
                let mut x = 0;
                while x < w {
                    let n = data[0] as usize;
                    if n > 128 {
                        for px in &mut rgbe[x..x + n - 128] {
                            px[c] = data[1];
                        }
                        x += n - 128;
                        data = &data[2..];
                    } else {
                        for (i, px) in rgbe[x..x + n].iter_mut().enumerate() {
                            px[c] = data[1 + i];
                        }
                        x += n;
                        data = &data[1 + n..];
                    }
                }
            }
        } else {
            for px in rgbe.iter_mut() {
                px.copy_from_slice(&data[..4]);
                data = &data[4..];
            }
        }
        for [r, g, b, e] in rgbe {
            let f = if e == 0 { 0.0 } else { 2f32.powi(e as i32 - 136) };
            out.push([r as f32 * f, g as f32 * f, b as f32 * f]);
        }
    }
    (w, h, out)
}

#[test]
fn hdr_round_trips_values_rgbe_holds_exactly() {
    let dir = tempfile::tempdir().unwrap();
    for width in [5, 40] {
        // Widths of 8 and more are run-length encoded, narrower ones flat.
        let mut img = Image::new(width, 3);
        let base = sample_image();
        for y in 0..3 {
            for x in 0..width {
                img.set(x, y, base.pixel(x % 5, y));
            }
        }
        let path = dir.path().join(format!("w{width}.hdr"));
        write(&img, &path, None);
        let (w, h, px) = read_hdr(&std::fs::read(&path).unwrap());
        assert_eq!((w, h), (width as usize, 3));
        for y in 0..3 {
            for x in 0..width {
                assert_eq!(px[(y * width + x) as usize], img.pixel(x, y).to_array(), "width {width}, ({x}, {y})");
            }
        }
    }
}

#[test]
fn png16_jpeg_and_srgb_from_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("grey.toml");
    // A flat grey card filling the view, lit only by ambient 0.5 of white: 0.5 everywhere.
    std::fs::write(
        &scene,
        "[camera]\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\nfov = 30\nwidth = 6\nheight = 4\n\
         [settings]\nambient = 0.5\ncolor = \"srgb\"\n\
         [[quad]]\ncorner = [-5, -5, 0]\nedge_u = [10, 0, 0]\nedge_v = [0, 10, 0]\n\
         material = { color = [1, 1, 1], diffuse = 0, specular = 0 }\n",
    )
    .unwrap();
    let s = scene.to_str().unwrap();
    let run = |out: &str, extra: &[&str]| {
        let path = dir.path().join(out);
        let mut args = vec!["render", s, "-q", "-o", path.to_str().unwrap()];
        args.extend_from_slice(extra);
        let o = whitted(&args);
        assert!(o.status.success(), "{out}: {}", String::from_utf8_lossy(&o.stderr));
        path
    };
    // The scene asks for sRGB: 0.5 -> 188; the flag overrides it.
    let p = image::open(run("a.png", &[])).unwrap();
    assert_eq!(p.as_rgb8().unwrap().get_pixel(2, 2).0, [188; 3]);
    let p = image::open(run("b.png", &["--color", "linear"])).unwrap();
    assert_eq!(p.as_rgb8().unwrap().get_pixel(2, 2).0, [128; 3]);
    let p = image::open(run("c.png", &["--bits", "16"])).unwrap();
    assert_eq!(p.as_rgb16().unwrap().get_pixel(2, 2).0, [48192; 3]);
    let p = image::open(run("d.jpg", &[])).unwrap().to_rgb8();
    assert!(p.pixels().all(|q| q.0.iter().all(|&v| v.abs_diff(188) <= 1)), "{:?}", p.get_pixel(0, 0));
    // EXR stays linear whatever the encoding.
    let p = image::open(run("e.exr", &[])).unwrap().to_rgb32f();
    assert_eq!(p.get_pixel(2, 2).0, [0.5; 3]);

    let bad = dir.path().join("f.jpg");
    let o = whitted(&["render", s, "-q", "-o", bad.to_str().unwrap(), "--bits", "16"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("8 bits per channel, not 16"));
    assert!(!bad.exists());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 6, "no temporary files left");
}
