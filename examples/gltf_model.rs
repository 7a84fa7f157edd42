//! Writes `scenes/model.glb`, the glTF 2.0 still life of the README's gallery: a copper
//! torus (metallic), a glass ball (KHR_materials_transmission and KHR_materials_ior), a
//! bumpy red ball without normals (Whitted computes them), a floor, a node tree with
//! transforms, a perspective camera, and a spot and a directional light
//! (KHR_lights_punctual). Everything in it is made here.
//!
//! cargo run --example gltf_model -- scenes/model.glb

use serde_json::{Value, json};
use std::f32::consts::TAU;

/// A glTF document's binary buffer, its views and accessors.
#[derive(Default)]
struct Buffer {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Buffer {
    fn push(&mut self, bytes: Vec<u8>, accessor: Value) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.views.push(json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()}));
        self.bin.extend(bytes);
        let mut a = accessor;
        a["bufferView"] = json!(self.views.len() - 1);
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    fn vec3s(&mut self, data: &[[f32; 3]]) -> usize {
        let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
        for p in data {
            for k in 0..3 {
                (lo[k], hi[k]) = (lo[k].min(p[k]), hi[k].max(p[k]));
            }
        }
        let bytes = data.iter().flatten().flat_map(|f| f.to_le_bytes()).collect();
        self.push(bytes, json!({"componentType": 5126, "count": data.len(), "type": "VEC3", "min": lo, "max": hi}))
    }

    fn indices(&mut self, tris: &[[u32; 3]]) -> usize {
        let bytes = tris.iter().flatten().flat_map(|i| i.to_le_bytes()).collect();
        self.push(bytes, json!({"componentType": 5125, "count": tris.len() * 3, "type": "SCALAR"}))
    }

    /// A primitive of `material` from positions, optional normals and triangles.
    fn primitive(&mut self, p: &[[f32; 3]], n: Option<&[[f32; 3]]>, t: &[[u32; 3]], material: usize) -> Value {
        let mut attributes = json!({"POSITION": self.vec3s(p)});
        if let Some(n) = n {
            attributes["NORMAL"] = json!(self.vec3s(n));
        }
        json!({"attributes": attributes, "indices": self.indices(t), "material": material})
    }
}

/// A grid of `nu` x `nv` quads over a surface `f(u, v) -> (point, normal)`, u and v in
/// [0, 1], wrapping in both directions.
#[allow(clippy::type_complexity)]
fn wrapped(
    nu: u32,
    nv: u32,
    f: impl Fn(f32, f32) -> ([f32; 3], [f32; 3]),
) -> (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let (mut p, mut n, mut t) = (Vec::new(), Vec::new(), Vec::new());
    for j in 0..=nv {
        for i in 0..=nu {
            let (a, b) = f(i as f32 / nu as f32, j as f32 / nv as f32);
            p.push(a);
            n.push(b);
        }
    }
    let at = |i: u32, j: u32| j * (nu + 1) + i;
    for j in 0..nv {
        for i in 0..nu {
            t.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            t.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    (p, n, t)
}

fn main() {
    let out = std::env::args().nth(1).unwrap_or_else(|| "scenes/model.glb".into());
    let mut b = Buffer::default();
    // A torus about the y axis (radius 1, tube 0.35), normals outward.
    let (tp, tn, tt) = wrapped(64, 24, |u, v| {
        let (a, c) = (u * TAU, v * TAU);
        let (sa, ca, sc, cc) = (a.sin(), a.cos(), c.sin(), c.cos());
        let r = 1.0 + 0.35 * cc;
        ([r * ca, 0.35 * sc, -r * sa], [cc * ca, sc, -cc * sa])
    });
    // A unit sphere (latitude-longitude), normals outward.
    let (sp, sn, st) = wrapped(48, 24, |u, v| {
        let (a, c) = (u * TAU, (v - 0.5) * TAU / 2.0);
        let d = [c.cos() * a.cos(), c.sin(), -c.cos() * a.sin()];
        (d, d)
    });
    let bumpy = whitted::scene::generate::cube_sphere(16);
    let bp: Vec<[f32; 3]> = bumpy.positions().iter().map(|p| p.to_array()).collect();
    let floor = [[-6.0, 0.0, 6.0], [6.0, 0.0, 6.0], [6.0, 0.0, -6.0], [-6.0, 0.0, -6.0]];
    let meshes = json!([
        {"name": "torus", "primitives": [b.primitive(&tp, Some(&tn), &tt, 0)]},
        {"name": "glass ball", "primitives": [b.primitive(&sp, Some(&sn), &st, 1)]},
        {"name": "bumpy ball", "primitives": [b.primitive(&bp, None, bumpy.triangles(), 2)]},
        {"name": "floor", "primitives": [b.primitive(&floor, Some(&[[0.0, 1.0, 0.0]; 4]), &[[0, 1, 2], [0, 2, 3]], 3)]},
    ]);
    let materials = json!([
        {"name": "copper", "pbrMetallicRoughness": {"baseColorFactor": [0.95, 0.55, 0.3, 1.0], "metallicFactor": 0.6, "roughnessFactor": 0.2}},
        {"name": "glass", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.95, 1.0, 1.0], "metallicFactor": 0.0},
         "extensions": {"KHR_materials_transmission": {"transmissionFactor": 0.85}, "KHR_materials_ior": {"ior": 1.5}}},
        {"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.12, 0.1, 1.0], "metallicFactor": 0.0}},
        {"name": "floor", "pbrMetallicRoughness": {"baseColorFactor": [0.55, 0.55, 0.5, 1.0], "metallicFactor": 0.1}},
    ]);
    // A node tree: the still life's root lifts and turns its children; the camera and
    // lights hang from the scene root. Rotations are unit quaternions (x, y, z, w).
    // About x or y by `deg` degrees.
    let qx = |deg: f32| [(deg.to_radians() / 2.0).sin(), 0.0, 0.0, (deg.to_radians() / 2.0).cos()];
    let qy = |deg: f32| [0.0, (deg.to_radians() / 2.0).sin(), 0.0, (deg.to_radians() / 2.0).cos()];
    let nodes = json!([
        {"name": "still life", "children": [1, 2, 3], "rotation": qy(30.0)},
        {"name": "torus", "mesh": 0, "translation": [-1.3, 0.55, 0.0], "rotation": qx(35.0)},
        {"name": "glass ball", "mesh": 1, "translation": [0.9, 0.8, 0.6], "scale": [0.8, 0.8, 0.8]},
        {"name": "bumpy ball", "mesh": 2, "translation": [0.6, 0.7, -1.6], "scale": [0.7, 0.7, 0.7]},
        {"name": "floor", "mesh": 3},
        {"name": "camera", "camera": 0, "translation": [0.0, 2.6, 6.5], "rotation": qx(-18.0)},
        {"name": "spot", "extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [-2.0, 5.0, 3.0],
         "rotation": qx(-60.0)},
        {"name": "sun", "extensions": {"KHR_lights_punctual": {"light": 1}}, "rotation": qx(-35.0)},
    ]);
    let doc = json!({
        "asset": {"version": "2.0", "generator": "whitted examples/gltf_model.rs"},
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_transmission", "KHR_materials_ior"],
        "scene": 0,
        "scenes": [{"nodes": [0, 4, 5, 6, 7]}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.7, "aspectRatio": 1.6, "znear": 0.05}}],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "spot", "color": [1.0, 0.95, 0.85], "intensity": 1.0, "spot": {"innerConeAngle": 0.35, "outerConeAngle": 0.6}},
            {"type": "directional", "color": [0.5, 0.55, 0.7], "intensity": 1.0}
        ]}},
        "buffers": [{"byteLength": b.bin.len()}],
        "bufferViews": b.views,
        "accessors": b.accessors,
    });
    let mut json = serde_json::to_vec(&doc).expect("JSON");
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin = b.bin;
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut glb = Vec::with_capacity(total);
    glb.extend_from_slice(b"glTF");
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&(total as u32).to_le_bytes());
    glb.extend_from_slice(&(json.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"JSON");
    glb.extend(json);
    glb.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"BIN\0");
    glb.extend(bin);
    std::fs::write(&out, glb).expect("written");
    println!("wrote {out}");
}
