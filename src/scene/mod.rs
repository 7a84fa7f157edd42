//! The scene: what the renderer draws, whether read from a file or built in code.
//!
//! ```
//! use whitted::prelude::*;
//!
//! let mut scene = Scene::new(Camera::new(Vec3::ZERO, Vec3::NEG_Z, Vec3::Y, 45.0, 64, 64));
//! let red = scene.add_material(Material::color(Color::new(1.0, 0.0, 0.0)));
//! scene.add(Sphere::new(Vec3::new(0.0, 0.0, -5.0), 1.0), red);
//! scene.add_light(PointLight::new(Vec3::new(5.0, 5.0, 0.0), Color::ONE));
//! let image = Renderer::new(&scene).unwrap().render();
//! assert_eq!(image.width(), 64);
//! ```

pub mod animation;
mod error;
pub mod frame;
pub mod generate;
pub mod gltf;
pub mod limits;
mod load;
pub mod nff;
pub mod obj;
pub mod save;

pub use animation::Animation;
pub use error::SceneError;
pub use load::{
    DEFAULT_SCENE, DEFAULT_SCENE_NAME, MAX_RESOLUTION, load_animated_file, load_animated_str, load_file, load_str,
};

use crate::camera::Camera;
use crate::geometry::Shape;
use crate::light::Light;
use crate::material::Material;
use crate::math::{Color, Vec3};
use std::path::Path;

/// The scene file formats [`load_path`] reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// The project's own format ([`load_file`]).
    Toml,
    /// Eric Haines' Neutral File Format ([`nff`]).
    Nff,
    /// A Wavefront OBJ mesh on its own ([`obj`]), in the default view ([`frame`]).
    Obj,
    /// glTF 2.0, `.gltf` or `.glb` ([`gltf`]).
    Gltf,
}

impl Format {
    /// By extension (any case): `.nff`, `.obj`, `.gltf` and `.glb`; anything else TOML.
    pub fn of_path(path: &Path) -> Format {
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
        match ext.as_str() {
            "nff" => Format::Nff,
            "obj" => Format::Obj,
            "gltf" | "glb" => Format::Gltf,
            _ => Format::Toml,
        }
    }
}

/// A scene read from a file, with what its reader had to say.
#[derive(Clone, Debug)]
pub struct Loaded {
    pub scene: Scene,
    /// The reader's warnings (skipped or adjusted entities); [`Scene::warnings`] adds
    /// those about the scene as a whole.
    pub warnings: Vec<String>,
    /// What the reader filled in (a default camera or light), worth a line on stderr.
    pub notes: Vec<String>,
    /// For NFF: what the file held and its size.
    pub nff: Option<nff::Counts>,
    /// What moves, for a TOML file with keys ([`animation`]); `scene` is then its first
    /// frame.
    pub animation: Option<Animation>,
}

/// Reads a scene file in the given format.
pub fn load_path(path: &Path, format: Format) -> Result<Loaded, SceneError> {
    match format {
        Format::Toml => {
            let (scene, animation, warnings) = load::load_animated_file(path)?;
            let animation = (!animation.is_static()).then_some(animation);
            Ok(Loaded { scene, warnings, notes: Vec::new(), nff: None, animation })
        }
        Format::Nff => {
            let n = nff::load_nff(path)?;
            Ok(Loaded { scene: n.scene, warnings: n.warnings, notes: Vec::new(), nff: Some(n.counts), animation: None })
        }
        Format::Obj => {
            let mesh = obj::load_obj(path, true)?;
            let placeholder = Camera::new(Vec3::Z, Vec3::ZERO, Vec3::Y, 40.0, frame::WIDTH, frame::HEIGHT);
            let mut scene = Scene::new(placeholder);
            let m = scene.add_material(Material::default());
            scene.add(mesh, m);
            let mut notes = Vec::new();
            frame::complete(&mut scene, false, &path.display().to_string(), &mut notes);
            Ok(Loaded { scene, warnings: Vec::new(), notes, nff: None, animation: None })
        }
        Format::Gltf => self::gltf::load_gltf(path),
    }
}

/// Index of a material in [`Scene::materials`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MaterialId(pub u32);

/// A shape with its material.
#[derive(Clone, Debug)]
pub struct Object {
    pub shape: Shape,
    pub material: MaterialId,
}

/// Rendering settings that belong to the scene (the command line may override them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    pub background: Color,
    /// Longest chain of rays; the primary ray is step 1.
    pub max_depth: u32,
    /// Samples per pixel.
    pub samples: u32,
    /// Ambient light: this share of a surface's colour shows even in full shadow.
    pub ambient: f32,
    /// A ray whose share of its pixel (largest channel) falls below this is not
    /// followed, as POV-Ray's `adc_bailout`; 0 follows every ray to `max_depth`.
    pub cutoff: f32,
    /// How 8- and 16-bit output files encode colour (`[settings] color`).
    pub color: crate::film::ColorEncoding,
}

/// A ray's share of its pixel below which it is not followed, by default: POV-Ray's
/// `adc_bailout`, one level of an 8-bit channel.
pub const DEFAULT_CUTOFF: f32 = 1.0 / 255.0;

impl Default for Settings {
    fn default() -> Self {
        Settings {
            background: Color::ZERO,
            max_depth: 10,
            samples: 1,
            ambient: 0.2,
            cutoff: DEFAULT_CUTOFF,
            color: crate::film::ColorEncoding::Linear,
        }
    }
}

#[derive(Clone, Debug)]
pub struct Scene {
    pub camera: Camera,
    pub settings: Settings,
    pub lights: Vec<Light>,
    pub materials: Vec<Material>,
    pub objects: Vec<Object>,
    /// What the scene file called its materials and objects, for messages; empty for
    /// scenes built in code.
    pub labels: Labels,
}

/// Names and places from the scene file, so that messages about a material or an object
/// use the file's words (`material "planet" (line 31)`, `[[sphere]] 6 (line 80)`)
/// rather than internal indices.
#[derive(Clone, Debug, Default)]
pub struct Labels {
    /// By material index.
    pub materials: Vec<MaterialLabel>,
    /// By object index.
    pub objects: Vec<ObjectLabel>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct MaterialLabel {
    /// `planet` for `[material.planet]`; `None` for one written inline in an object.
    pub name: Option<String>,
    /// The object table an inline material belongs to (`[[sphere]] 2`).
    pub owner: Option<String>,
    /// Where it starts, from 1.
    pub line: usize,
    /// The texture `kind` as written (`planet`, `image`...), if any.
    pub texture: Option<String>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct ObjectLabel {
    /// The table: `sphere`, `quad`...
    pub table: &'static str,
    /// Which `[[table]]` of that kind, counted from 1 in file order.
    pub index: usize,
    pub line: usize,
}

impl std::fmt::Display for ObjectLabel {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(f, "[[{}]] {} (line {})", self.table, self.index, self.line)
    }
}

impl std::fmt::Display for MaterialLabel {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        match (&self.name, &self.owner) {
            (Some(n), _) => write!(f, "material {n:?} (line {})", self.line),
            (None, Some(o)) => write!(f, "the material of {o} (line {})", self.line),
            (None, None) => write!(f, "the material on line {}", self.line),
        }
    }
}

impl Scene {
    /// A material as the user knows it: its label from the file, else its index.
    pub fn material_label(&self, i: usize) -> String {
        self.labels.materials.get(i).map_or_else(|| format!("material {i}"), |l| l.to_string())
    }

    /// An object as the user knows it: its table, index and line, else its index.
    pub fn object_label(&self, i: usize) -> String {
        self.labels.objects.get(i).map_or_else(|| format!("object {i}"), |l| l.to_string())
    }
}

impl Scene {
    /// An empty scene with default settings.
    pub fn new(camera: Camera) -> Self {
        Scene {
            camera,
            settings: Settings::default(),
            lights: Vec::new(),
            materials: Vec::new(),
            objects: Vec::new(),
            labels: Labels::default(),
        }
    }

    pub fn add_material(&mut self, material: Material) -> MaterialId {
        self.materials.push(material);
        MaterialId(self.materials.len() as u32 - 1)
    }

    /// Adds a shape (anything that converts into [`Shape`]: `Sphere`, `Quad`, ...).
    pub fn add(&mut self, shape: impl Into<Shape>, material: MaterialId) -> &mut Self {
        self.objects.push(Object { shape: shape.into(), material });
        self
    }

    /// Adds a light (a [`Light`] or anything that converts into one: `PointLight`,
    /// `DirectionalLight`, `SpotLight`).
    pub fn add_light(&mut self, light: impl Into<Light>) -> &mut Self {
        self.lights.push(light.into());
        self
    }

    pub fn material(&self, id: MaterialId) -> &Material {
        &self.materials[id.0 as usize]
    }

    /// Things worth telling the user that do not stop a render.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        if self.objects.is_empty() {
            w.push("the scene has no objects: the image will be the background colour".to_string());
        }
        if self.lights.is_empty() {
            w.push("the scene has no lights: only ambient light will show".to_string());
        }
        w
    }
}
