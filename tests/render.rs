//! End-to-end renders: the command line's default scene, determinism across thread
//! counts, and an image regression test of the room against a committed reference.

use std::path::{Path, PathBuf};
use whitted::prelude::*;
use whitted::scene;

mod common;

fn whitted(args: &[&str]) {
    let out = common::whitted_command().args(args).output().expect("run whitted");
    assert!(out.status.success(), "whitted {args:?} failed: {}", String::from_utf8_lossy(&out.stderr));
}

fn manifest(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn room() -> Scene {
    scene::load_file(&manifest("scenes/room.toml")).expect("room loads")
}

#[test]
fn default_scene_is_the_room_file_byte_for_byte() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("a.png"), tmp.path().join("b.png"));
    let room = manifest("scenes/room.toml");
    let small = ["--width", "120", "--height", "120", "-q"];
    whitted(&[&["render", room.to_str().unwrap(), "-o", a.to_str().unwrap()], &small[..]].concat());
    whitted(&[&["render", "-o", b.to_str().unwrap()], &small[..]].concat());
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
}

#[test]
fn thread_count_does_not_change_the_image() {
    let tmp = tempfile::tempdir().unwrap();
    for spp in ["1", "16"] {
        let mut files = Vec::new();
        for threads in ["1", "2", "3"] {
            let out = tmp.path().join(format!("t{threads}-s{spp}.png"));
            whitted(&[
                "render",
                "-o",
                out.to_str().unwrap(),
                "--width",
                "96",
                "--height",
                "96",
                "--spp",
                spp,
                "--threads",
                threads,
                "-q",
            ]);
            files.push(std::fs::read(&out).unwrap());
        }
        assert_eq!(files[0], files[1], "spp {spp}: 1 vs 2 threads");
        assert_eq!(files[0], files[2], "spp {spp}: 1 vs 3 threads");
    }
}

#[test]
fn anti_aliasing_smooths_edges_but_keeps_the_picture() {
    let scene = room();
    let one = Renderer::new(&scene).unwrap().size(100, 100).spp(1).render();
    let aa = Renderer::new(&scene).unwrap().size(100, 100).spp(16).render();
    let (mut changed, mut total_diff) = (0, 0.0);
    for y in 0..100 {
        for x in 0..100 {
            let d = (one.pixel(x, y) - aa.pixel(x, y)).abs().max_element();
            total_diff += d;
            if d > 0.02 {
                changed += 1;
            }
        }
    }
    // Edges and the checkered ceiling change; flat regions barely do.
    assert!(changed > 300, "only {changed} pixels changed with 16 spp");
    assert!(total_diff / 10_000.0 < 0.1, "mean change {}", total_diff / 10_000.0);
}

/// Pixels may differ by rounding where floating-point results differ across CPUs or
/// compilers: at most 1 % of pixels may differ by more than 8 levels (of 255) in a
/// channel, and the mean difference must stay under 0.5 levels.
#[test]
fn room_matches_reference_image() {
    const REFERENCE: &str = "tests/reference/room-200-spp4.png";
    let image = Renderer::new(&room()).unwrap().size(200, 200).spp(4).render().to_rgb8();
    let reference_path = manifest(REFERENCE);
    if std::env::var_os("WHITTED_BLESS").is_some() {
        image.save(&reference_path).unwrap();
        eprintln!("wrote {REFERENCE}");
        return;
    }
    let reference = image::open(&reference_path)
        .unwrap_or_else(|e| panic!("{REFERENCE}: {e} (WHITTED_BLESS=1 cargo test writes it)"))
        .to_rgb8();
    assert_eq!(image.dimensions(), reference.dimensions());
    let mut diff = image::RgbImage::new(image.width(), image.height());
    let (mut big, mut sum) = (0usize, 0u64);
    for ((a, b), d) in image.pixels().zip(reference.pixels()).zip(diff.pixels_mut()) {
        let delta = [0, 1, 2].map(|c| a.0[c].abs_diff(b.0[c]));
        sum += delta.iter().map(|&v| v as u64).sum::<u64>();
        if delta.iter().any(|&v| v > 8) {
            big += 1;
        }
        *d = image::Rgb(delta.map(|v| v.saturating_mul(8)));
    }
    let pixels = (image.width() * image.height()) as usize;
    let mean = sum as f64 / (pixels * 3) as f64;
    if big * 100 > pixels || mean > 0.5 {
        let dir = manifest("target/test-output");
        std::fs::create_dir_all(&dir).unwrap();
        image.save(dir.join("room-200-spp4.png")).unwrap();
        diff.save(dir.join("room-200-spp4-diff.png")).unwrap();
        panic!(
            "room differs from {REFERENCE}: {big} pixels off by > 8 levels, mean {mean:.3}; \
             see target/test-output/room-200-spp4{{,-diff}}.png"
        );
    }
}

/// The BVH must pick the same object as testing every object, even where a ray meets
/// two objects at once: the room's diagonal pixels look exactly into the corners where
/// walls meet the ceiling and floor. (With the tree, image tiles also find the hits of
/// the rays their hits send on ahead of shading, level by level, and count them there:
/// the counts must agree too.)
#[test]
fn room_is_identical_with_and_without_bvh() {
    use whitted::accel::AccelKind;
    let scene = room();
    let render =
        |accel| Renderer::new(&scene).unwrap().size(400, 400).spp(2).accel(accel).render_with_progress(&|_, _| {});
    let (bvh, none) = (render(AccelKind::Bvh), render(AccelKind::None));
    assert_eq!(bvh.stats, none.stats);
    assert!(bvh.stats.reflection > 50_000 && bvh.stats.refraction > 20_000, "{:?}", bvh.stats);
    let (bvh, none) = (bvh.image, none.image);
    let differing =
        (0..400).flat_map(|y| (0..400).map(move |x| (x, y))).filter(|&(x, y)| bvh.pixel(x, y) != none.pixel(x, y));
    let first: Vec<_> = differing.take(5).collect();
    assert!(first.is_empty(), "pixels differ, e.g. {first:?}");
}
