//! Reading scene files (TOML). Parsing keeps the byte span of every value, so that any
//! problem found later (a negative radius, an unknown material) is reported with the
//! file, line, column and field at fault. Unknown keys are errors: they are typos.
//!
//! Each table's fields are documented with its shape (`[[cone]]` in
//! [`Cone`](crate::geometry::Cone): `top_radius` and `top_cap` make a truncated cone;
//! `[[mesh]]` in [`Mesh`](crate::geometry::Mesh): an OBJ `file` or inline `positions`,
//! `normals` and `triangles`), the camera in [`crate::camera`], lights in
//! [`crate::light`], materials in [`crate::material`], keyframes (`keys`) in `keys.rs`
//! and [`crate::scene::animation`].

use super::{Animation, MaterialId, Object, Scene, SceneError, Settings};
use crate::camera::{Camera, CameraError};
use crate::film::ColorEncoding;
use crate::geometry::{self, Cone, Cylinder, Mesh, Polygon, Quad, Shape, Sphere, Triangle};
use crate::material::Material;
use crate::math::{Color, Vec2, Vec3};
use crate::texture::{ImageMap, Texture, planet};
use serde::Deserialize;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use toml::Spanned;

mod light;
use light::LightDesc;
mod extra;
mod mesh;
use mesh::MeshDesc;
mod instance;
mod keys;
mod texture;
use instance::InstanceDesc;
use keys::{CameraKey, Keys, LightKey, ObjectKey};

/// The built-in default scene: the seed room. The file in the repository is compiled in,
/// so the two cannot drift apart.
pub const DEFAULT_SCENE: &str = include_str!("../../scenes/room.toml");
/// The name the built-in scene goes by in messages.
pub const DEFAULT_SCENE_NAME: &str = "scenes/room.toml";
/// Largest image side accepted: 16384² RGB floats is already 3 GiB of film.
pub const MAX_RESOLUTION: i64 = 16384;
const MAX_DEPTH: i64 = 1000;
const MAX_SAMPLES: i64 = 65536;

/// Reads and checks a scene file. Relative texture paths are relative to the file. An
/// animated file gives its first frame ([`load_animated_file`] gives all).
pub fn load_file(path: &Path) -> Result<Scene, SceneError> {
    load_animated_file(path).map(|(scene, _, _)| scene)
}

/// A scene file with its animation and the warnings of the files it places (`[[gltf]]`
/// assets): the scene is the first frame of the file's range, and
/// [`Animation::scene_at`] gives the others.
pub fn load_animated_file(path: &Path) -> Result<(Scene, Animation, Vec<String>), SceneError> {
    let name = path.display().to_string();
    let mut bytes = Vec::new();
    std::io::Read::read_to_end(&mut super::limits::open_regular(path, "scene")?, &mut bytes)
        .map_err(|e| SceneError::File { file: name.clone(), message: format!("cannot read the scene: {e}") })?;
    let src = super::limits::utf8(bytes, &name)?;
    let base = path.parent().unwrap_or(Path::new("."));
    load_animated_str(&src, &name, base)
}

/// Parses a scene from text. `name` is used in messages; relative paths in the scene
/// are resolved against `base_dir`. An animated scene gives its first frame.
pub fn load_str(src: &str, name: &str, base_dir: &Path) -> Result<Scene, SceneError> {
    load_animated_str(src, name, base_dir).map(|(scene, _, _)| scene)
}

/// [`load_animated_file`] from text.
pub fn load_animated_str(
    src: &str,
    name: &str,
    base_dir: &Path,
) -> Result<(Scene, Animation, Vec<String>), SceneError> {
    let ctx = Ctx { name, src, base_dir, images: Default::default(), warnings: Default::default() };
    let desc: FileDesc = toml::from_str(src).map_err(|e| ctx.toml_error(&e))?;
    let (scene, animation) = ctx.build(desc)?;
    let scene = if animation.is_static() { scene } else { animation.scene_at(&scene, animation.first)? };
    Ok((scene, animation, ctx.warnings.into_inner()))
}

type V3 = [f32; 3];
type S<T> = Spanned<T>;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileDesc {
    camera: S<CameraDesc>,
    settings: Option<S<SettingsDesc>>,
    #[serde(default)]
    light: Vec<S<LightDesc>>,
    /// In file order, so that materials keep their order through `convert`.
    #[serde(default)]
    material: indexmap::IndexMap<String, S<MaterialDesc>>,
    #[serde(default)]
    sphere: Vec<S<SphereDesc>>,
    #[serde(default)]
    quad: Vec<S<QuadDesc>>,
    #[serde(default)]
    polygon: Vec<S<PolygonDesc>>,
    #[serde(default)]
    cylinder: Vec<S<CylinderDesc>>,
    #[serde(default)]
    cone: Vec<S<ConeDesc>>,
    #[serde(default)]
    triangle: Vec<S<TriangleDesc>>,
    #[serde(default)]
    mesh: Vec<S<MeshDesc>>,
    #[serde(default)]
    gltf: Vec<S<GltfDesc>>,
    #[serde(default)]
    instance: Vec<S<InstanceDesc>>,
}

/// A glTF asset placed in the scene: its meshes, materials and lights (not its cameras).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GltfDesc {
    /// Names the asset for `[[instance]]`.
    name: Option<S<String>>,
    file: S<String>,
    transform: Option<S<TransformDesc>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraDesc {
    position: S<V3>,
    look_at: S<V3>,
    up: Option<S<V3>>,
    fov: S<f32>,
    width: Option<S<i64>>,
    height: Option<S<i64>>,
    /// Keyframes of `position`, `look_at` and `fov` ([`keys`]).
    keys: Keys<CameraKey>,
    interpolation: Option<S<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SettingsDesc {
    background: Option<S<V3>>,
    max_depth: Option<S<i64>>,
    samples: Option<S<i64>>,
    ambient: Option<S<f32>>,
    cutoff: Option<S<f32>>,
    /// `"linear"` (default) or `"srgb"`: how 8- and 16-bit output files encode colour.
    color: Option<S<String>>,
    /// `[first, last]`: the frames an animation is meant to be seen over.
    frames: Option<S<[i64; 2]>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialDesc {
    color: Option<S<V3>>,
    texture: Option<S<TextureDesc>>,
    diffuse: Option<S<f32>>,
    specular: Option<S<f32>>,
    shininess: Option<S<f32>>,
    reflectivity: Option<S<f32>>,
    transparency: Option<S<f32>>,
    ior: Option<S<f32>>,
    fresnel: Option<bool>,
    absorption: Option<S<V3>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TextureDesc {
    kind: S<String>,
    colors: Option<S<[V3; 2]>>,
    axis: Option<S<V3>>,
    width: Option<S<f32>>,
    size: Option<S<f32>>,
    offset: Option<S<Vec<f32>>>,
    scale: Option<S<Vec<f32>>>,
    path: Option<S<String>>,
    seed: Option<S<i64>>,
    resolution: Option<S<[i64; 2]>>,
    /// Image files: `"linear"` (default: values as stored) or `"srgb"` (decoded).
    color_space: Option<S<String>>,
}

/// `material = "name"` or an inline table `material = { color = [1, 0, 0] }`.
enum MaterialRef {
    Named(String),
    Inline(Box<MaterialDesc>),
}

impl<'de> Deserialize<'de> for MaterialRef {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = MaterialRef;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a material name or a table of material fields")
            }
            fn visit_str<E: serde::de::Error>(self, s: &str) -> Result<MaterialRef, E> {
                Ok(MaterialRef::Named(s.to_owned()))
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(self, map: A) -> Result<MaterialRef, A::Error> {
                let desc = MaterialDesc::deserialize(serde::de::value::MapAccessDeserializer::new(map))?;
                Ok(MaterialRef::Inline(Box::new(desc)))
            }
        }
        d.deserialize_any(V)
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SphereDesc {
    center: S<V3>,
    radius: S<f32>,
    material: S<MaterialRef>,
    transform: Option<S<TransformDesc>>,
    keys: Keys<ObjectKey>,
    interpolation: Option<S<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct QuadDesc {
    corner: S<V3>,
    edge_u: S<V3>,
    edge_v: S<V3>,
    material: S<MaterialRef>,
    transform: Option<S<TransformDesc>>,
    keys: Keys<ObjectKey>,
    interpolation: Option<S<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PolygonDesc {
    vertices: S<Vec<V3>>,
    material: S<MaterialRef>,
    transform: Option<S<TransformDesc>>,
    keys: Keys<ObjectKey>,
    interpolation: Option<S<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CylinderDesc {
    base: S<V3>,
    axis: S<V3>,
    radius: S<f32>,
    height: S<f32>,
    caps: Option<bool>,
    material: S<MaterialRef>,
    transform: Option<S<TransformDesc>>,
    keys: Keys<ObjectKey>,
    interpolation: Option<S<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ConeDesc {
    base: S<V3>,
    axis: S<V3>,
    radius: S<f32>,
    /// Radius at the top: 0 (default) for a pointed cone, else a truncated one.
    top_radius: Option<S<f32>>,
    height: S<f32>,
    cap: Option<bool>,
    /// Close the top (default true; only for `top_radius` > 0).
    top_cap: Option<S<bool>>,
    material: S<MaterialRef>,
    transform: Option<S<TransformDesc>>,
    keys: Keys<ObjectKey>,
    interpolation: Option<S<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TransformDesc {
    translate: Option<S<V3>>,
    rotate: Option<S<V3>>,
    scale: Option<S<Scale>>,
}

/// `scale = 2` or `scale = [2, 1, 1]`.
#[derive(Deserialize)]
#[serde(untagged)]
enum Scale {
    Uniform(f32),
    Axes(V3),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TriangleDesc {
    vertices: S<[V3; 3]>,
    material: S<MaterialRef>,
    transform: Option<S<TransformDesc>>,
    keys: Keys<ObjectKey>,
    interpolation: Option<S<String>>,
}

/// What the checks need: the text (to turn byte offsets into lines) and where to find
/// the files it names.
struct Ctx<'a> {
    name: &'a str,
    src: &'a str,
    base_dir: &'a Path,
    /// Each image file is decoded once however many materials use it.
    images: std::cell::RefCell<HashMap<(PathBuf, ColorEncoding), Arc<ImageMap>>>,
    /// Warnings of the files placed in the scene.
    warnings: std::cell::RefCell<Vec<String>>,
}

type R<T> = Result<T, SceneError>;

impl Ctx<'_> {
    fn line_col(&self, offset: usize) -> (usize, usize) {
        let offset = offset.min(self.src.len());
        let before = &self.src[..offset];
        let line = before.matches('\n').count() + 1;
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        (line, before[line_start..].chars().count() + 1)
    }

    fn error_at(&self, offset: usize, field: &str, message: impl Into<String>) -> SceneError {
        let (line, column) = self.line_col(offset);
        SceneError::At { file: self.name.to_owned(), line, column, field: field.to_owned(), message: message.into() }
    }

    fn err<T>(&self, v: &S<T>, field: &str, message: impl Into<String>) -> SceneError {
        self.error_at(v.span().start, field, message)
    }

    /// A TOML or type error: the field is the one the message names in backquotes, or the
    /// key the error's position is the value of.
    fn toml_error(&self, e: &toml::de::Error) -> SceneError {
        let message = e.message().trim().to_owned();
        // The parser's nesting limit comes without a position: point at the first line
        // nested that deep (dotted keys, arrays or inline tables).
        let offset = e.span().map(|s| s.start).or_else(|| self.deeply_nested_line()).unwrap_or(0);
        let field = message
            .split('`')
            .nth(1)
            .filter(|_| message.starts_with("unknown field") || message.starts_with("missing field"))
            .map(str::to_owned)
            .or_else(|| self.key_before(offset))
            .unwrap_or_else(|| "syntax".to_owned());
        self.error_at(offset, &field, message)
    }

    /// The key whose value starts at `offset` (`radius` in `radius = "five"`).
    fn key_before(&self, offset: usize) -> Option<String> {
        let offset = offset.min(self.src.len());
        let line_start = self.src[..offset].rfind('\n').map_or(0, |i| i + 1);
        let prefix = &self.src[line_start..offset];
        let eq = prefix.rfind('=')?;
        let key = prefix[..eq].trim_end();
        let key = key.rsplit(|c: char| c == '{' || c == ',' || c.is_whitespace()).next()?;
        let key = key.trim_matches(|c| c == '"' || c == '\'');
        (!key.is_empty()).then(|| key.to_owned())
    }

    fn finite(&self, v: &S<f32>, field: &str) -> R<f32> {
        let x = *v.get_ref();
        if x.is_finite() { Ok(x) } else { Err(self.err(v, field, format!("must be a finite number (got {x})"))) }
    }

    fn positive(&self, v: &S<f32>, field: &str) -> R<f32> {
        let x = self.finite(v, field)?;
        if x > 0.0 { Ok(x) } else { Err(self.err(v, field, format!("must be > 0 (got {x})"))) }
    }

    fn non_negative(&self, v: &S<f32>, field: &str) -> R<f32> {
        let x = self.finite(v, field)?;
        if x >= 0.0 { Ok(x) } else { Err(self.err(v, field, format!("must be >= 0 (got {x})"))) }
    }

    fn share(&self, v: &S<f32>, field: &str) -> R<f32> {
        let x = self.finite(v, field)?;
        if (0.0..=1.0).contains(&x) { Ok(x) } else { Err(self.err(v, field, format!("must be in [0, 1] (got {x})"))) }
    }

    fn vec3(&self, v: &S<V3>, field: &str) -> R<Vec3> {
        let a = *v.get_ref();
        if a.iter().all(|x| x.is_finite()) {
            Ok(Vec3::from_array(a))
        } else {
            Err(self.err(v, field, format!("must be three finite numbers (got {a:?})")))
        }
    }

    fn direction(&self, v: &S<V3>, field: &str) -> R<Vec3> {
        let d = self.vec3(v, field)?;
        if d.length_squared() > 0.0 { Ok(d) } else { Err(self.err(v, field, "must not be the zero vector")) }
    }

    fn color(&self, v: &S<V3>, field: &str) -> R<Color> {
        let c = self.vec3(v, field)?;
        if c.min_element() >= 0.0 {
            Ok(c.into())
        } else {
            Err(self.err(v, field, format!("colour components must be >= 0 (got {c})")))
        }
    }

    fn int_in(&self, v: &S<i64>, field: &str, lo: i64, hi: i64, why: &str) -> R<u32> {
        let x = *v.get_ref();
        if (lo..=hi).contains(&x) {
            Ok(x as u32)
        } else {
            Err(self.err(v, field, format!("must be between {lo} and {hi}{why} (got {x})")))
        }
    }

    /// The scene with every table's own values, and what its keys animate.
    fn build(&self, desc: FileDesc) -> R<(Scene, Animation)> {
        let camera = self.camera(&desc.camera)?;
        let mut scene = Scene::new(camera);
        let mut range = None;
        if let Some(s) = &desc.settings {
            scene.settings = self.settings(s.get_ref())?;
            range = self.frame_range(s.get_ref())?;
        }
        let mut anim = Animation {
            file: self.name.to_owned(),
            camera: self.camera_keys(desc.camera.get_ref(), &camera, range)?,
            ..Default::default()
        };
        for (i, l) in desc.light.iter().enumerate() {
            let light = self.light(l)?;
            let d = l.get_ref();
            anim.lights.extend(self.light_keys(i, &d.keys, &d.interpolation, &light, range)?);
            scene.add_light(light);
        }
        let mut names = HashMap::new();
        for (name, m) in &desc.material {
            let id = scene.add_material(self.material(m.get_ref())?);
            names.insert(name.as_str(), id);
        }
        let resolve = |scene: &mut Scene, m: &S<MaterialRef>| -> R<MaterialId> {
            match m.get_ref() {
                MaterialRef::Named(n) => names.get(n.as_str()).copied().ok_or_else(|| {
                    let mut known: Vec<_> = names.keys().copied().collect();
                    known.sort_unstable();
                    self.err(m, "material", format!("no material named {n:?} (defined: {})", known.join(", ")))
                }),
                MaterialRef::Inline(d) => Ok(scene.add_material(self.material(d)?)),
            }
        };
        let objects = std::cell::RefCell::new(Vec::new());
        let place = |scene: &mut Scene,
                     shape: Shape,
                     material: &S<MaterialRef>,
                     transform: &Option<S<TransformDesc>>,
                     (keys, interpolation): (&Keys<ObjectKey>, &Option<S<String>>)|
         -> R<()> {
            let material = resolve(scene, material)?;
            let index = scene.objects.len();
            objects.borrow_mut().extend(self.object_keys(index, &shape, transform, keys, interpolation, range)?);
            let shape = match transform {
                None => shape,
                Some(t) => {
                    let m = self.transform(t.get_ref())?;
                    geometry::transform(shape, &m)
                        .map_err(|e| self.err(t, "transform", format!("makes the polygon degenerate: {e}")))?
                }
            };
            scene.objects.push(Object { shape, material });
            Ok(())
        };
        for s in &desc.sphere {
            let s = s.get_ref();
            let shape = Sphere::new(self.vec3(&s.center, "center")?, self.positive(&s.radius, "radius")?);
            place(&mut scene, shape.into(), &s.material, &s.transform, (&s.keys, &s.interpolation))?;
        }
        for q in &desc.quad {
            let q = q.get_ref();
            let (u, v) = (self.direction(&q.edge_u, "edge_u")?, self.direction(&q.edge_v, "edge_v")?);
            if u.cross(v).length_squared() <= 1e-12 * u.length_squared() * v.length_squared() {
                return Err(self.err(&q.edge_v, "edge_v", "is parallel to edge_u: the quad has no area"));
            }
            let shape = Quad::new(self.vec3(&q.corner, "corner")?, u, v);
            place(&mut scene, shape.into(), &q.material, &q.transform, (&q.keys, &q.interpolation))?;
        }
        for p in &desc.polygon {
            let p = p.get_ref();
            let mut vertices = Vec::with_capacity(p.vertices.get_ref().len());
            for v in p.vertices.get_ref() {
                if !v.iter().all(|x| x.is_finite()) {
                    return Err(self.err(&p.vertices, "vertices", format!("vertex {v:?} is not finite")));
                }
                vertices.push(Vec3::from_array(*v));
            }
            let shape = self.polygon(&p.vertices, vertices)?;
            place(&mut scene, shape, &p.material, &p.transform, (&p.keys, &p.interpolation))?;
        }
        for c in &desc.cylinder {
            let c = c.get_ref();
            let shape = Cylinder::new(
                self.vec3(&c.base, "base")?,
                self.direction(&c.axis, "axis")?,
                self.positive(&c.radius, "radius")?,
                self.positive(&c.height, "height")?,
                c.caps.unwrap_or(true),
            );
            place(&mut scene, shape.into(), &c.material, &c.transform, (&c.keys, &c.interpolation))?;
        }
        for c in &desc.cone {
            let c = c.get_ref();
            let top_radius = c.top_radius.as_ref().map_or(Ok(0.0), |r| self.non_negative(r, "top_radius"))?;
            if let Some(top_cap) = &c.top_cap
                && *top_cap.get_ref()
                && top_radius == 0.0
            {
                return Err(self.err(top_cap, "top_cap", "a pointed cone (top_radius 0) has no top to close"));
            }
            let shape = Cone::truncated(
                self.vec3(&c.base, "base")?,
                self.direction(&c.axis, "axis")?,
                self.positive(&c.radius, "radius")?,
                top_radius,
                self.positive(&c.height, "height")?,
                c.cap.unwrap_or(true),
                top_radius > 0.0 && c.top_cap.as_ref().is_none_or(|t| *t.get_ref()),
            );
            place(&mut scene, shape.into(), &c.material, &c.transform, (&c.keys, &c.interpolation))?;
        }
        for t in &desc.triangle {
            let t = t.get_ref();
            let [a, b, c] = *t.vertices.get_ref();
            let [a, b, c] = [a, b, c].map(Vec3::from_array);
            if !(a.is_finite() && b.is_finite() && c.is_finite()) {
                return Err(self.err(&t.vertices, "vertices", "vertices must be finite"));
            }
            if (b - a).cross(c - a).length_squared() <= 0.0 {
                return Err(self.err(&t.vertices, "vertices", "the triangle has no area (collinear vertices)"));
            }
            place(
                &mut scene,
                Shape::Triangle(Triangle::new(a, b, c)),
                &t.material,
                &t.transform,
                (&t.keys, &t.interpolation),
            )?;
        }
        let mut named = HashMap::new();
        for m in &desc.mesh {
            let mesh = self.mesh(m)?;
            let m = m.get_ref();
            place(&mut scene, mesh.into(), &m.material, &m.transform, (&m.keys, &m.interpolation))?;
            let placed = m.transform.as_ref().map_or(Ok(glam::Affine3A::IDENTITY), |t| self.transform(t.get_ref()))?;
            let k = scene.objects.len();
            self.name_asset(&mut named, &m.name, k - 1..k, placed)?;
        }
        for g in &desc.gltf {
            let g = g.get_ref();
            let transform = match &g.transform {
                Some(t) => glam::Mat4::from(self.transform(t.get_ref())?),
                None => glam::Mat4::IDENTITY,
            };
            let path = self.base_dir.join(g.file.get_ref());
            let first = scene.objects.len();
            let asset = super::gltf::add_gltf(&mut scene, &path, transform)
                .map_err(|e| self.err(&g.file, "file", e.to_string()))?;
            self.warnings.borrow_mut().extend(asset.warnings);
            let placed = glam::Affine3A::from_mat4(transform);
            self.name_asset(&mut named, &g.name, first..scene.objects.len(), placed)?;
        }
        for i in &desc.instance {
            self.instance(&mut scene, &named, i, resolve, (&mut objects.borrow_mut(), range))?;
        }
        scene.labels = self.labels(&desc);
        anim.objects = objects.into_inner();
        let last_key = anim.lights.iter().map(|l| l.position.span().1);
        let last_key = last_key.chain(anim.objects.iter().filter_map(|o| o.span()).map(|s| s.1));
        let c = &anim.camera;
        let last_key = last_key.chain([&c.position, &c.look_at, &c.fov].into_iter().flatten().map(|t| t.span().1));
        (anim.first, anim.last) = range.unwrap_or((0, last_key.max().unwrap_or(0)));
        Ok((scene, anim))
    }

    fn transform(&self, t: &TransformDesc) -> R<glam::Affine3A> {
        let [translate, rotate, scale] = self.transform_parts(t)?;
        Ok(geometry::affine(translate.unwrap_or(Vec3::ZERO), rotate.unwrap_or(Vec3::ZERO), scale.unwrap_or(Vec3::ONE)))
    }

    fn camera(&self, c: &S<CameraDesc>) -> R<Camera> {
        let d = c.get_ref();
        let resolution = |v: &Option<S<i64>>, field| {
            v.as_ref().map_or(Ok(800), |v| self.int_in(v, field, 1, MAX_RESOLUTION, " pixels"))
        };
        let camera = Camera::new(
            self.vec3(&d.position, "position")?,
            self.vec3(&d.look_at, "look_at")?,
            d.up.as_ref().map_or(Ok(Vec3::Y), |u| self.vec3(u, "up"))?,
            self.finite(&d.fov, "fov")?,
            resolution(&d.width, "width")?,
            resolution(&d.height, "height")?,
        );
        match camera.rig() {
            Ok(_) => Ok(camera),
            Err(e @ CameraError::ZeroDirection) => Err(self.err(&d.look_at, "look_at", e.to_string())),
            Err(e @ CameraError::BadUp) => Err(d
                .up
                .as_ref()
                .map_or_else(|| self.err(c, "up", e.to_string()), |u| self.err(u, "up", e.to_string()))),
            Err(e @ CameraError::BadFov) => Err(self.err(&d.fov, "fov", e.to_string())),
        }
    }

    fn settings(&self, s: &SettingsDesc) -> R<Settings> {
        let mut out = Settings::default();
        if let Some(b) = &s.background {
            out.background = self.color(b, "background")?;
        }
        if let Some(d) = &s.max_depth {
            out.max_depth = self.int_in(d, "max_depth", 1, MAX_DEPTH, "")?;
        }
        if let Some(n) = &s.samples {
            out.samples = self.int_in(n, "samples", 1, MAX_SAMPLES, " per pixel")?;
        }
        if let Some(a) = &s.ambient {
            out.ambient = self.non_negative(a, "ambient")?;
        }
        if let Some(c) = &s.cutoff {
            out.cutoff = self.non_negative(c, "cutoff")?;
        }
        if let Some(c) = &s.color {
            out.color = ColorEncoding::parse(c.get_ref()).ok_or_else(|| {
                self.err(c, "color", format!("expected \"linear\" or \"srgb\", got {:?}", c.get_ref()))
            })?;
        }
        Ok(out)
    }

    fn material(&self, d: &MaterialDesc) -> R<Material> {
        let mut m = Material::default();
        match (&d.color, &d.texture) {
            (Some(_), Some(t)) => {
                return Err(self.err(t, "texture", "give a material either a color or a texture, not both"));
            }
            (Some(c), None) => m.texture = Texture::Solid(self.color(c, "color")?),
            (None, Some(t)) => m.texture = self.texture(t.get_ref())?,
            (None, None) => {}
        }
        if let Some(v) = &d.diffuse {
            m.diffuse = self.non_negative(v, "diffuse")?;
        }
        if let Some(v) = &d.specular {
            m.specular = self.non_negative(v, "specular")?;
        }
        if let Some(v) = &d.shininess {
            m.shininess = self.non_negative(v, "shininess")?;
        }
        if let Some(v) = &d.reflectivity {
            m.reflectivity = self.share(v, "reflectivity")?;
        }
        if let Some(v) = &d.transparency {
            m.transparency = self.share(v, "transparency")?;
        }
        if let Some(v) = &d.ior {
            m.ior = self.positive(v, "ior")?;
        }
        m.fresnel = d.fresnel.unwrap_or(false);
        if let Some(v) = &d.absorption {
            m.absorption = self.color(v, "absorption")?;
            if m.absorbs() && m.transparency == 0.0 {
                return Err(self.err(v, "absorption", "needs transparency > 0: nothing travels inside to be absorbed"));
            }
        }
        if m.reflectivity + m.transparency > 1.0 + 1e-6 {
            let at = d.transparency.as_ref().or(d.reflectivity.as_ref()).expect("one is set when the sum exceeds 1");
            return Err(self.err(
                at,
                "transparency",
                format!("reflectivity + transparency must be at most 1 (got {} + {})", m.reflectivity, m.transparency),
            ));
        }
        Ok(m)
    }
}

#[cfg(test)]
mod tests;
