//! Writing a scene as the project's TOML, so that scenes from other formats (NFF) can be
//! edited with the full format: `whitted convert balls.nff balls.toml`.
//!
//! What is written reads back ([`super::load_file`]) as the same scene, number for number:
//! every field is written, floats in their shortest form that parses back to the same
//! bits. Objects are written grouped by kind, in the order the loader reads the kinds
//! (spheres, quads, polygons, cylinders, cones, triangles, meshes), so a scene whose
//! objects are already in that order (as every loaded scene's are) keeps its order
//! too. Materials keep the names the file gave them (others are named `m0`, `m1`...),
//! and meshes are written inline. Shapes placed with a general transform, image and planet
//! textures, and mesh texture coordinates have no TOML form that reproduces them, and
//! are refused.

use super::Scene;
use crate::geometry::Shape;
use crate::light::Light;
use crate::math::Vec3;
use crate::texture::Texture;
use std::fmt::Write as _;
use std::io::Write;
use std::path::Path;

/// Why a scene could not be written.
#[derive(Debug, thiserror::Error)]
pub enum SaveError {
    #[error("cannot be written as TOML: {0}")]
    Unsupported(String),
    #[error("{path}: {source}")]
    Io { path: String, source: std::io::Error },
}

/// A float TOML reads back (as f64, then narrowed) to the same f32: the shortest form,
/// or failing that the f64 value's, which always does.
fn num(x: f32) -> Result<String, SaveError> {
    if !x.is_finite() {
        return Err(SaveError::Unsupported(format!("the number {x}")));
    }
    let short = format!("{x:?}");
    match short.parse::<f64>() {
        Ok(y) if (y as f32).to_bits() == x.to_bits() => Ok(short),
        _ => Ok(format!("{:?}", x as f64)),
    }
}

/// The TOML name of each material: the name the file gave it, else `m0`, `m1`...
/// (zero-padded, so they sort in order), skipping names already taken.
fn material_names(scene: &Scene) -> Vec<String> {
    let given: Vec<Option<&str>> =
        (0..scene.materials.len()).map(|i| scene.labels.materials.get(i).and_then(|l| l.name.as_deref())).collect();
    let mut taken: std::collections::HashSet<String> = given.iter().flatten().map(|s| s.to_string()).collect();
    let width = scene.materials.len().saturating_sub(1).to_string().len();
    given
        .iter()
        .enumerate()
        .map(|(i, g)| match g {
            Some(n) => n.to_string(),
            None => {
                let mut n = format!("m{i:0width$}");
                while taken.contains(&n) {
                    n.push('_');
                }
                taken.insert(n.clone());
                n
            }
        })
        .collect()
}

/// A table key: bare when TOML allows it, else quoted.
fn key(name: &str) -> String {
    if !name.is_empty() && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-') {
        name.to_owned()
    } else {
        toml::Value::String(name.to_owned()).to_string()
    }
}

/// A point, direction or colour ([`crate::math::Color`]) as a TOML array.
fn vec3(v: impl Into<Vec3>) -> Result<String, SaveError> {
    let v = v.into();
    Ok(format!("[{}, {}, {}]", num(v.x)?, num(v.y)?, num(v.z)?))
}

/// Writes `scene` as TOML. `note` goes into a comment at the top (where it came from).
pub fn write_toml(scene: &Scene, note: &str, out: &mut impl Write) -> Result<(), SaveError> {
    let mut s = String::with_capacity(1 << 16);
    let io = |source| SaveError::Io { path: "output".into(), source };
    let flush = |s: &mut String, out: &mut dyn Write| -> Result<(), SaveError> {
        out.write_all(s.as_bytes()).map_err(io)?;
        s.clear();
        Ok(())
    };
    // Writing into a String cannot fail; `let _ =` keeps that out of the way.
    for line in note.lines() {
        let _ = writeln!(s, "# {line}");
    }
    let c = &scene.camera;
    let _ = writeln!(
        s,
        "\n[camera]\nposition = {}\nlook_at = {}\nup = {}\nfov = {}\nwidth = {}\nheight = {}",
        vec3(c.position)?,
        vec3(c.look_at)?,
        vec3(c.up)?,
        num(c.fov)?,
        c.width,
        c.height
    );
    let st = &scene.settings;
    let _ = writeln!(
        s,
        "\n[settings]\nbackground = {}\nmax_depth = {}\nsamples = {}\nambient = {}\ncutoff = {}",
        vec3(st.background)?,
        st.max_depth,
        st.samples,
        num(st.ambient)?,
        num(st.cutoff)?
    );
    if st.color == crate::film::ColorEncoding::Srgb {
        let _ = writeln!(s, "color = \"srgb\"");
    }
    for l in &scene.lights {
        match l {
            Light::Point(p) => {
                let _ = writeln!(s, "\n[[light]]\nposition = {}", vec3(p.position)?);
            }
            Light::Directional(d) => {
                let _ = writeln!(s, "\n[[light]]\nkind = \"directional\"\ndirection = {}", vec3(d.direction)?);
            }
            Light::Spot(p) => {
                let _ = writeln!(
                    s,
                    "\n[[light]]\nkind = \"spot\"\nposition = {}\ndirection = {}\ninner_angle = {}\nouter_angle = {}",
                    vec3(p.position)?,
                    vec3(p.direction)?,
                    num(p.inner_angle)?,
                    num(p.outer_angle)?
                );
            }
        }
        let _ = writeln!(s, "color = {}", vec3(l.color())?);
        if let Some(a) = l.attenuation().filter(|a| !a.is_none()) {
            let _ = writeln!(s, "attenuation = [{}, {}, {}]", num(a.constant)?, num(a.linear)?, num(a.quadratic)?);
        }
    }

    let names = material_names(scene);
    let name = |id: u32| names[id as usize].clone();
    for (i, m) in scene.materials.iter().enumerate() {
        let _ = writeln!(s, "\n[material.{}]", key(&names[i]));
        match &m.texture {
            Texture::Solid(c) => {
                let _ = writeln!(s, "color = {}", vec3(*c)?);
            }
            Texture::Stripes { axis, width, colors } => {
                let _ = writeln!(
                    s,
                    "texture = {{ kind = \"stripes\", axis = {}, width = {}, colors = [{}, {}] }}",
                    vec3(*axis)?,
                    num(*width)?,
                    vec3(colors[0])?,
                    vec3(colors[1])?
                );
            }
            Texture::Checker { size, offset, colors } => {
                let _ = writeln!(
                    s,
                    "texture = {{ kind = \"checker\", size = {}, offset = {}, colors = [{}, {}] }}",
                    num(*size)?,
                    vec3(*offset)?,
                    vec3(colors[0])?,
                    vec3(colors[1])?
                );
            }
            Texture::Image { .. } => {
                let kind = scene.labels.materials.get(i).and_then(|l| l.texture.as_deref());
                let why = match kind {
                    Some("planet") => "its planet texture is generated when the scene loads and has no TOML form yet",
                    Some("image") => "its image texture has no TOML form yet",
                    _ => "its image texture has no TOML form",
                };
                return Err(SaveError::Unsupported(format!("{}: {why}", scene.material_label(i))));
            }
        }
        let _ = writeln!(
            s,
            "diffuse = {}\nspecular = {}\nshininess = {}\nreflectivity = {}\ntransparency = {}\nior = {}",
            num(m.diffuse)?,
            num(m.specular)?,
            num(m.shininess)?,
            num(m.reflectivity)?,
            num(m.transparency)?,
            num(m.ior)?
        );
        if m.fresnel {
            let _ = writeln!(s, "fresnel = true");
        }
        if m.absorbs() {
            let _ = writeln!(s, "absorption = {}", vec3(m.absorption)?);
        }
    }
    flush(&mut s, out)?;

    // Kinds in the loader's order.
    for kind in 0..7 {
        for (i, o) in scene.objects.iter().enumerate() {
            let material = toml::Value::String(name(o.material.0)).to_string();
            match (&o.shape, kind) {
                (Shape::Sphere(x), 0) => {
                    let _ = writeln!(
                        s,
                        "\n[[sphere]]\ncenter = {}\nradius = {}\nmaterial = {material}",
                        vec3(x.center)?,
                        num(x.radius)?
                    );
                }
                (Shape::Quad(q), 1) => {
                    let _ = writeln!(
                        s,
                        "\n[[quad]]\ncorner = {}\nedge_u = {}\nedge_v = {}\nmaterial = {material}",
                        vec3(q.corner)?,
                        vec3(q.edge_u)?,
                        vec3(q.edge_v)?
                    );
                }
                (Shape::Polygon(p), 2) => {
                    let vertices = p.vertices().iter().map(|v| vec3(*v)).collect::<Result<Vec<_>, _>>()?;
                    let _ = writeln!(s, "\n[[polygon]]\nvertices = [{}]\nmaterial = {material}", vertices.join(", "));
                }
                (Shape::Cylinder(c), 3) => {
                    let _ = writeln!(
                        s,
                        "\n[[cylinder]]\nbase = {}\naxis = {}\nradius = {}\nheight = {}\ncaps = {}\nmaterial = {material}",
                        vec3(c.base)?,
                        vec3(c.axis)?,
                        num(c.radius)?,
                        num(c.height)?,
                        c.caps
                    );
                }
                (Shape::Cone(c), 4) => {
                    let _ = writeln!(
                        s,
                        "\n[[cone]]\nbase = {}\naxis = {}\nradius = {}\ntop_radius = {}\nheight = {}\ncap = {}\ntop_cap = {}\nmaterial = {material}",
                        vec3(c.base)?,
                        vec3(c.axis)?,
                        num(c.radius)?,
                        num(c.top_radius)?,
                        num(c.height)?,
                        c.cap,
                        c.top_cap && c.top_radius > 0.0
                    );
                }
                (Shape::Triangle(t), 5) => {
                    let _ = writeln!(
                        s,
                        "\n[[triangle]]\nvertices = [{}, {}, {}]\nmaterial = {material}",
                        vec3(t.v0)?,
                        vec3(t.v1)?,
                        vec3(t.v2)?
                    );
                }
                (Shape::Mesh(m), 6) => {
                    if !m.uvs().is_empty() {
                        return Err(SaveError::Unsupported(format!(
                            "{}: mesh texture coordinates have no TOML form yet",
                            scene.object_label(i)
                        )));
                    }
                    let _ = writeln!(s, "\n[[mesh]]\nsmooth = {}\nmaterial = {material}", m.is_smooth());
                    let mut array = |s: &mut String, key: &str, items: &[Vec3]| -> Result<(), SaveError> {
                        let _ = writeln!(s, "{key} = [");
                        for v in items {
                            let _ = writeln!(s, "  {},", vec3(*v)?);
                            if s.len() > 1 << 16 {
                                flush(s, out)?;
                            }
                        }
                        let _ = writeln!(s, "]");
                        Ok(())
                    };
                    array(&mut s, "positions", m.positions())?;
                    if m.is_smooth() {
                        array(&mut s, "normals", m.normals())?;
                    }
                    let _ = writeln!(s, "triangles = [");
                    for [a, b, c] in m.triangles() {
                        let _ = writeln!(s, "  [{a}, {b}, {c}],");
                        if s.len() > 1 << 16 {
                            flush(&mut s, out)?;
                        }
                    }
                    let _ = writeln!(s, "]");
                }
                (Shape::Transformed(t), 0) => {
                    let what = match scene.labels.objects.get(i).map(|l| l.table) {
                        _ if t.mesh().is_some() => "an instance of a mesh".to_owned(),
                        Some(t @ ("sphere" | "cylinder" | "cone")) => format!("a {t} stretched by a non-uniform scale"),
                        _ => "a shape under a non-uniform scale".to_owned(),
                    };
                    return Err(SaveError::Unsupported(format!(
                        "{}: {what} has no TOML form without its transform",
                        scene.object_label(i)
                    )));
                }
                _ => {}
            }
            if s.len() > 1 << 16 {
                flush(&mut s, out)?;
            }
        }
    }
    flush(&mut s, out)
}

/// Writes `scene` to `path` as TOML, whole or not at all (see [`write_atomically`]).
pub fn save_toml(scene: &Scene, note: &str, path: &Path) -> Result<(), SaveError> {
    let mut inner = None;
    write_atomically(path, |w| {
        write_toml(scene, note, w).map_err(|e| match e {
            SaveError::Io { source, .. } => source,
            other => {
                let message = other.to_string();
                inner = Some(other);
                std::io::Error::other(message)
            }
        })
    })
    .map_err(|source| inner.take().unwrap_or(SaveError::Io { path: path.display().to_string(), source }))
}

/// Writes a file whole or not at all: into a temporary file beside `path`, synced and
/// renamed over it only once `write` has succeeded, so a failure never leaves half a
/// file or clobbers a good one.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<&mut std::fs::File>) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let mut temp = crate::film::temp_file_beside(path)?;
    {
        let mut w = std::io::BufWriter::with_capacity(1 << 16, temp.as_file_mut());
        write(&mut w)?;
        w.flush()?;
    }
    temp.as_file().sync_all()?;
    let temp_path = temp.path().to_owned();
    let result = temp.persist(path);
    crate::cleanup::forget(&temp_path);
    result.map_err(|e| e.error)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Camera;
    use crate::geometry::{Cone, Cylinder, Mesh, Polygon, Quad, Sphere, Triangle};
    use crate::light::{Attenuation, DirectionalLight, PointLight, SpotLight};
    use crate::material::Material;
    use crate::math::Color;
    use crate::sampler::Rng;

    #[test]
    fn floats_read_back_to_the_same_bits() {
        let mut r = Rng::new(7);
        for i in 0..200_000u32 {
            let x = match i % 4 {
                0 => f32::from_bits(r.next_u32()),
                1 => r.next_f32(),
                2 => (r.next_f32() - 0.5) * 1e6,
                _ => (r.next_f32() - 0.5) * 1e-6,
            };
            if !x.is_finite() {
                continue;
            }
            let text = format!("x = {}\n", num(x).unwrap());
            #[derive(serde::Deserialize)]
            struct X {
                x: f32,
            }
            let back: X = toml::from_str(&text).unwrap_or_else(|e| panic!("{text}: {e}"));
            assert_eq!(back.x.to_bits(), x.to_bits(), "{text}");
        }
    }

    /// A scene with every kind of shape and material this format can hold.
    fn every_kind() -> Scene {
        let mut s =
            Scene::new(Camera::new(Vec3::new(0.1, 0.2, 5.3), Vec3::ZERO, Vec3::new(0.0, 1.0, 0.3), 41.3, 40, 30));
        s.settings.background = Color::new(0.078, 0.361, 0.753);
        s.settings.ambient = 0.288_675_13;
        s.settings.max_depth = 7;
        s.add_light(PointLight::new(Vec3::new(4.0, 3.0, 2.0), Color::splat(0.3)));
        let falloff = Attenuation::new(1.0, 0.125, 1.0 / 3.0);
        s.add_light(PointLight::new(Vec3::new(-4.0, 3.0, 2.0), Color::splat(0.7)).with_attenuation(falloff));
        s.add_light(DirectionalLight::new(Vec3::new(0.3, -1.0, -0.7), Color::new(1.0, 0.9, 0.8)));
        let spot = SpotLight::new(Vec3::new(0.0, 5.0, 1.0), Vec3::new(0.1, -1.0, 0.2), 12.5, 1.0 / 0.03, Color::ONE);
        s.add_light(spot.with_attenuation(Attenuation::new(0.0, 0.0, 0.1)));
        let a = s.add_material(Material::color(Color::new(1.0, 0.9, 0.7)).reflective(0.5).shininess(3.0827));
        let b = s.add_material(Material {
            texture: Texture::Checker {
                size: 0.7,
                offset: Vec3::new(0.0, 1.0, 0.0),
                colors: [Color::ZERO, Color::ONE],
            },
            ..Material::default().transparent(0.3, 1.5)
        });
        let glass = Material::default().transparent(0.9, 1.45).with_fresnel(true);
        let glass = s.add_material(glass.absorbing(Color::new(0.1, 0.0, 1.0 / 3.0)));
        for i in 0..11 {
            s.add(Sphere::new(Vec3::new(i as f32 * 0.1, 0.3, -1.0 / 3.0), 1.0 / 7.0), a);
        }
        s.add(Sphere::new(Vec3::new(0.0, -2.0, 0.0), 0.5), glass);
        s.add(Quad::new(Vec3::ZERO, Vec3::X * 2.0, Vec3::new(0.0, 0.3, 1.1)), b);
        let pts = vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        s.add(Polygon::new(pts.clone()).unwrap(), a);
        s.add(Cylinder::new(Vec3::ONE, Vec3::new(0.3, 1.0, 0.7), 0.3, 1.7, false), a);
        s.add(Cone::truncated(Vec3::ONE, Vec3::new(-0.3, 1.0, 0.1), 0.9, 0.2, 1.3, false, false), b);
        s.add(Cone::new(Vec3::ONE, Vec3::new(-0.3, 1.0, 0.1), 0.9, 1.3, true), b);
        s.add(Triangle::new(Vec3::ZERO, Vec3::X, Vec3::new(0.2, 0.9, 0.1)), b);
        let normals = pts.iter().map(|p| (*p + Vec3::Z).normalize()).collect();
        s.add(Mesh::new(pts.clone(), normals, vec![], vec![[0, 1, 2], [0, 2, 3]], true).unwrap(), a);
        s.add(Mesh::new(pts, vec![], vec![], vec![[0, 1, 2]], false).unwrap(), b);
        s
    }

    #[test]
    fn a_written_scene_loads_back_the_same() {
        let scene = every_kind();
        let mut text = Vec::new();
        write_toml(&scene, "test scene\nsecond line", &mut text).unwrap();
        let text = String::from_utf8(text).unwrap();
        let back = crate::scene::load_str(&text, "w.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}\n{text}"));
        assert_eq!(back.camera, scene.camera);
        assert_eq!(back.settings, scene.settings);
        assert_eq!(back.lights, scene.lights);
        assert_eq!(back.objects.len(), scene.objects.len());
        for (a, b) in back.objects.iter().zip(&scene.objects) {
            assert_eq!(a.shape, b.shape);
            assert_eq!(a.material, b.material);
        }
        for (a, b) in back.materials.iter().zip(&scene.materials) {
            assert_eq!(format!("{a:?}"), format!("{b:?}"));
        }
        // Written again, the text is the same.
        let mut again = Vec::new();
        write_toml(&back, "test scene\nsecond line", &mut again).unwrap();
        assert_eq!(String::from_utf8(again).unwrap(), text);
    }

    #[test]
    fn unsupported_things_are_refused() {
        let mut scene = every_kind();
        let m = glam::Affine3A::from_scale(Vec3::new(1.0, 2.0, 3.0));
        let sphere = crate::geometry::transform(Sphere::new(Vec3::ZERO, 1.0).into(), &m).unwrap();
        scene.add(sphere, crate::scene::MaterialId(0));
        assert!(matches!(write_toml(&scene, "", &mut Vec::new()), Err(SaveError::Unsupported(_))));
    }

    #[test]
    fn saving_is_atomic() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.toml");
        std::fs::write(&path, "old").unwrap();
        let mut scene = every_kind();
        scene.materials[0].texture = Texture::Image {
            map: std::sync::Arc::new(crate::texture::planet(4, 4, 1)),
            scale: crate::math::Vec2::ONE,
            offset: crate::math::Vec2::ZERO,
        };
        assert!(matches!(save_toml(&scene, "", &path), Err(SaveError::Unsupported(_))));
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        save_toml(&every_kind(), "", &path).unwrap();
        assert!(std::fs::read_to_string(&path).unwrap().contains("[[mesh]]"));
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
