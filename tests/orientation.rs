//! How an image lies on each shape: an asymmetric test image (a grid of 4 x 2 coloured
//! cells with a black "F" in the top-left one) on a quad, a sphere, a cylinder and an
//! OBJ mesh, checked at known pixels. Lit by ambient light 1 alone, so a pixel's colour
//! is the texel's. The renders are also saved side by side in the target folder
//! (`orientation.png`) to look at; docs/formats.md shows them.

use std::sync::Arc;
use whitted::film::Image;
use whitted::prelude::*;
use whitted::texture::ImageMap;

const W: u32 = 64;
const H: u32 = 32;
/// Cell colours, row-major from the top-left: distinct, so any flip shows.
const CELLS: [[f32; 3]; 8] = [
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
    [1.0, 1.0, 0.0],
    [1.0, 0.0, 1.0],
    [0.0, 1.0, 1.0],
    [1.0, 1.0, 1.0],
    [1.0, 0.5, 0.0],
];

fn cell(col: usize, row: usize) -> Color {
    Color::from_array(CELLS[row * 4 + col])
}

/// Whether texel `(x, y)` of the test image is part of the "F" (top-left cell only).
fn in_f(x: u32, y: u32) -> bool {
    let (vertical, top, middle) = (
        (3..6).contains(&x) && (3..13).contains(&y),
        (3..13).contains(&x) && (3..6).contains(&y),
        (3..10).contains(&x) && (7..9).contains(&y),
    );
    vertical || top || middle
}

fn test_map() -> Arc<ImageMap> {
    Arc::new(ImageMap::from_fn(
        W,
        H,
        |x, y| {
            if in_f(x, y) { Color::ZERO } else { cell(x as usize / 16, y as usize / 16) }
        },
    ))
}

/// A scene with the camera on +z looking at the origin, vertical field of view 90°
/// (the image plane spans y in [-1, 1] at distance 1), lit only by ambient 1.
fn scene(distance: f32) -> (Scene, MaterialId) {
    let mut s = Scene::new(Camera::new(Vec3::new(0.0, 0.0, distance), Vec3::ZERO, Vec3::Y, 90.0, W, H));
    s.settings.background = Color::splat(0.15);
    s.settings.ambient = 1.0;
    let m = s.add_material(Material { diffuse: 0.0, specular: 0.0, ..Material::default() }.with_texture(test_map()));
    (s, m)
}

trait WithTexture {
    fn with_texture(self, map: Arc<ImageMap>) -> Material;
}

impl WithTexture for Material {
    fn with_texture(mut self, map: Arc<ImageMap>) -> Material {
        self.texture = Texture::image(map);
        self
    }
}

fn render(s: &Scene) -> Image {
    Renderer::new(s).unwrap().render()
}

fn close(a: Color, b: Color) -> bool {
    (a - b).abs().max_element() < 2e-3
}

/// A card filling the frame must show the image texel for texel (pixel centres fall
/// on texel centres, where bilinear sampling is exact).
fn assert_is_the_image(img: &Image, what: &str) {
    let map = test_map();
    for y in 0..H {
        for x in 0..W {
            assert!(
                close(img.pixel(x, y), map.texel(x, y)),
                "{what}: pixel ({x}, {y}) is {} not {}",
                img.pixel(x, y),
                map.texel(x, y)
            );
        }
    }
}

/// Which cell's colour pixel `(x, y)` shows, if any.
fn cell_at(img: &Image, x: u32, y: u32) -> Option<(usize, usize)> {
    (0..8).map(|i| (i % 4, i / 4)).find(|&(c, r)| close(img.pixel(x, y), cell(c, r)))
}

/// A quad with its corner at the bottom-left and `edge_v` up shows the image upright.
fn quad() -> Image {
    let (mut s, m) = scene(1.0);
    s.add(Quad::new(Vec3::new(-2.0, -1.0, 0.0), Vec3::new(4.0, 0.0, 0.0), Vec3::new(0.0, 2.0, 0.0)), m);
    render(&s)
}

/// A unit sphere: the image's centre faces +z, its top at +y.
fn sphere() -> Image {
    let (mut s, m) = scene(3.0);
    s.add(Sphere::new(Vec3::ZERO, 1.0), m);
    render(&s)
}

/// An upright cylinder from y = -1 to 1: the image's top at the top end.
fn cylinder() -> Image {
    let (mut s, m) = scene(3.0);
    s.add(Cylinder::new(Vec3::new(0.0, -1.0, 0.0), Vec3::Y, 1.0, 2.0, false), m);
    render(&s)
}

/// An OBJ card with standard texture coordinates (v = 0 at the bottom of the image).
fn obj_card() -> Image {
    let (mut s, m) = scene(1.0);
    let obj = "v -2 -1 0\nv 2 -1 0\nv 2 1 0\nv -2 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n";
    let mesh = whitted::scene::obj::read_obj(obj.as_bytes(), "card.obj", false).unwrap();
    s.add(mesh, m);
    render(&s)
}

/// The pixel that sees the point `p` from a camera at `(0, 0, d)` (fov 90°, W x H).
fn pixel_of(p: Vec3, d: f32) -> (u32, u32) {
    let (sx, sy) = (p.x / (d - p.z), p.y / (d - p.z)); // on the plane at distance 1
    let px = (sx + W as f32 / H as f32) * H as f32 / 2.0;
    let py = (1.0 - sy) * H as f32 / 2.0;
    (px as u32, py as u32)
}

#[test]
fn an_image_lies_upright_on_a_quad_and_an_obj_card() {
    assert_is_the_image(&quad(), "quad");
    assert_is_the_image(&obj_card(), "OBJ card");
}

#[test]
fn an_image_wraps_a_sphere_upright_and_unmirrored() {
    let img = sphere();
    // In front, left of centre: column 1 (u just below 0.5); right: column 2. Above the
    // equator row 0, below it row 1.
    let at = |x: f32, y: f32| {
        let p = Vec3::new(x, y, (1.0 - x * x - y * y).sqrt());
        let (px, py) = pixel_of(p, 3.0);
        cell_at(&img, px, py)
    };
    assert_eq!(at(-0.3, 0.3), Some((1, 0)));
    assert_eq!(at(0.3, 0.3), Some((2, 0)));
    assert_eq!(at(-0.3, -0.3), Some((1, 1)));
    assert_eq!(at(0.3, -0.3), Some((2, 1)));
}

#[test]
fn an_image_wraps_a_cylinder_upright_and_unmirrored() {
    let img = cylinder();
    // u = 0 at +x, increasing counter-clockwise seen from the top: +z is u = 0.75, so
    // from the front the left of centre is column 2 and the right column 3.
    let at = |x: f32, y: f32| {
        let p = Vec3::new(x, y, (1.0 - x * x).sqrt());
        let (px, py) = pixel_of(p, 3.0);
        cell_at(&img, px, py)
    };
    assert_eq!(at(-0.3, 0.5), Some((2, 0)));
    assert_eq!(at(0.3, 0.5), Some((3, 0)));
    assert_eq!(at(-0.3, -0.5), Some((2, 1)));
    assert_eq!(at(0.3, -0.5), Some((3, 1)));
}

/// Saves the four views side by side, three times the size and the round shapes seen
/// from closer, for a look (docs/orientation.png is this picture).
#[test]
fn save_the_renders_to_look_at() {
    let (w, h) = (W * 3, H * 3);
    let big = |mut s: Scene, d: f32| {
        s.camera.position = Vec3::new(0.0, 0.0, d);
        Renderer::new(&s).unwrap().size(w, h).render()
    };
    let with = |shape: Shape, d: f32| {
        let (mut s, m) = scene(d);
        s.add(shape, m);
        big(s, d)
    };
    let card = whitted::scene::obj::read_obj(
        "v -2 -1 0\nv 2 -1 0\nv 2 1 0\nv -2 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n".as_bytes(),
        "card.obj",
        false,
    )
    .unwrap();
    let images = [
        with(Quad::new(Vec3::new(-2.0, -1.0, 0.0), Vec3::new(4.0, 0.0, 0.0), Vec3::new(0.0, 2.0, 0.0)).into(), 1.0),
        with(Sphere::new(Vec3::ZERO, 1.0).into(), 1.8),
        with(Cylinder::new(Vec3::new(0.0, -1.0, 0.0), Vec3::Y, 1.0, 2.0, false).into(), 2.4),
        with(card.into(), 1.0),
    ];
    let mut strip = Image::new(w * 4 + 3 * 6, h);
    for (i, img) in images.iter().enumerate() {
        for y in 0..h {
            for x in 0..w {
                strip.set(i as u32 * (w + 6) + x, y, img.pixel(x, y));
            }
        }
    }
    let path = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("orientation.png");
    whitted::film::write_png(&strip, &path).unwrap();
}
