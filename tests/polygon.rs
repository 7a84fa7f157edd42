//! Concave TOML polygons are ear-clipped like NFF ones; self-crossing ones are refused
//! with the crossing edges named.

mod common;

use common::whitted;

const HEAD: &str = "[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, -1]\nfov = 40\nwidth = 64\nheight = 64\n\
                    [settings]\nambient = 1\n[[light]]\nposition = [0, 0, 0]\n";

#[test]
fn a_concave_polygon_renders_its_outline() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("l.toml");
    // An L filling the left column and the bottom row of a 2x2 square: the top-right
    // quarter is the notch.
    let body = format!(
        "{HEAD}[[polygon]]\nvertices = [[-1, -1, -3], [1, -1, -3], [1, 0, -3], [0, 0, -3], [0, 1, -3], [-1, 1, -3]]\n\
         material = {{ color = [1, 0, 0], diffuse = 0, specular = 0 }}\n"
    );
    std::fs::write(&scene, body).unwrap();
    let png = tmp.path().join("l.png");
    let out = whitted(&["render", scene.to_str().unwrap(), "-o", png.to_str().unwrap(), "-q"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let img = image::open(&png).unwrap().to_rgb8();
    // The square spans about 20 pixels either side of the centre (fov 40 at distance 3).
    let red = |x, y| img.get_pixel(x, y).0 == [255, 0, 0];
    assert!(red(22, 42), "bottom-left arm");
    assert!(red(42, 42), "bottom-right arm");
    assert!(red(22, 22), "top-left arm");
    assert!(!red(42, 22), "the notch is filled");
    assert_eq!(img.get_pixel(42, 22).0, [0, 0, 0], "the notch shows the background");
}

#[test]
fn a_self_crossing_polygon_names_the_crossing() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("x.toml");
    let body = format!(
        "{HEAD}[[polygon]]\nvertices = [[0, 0, -5], [3, 0, -5], [0, 2, -5], [2, 2, -5]]\nmaterial = {{ color = [1, 0, 0] }}\n"
    );
    std::fs::write(&scene, body).unwrap();
    let out = whitted(&["render", scene.to_str().unwrap(), "-o", tmp.path().join("x.png").to_str().unwrap()]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{e}");
    assert!(e.contains("x.toml:12:") && e.contains("crosses itself"), "{e}");
    assert!(e.contains("edge from vertex 3 to 0 crosses the edge from vertex 1 to 2"), "{e}");
}
