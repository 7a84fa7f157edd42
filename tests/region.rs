//! Region rendering: any rectangle renders exactly as that part of the full image, from
//! the library and through `whitted render --region`.

mod common;

use std::path::Path;
use whitted::prelude::*;
use whitted::scene;

fn room(size: u32) -> Scene {
    let mut s = scene::load_file(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/room.toml")).unwrap();
    s.camera.width = size;
    s.camera.height = size;
    s
}

fn crop(full: &Image, (x0, y0, x1, y1): (u32, u32, u32, u32)) -> Image {
    let mut out = Image::new(x1 - x0, y1 - y0);
    for y in y0..y1 {
        for x in x0..x1 {
            out.set(x - x0, y - y0, full.pixel(x, y));
        }
    }
    out
}

#[test]
fn a_region_is_that_part_of_the_full_image_bit_for_bit() {
    let scene = room(100);
    for spp in [1, 4, 3] {
        let full = Renderer::new(&scene).unwrap().spp(spp).threads(2).render();
        // On the 16-pixel tile grid, off it, one pixel, one row, the last column, all.
        for r in
            [(16, 32, 48, 64), (5, 7, 61, 43), (37, 91, 38, 92), (0, 50, 100, 51), (99, 0, 100, 100), (0, 0, 100, 100)]
        {
            let part = Renderer::new(&scene).unwrap().spp(spp).threads(2).region(r.0, r.1, r.2, r.3).unwrap().render();
            assert_eq!((part.width(), part.height()), (r.2 - r.0, r.3 - r.1));
            // `==` on pixels: bit for bit (no NaN in a render).
            assert!(part == crop(&full, r), "spp {spp}, region {r:?}");
        }
    }
    // Corner sampling too: each corner ray is traced where it lies.
    let full = Renderer::new(&scene).unwrap().spd_rules().render();
    let r = (3, 17, 70, 40);
    let part = Renderer::new(&scene).unwrap().spd_rules().region(r.0, r.1, r.2, r.3).unwrap().render();
    assert!(part == crop(&full, r));
}

#[test]
fn a_region_outside_the_image_or_empty_is_refused() {
    let scene = room(100);
    for r in [(0, 0, 101, 10), (10, 10, 10, 20), (20, 0, 10, 10), (0, 100, 10, 101)] {
        let err = Renderer::new(&scene).unwrap().region(r.0, r.1, r.2, r.3).unwrap_err();
        assert!(err.to_string().contains("100 x 100"), "{err}");
    }
}

#[test]
fn the_cli_writes_just_the_region() {
    let tmp = tempfile::tempdir().unwrap();
    let run = |extra: &[&str], out: &Path| {
        let mut args =
            vec!["render", "--width", "64", "--height", "48", "--spp", "4", "-q", "-o", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        common::whitted_command().args(&args).output().unwrap()
    };
    let (full, part) = (tmp.path().join("full.png"), tmp.path().join("part.png"));
    assert!(run(&[], &full).status.success());
    let out = run(&["--region", "10,5,43,37"], &part);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (full, part) = (image::open(&full).unwrap().to_rgb8(), image::open(&part).unwrap().to_rgb8());
    assert_eq!(part.dimensions(), (33, 32));
    for (x, y, p) in part.enumerate_pixels() {
        assert_eq!(p, full.get_pixel(x + 10, y + 5), "({x}, {y})");
    }
    // Bad regions: a clear message and a failed exit, no file.
    let bad = tmp.path().join("bad.png");
    for (region, says) in [("10,5,80,37", "64 x 48"), ("1,2,3", "X0,Y0,X1,Y1"), ("a,b,c,d", "X0,Y0,X1,Y1")] {
        let out = run(&["--region", region], &bad);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(says), "{region}: {err}");
        assert!(!bad.exists());
    }
}
