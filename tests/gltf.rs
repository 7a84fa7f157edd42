//! glTF 2.0 in: files the tests write themselves (a textured card, a node tree, a
//! camera, lights, a .glb), rendered and checked against expected pixels, and broken
//! files, which must fail with the file and the part named, exit 1 and no output.

mod common;

use common::whitted;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use whitted::film::{ColorEncoding, Image};
use whitted::prelude::*;
use whitted::scene::{self, Format, Loaded};

/// Builds a glTF document and its binary buffer.
#[derive(Default)]
struct Builder {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Builder {
    fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.views.push(json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()}));
        self.bin.extend_from_slice(bytes);
        self.views.len() - 1
    }

    fn floats(&mut self, data: &[f32], width: usize) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|f| f.to_le_bytes()).collect();
        let view = self.view(&bytes);
        let kind = ["", "SCALAR", "VEC2", "VEC3"][width];
        let mut a = json!({"bufferView": view, "componentType": 5126, "count": data.len() / width, "type": kind});
        if width == 3 {
            let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
            for p in data.chunks(3) {
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
            a["min"] = json!(lo);
            a["max"] = json!(hi);
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    fn indices(&mut self, data: &[u16]) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&bytes);
        self.accessors.push(json!({"bufferView": view, "componentType": 5123, "count": data.len(), "type": "SCALAR"}));
        self.accessors.len() - 1
    }

    /// A rectangle in the z = 0 plane from (x0, y0) to (x1, y1), facing +z, with glTF
    /// texture coordinates (v down: the top-left corner is (0, 0)). The primitive.
    fn card(&mut self, x0: f32, y0: f32, x1: f32, y1: f32, material: usize) -> Value {
        let p = self.floats(&[x0, y0, 0.0, x1, y0, 0.0, x1, y1, 0.0, x0, y1, 0.0], 3);
        let n = self.floats(&[0.0, 0.0, 1.0].repeat(4), 3);
        let t = self.floats(&[0.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0], 2);
        let i = self.indices(&[0, 1, 2, 0, 2, 3]);
        json!({"attributes": {"POSITION": p, "NORMAL": n, "TEXCOORD_0": t}, "indices": i, "material": material})
    }

    /// The document, its buffer given by `uri` (or the GLB chunk when `None`).
    fn document(&self, mut doc: Value, uri: Option<&str>) -> Value {
        let mut buffer = json!({"byteLength": self.bin.len()});
        if let Some(u) = uri {
            buffer["uri"] = json!(u);
        }
        doc["asset"] = json!({"version": "2.0"});
        doc["buffers"] = json!([buffer]);
        doc["bufferViews"] = json!(self.views);
        doc["accessors"] = json!(self.accessors);
        doc
    }
}

fn base64(data: &[u8]) -> String {
    const A: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in data.chunks(3) {
        let n = (c[0] as u32) << 16 | (*c.get(1).unwrap_or(&0) as u32) << 8 | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// A binary glTF: header, JSON chunk (padded with spaces), BIN chunk (padded with zeros).
fn glb(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut json = serde_json::to_vec(doc).unwrap();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

/// The test picture: four columns by two rows of distinct colours, as 8-bit sRGB.
const CELLS: [[u8; 3]; 8] = [
    [255, 0, 0],
    [0, 255, 0],
    [0, 0, 255],
    [255, 255, 0],
    [255, 0, 255],
    [0, 255, 255],
    [255, 255, 255],
    [255, 128, 0],
];

fn cell_png() -> Vec<u8> {
    let img = image::RgbImage::from_fn(64, 32, |x, y| image::Rgb(CELLS[(y / 16 * 4 + x / 16) as usize]));
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

/// A perspective camera node at (0, 0, d) looking down -z, vertical fov 90°, aspect 2.
fn camera_doc(d: f32) -> (Value, Value) {
    (
        json!([{"type": "perspective", "perspective": {"yfov": std::f32::consts::FRAC_PI_2, "aspectRatio": 2.0, "znear": 0.01}}]),
        json!({"camera": 0, "translation": [0.0, 0.0, d]}),
    )
}

/// The textured card filling a 90° view from distance 1, with a camera: `(doc, bin)`,
/// the image given by `image` (a uri or embedded through a buffer view).
fn card_doc(embedded_image: bool) -> (Value, Vec<u8>) {
    let mut b = Builder::default();
    let prim = b.card(-2.0, -1.0, 2.0, 1.0, 0);
    let image = if embedded_image {
        let png = cell_png();
        let view = b.view(&png);
        json!({"bufferView": view, "mimeType": "image/png"})
    } else {
        json!({"uri": "cells.png"})
    };
    let (cameras, cam_node) = camera_doc(1.0);
    let doc = json!({
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0}, cam_node],
        "meshes": [{"primitives": [prim]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0}}],
        "textures": [{"source": 0}],
        "images": [image],
        "cameras": cameras,
    });
    (b.document(doc, None), b.bin)
}

fn write_gltf(dir: &Path, name: &str, doc: &Value) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, serde_json::to_vec_pretty(doc).unwrap()).unwrap();
    p
}

fn load(p: &Path) -> Loaded {
    scene::load_path(p, Format::of_path(p)).unwrap_or_else(|e| panic!("{e}"))
}

/// Renders with the lights off and ambient 1: a pixel is its surface's colour.
fn flat_render(mut s: Scene) -> Image {
    s.lights.clear();
    s.settings.ambient = 1.0;
    for m in &mut s.materials {
        (m.diffuse, m.specular) = (0.0, 0.0);
    }
    Renderer::new(&s).unwrap().size(64, 32).render()
}

/// The render, sRGB-encoded, is the texture: texel centres fall on pixel centres.
fn assert_shows_the_cells(img: &Image, what: &str) {
    let rgb = img.to_rgb8_as(ColorEncoding::Srgb);
    for (x, y, p) in rgb.enumerate_pixels() {
        let want = CELLS[(y / 16 * 4 + x / 16) as usize];
        assert!(p.0.iter().zip(want).all(|(a, b)| a.abs_diff(b) <= 1), "{what}: ({x}, {y}) is {:?}, not {want:?}", p.0);
    }
}

#[test]
fn a_textured_card_with_a_camera_renders_upright_from_gltf_and_glb() {
    let dir = tempfile::tempdir().unwrap();
    // .gltf with a .bin and a .png beside it.
    let (doc, bin) = card_doc(false);
    std::fs::write(dir.path().join("card.bin"), &bin).unwrap();
    std::fs::write(dir.path().join("cells.png"), cell_png()).unwrap();
    let mut with_uri = doc.clone();
    with_uri["buffers"][0]["uri"] = json!("card.bin");
    let loaded = load(&write_gltf(dir.path(), "card.gltf", &with_uri));
    assert_eq!(loaded.scene.settings.color, ColorEncoding::Srgb, "glTF scenes are written sRGB");
    let cam = loaded.scene.camera;
    assert_eq!((cam.position, cam.fov.round(), cam.width, cam.height), (Vec3::new(0.0, 0.0, 1.0), 90.0, 1200, 600));
    assert!(loaded.notes.iter().any(|n| n.contains("no lights")), "{:?}", loaded.notes);
    assert_shows_the_cells(&flat_render(loaded.scene), "card.gltf");

    // Everything embedded as base64.
    let (doc, bin) = card_doc(true);
    let mut embedded = doc.clone();
    embedded["buffers"][0]["uri"] = json!(format!("data:application/octet-stream;base64,{}", base64(&bin)));
    let loaded = load(&write_gltf(dir.path(), "embedded.gltf", &embedded));
    assert_shows_the_cells(&flat_render(loaded.scene), "embedded.gltf");

    // Binary glTF.
    let path = dir.path().join("card.glb");
    std::fs::write(&path, glb(&doc, &bin)).unwrap();
    let loaded = load(&path);
    assert_shows_the_cells(&flat_render(loaded.scene), "card.glb");

    // And from the command line, lit by the default light, sRGB by default.
    let out = dir.path().join("card.png");
    let o =
        whitted(&["render", path.to_str().unwrap(), "-o", out.to_str().unwrap(), "--width", "64", "--height", "32"]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(stderr.contains("note:") && stderr.contains("over the camera's shoulder"), "{stderr}");
    let img = image::open(&out).unwrap().to_rgb8();
    // Top-left cell red, bottom-right orange: the dominant channels survive the lighting.
    let p = img.get_pixel(8, 8).0;
    assert!(p[0] > 100 && p[1] < 40 && p[2] < 40, "{p:?}");
    let p = img.get_pixel(56, 24).0;
    assert!(p[0] > 100 && p[1] > 30 && p[1] < p[0] && p[2] < 40, "{p:?}");
}

#[test]
fn a_node_tree_places_its_meshes_by_the_product_of_transforms() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Builder::default();
    // A unit card from (0, 0) to (1, 1), red, and a green one.
    let red = b.card(0.0, 0.0, 1.0, 1.0, 0);
    let green = b.card(0.0, 0.0, 1.0, 1.0, 1);
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let doc = json!({
        "scenes": [{"nodes": [0, 3]}],
        "nodes": [
            // Parent: moved by (-3, 0, 0) and scaled 2: its child turned 90° about z
            // (quaternion [0, 0, sin 45°, cos 45°]) and moved 1 along the parent's x.
            {"translation": [-3.0, 0.0, 0.0], "scale": [2.0, 2.0, 2.0], "children": [1]},
            {"rotation": [0.0, 0.0, s, s], "translation": [1.0, 0.0, 0.0], "children": [2]},
            {"mesh": 0},
            // A matrix node: the green card moved to (2, -1).
            {"matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 2,-1,0,1], "mesh": 1},
        ],
        "meshes": [{"primitives": [red]}, {"primitives": [green]}],
        "materials": [
            {"pbrMetallicRoughness": {"baseColorFactor": [1, 0, 0, 1], "metallicFactor": 0}},
            {"pbrMetallicRoughness": {"baseColorFactor": [0, 1, 0, 1], "metallicFactor": 0}},
        ],
    });
    let doc = b.document(doc, Some(&format!("data:application/octet-stream;base64,{}", base64(&b.bin))));
    let loaded = load(&write_gltf(dir.path(), "tree.gltf", &doc));
    let s = &loaded.scene;
    assert_eq!(s.objects.len(), 2);
    let whitted::geometry::Shape::Mesh(m) = &s.objects[0].shape else { panic!("not a mesh") };
    // Corner (1, 0) turned to (0, 1), moved to (1, 1), scaled to (2, 2), moved to (-1, 2).
    let want =
        [Vec3::new(-1.0, 0.0, 0.0), Vec3::new(-1.0, 2.0, 0.0), Vec3::new(-3.0, 2.0, 0.0), Vec3::new(-3.0, 0.0, 0.0)];
    for (p, w) in m.positions().iter().zip(want) {
        assert!((*p - w).length() < 1e-5, "{p} vs {w}");
    }
    // No camera: the default view frames both; render it flat and find the two colours
    // where they should be: red on the left (x from -3 to -1), green on the right.
    assert!(loaded.notes.iter().any(|n| n.contains("no camera")), "{:?}", loaded.notes);
    let mut s = loaded.scene.clone();
    s.camera = Camera::new(Vec3::new(0.0, 0.5, 10.0), Vec3::new(0.0, 0.5, 0.0), Vec3::Y, 30.0, 64, 32);
    let img = flat_render(s);
    let px = |x: f32, y: f32| {
        // The plane z = 0 seen from z = 10 with a 30° vertical view: half-height 10 tan 15°.
        let half = 10.0 * (15f32.to_radians()).tan();
        let (u, v) = ((x / (2.0 * half) + 1.0) * 32.0, (1.0 - (y - 0.5) / half) * 16.0);
        img.pixel(u as u32, v as u32)
    };
    assert_eq!(px(-2.0, 1.0), Color::new(1.0, 0.0, 0.0));
    assert_eq!(px(2.5, -0.5), Color::new(0.0, 1.0, 0.0));
    assert_eq!(px(0.0, 0.5), Color::ZERO, "nothing between them");
    assert_eq!(px(2.5, 0.5), Color::ZERO, "the green card is below y = 0");
}

#[test]
fn camera_lights_and_materials_map_and_the_rest_is_warned_about_once() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Builder::default();
    let prims: Vec<Value> = (0..3).map(|m| b.card(-1.0, -1.0, 1.0, 1.0, m)).collect();
    let turn = std::f32::consts::FRAC_1_SQRT_2; // 90° about y: looking down -x
    let doc = json!({
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_transmission", "KHR_materials_ior", "KHR_texture_transform"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "point", "color": [1, 0.5, 0.25], "intensity": 100},
            {"type": "point", "intensity": 50},
            {"type": "spot", "spot": {}},
            {"type": "spot", "spot": {}},
            {"type": "directional"},
        ]}},
        "scenes": [{"nodes": [0, 1, 2, 3, 4, 5, 6, 7]}],
        "nodes": [
            {"mesh": 0},
            {"camera": 0, "translation": [5, 1, 0], "rotation": [0, turn, 0, turn]},
            {"extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [0, 10, 0]},
            {"extensions": {"KHR_lights_punctual": {"light": 1}}, "translation": [0, 0, 10]},
            {"extensions": {"KHR_lights_punctual": {"light": 2}}},
            {"extensions": {"KHR_lights_punctual": {"light": 3}}},
            {"extensions": {"KHR_lights_punctual": {"light": 4}}},
            {"mesh": 1, "translation": [0, 0, -3]},
        ],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.1}}],
        "meshes": [{"primitives": [prims[0]]}, {"primitives": [prims[1], prims[2]]}],
        "materials": [
            {"pbrMetallicRoughness": {"metallicFactor": 0.6, "roughnessFactor": 0.3}, "normalTexture": {"index": 0}},
            {"pbrMetallicRoughness": {"metallicFactor": 0},
             "extensions": {"KHR_materials_transmission": {"transmissionFactor": 0.8}, "KHR_materials_ior": {"ior": 1.33}}},
            {"pbrMetallicRoughness": {"metallicFactor": 0}, "emissiveFactor": [1, 1, 1]},
        ],
        "textures": [{"source": 0}],
        "images": [{"uri": "cells.png"}],
    });
    std::fs::write(dir.path().join("cells.png"), cell_png()).unwrap();
    let doc = b.document(doc, Some(&format!("data:application/octet-stream;base64,{}", base64(&b.bin))));
    let loaded = load(&write_gltf(dir.path(), "kit.gltf", &doc));
    let s = &loaded.scene;
    // The camera: at (5, 1, 0), its -z turned to -x, 0.5 rad = 28.6°, no aspect: 800 x 600.
    assert!((s.camera.position - Vec3::new(5.0, 1.0, 0.0)).length() < 1e-5);
    assert!((s.camera.look_at - Vec3::new(4.0, 1.0, 0.0)).length() < 1e-5, "{}", s.camera.look_at);
    assert!((s.camera.fov - 0.5f32.to_degrees()).abs() < 1e-3);
    assert_eq!((s.camera.width, s.camera.height), (800, 600));
    // Two point lights, the brightest at 1, the other at half; two spots with glTF's
    // default cone (0 to 45 degrees) and a directional light, all down their node's -z
    // (intensity 1 of 100).
    assert_eq!(s.lights.len(), 5);
    assert_eq!(
        (s.lights[0].position(), s.lights[0].color()),
        (Some(Vec3::new(0.0, 10.0, 0.0)), Color::new(1.0, 0.5, 0.25))
    );
    assert_eq!((s.lights[1].position(), s.lights[1].color()), (Some(Vec3::new(0.0, 0.0, 10.0)), Color::splat(0.5)));
    match s.lights[2] {
        Light::Spot(spot) => {
            assert_eq!((spot.position, spot.direction), (Vec3::ZERO, Vec3::NEG_Z));
            assert!(
                (spot.inner_angle, spot.outer_angle) == (0.0, 45.0) && spot.color == Color::splat(0.01),
                "{spot:?}"
            );
        }
        ref other => panic!("{other:?}"),
    }
    assert!(matches!(s.lights[4], Light::Directional(d) if d.direction == Vec3::NEG_Z), "{:?}", s.lights[4]);
    // Materials.
    let mat = |i: usize| s.material(s.objects[i].material);
    assert_eq!(mat(0).reflectivity, 0.6);
    assert_eq!((mat(1).transparency, mat(1).ior), (0.8, 1.33));
    assert_eq!(mat(2).transparency, 0.0);
    // One warning per kind, never fatal.
    let w = loaded.warnings.join("\n");
    for kind in ["normal maps", "emission", "roughness", "KHR_texture_transform"] {
        assert_eq!(w.matches(kind).count(), 1, "{kind} in:\n{w}");
    }
    assert!(loaded.notes.is_empty(), "it has a camera and lights: {:?}", loaded.notes);
    // The cards face +z, edge-on to the file's camera: seen from the front, the
    // metallic one is lit.
    let mut front = s.clone();
    front.camera = Camera::new(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 40.0, 16, 16);
    let img = Renderer::new(&front).unwrap().render();
    assert!(img.pixel(8, 8).max_element() > 0.2, "{}", img.pixel(8, 8));
}

#[test]
fn a_gltf_asset_is_placed_in_a_toml_scene() {
    let dir = tempfile::tempdir().unwrap();
    let (doc, bin) = card_doc(true);
    std::fs::write(dir.path().join("card.glb"), glb(&doc, &bin)).unwrap();
    let toml = dir.path().join("scene.toml");
    std::fs::write(
        &toml,
        "[camera]\nposition = [10, 0, 1]\nlook_at = [10, 0, 0]\nfov = 90\nwidth = 64\nheight = 32\n\
         [[gltf]]\nfile = \"card.glb\"\ntransform = { translate = [10, 0, 0] }\n",
    )
    .unwrap();
    let loaded = load(&toml);
    assert_eq!(loaded.scene.camera.position, Vec3::new(10.0, 0.0, 1.0), "the scene's camera, not the asset's");
    assert_shows_the_cells(&flat_render(loaded.scene), "placed card");
    // A missing asset is reported at the line that names it.
    std::fs::write(
        &toml,
        "[camera]\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\nfov = 90\n[[gltf]]\nfile = \"nope.glb\"\n",
    )
    .unwrap();
    let e = scene::load_path(&toml, Format::Toml).unwrap_err().to_string();
    assert!(e.contains("scene.toml:6:") && e.contains("nope.glb"), "{e}");
}

#[test]
fn an_obj_renders_directly_in_a_default_view() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("tetra.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n").unwrap();
    let out = dir.path().join("tetra.png");
    let o = whitted(&["render", obj.to_str().unwrap(), "-o", out.to_str().unwrap(), "--width", "40", "--height", "30"]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(stderr.contains("note:") && stderr.contains("no camera") && stderr.contains("no lights"), "{stderr}");
    assert!(!stderr.contains("TOML"), "{stderr}");
    let img = image::open(&out).unwrap().to_rgb8();
    // The model is in the middle and lit; the corners are background.
    assert!(img.get_pixel(20, 15).0.iter().any(|&c| c > 60), "{:?}", img.get_pixel(20, 15));
    assert_eq!(img.get_pixel(0, 0).0, [0, 0, 0]);
    assert_eq!(img.get_pixel(39, 29).0, [0, 0, 0]);
}

/// One broken file: what to change, and what the message must name.
struct Bad {
    name: &'static str,
    file: Vec<u8>,
    part: &'static str,
}

fn bad_files(dir: &Path) -> Vec<Bad> {
    let (doc, bin) = card_doc(true);
    let b64 = |bin: &[u8]| json!(format!("data:application/octet-stream;base64,{}", base64(bin)));
    let with = |f: &dyn Fn(&mut Value)| {
        let mut d = doc.clone();
        d["buffers"][0]["uri"] = b64(&bin);
        f(&mut d);
        serde_json::to_vec_pretty(&d).unwrap()
    };
    let good = with(&|_| {});
    let good_glb = glb(&doc, &bin);
    std::fs::write(dir.join("short.bin"), &bin[..20]).unwrap();
    vec![
        Bad { name: "truncated.gltf", file: good[..good.len() / 2].to_vec(), part: "not valid glTF JSON" },
        Bad { name: "truncated.glb", file: good_glb[..good_glb.len() - 100].to_vec(), part: "binary glTF" },
        Bad { name: "garbage.glb", file: b"glTF\x07\0\0\0 this is not a glb".to_vec(), part: "binary glTF" },
        Bad {
            name: "bad-accessor.gltf",
            file: with(&|d| d["accessors"][0]["bufferView"] = json!(42)),
            part: "accessors[0].bufferView",
        },
        Bad {
            name: "accessor-overrun.gltf",
            file: with(&|d| d["accessors"][0]["count"] = json!(1000)),
            part: "meshes[0].primitives[0].attributes.POSITION (accessors[0])",
        },
        Bad {
            name: "index-out-of-range.gltf",
            file: {
                // Indices 0 1 2 0 2 3 become 0 1 2 0 2 9.
                let mut bin = bin.clone();
                let view = doc["bufferViews"][3]["byteOffset"].as_u64().unwrap() as usize;
                bin[view + 10] = 9;
                let mut d = doc.clone();
                d["buffers"][0]["uri"] = b64(&bin);
                serde_json::to_vec(&d).unwrap()
            },
            part: "meshes[0].primitives[0].indices: index 5 is 9, but there are 4 vertices",
        },
        Bad {
            // The `gltf` crate's own check of this indexes past the accessors (a panic).
            name: "position-out-of-range.gltf",
            file: with(&|d| d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(17)),
            part: "meshes[0].primitives[0].attributes.POSITION: accessor 17 does not exist",
        },
        Bad {
            name: "missing-buffer.gltf",
            file: with(&|d| d["buffers"][0]["uri"] = json!("nowhere.bin")),
            part: "buffers[0] (nowhere.bin): cannot read",
        },
        Bad {
            name: "bad-base64.gltf",
            file: with(&|d| d["buffers"][0]["uri"] = json!("data:application/octet-stream;base64,@@not base64@@")),
            part: "buffers[0]: bad base64",
        },
        Bad {
            name: "short-buffer.gltf",
            file: with(&|d| d["buffers"][0]["uri"] = json!("short.bin")),
            part: "buffers[0] (short.bin): 20 bytes, but byteLength says",
        },
        Bad {
            name: "bad-image.gltf",
            file: with(&|d| d["images"][0] = json!({"uri": "data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAA"})),
            part: "images[0]",
        },
        Bad {
            name: "wrong-type.gltf",
            file: with(&|d| d["accessors"][0]["type"] = json!("VEC2")),
            part: "attributes.POSITION (accessors[0]): is Vec2 of F32, expected VEC3",
        },
        Bad {
            name: "node-cycle.gltf",
            file: with(&|d| d["nodes"][0]["children"] = json!([1, 0])),
            part: "nodes[0]: reached twice",
        },
        Bad {
            name: "no-asset.gltf",
            file: with(&|d| {
                d.as_object_mut().unwrap().remove("asset");
            }),
            part: "asset",
        },
    ]
}

#[test]
fn broken_gltf_files_fail_naming_the_file_and_the_part_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let mut failures = Vec::new();
    let bad = bad_files(dir.path());
    assert!(bad.len() >= 8);
    for b in bad {
        let path = dir.path().join(b.name);
        std::fs::write(&path, &b.file).unwrap();
        let out = dir.path().join("out.png");
        let o = whitted(&["render", path.to_str().unwrap(), "-o", out.to_str().unwrap(), "-q"]);
        let stderr = String::from_utf8_lossy(&o.stderr);
        eprintln!("{}", stderr.trim()); // shown with --nocapture
        let ok = o.status.code() == Some(1)
            && stderr.contains(b.name)
            && stderr.contains(b.part)
            && !stderr.contains("panicked")
            && !out.exists();
        if !ok {
            failures.push(format!("{}: status {:?}, output {}: {stderr}", b.name, o.status.code(), out.exists()));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
