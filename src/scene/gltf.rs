//! glTF 2.0 scenes, as Blender, three.js and Sketchfab export them: `.gltf` (with `.bin`
//! files or embedded base64 data) and `.glb`, read with the `gltf` crate.
//!
//! What is kept: the default scene's node hierarchy with its transforms (baked into the
//! vertices), triangle meshes with normals (computed when absent) and `TEXCOORD_0`,
//! materials (base colour factor and texture, decoded from sRGB; metallic as
//! reflectivity; `KHR_materials_transmission` and `KHR_materials_ior` as transparency
//! and index), the first perspective camera, and `KHR_lights_punctual` point, spot and directional lights.
//! Light intensities are relative: the brightest light gets intensity 1, since the
//! renderer's lights do not fall off with distance as glTF's physical ones do.
//! Whatever cannot be mapped (roughness, normal, occlusion and emission maps, skins,
//! morph targets, animations, ...) is warned about once per kind and otherwise ignored.
//! Broken files are errors naming the file and the part at fault (`meshes[0]
//! .primitives[0].indices`), never panics: every accessor is bounds-checked before it
//! is read.

use super::{Loaded, MaterialId, Scene, SceneError};
use crate::camera::Camera;
use crate::film::ColorEncoding;
use crate::geometry::Mesh;
use crate::light::{DirectionalLight, Light, PointLight, SpotLight};
use crate::material::Material;
use crate::math::{Vec2, Vec3};
use crate::texture::{ImageMap, Texture};
use glam::{Mat3, Mat4};
use gltf::mesh::Mode;
use std::collections::{BTreeSet, HashMap};
use std::path::Path;
use std::sync::Arc;

/// What a glTF file adds to a scene.
pub struct Asset {
    /// Camera of the first node that has a perspective one, if any.
    pub camera: Option<Camera>,
    /// Warnings, one per kind of thing ignored.
    pub warnings: Vec<String>,
}

/// Reads a glTF file as a whole scene: its camera, or else the default view of its
/// bounds, and its lights, or else one over the camera's shoulder. Output is sRGB, as
/// glTF assumes.
pub fn load_gltf(path: &Path) -> Result<Loaded, SceneError> {
    let placeholder = Camera::new(Vec3::Z, Vec3::ZERO, Vec3::Y, 40.0, super::frame::WIDTH, super::frame::HEIGHT);
    let mut scene = Scene::new(placeholder);
    scene.settings.color = ColorEncoding::Srgb;
    let asset = add_gltf(&mut scene, path, Mat4::IDENTITY)?;
    let mut warnings = asset.warnings;
    let mut notes = Vec::new();
    if scene.objects.is_empty() {
        warnings.push(format!("{}: no triangle meshes in the default scene", path.display()));
    }
    if let Some(c) = asset.camera {
        scene.camera = c;
    }
    super::frame::complete(&mut scene, asset.camera.is_some(), &path.display().to_string(), &mut notes);
    Ok(Loaded { scene, warnings, notes, nff: None, animation: None })
}

/// Adds the meshes and lights of the glTF file at `path`, placed by `transform`, to
/// `scene` (cameras are returned, not applied).
pub fn add_gltf(scene: &mut Scene, path: &Path, transform: Mat4) -> Result<Asset, SceneError> {
    let name = path.display().to_string();
    let fail = |message: String| SceneError::File { file: name.clone(), message };
    let bytes = std::fs::read(path).map_err(|e| fail(format!("cannot read the glTF file: {e}")))?;
    let gltf::Gltf { document, mut blob } =
        gltf::Gltf::from_slice_without_validation(&bytes).map_err(|e| fail(describe(&e)))?;
    validate(document.as_json()).map_err(fail)?;
    let base = path.parent().unwrap_or(Path::new("."));
    let mut buffers = Vec::new();
    for b in document.buffers() {
        let part = format!("buffers[{}]{}", b.index(), uri_of(b.source()));
        let data = gltf::buffer::Data::from_source_and_blob(b.source(), Some(base), &mut blob)
            .map_err(|e| fail(format!("{part}: {}", describe(&e))))?;
        if data.len() < b.length() {
            return Err(fail(format!("{part}: {} bytes, but byteLength says {}", data.len(), b.length())));
        }
        buffers.push(data.0);
    }
    let mut reader = Reader {
        doc: &document,
        buffers: &buffers,
        base,
        fail: &fail,
        warned: BTreeSet::new(),
        materials: HashMap::new(),
        images: HashMap::new(),
        camera: None,
        lights: Vec::new(),
        visited: vec![false; document.nodes().len()],
    };
    reader.check_document();
    let gltf_scene = document.default_scene().or_else(|| document.scenes().next());
    if let Some(s) = gltf_scene {
        for node in s.nodes() {
            reader.node(scene, &node, transform)?;
        }
    }
    // Lights: relative intensities, the brightest at 1.
    let brightest = reader.lights.iter().map(|(_, i)| *i).fold(0.0f32, f32::max);
    for (light, intensity) in std::mem::take(&mut reader.lights) {
        let k = if brightest > 0.0 { intensity / brightest } else { 1.0 };
        scene.add_light(match light {
            Light::Point(p) => Light::Point(PointLight { color: p.color * k, ..p }),
            Light::Directional(d) => Light::Directional(DirectionalLight { color: d.color * k, ..d }),
            Light::Spot(s) => Light::Spot(SpotLight { color: s.color * k, ..s }),
        });
    }
    let warnings = reader.warned.iter().map(|w| format!("{name}: {w}")).collect();
    Ok(Asset { camera: reader.camera, warnings })
}

/// The `gltf` crate's checks of a parsed document, after one of ours that they rely on:
/// its check of a primitive's `POSITION` accessor indexes the accessors without a bound
/// (gltf-json 1.4.1, `mesh.rs`), so an index past them would panic, not be reported.
fn validate(root: &gltf::json::Root) -> Result<(), String> {
    use gltf::json::validation::{Checked, Validate};
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let position = primitive.attributes.get(&Checked::Valid(gltf::Semantic::Positions));
            if let Some(i) = position.map(|i| i.value())
                && i >= root.accessors.len()
            {
                return Err(format!(
                    "invalid glTF: meshes[{m}].primitives[{p}].attributes.POSITION: accessor {i} does not exist \
                     (the file has {} accessors)",
                    root.accessors.len()
                ));
            }
        }
    }
    let mut errors = Vec::new();
    root.validate(root, gltf::json::Path::new, &mut |path, error| errors.push((path(), error)));
    match errors.is_empty() {
        true => Ok(()),
        false => Err(describe(&gltf::Error::Validation(errors))),
    }
}

/// What an accessor must hold to be read as.
#[derive(Clone, Copy)]
enum Kind {
    Vec3,
    TexCoord,
    Index,
}

/// " (file.bin)" or "" for embedded and binary-chunk data, for messages.
fn uri_of(source: gltf::buffer::Source) -> String {
    match source {
        gltf::buffer::Source::Uri(u) if !u.starts_with("data:") => format!(" ({u})"),
        _ => String::new(),
    }
}

/// The crate's error, with every validation problem and JSON position spelled out.
fn describe(e: &gltf::Error) -> String {
    match e {
        gltf::Error::Validation(list) => {
            let parts: Vec<String> = list.iter().take(5).map(|(path, err)| format!("{path}: {err}")).collect();
            let more = if list.len() > 5 { format!(" (and {} more)", list.len() - 5) } else { String::new() };
            format!("invalid glTF: {}{more}", parts.join("; "))
        }
        gltf::Error::Deserialize(j) => {
            // serde_json ends its message with the place, which this puts first.
            let (line, column) = (j.line(), j.column());
            let message = j.to_string();
            let message = message.strip_suffix(&format!(" at line {line} column {column}")).unwrap_or(&message);
            format!("line {line}, column {column}: not valid glTF JSON: {message}")
        }
        gltf::Error::Binary(b) => {
            use gltf::binary::Error as B;
            let detail = match b {
                B::Length { length, length_read } => {
                    format!("the header says {length} bytes, the file has {length_read} (truncated?)")
                }
                B::ChunkLength { ty, length, length_read } => {
                    format!("the {ty:?} chunk says {length} bytes, {length_read} are left (truncated?)")
                }
                B::Version(v) => format!("version {v} (expected 2)"),
                other => other.to_string(),
            };
            format!("not a valid binary glTF (.glb) file: {detail}")
        }
        gltf::Error::Base64(b) => format!("bad base64 data: {b}"),
        gltf::Error::Io(io) => format!("cannot read: {io}"),
        gltf::Error::MissingBlob => "refers to the binary chunk, which the file lacks".into(),
        gltf::Error::UnsupportedScheme => "unsupported URI scheme".into(),
        other => other.to_string(),
    }
}

struct Reader<'a, F: Fn(String) -> SceneError> {
    doc: &'a gltf::Document,
    buffers: &'a [Vec<u8>],
    base: &'a Path,
    fail: &'a F,
    /// Things ignored, each said once.
    warned: BTreeSet<String>,
    materials: HashMap<Option<usize>, MaterialId>,
    images: HashMap<usize, Arc<ImageMap>>,
    camera: Option<Camera>,
    /// Lights and their intensities (normalised at the end).
    lights: Vec<(Light, f32)>,
    /// Nodes reached so far: a glTF node has at most one parent, and a file where one
    /// is reached twice (a cycle, or a shared child) would otherwise loop or blow up.
    visited: Vec<bool>,
}

impl<F: Fn(String) -> SceneError> Reader<'_, F> {
    fn warn(&mut self, what: &str) {
        self.warned.insert(what.to_owned());
    }

    /// Document-wide things that are not mapped.
    fn check_document(&mut self) {
        if self.doc.animations().next().is_some() {
            self.warn("animations are not supported: the scene is rendered at rest");
        }
        const KNOWN: &[&str] = &["KHR_lights_punctual", "KHR_materials_transmission", "KHR_materials_ior"];
        let unknown: Vec<&str> = self.doc.extensions_used().filter(|e| !KNOWN.contains(e)).collect();
        for e in unknown {
            self.warn(&format!("extension {e} is not supported: ignored"));
        }
    }

    fn node(&mut self, scene: &mut Scene, node: &gltf::Node, parent: Mat4) -> Result<(), SceneError> {
        if std::mem::replace(&mut self.visited[node.index()], true) {
            return Err((self.fail)(format!(
                "nodes[{}]: reached twice in the scene's node tree (a cycle, or a node with two parents)",
                node.index()
            )));
        }
        let local = Mat4::from_cols_array_2d(&node.transform().matrix());
        let world = parent * local;
        if !world.is_finite() {
            return Err((self.fail)(format!("nodes[{}]: the transform is not finite", node.index())));
        }
        if node.skin().is_some() {
            self.warn("skins are not supported: skinned meshes are shown in their bind pose");
        }
        if let Some(mesh) = node.mesh() {
            self.mesh(scene, &mesh, world)?;
        }
        if let Some(camera) = node.camera() {
            self.camera(&camera, world);
        }
        if let Some(light) = node.light() {
            self.light(&light, world);
        }
        for child in node.children() {
            self.node(scene, &child, world)?;
        }
        Ok(())
    }

    fn camera(&mut self, camera: &gltf::Camera, world: Mat4) {
        let gltf::camera::Projection::Perspective(p) = camera.projection() else {
            self.warn("orthographic cameras are not supported: ignored");
            return;
        };
        if self.camera.is_some() {
            self.warn("more than one camera: the first one is used");
            return;
        }
        let position = world.transform_point3(Vec3::ZERO);
        let forward = world.transform_vector3(Vec3::NEG_Z).normalize_or(Vec3::NEG_Z);
        let up = world.transform_vector3(Vec3::Y).normalize_or(Vec3::Y);
        let fov = p.yfov().to_degrees();
        let fov = if fov.is_finite() { fov.clamp(1.0, 179.0) } else { 40.0 };
        let height = super::frame::HEIGHT;
        let width = match p.aspect_ratio() {
            Some(a) if a.is_finite() && a > 0.0 => {
                ((height as f32 * a).round() as u32).clamp(1, super::MAX_RESOLUTION as u32)
            }
            _ => super::frame::WIDTH,
        };
        self.camera = Some(Camera::new(position, position + forward, up, fov, width, height));
    }

    fn light(&mut self, light: &gltf::khr_lights_punctual::Light, world: Mat4) {
        use gltf::khr_lights_punctual::Kind;
        let color = Vec3::from_array(light.color());
        let intensity = light.intensity();
        if !(color.is_finite() && color.min_element() >= 0.0 && intensity.is_finite() && intensity >= 0.0) {
            self.warn("lights with non-finite or negative values are skipped");
            return;
        }
        // A light shines down its node's -z axis.
        let position = world.transform_point3(Vec3::ZERO);
        let direction = world.transform_vector3(Vec3::NEG_Z);
        if !(position.is_finite() && direction.is_finite() && direction != Vec3::ZERO) {
            self.warn("lights with non-finite or degenerate placements are skipped");
            return;
        }
        let light = match light.kind() {
            Kind::Point => Light::Point(PointLight::new(position, color.into())),
            Kind::Directional => Light::Directional(DirectionalLight::new(direction, color.into())),
            Kind::Spot { inner_cone_angle, outer_cone_angle } => {
                let (inner, outer) = (inner_cone_angle.to_degrees(), outer_cone_angle.to_degrees());
                if !(inner.is_finite() && outer.is_finite() && 0.0 <= inner && inner <= outer && outer < 90.0) {
                    self.warn("spot lights whose cone angles are not 0 <= inner <= outer < 90 degrees are skipped");
                    return;
                }
                Light::Spot(SpotLight::new(position, direction, inner, outer, color.into()))
            }
        };
        self.lights.push((light, intensity));
    }

    fn mesh(&mut self, scene: &mut Scene, mesh: &gltf::Mesh, world: Mat4) -> Result<(), SceneError> {
        let normal_matrix = Mat3::from_mat4(world).inverse().transpose();
        let flip = Mat3::from_mat4(world).determinant() < 0.0;
        for prim in mesh.primitives() {
            let part = format!("meshes[{}].primitives[{}]", mesh.index(), prim.index());
            if prim.mode() != Mode::Triangles {
                self.warn("points, lines and triangle strips or fans are not supported: skipped");
                continue;
            }
            if prim.morph_targets().next().is_some() {
                self.warn("morph targets are not supported: the base shape is used");
            }
            let get = |s: gltf::Semantic| prim.get(&s);
            let Some(pos_acc) = get(gltf::Semantic::Positions) else {
                return Err((self.fail)(format!("{part}: no POSITION attribute")));
            };
            self.check_accessor(&pos_acc, &format!("{part}.attributes.POSITION"), Kind::Vec3)?;
            let count = pos_acc.count();
            let normal_acc = get(gltf::Semantic::Normals);
            let uv_acc = get(gltf::Semantic::TexCoords(0));
            for (acc, what, kind) in [(&normal_acc, "NORMAL", Kind::Vec3), (&uv_acc, "TEXCOORD_0", Kind::TexCoord)] {
                if let Some(a) = acc {
                    self.check_accessor(a, &format!("{part}.attributes.{what}"), kind)?;
                    if a.count() != count {
                        return Err((self.fail)(format!(
                            "{part}.attributes.{what}: {} entries for {count} positions",
                            a.count()
                        )));
                    }
                }
            }
            if let Some(a) = prim.indices() {
                self.check_accessor(&a, &format!("{part}.indices"), Kind::Index)?;
            }
            let reader = prim.reader(|b| self.buffers.get(b.index()).map(|d| d.as_slice()));
            let bad = |what: &str| (self.fail)(format!("{part}.{what}: cannot be read"));
            let positions: Vec<Vec3> = reader
                .read_positions()
                .ok_or_else(|| bad("attributes.POSITION"))?
                .map(|p| world.transform_point3(Vec3::from_array(p)))
                .collect();
            if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
                return Err((self.fail)(format!("{part}.attributes.POSITION: entry {i} is not finite")));
            }
            let normals: Vec<Vec3> = match reader.read_normals() {
                Some(n) if normal_acc.is_some() => {
                    n.map(|n| (normal_matrix * Vec3::from_array(n)).normalize_or(Vec3::NAN)).collect()
                }
                _ => Vec::new(),
            };
            let uvs: Vec<Vec2> = match reader.read_tex_coords(0) {
                Some(t) if uv_acc.is_some() => t.into_f32().map(Vec2::from_array).collect(),
                _ => Vec::new(),
            };
            let mut indices: Vec<u32> = match reader.read_indices() {
                Some(i) => i.into_u32().collect(),
                None => (0..count as u32).collect(),
            };
            if !indices.len().is_multiple_of(3) {
                return Err((self.fail)(format!(
                    "{part}.indices: {} indices is not a whole number of triangles",
                    indices.len()
                )));
            }
            if let Some((k, &i)) = indices.iter().enumerate().find(|(_, i)| **i as usize >= count) {
                return Err((self.fail)(format!("{part}.indices: index {k} is {i}, but there are {count} vertices")));
            }
            if indices.is_empty() {
                continue;
            }
            let mut triangles: Vec<[u32; 3]> = indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
            if flip {
                for t in &mut triangles {
                    t.swap(1, 2);
                }
            }
            indices.clear();
            let mesh =
                Mesh::new(positions, normals, uvs, triangles, true).map_err(|e| (self.fail)(format!("{part}: {e}")))?;
            let material = self.material(scene, prim.material(), uv_acc.is_some())?;
            scene.add(mesh, material);
        }
        Ok(())
    }

    /// That the accessor's data lies inside its buffer view and the view inside its
    /// buffer, so reading it cannot go out of bounds.
    fn check_accessor(&mut self, a: &gltf::Accessor, part: &str, kind: Kind) -> Result<(), SceneError> {
        use gltf::accessor::{DataType as T, Dimensions as D};
        let here = format!("{part} (accessors[{}])", a.index());
        let (dims, ty, norm) = (a.dimensions(), a.data_type(), a.normalized());
        let fits = match kind {
            Kind::Vec3 => dims == D::Vec3 && ty == T::F32,
            Kind::TexCoord => dims == D::Vec2 && (ty == T::F32 || (norm && matches!(ty, T::U8 | T::U16))),
            Kind::Index => dims == D::Scalar && matches!(ty, T::U8 | T::U16 | T::U32),
        };
        if !fits {
            let want = match kind {
                Kind::Vec3 => "VEC3 of floats",
                Kind::TexCoord => "VEC2 of floats or normalized bytes or shorts",
                Kind::Index => "SCALAR unsigned bytes, shorts or ints",
            };
            return Err((self.fail)(format!("{here}: is {dims:?} of {ty:?}, expected {want}")));
        }
        if a.count() == 0 {
            return Err((self.fail)(format!("{here}: count is 0")));
        }
        if a.sparse().is_some() {
            return Err((self.fail)(format!("{here}: sparse accessors are not supported")));
        }
        let Some(view) = a.view() else {
            return Err((self.fail)(format!("{here}: has no bufferView")));
        };
        let buffer_len = self.buffers.get(view.buffer().index()).map_or(0, |b| b.len());
        let view_end = view.offset().checked_add(view.length());
        if view_end.is_none_or(|end| end > buffer_len) {
            return Err((self.fail)(format!(
                "{here}: bufferViews[{}] (bytes {} to {}) lies outside its buffer of {buffer_len} bytes",
                view.index(),
                view.offset(),
                view.offset() as u128 + view.length() as u128
            )));
        }
        let size = a.size();
        let stride = view.stride().unwrap_or(size);
        if stride < size {
            return Err((self.fail)(format!("{here}: byteStride {stride} is less than the element size {size}")));
        }
        let end = (a.count() as u128 - 1) * stride as u128 + size as u128 + a.offset() as u128;
        if end > view.length() as u128 {
            return Err((self.fail)(format!(
                "{here}: {} elements from byte {} need {end} bytes, but bufferViews[{}] has {}",
                a.count(),
                a.offset(),
                view.index(),
                view.length()
            )));
        }
        Ok(())
    }

    fn material(&mut self, scene: &mut Scene, m: gltf::Material, has_uv: bool) -> Result<MaterialId, SceneError> {
        let key = m.index();
        if let Some(&id) = self.materials.get(&key) {
            return Ok(id);
        }
        let pbr = m.pbr_metallic_roughness();
        let [r, g, b, a] = pbr.base_color_factor();
        let factor = crate::math::Color::new(r, g, b);
        if a < 1.0 || m.alpha_mode() != gltf::material::AlphaMode::Opaque {
            self.warn("alpha (cut-outs and blending) is not supported: surfaces are opaque");
        }
        let mut mat = Material { texture: Texture::Solid(factor), ..Material::default() };
        if let Some(info) = pbr.base_color_texture() {
            if info.tex_coord() != 0 {
                self.warn(
                    "texture coordinate sets other than TEXCOORD_0 are not supported: the base colour factor is used",
                );
            } else if !has_uv {
                self.warn("textured primitives without texture coordinates use the base colour factor");
            } else {
                let image = info.texture().source();
                let map = self.image(&image)?;
                let map = if factor == crate::math::Color::ONE {
                    map
                } else {
                    let tinted = ImageMap::from_fn(map.width(), map.height(), |x, y| map.texel(x, y) * factor);
                    Arc::new(tinted)
                };
                mat.texture = Texture::image(map);
            }
        }
        mat.reflectivity = pbr.metallic_factor().clamp(0.0, 1.0);
        if pbr.metallic_roughness_texture().is_some() {
            self.warn("metallic-roughness textures are not supported: the factors are used");
        }
        if pbr.roughness_factor() < 1.0 && mat.reflectivity > 0.0 {
            self.warn("roughness is not supported: metals reflect like mirrors");
        }
        if let Some(t) = m.transmission() {
            mat.transparency = t.transmission_factor().clamp(0.0, 1.0 - mat.reflectivity);
            if t.transmission_texture().is_some() {
                self.warn("transmission textures are not supported: the factor is used");
            }
        }
        if let Some(ior) = m.ior() {
            if ior.is_finite() && ior > 0.0 {
                mat.ior = ior;
            }
        } else if mat.transparency > 0.0 {
            mat.ior = 1.5; // glTF's default index
        }
        if m.normal_texture().is_some() {
            self.warn("normal maps are not supported: ignored");
        }
        if m.occlusion_texture().is_some() {
            self.warn("occlusion maps are not supported: ignored");
        }
        if m.emissive_texture().is_some() || m.emissive_factor() != [0.0; 3] {
            self.warn("emission is not supported: ignored");
        }
        if mat.reflectivity > 0.0 || mat.transparency > 0.0 {
            mat.specular = 0.5;
        }
        let id = scene.add_material(mat);
        self.materials.insert(key, id);
        Ok(id)
    }

    fn image(&mut self, image: &gltf::Image) -> Result<Arc<ImageMap>, SceneError> {
        if let Some(m) = self.images.get(&image.index()) {
            return Ok(m.clone());
        }
        let part = format!("images[{}]", image.index());
        let (bytes, hint) = match image.source() {
            gltf::image::Source::View { view, mime_type } => {
                let buffer = &self.buffers[view.buffer().index()];
                let end = view.offset().checked_add(view.length()).filter(|&e| e <= buffer.len());
                let Some(end) = end else {
                    return Err((self.fail)(format!("{part}: bufferViews[{}] lies outside its buffer", view.index())));
                };
                (buffer[view.offset()..end].to_vec(), image::ImageFormat::from_mime_type(mime_type))
            }
            gltf::image::Source::Uri { uri, mime_type } => {
                let data = gltf::buffer::Data::from_source(gltf::buffer::Source::Uri(uri), Some(self.base))
                    .map_err(|e| (self.fail)(format!("{part} ({}): {}", short(uri), describe(&e))))?;
                let hint = mime_type
                    .and_then(image::ImageFormat::from_mime_type)
                    .or_else(|| image::ImageFormat::from_path(uri).ok());
                (data.0, hint)
            }
        };
        // Colour textures are sRGB-encoded (glTF 2.0, 3.9.2).
        let map =
            ImageMap::decode(&bytes, hint, ColorEncoding::Srgb).map_err(|e| (self.fail)(format!("{part}: {e}")))?;
        let map = Arc::new(map);
        self.images.insert(image.index(), map.clone());
        Ok(map)
    }
}

/// A URI for messages: data URIs cut short.
fn short(uri: &str) -> String {
    if uri.starts_with("data:") { format!("{}...", uri.chars().take(30).collect::<String>()) } else { uri.to_owned() }
}
