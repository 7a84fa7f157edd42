//! The compiled half of the `whitted` Python package (`whitted._core`): a scene held in
//! Rust, rendering into numpy arrays and writing PNG files. The Pythonic surface (scene
//! classes, overrides, pickling, Dask) is in `whitted/*.py`; this stays a thin layer over
//! the library's public API so that changes to the render core do not ripple into it.

use numpy::{PyArray1, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PySlice, PyTuple};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc;
use std::time::Duration;
use whitted::camera::Camera;
use whitted::film::{ColorEncoding, Image, OutputError, OutputOptions, PendingOutput, rgb8_of};
use whitted::geometry::{Cone, Cylinder, Mesh, Quad, Sphere, Triangle};
use whitted::light::{Attenuation, DirectionalLight, Light, PointLight, SpotLight};
use whitted::material::Material;
use whitted::math::{Color, Vec3};
use whitted::render::Renderer;
use whitted::scene::{self, Animation, MaterialId, Scene};
use whitted::texture::Texture;

create_exception!(
    whitted,
    SceneError,
    PyException,
    "A scene that cannot be used; the message names the file, line, column and field, as the command line does."
);

/// How often a running render looks for Ctrl-C and reports progress.
const POLL: Duration = Duration::from_millis(20);

type V3 = (f32, f32, f32);
/// position, look_at, up, fov, width, height
type CameraArgs = (V3, V3, V3, f32, u32, u32);

fn v3((x, y, z): V3) -> Vec3 {
    Vec3::new(x, y, z)
}

/// A colour from Python's three numbers.
fn c3(v: V3) -> Color {
    v3(v).into()
}

fn t3(v: Vec3) -> V3 {
    (v.x, v.y, v.z)
}

fn scene_error(e: scene::SceneError) -> PyErr {
    SceneError::new_err(e.to_string())
}

/// A scene ready to render. Immutable once made, so that Dask may run several tasks on
/// one scene at once.
#[pyclass(module = "whitted._core", frozen)]
struct CoreScene {
    scene: Scene,
    /// What moves, for a TOML file with keys; `scene` is then one of its frames.
    animation: Option<Arc<Animation>>,
}

#[pymethods]
impl CoreScene {
    /// Reads a scene file with the command line's reader and messages; `format` is
    /// `toml`, `nff`, `obj` or `gltf`. Returns the scene and, for the text formats, the
    /// file's text (kept so the scene can be pickled; OBJ and glTF files are read again).
    #[staticmethod]
    fn load(py: Python<'_>, path: &str, format: &str) -> PyResult<(CoreScene, Option<String>)> {
        let path = Path::new(path);
        let format = match format {
            "toml" => scene::Format::Toml,
            "nff" => scene::Format::Nff,
            "obj" => scene::Format::Obj,
            "gltf" => scene::Format::Gltf,
            other => {
                return Err(PyValueError::new_err(format!("format: expected toml, nff, obj or gltf, got {other:?}")));
            }
        };
        let loaded = py.detach(|| scene::load_path(path, format)).map_err(scene_error)?;
        let text = match format {
            scene::Format::Toml | scene::Format::Nff => Some(
                std::fs::read_to_string(path)
                    .map_err(|e| SceneError::new_err(format!("{}: cannot read the scene: {e}", path.display())))?,
            ),
            scene::Format::Obj | scene::Format::Gltf => None,
        };
        Ok((CoreScene { scene: loaded.scene, animation: loaded.animation.map(Arc::new) }, text))
    }

    /// Parses scene text; `name` is used in messages, relative paths resolve against
    /// `base_dir`.
    #[staticmethod]
    fn parse(py: Python<'_>, text: &str, name: &str, base_dir: &str, nff: bool) -> PyResult<CoreScene> {
        let (scene, animation) = py
            .detach(|| {
                if nff {
                    scene::nff::read_nff(text.as_bytes(), name).map(|n| (n.scene, None))
                } else {
                    scene::load_animated_str(text, name, Path::new(base_dir))
                        .map(|(scene, a, _)| (scene, (!a.is_static()).then(|| Arc::new(a))))
                }
            })
            .map_err(scene_error)?;
        Ok(CoreScene { scene, animation })
    }

    /// `(first, last)` of an animated scene's `[settings] frames` (else 0 to its last
    /// key); `None` for a scene without keys.
    fn frames(&self) -> Option<(u32, u32)> {
        self.animation.as_ref().map(|a| (a.first, a.last))
    }

    /// The scene at `frame`: every keyed value of that frame written in (a scene without
    /// keys is returned as it is). Frames beyond the keys hold their values.
    fn at_frame(&self, py: Python<'_>, frame: u32) -> PyResult<CoreScene> {
        let Some(anim) = &self.animation else {
            return Ok(CoreScene { scene: self.scene.clone(), animation: None });
        };
        let scene = py.detach(|| anim.scene_at(&self.scene, frame)).map_err(scene_error)?;
        Ok(CoreScene { scene, animation: Some(anim.clone()) })
    }

    /// `camera` with the fields the scene's keys animate set to their values at `frame`.
    fn camera_at(&self, camera: CameraArgs, frame: u32) -> CameraArgs {
        let (position, look_at, up, fov, width, height) = camera;
        let cam = Camera::new(v3(position), v3(look_at), v3(up), fov, width, height);
        let c = self.animation.as_ref().map_or(cam, |a| a.camera_at(&cam, frame));
        (t3(c.position), t3(c.look_at), t3(c.up), c.fov, c.width, c.height)
    }

    /// An empty scene (its camera is given at render time).
    #[staticmethod]
    fn empty() -> CoreScene {
        let camera = Camera::new(Vec3::ZERO, Vec3::NEG_Z, Vec3::Y, 45.0, 64, 64);
        CoreScene { scene: Scene::new(camera), animation: None }
    }

    fn camera(&self) -> CameraArgs {
        let c = self.scene.camera;
        (t3(c.position), t3(c.look_at), t3(c.up), c.fov, c.width, c.height)
    }

    /// (background, max_depth, samples, ambient)
    fn settings(&self) -> (V3, u32, u32, f32) {
        let s = self.scene.settings;
        (t3(s.background.into()), s.max_depth, s.samples, s.ambient)
    }

    /// How the scene file says 8-bit output encodes colour (`[settings] color`; glTF
    /// files: sRGB): `"linear"` or `"srgb"`.
    fn color(&self) -> &'static str {
        match self.scene.settings.color {
            ColorEncoding::Linear => "linear",
            ColorEncoding::Srgb => "srgb",
        }
    }

    /// Counts of (materials, objects, lights).
    fn counts(&self) -> (usize, usize, usize) {
        (self.scene.materials.len(), self.scene.objects.len(), self.scene.lights.len())
    }

    /// A copy with settings changed and materials, objects and lights added. Objects
    /// are tuples `(kind, material index among the added ones, fields...)`, lights
    /// tuples `(kind, fields...)` (see [`light`]), checked on the Python side; what
    /// could still be wrong (a mesh index) raises ValueError.
    #[pyo3(signature = (background, ambient, materials, objects, lights))]
    fn extend(
        &self,
        background: Option<V3>,
        ambient: Option<f32>,
        materials: Vec<Bound<'_, PyTuple>>,
        objects: Vec<Bound<'_, PyTuple>>,
        lights: Vec<Bound<'_, PyTuple>>,
    ) -> PyResult<CoreScene> {
        let mut scene = self.scene.clone();
        if let Some(b) = background {
            scene.settings.background = c3(b);
        }
        if let Some(a) = ambient {
            scene.settings.ambient = a;
        }
        let first = scene.materials.len() as u32;
        for m in materials {
            scene.add_material(material(&m)?);
        }
        let count = scene.materials.len() as u32;
        for o in objects {
            let kind: String = o.get_item(0)?.extract()?;
            let index: u32 = o.get_item(1)?.extract()?;
            if first + index >= count {
                return Err(PyValueError::new_err(format!("material index {index} out of range")));
            }
            let id = MaterialId(first + index);
            let f = |i: usize| o.get_item(i);
            match kind.as_str() {
                "sphere" => scene.add(Sphere::new(v3(f(2)?.extract()?), f(3)?.extract()?), id),
                "quad" => scene.add(Quad::new(v3(f(2)?.extract()?), v3(f(3)?.extract()?), v3(f(4)?.extract()?)), id),
                "triangle" => {
                    scene.add(Triangle::new(v3(f(2)?.extract()?), v3(f(3)?.extract()?), v3(f(4)?.extract()?)), id)
                }
                "cylinder" => {
                    let (base, axis, radius, height, caps): (V3, V3, f32, f32, bool) = o.get_slice(2, 7).extract()?;
                    scene.add(Cylinder::new(v3(base), v3(axis), radius, height, caps), id)
                }
                "cone" => {
                    let (base, axis, radius, top, height, cap, top_cap): (V3, V3, f32, f32, f32, bool, bool) =
                        o.get_slice(2, 9).extract()?;
                    scene.add(Cone::truncated(v3(base), v3(axis), radius, top, height, cap, top_cap), id)
                }
                "mesh" => scene.add(mesh(&o)?, id),
                other => return Err(PyValueError::new_err(format!("unknown shape kind {other:?}"))),
            };
        }
        for l in lights {
            scene.add_light(light(&l)?);
        }
        // Objects and lights added here come after the file's, so the keys still point
        // at the ones they animate.
        Ok(CoreScene { scene, animation: self.animation.clone() })
    }

    /// Renders through `camera` into a new float32 array of shape (height, width, 3), or
    /// of the region's size. The GIL is released while the render runs on its own
    /// thread; this thread wakes every 20 ms to report progress and to look for Ctrl-C,
    /// which stops the render (within one tile) and raises KeyboardInterrupt.
    #[pyo3(signature = (camera, spp=None, max_depth=None, threads=None, region=None, progress=None))]
    #[allow(clippy::too_many_arguments)] // Python's keyword arguments
    fn render<'py>(
        &self,
        py: Python<'py>,
        camera: CameraArgs,
        spp: Option<u32>,
        max_depth: Option<u32>,
        threads: Option<usize>,
        region: Option<(u32, u32, u32, u32)>,
        progress: Option<Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (position, look_at, up, fov, width, height) = camera;
        let cam = Camera::new(v3(position), v3(look_at), v3(up), fov, width, height);
        let bad = |e: &dyn std::fmt::Display| PyValueError::new_err(format!("camera: {e}"));
        let mut r = Renderer::new(&self.scene).map_err(|e| bad(&e))?.camera(cam).map_err(|e| bad(&e))?;
        r = r.size(width, height);
        if let Some(n) = spp {
            r = r.spp(n);
        }
        if let Some(d) = max_depth {
            r = r.max_depth(d);
        }
        if let Some(t) = threads {
            r = r.threads(t);
        }
        if let Some((x0, y0, x1, y1)) = region {
            r = r.region(x0, y0, x1, y1).map_err(|e| PyValueError::new_err(e.to_string()))?;
        }
        let cancel = AtomicBool::new(false);
        let (done, total) = (AtomicUsize::new(0), AtomicUsize::new(0));
        let note = |d: usize, t: usize| {
            total.store(t, Ordering::Relaxed);
            done.fetch_max(d, Ordering::Relaxed);
        };
        let r = &r;
        let progress: Option<Py<PyAny>> = progress.map(Bound::unbind);
        let mut reported = 0;
        let mut report = |py: Python<'_>, force: bool| -> PyResult<()> {
            let (d, t) = (done.load(Ordering::Relaxed), total.load(Ordering::Relaxed));
            if let Some(cb) = &progress
                && t > 0
                && (d != reported || force)
            {
                reported = d;
                cb.call1(py, (d, t))?;
            }
            Ok(())
        };
        let progress_set = progress.is_some();
        let outcome: PyResult<Image> = py.detach(|| {
            std::thread::scope(|s| {
                let (tx, rx) = mpsc::channel();
                let (note, cancel) = (&note, &cancel);
                s.spawn(move || {
                    let out = r.render_with_progress_cancellable(note, cancel);
                    let _ = tx.send(out);
                });
                loop {
                    match rx.recv_timeout(POLL) {
                        Ok(Some(out)) => {
                            if progress_set {
                                Python::attach(|py| report(py, true))?;
                            }
                            return Ok(out.image);
                        }
                        Ok(None) | Err(mpsc::RecvTimeoutError::Disconnected) => {
                            return Err(PyException::new_err("the render stopped unexpectedly"));
                        }
                        Err(mpsc::RecvTimeoutError::Timeout) => {
                            let polled = Python::attach(|py| py.check_signals().and_then(|()| report(py, false)));
                            if let Err(e) = polled {
                                // Ctrl-C or a failing progress callback: stop the render,
                                // wait for its threads, then raise.
                                cancel.store(true, Ordering::Relaxed);
                                let _ = rx.recv();
                                return Err(e);
                            }
                        }
                    }
                }
            })
        });
        let image = outcome?;
        to_numpy(py, image)
    }

    /// Pickling goes through the Python wrapper, which keeps the scene's source.
    fn __reduce__(&self) -> PyResult<()> {
        Err(pyo3::exceptions::PyTypeError::new_err(
            "whitted._core.CoreScene is not picklable: pickle a whitted.Scene, which keeps the scene's source",
        ))
    }
}

/// A light from `(kind, fields...)`, its fields checked on the Python side as the
/// scene reader checks them; built as the reader builds it (colour times intensity in
/// f32, the same constructors), so that it renders as the same light read from TOML:
/// - `("point", position, color, intensity, attenuation)`
/// - `("directional", direction, color, intensity)`
/// - `("spot", position, direction, inner_angle, outer_angle, color, intensity, attenuation)`
///
/// `attenuation` is `(constant, linear, quadratic)`; `(1, 0, 0)` is none.
fn light(l: &Bound<'_, PyTuple>) -> PyResult<Light> {
    let kind: String = l.get_item(0)?.extract()?;
    let attenuation = |(c, lin, q): V3| Attenuation::new(c, lin, q);
    Ok(match kind.as_str() {
        "point" => {
            let (position, color, intensity, att): (V3, V3, f32, V3) = l.get_slice(1, 5).extract()?;
            PointLight::new(v3(position), c3(color) * intensity).with_attenuation(attenuation(att)).into()
        }
        "directional" => {
            let (direction, color, intensity): (V3, V3, f32) = l.get_slice(1, 4).extract()?;
            DirectionalLight::new(v3(direction), c3(color) * intensity).into()
        }
        "spot" => {
            let (position, direction, inner, outer, color, intensity, att): (V3, V3, f32, f32, V3, f32, V3) =
                l.get_slice(1, 8).extract()?;
            SpotLight::new(v3(position), v3(direction), inner, outer, c3(color) * intensity)
                .with_attenuation(attenuation(att))
                .into()
        }
        other => return Err(PyValueError::new_err(format!("unknown light kind {other:?}"))),
    })
}

/// `(color, diffuse, specular, shininess, reflectivity, transparency, ior, texture,
/// fresnel, absorption)`, checked on the Python side.
type MaterialArgs<'py> = (V3, f32, f32, f32, f32, f32, f32, Option<Bound<'py, PyTuple>>, bool, V3);

fn material(m: &Bound<'_, PyTuple>) -> PyResult<Material> {
    let args: MaterialArgs<'_> = m.extract()?;
    let (color, diffuse, specular, shininess, reflectivity, transparency, ior, texture, fresnel, absorption) = args;
    let texture = match texture {
        None => Texture::Solid(c3(color)),
        Some(t) => {
            let kind: String = t.get_item(0)?.extract()?;
            match kind.as_str() {
                "checker" => {
                    let (size, offset, a, b): (f32, V3, V3, V3) = t.get_slice(1, 5).extract()?;
                    Texture::Checker { size, offset: v3(offset), colors: [c3(a), c3(b)] }
                }
                "stripes" => {
                    let (axis, width, a, b): (V3, f32, V3, V3) = t.get_slice(1, 5).extract()?;
                    Texture::Stripes { axis: v3(axis).normalize_or(Vec3::Y), width, colors: [c3(a), c3(b)] }
                }
                other => return Err(PyValueError::new_err(format!("unknown texture kind {other:?}"))),
            }
        }
    };
    Ok(Material {
        texture,
        diffuse,
        specular,
        shininess,
        reflectivity,
        transparency,
        ior,
        fresnel,
        absorption: c3(absorption),
    })
}

/// `("mesh", material, positions (N, 3) float32, triangles (M, 3) uint32, normals or None, smooth)`
fn mesh(o: &Bound<'_, PyTuple>) -> PyResult<Mesh> {
    let positions: PyReadonlyArray2<'_, f32> = o.get_item(2)?.extract()?;
    let triangles: PyReadonlyArray2<'_, u32> = o.get_item(3)?.extract()?;
    let normals: Option<PyReadonlyArray2<'_, f32>> = o.get_item(4)?.extract()?;
    let smooth: bool = o.get_item(5)?.extract()?;
    let rows = |a: &[f32]| a.chunks_exact(3).map(|p| Vec3::new(p[0], p[1], p[2])).collect::<Vec<_>>();
    let positions = rows(positions.as_slice()?);
    let normals = normals.map(|n| n.as_slice().map(rows)).transpose()?.unwrap_or_default();
    let triangles = triangles.as_slice()?.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
    Mesh::new(positions, normals, Vec::new(), triangles, smooth)
        .map_err(|e| PyValueError::new_err(format!("mesh: {e}")))
}

fn to_numpy(py: Python<'_>, image: Image) -> PyResult<Bound<'_, PyAny>> {
    let (w, h) = (image.width() as usize, image.height() as usize);
    // The film's own memory becomes the array's, not a copy: an 800x800 image is 7.7 MB
    // that would be written twice (and faulted in twice) otherwise. Its pixels start
    // at `start` in that memory (the film begins on a huge page), hence the view.
    let (floats, start) = image.into_floats();
    let all = PyArray1::from_vec(py, floats);
    let pixels =
        all.call_method1("__getitem__", (PySlice::new(py, start as isize, (start + w * h * 3) as isize, 1),))?;
    pixels.call_method1("reshape", ((h, w, 3),))
}

/// An image array's width, height and floats (row after row, three per pixel), or why
/// it is not one.
fn image_floats<'a>(array: &'a PyReadonlyArray3<'_, f32>) -> PyResult<(u32, u32, &'a [f32])> {
    let shape = array.shape();
    if shape[2] != 3 || shape[0] == 0 || shape[1] == 0 {
        return Err(PyValueError::new_err(format!(
            "image: expected shape (height, width, 3) with height, width >= 1, got {shape:?}"
        )));
    }
    let (h, w) = (shape[0] as u32, shape[1] as u32);
    let data = array.as_slice()?;
    Ok((w, h, data))
}

fn from_numpy(array: &PyReadonlyArray3<'_, f32>) -> PyResult<Image> {
    let (w, h, data) = image_floats(array)?;
    let mut image = Image::new(w, h);
    for (dst, src) in image.pixels_mut().iter_mut().zip(data.chunks_exact(3)) {
        *dst = Vec3::new(src[0], src[1], src[2]);
    }
    Ok(image)
}

/// Writes a (height, width, 3) float32 C-contiguous array as a PNG file, whole or not at
/// all (a temporary file renamed into place), quantised as the command line does.
#[pyfunction]
fn write_png_array(py: Python<'_>, image: PyReadonlyArray3<'_, f32>, path: &str, srgb: bool) -> PyResult<()> {
    let image = from_numpy(&image)?;
    let path = Path::new(path);
    // The command line picks the format by extension; this function is named for one.
    if !path.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("png")) {
        return Err(PyValueError::new_err(format!("{}: write_png writes only PNG files (.png)", path.display())));
    }
    let options = OutputOptions { color: encoding(srgb), bits: None };
    py.detach(|| PendingOutput::create_with(path, options)?.commit(&image)).map_err(|e| match e {
        OutputError::Io { .. } => PyOSError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    })
}

/// The PNG file's bytes for an image (for Jupyter, and the frames Dask workers send):
/// quantised straight from the array as the command line does, the GIL released.
#[pyfunction]
fn encode_png<'py>(py: Python<'py>, image: PyReadonlyArray3<'_, f32>, srgb: bool) -> PyResult<Bound<'py, PyBytes>> {
    let (w, h, data) = image_floats(&image)?;
    let png = py.detach(|| {
        let rgb = image::RgbImage::from_raw(w, h, rgb8_of(data, encoding(srgb))).expect("h x w x 3 floats");
        let mut out = std::io::Cursor::new(Vec::new());
        rgb.write_to(&mut out, image::ImageFormat::Png).map(|()| out.into_inner())
    });
    let png = png.map_err(|e| PyValueError::new_err(format!("cannot encode the image: {e}")))?;
    Ok(PyBytes::new(py, &png))
}

fn encoding(srgb: bool) -> ColorEncoding {
    if srgb { ColorEncoding::Srgb } else { ColorEncoding::Linear }
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<CoreScene>()?;
    m.add("SceneError", m.py().get_type::<SceneError>())?;
    m.add_function(wrap_pyfunction!(write_png_array, m)?)?;
    m.add_function(wrap_pyfunction!(encode_png, m)?)?;
    m.add("MAX_RESOLUTION", scene::MAX_RESOLUTION)?;
    Ok(())
}
