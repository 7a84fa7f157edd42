//! NFF, the Neutral File Format of Eric Haines' Standard Procedural Databases (SPD):
//! sphereflake (balls), gears, mount, rings, teapot, tetra, tree. The format is
//! described in Eric Haines' SPD documentation (`nff.doc`); this is what each entity becomes here.
//!
//! Reading: whitespace-separated tokens, which may run over several lines (the spec's
//! `c` takes 3 lines, SPD writes it on one), `#` to the end of a line is a comment. The
//! file streams through one reused buffer of a chunk of lines, so size is limited by
//! the scene's memory, not the file's; a big file is read in parts on several threads
//! at once, each streaming its own, with the same result (`chunks`). Every error names the file, line, column and the
//! command at fault, as in `balls.nff:12:1: s: expected 4 numbers (x y z radius), found 3 ...`:
//! unknown commands, too few or too many numbers, values that are not (finite)
//! numbers, vertex counts that do not match the vertices, impossible views, materials
//! and cones. Nothing is rendered then.
//!
//! | entity | becomes |
//! |--------|---------|
//! | `v` | the camera. `angle` is the full vertical field of view, edge to edge of the image (so the outermost rays of the `--spd-rules` corner pattern are exactly `angle` apart); `up` need not be perpendicular; `hither` is read and ignored (rays start at the eye); `resolution` is the image size unless `--width/--height` say otherwise, 512 × 512 when absent. The aspect ratio follows the resolution with square pixels. |
//! | `b` | the background colour (black without one). |
//! | `l` | a point light. Without a colour each light gets `sqrt(N) / (2N)` white for N lights, as the SPD docs suggest, and the ambient term is that value too. A file without lights renders with ambient light only, like a TOML scene (with a warning). |
//! | `f` | a material, see [`nff_material`]. Identical `f` lines share one. Objects before the first `f` are white and matte (with a warning). |
//! | `s` | a sphere. A negative radius (inside visible) is made positive: surfaces are shaded from whichever side they are seen. A zero radius is skipped with a warning. |
//! | `c` | open-ended (no caps): a truncated cone, a pointed cone when one radius is 0, a cylinder when they are equal. The narrow end becomes the cone's top. Both radii negative (inside visible) are made positive. Coinciding ends, mixed-sign radii are errors; both radii 0 is skipped with a warning. |
//! | `p` | triangles in a mesh: convex polygons are fanned, concave ones ear-clipped (see [`triangulate`]), wound as the polygon. Zero-area polygons are skipped with a warning. |
//! | `pp` | as `p`, with the per-vertex normals kept for smooth shading (normalised). |
//!
//! All `p` of one material form one flat-shaded mesh object, all `pp` of one material
//! one smooth mesh, so a scene of thousands of polygons is a few objects with their own
//! BVHs. Objects come out grouped by kind (spheres, cylinders, cones, meshes), the order
//! the TOML loader uses, so a converted scene loads back identical.
//!
//! `render --spd-rules` ([`Renderer::spd_rules`](crate::render::Renderer::spd_rules))
//! adds the SPD's testing procedure: opaque surfaces are then shaded one-sided, as its
//! rule 2 allows. Its exception for the teapot's body (double-sided, since the lid
//! leaves a gap) cannot be recognised in the file and is not made.

use super::{MaterialId, Object, Scene, SceneError};
use crate::camera::{Camera, CameraError};
use crate::geometry::triangulate::{Split, triangulate};
use crate::geometry::{Cone, Cylinder, Mesh, Quad, Shape, Sphere};
use crate::light::PointLight;
use crate::material::Material;
use crate::math::{Color, Vec3};
use crate::texture::Texture;
use std::collections::HashMap;
use std::fmt;
use std::io::BufRead;
use std::path::Path;

mod chunks;
mod lexer;

use lexer::{Cmd, Lexer, Tok, is_keyword, parse_f32, show};

/// Image size when the `v` entity has no `resolution` (the SPD benchmark size).
pub const DEFAULT_RESOLUTION: u32 = 512;

/// A scene read from NFF, with what was changed or skipped on the way.
#[derive(Clone, Debug)]
pub struct Nff {
    pub scene: Scene,
    /// Things worth telling the user that did not stop the reading.
    pub warnings: Vec<String>,
    pub counts: Counts,
}

/// How many of each entity the file held, and its size.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    pub lines: usize,
    pub bytes: u64,
    pub views: usize,
    pub backgrounds: usize,
    pub lights: usize,
    pub fills: usize,
    pub spheres: usize,
    pub cones: usize,
    pub polygons: usize,
    pub patches: usize,
    /// Triangles made from `p` and `pp`.
    pub triangles: usize,
    /// Polygons read as one parallelogram rather than triangles (`FEW_QUADS`).
    pub quads: usize,
}

/// Most vertices one `p` polygon or `pp` patch may have.
pub const MAX_POLYGON_VERTICES: u64 = 1_000_000;

/// Reads an NFF file.
pub fn load_nff(path: &Path) -> Result<Nff, SceneError> {
    let name = path.display().to_string();
    let file = super::limits::open_regular(path, "scene")?;
    // A big file in chunks, one a thread (of the current rayon pool), where that gives
    // what one pass gives (see `chunks`); else, and for every error, in one pass.
    let len = file.metadata().map_or(0, |m| m.len());
    let chunks = (len / CHUNK_BYTES).min(rayon::current_num_threads() as u64) as usize;
    if chunks > 1
        && let Some(nff) = chunks::read_chunked(path, &name, len, chunks)
    {
        return nff;
    }
    read_nff(std::io::BufReader::with_capacity(1 << 16, file), &name)
}

/// Bytes of a file per chunk at least, for [`load_nff`] to read it in chunks.
const CHUNK_BYTES: u64 = 1 << 17;

/// Reads NFF text; `name` is used in messages.
pub fn read_nff(input: impl BufRead, name: &str) -> Result<Nff, SceneError> {
    let mut p = Parser::new(input, name);
    p.run()?;
    p.finish()
}

/// The material for `f r g b Kd Ks Shine T ior`, mapped so that the rendered colour is
/// what the format defines: `Kd`·Lambert + `Ks`·reflected + `T`·transmitted + `Ks`·Phong
/// highlight (exponent `Shine`, as SPD's own `readnff` does), plus an ambient term.
///
/// - colour → a solid texture; reflectivity = `Ks`; transparency = `T`; ior = `ior`
///   when `T` > 0 (opaque SPD materials write `ior 0`, so it is not used then).
/// - The integrator scales a surface's own shading (ambient and Lambert) by the share
///   left to it, `1 − reflectivity − transparency`, so diffuse = `Kd / (1 − Ks − T)`
///   makes the Lambert term exactly `Kd`; the ambient term is the scene's ambient
///   times that share.
/// - `Ks + T > 1` (not physical, but found in files): both are scaled down to sum to 1,
///   and `Kd` then has no share left; the second value says so (for a warning).
/// - specular = `Ks`, shininess = `Shine` (SPD writes 100000 for "no highlight", which
///   is as good as none).
///
/// Returns the material and whether it had to be changed (Ks + T > 1, or Kd lost).
pub fn nff_material(color: Color, kd: f32, ks: f32, shine: f32, t: f32, ior: f32) -> (Material, bool) {
    let sum = ks + t;
    let (reflectivity, transparency) = if sum > 1.0 { (ks / sum, t / sum) } else { (ks, t) };
    let mut m = Material {
        texture: Texture::Solid(color),
        diffuse: 0.0,
        specular: ks,
        shininess: shine,
        reflectivity,
        transparency,
        ior: if t > 0.0 { ior } else { 1.0 },
        ..Material::default()
    };
    let share = m.local_share();
    let changed = sum > 1.0 || (kd > 0.0 && share <= 0.0);
    m.diffuse = if share > 0.0 { kd / share } else { 0.0 };
    (m, changed)
}

/// The entity being read, for messages about its numbers.
#[derive(Clone, Copy)]
struct Entity {
    cmd: Cmd,
    line: usize,
    column: usize,
}

/// Triangles of one material, flat (`p`) or smooth (`pp`).
#[derive(Default)]
struct MeshBuilder {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    /// Polygons added.
    polygons: usize,
    /// Each polygon as a parallelogram, while every one so far is one and there are at
    /// most [`FEW_QUADS`].
    quads: Vec<Quad>,
}

/// A material's flat polygons, when they are this many parallelograms or fewer (a
/// floor, a wall, a box), become quads rather than a mesh: a mesh of a few triangles
/// costs a walk of its own tree and a normal rebuilt at each hit, a fifth of the
/// sphereflake's camera rays for its floor. More stay a mesh, whose tree and packed
/// triangle tests pay there, and so do mixed ones (quads beside a mesh over the same
/// ground would make rays walk both).
const FEW_QUADS: usize = 4;

/// Problems worth one warning each however often they occur: how many, and the first line.
#[derive(Default)]
struct Tally {
    count: usize,
    first_line: usize,
}

impl Tally {
    fn add(&mut self, line: usize) {
        if self.count == 0 {
            self.first_line = line;
        }
        self.count += 1;
    }
}

struct Parser<'a, R> {
    lex: Lexer<R>,
    name: &'a str,
    counts: Counts,
    /// The camera and the lines of its `v`, `at`, `up` and `angle` (for its errors).
    view: Option<(Camera, [Tok; 4])>,
    background: Color,
    lights: Vec<(Vec3, Option<Color>)>,
    materials: Vec<Material>,
    material_ids: HashMap<[u32; 8], MaterialId>,
    current: Option<MaterialId>,
    spheres: Vec<Object>,
    cylinders: Vec<Object>,
    cones: Vec<Object>,
    meshes: Vec<(MaterialId, bool, MeshBuilder)>,
    mesh_ids: HashMap<(MaterialId, bool), usize>,
    /// Reused for each polygon.
    points: Vec<Vec3>,
    normals: Vec<Vec3>,
    zero_area: Tally,
    /// Polygons some of whose triangles had (nearly) no area and were left out.
    thin: Tally,
    zero_size: Tally,
    crossing: Tally,
    shares: Tally,
    no_material: Tally,
    /// Per material made, in order: its `f` line's numbers (none for the white one
    /// made for objects before any `f`), its line, and whether it had to be changed
    /// (`shares`): what [`chunks`] needs to number one chunk's materials after another's.
    made: Vec<(Option<[u32; 8]>, usize, bool)>,
}

type Res<T> = Result<T, SceneError>;

impl<'a, R: BufRead> Parser<'a, R> {
    fn new(input: R, name: &'a str) -> Self {
        Parser {
            lex: Lexer::new(input),
            name,
            counts: Counts::default(),
            view: None,
            background: Color::ZERO,
            lights: Vec::new(),
            materials: Vec::new(),
            material_ids: HashMap::new(),
            current: None,
            spheres: Vec::new(),
            cylinders: Vec::new(),
            cones: Vec::new(),
            meshes: Vec::new(),
            mesh_ids: HashMap::new(),
            points: Vec::new(),
            normals: Vec::new(),
            zero_area: Tally::default(),
            thin: Tally::default(),
            zero_size: Tally::default(),
            crossing: Tally::default(),
            shares: Tally::default(),
            no_material: Tally::default(),
            made: Vec::new(),
        }
    }

    fn error(&self, line: usize, column: usize, field: &str, message: impl Into<String>) -> SceneError {
        SceneError::At { file: self.name.to_owned(), line, column, field: field.to_owned(), message: message.into() }
    }

    fn at(&self, e: &Entity, message: impl Into<String>) -> SceneError {
        self.error(e.line, e.column, e.cmd.name(), message)
    }

    /// Numbers ran out: say how many there were and what came instead.
    fn short(&self, e: &Entity, want: &(impl fmt::Display + ?Sized), got: usize, next: Option<Tok>) -> SceneError {
        let instead = match next {
            None => "at the end of the file".to_owned(),
            Some(t) => format!("before `{}` on line {}", show(self.lex.text(t)), t.line),
        };
        self.at(e, format!("expected {want}, found {got} {instead}"))
    }

    fn peek(&mut self) -> Res<Option<Tok>> {
        self.lex.peek(self.name)
    }

    /// The next number of entity `e`, which has read `got` of the `want` it needs.
    #[inline]
    fn number(&mut self, e: &Entity, want: &(impl fmt::Display + ?Sized), got: usize) -> Res<f32> {
        match self.lex.quick_number() {
            Some(x) => Ok(x),
            None => self.any_number(e, want, got),
        }
    }

    /// [`Parser::number`] for the cases [`Lexer::quick_number`] leaves: the next line
    /// to read, numbers the fast parser does not take, and errors.
    #[inline(never)]
    fn any_number(&mut self, e: &Entity, want: &(impl fmt::Display + ?Sized), got: usize) -> Res<f32> {
        let next = self.peek()?;
        let Some(tok) = next else { return Err(self.short(e, want, got, None)) };
        let word = self.lex.text(tok);
        match parse_f32(word) {
            Some(x) if x.is_finite() => {
                self.lex.bump(tok);
                Ok(x)
            }
            Some(_) => {
                Err(self.error(tok.line, tok.column(), e.cmd.name(), format!("{} is not a finite number", show(word))))
            }
            None if is_keyword(word) => Err(self.short(e, want, got, Some(tok))),
            None => Err(self.error(tok.line, tok.column(), e.cmd.name(), format!("{:?} is not a number", show(word)))),
        }
    }

    fn vec3(&mut self, e: &Entity, want: &(impl fmt::Display + ?Sized), got: usize) -> Res<Vec3> {
        Ok(Vec3::new(self.number(e, want, got)?, self.number(e, want, got + 1)?, self.number(e, want, got + 2)?))
    }

    /// A whole number in `lo..=hi` (vertex counts, resolutions).
    fn count(&mut self, e: &Entity, what: &str, lo: u64, hi: u64) -> Res<u64> {
        let Some(tok) = self.peek()? else { return Err(self.short(e, &what, 0, None)) };
        let word = self.lex.text(tok);
        let text = std::str::from_utf8(word).unwrap_or("");
        let err = |m: String| self.error(tok.line, tok.column(), e.cmd.name(), m);
        // Written out only in a message (formatted for every polygon, it cost more than
        // reading the polygon's count).
        let range = || if hi == u32::MAX as u64 { format!("at least {lo}") } else { format!("between {lo} and {hi}") };
        match text.parse::<u64>() {
            Ok(n) if (lo..=hi).contains(&n) => {
                self.lex.bump(tok);
                Ok(n)
            }
            Ok(n) if n < lo => Err(err(format!("{what} must be at least {lo} (got {n})"))),
            Ok(n) => Err(err(format!("{what} must be at most {hi} (got {n})"))),
            Err(_) if !text.is_empty() && text.bytes().all(|b| b.is_ascii_digit()) => {
                Err(err(format!("{what} must be at most {hi} (got {})", show(word))))
            }
            Err(_) if is_keyword(word) => Err(self.short(e, &what, 0, Some(tok))),
            Err(_) if parse_f32(word).is_some() => {
                Err(err(format!("{what} must be a whole number {} (got {})", range(), show(word))))
            }
            Err(_) => Err(err(format!("{what}: {:?} is not a whole number", show(word)))),
        }
    }

    /// Reads entities until the end of the input.
    fn run(&mut self) -> Res<()> {
        let mut previous: Option<Entity> = None;
        while let Some(tok) = self.peek()? {
            let word = self.lex.text(tok);
            let Some(cmd) = Cmd::parse(word) else {
                let shown = show(word);
                if let (Some(prev), Some(_)) = (previous, parse_f32(word)) {
                    let takes = match prev.cmd {
                        Cmd::Polygon | Cmd::Patch => "than the vertex count it declares".to_owned(),
                        Cmd::Light => "than its 3 or 6".to_owned(),
                        Cmd::View => "than its labelled lines".to_owned(),
                        c => format!("than its {}", takes(c)),
                    };
                    let message = format!("more numbers after `{}` (line {}) {takes}", prev.cmd.name(), prev.line);
                    return Err(self.error(tok.line, tok.column(), prev.cmd.name(), message));
                }
                let message = format!("unknown NFF command {shown:?} (expected v, b, l, f, c, s, p or pp)");
                return Err(self.error(tok.line, tok.column(), &shown, message));
            };
            self.lex.bump(tok);
            let e = Entity { cmd, line: tok.line, column: tok.column() };
            match cmd {
                Cmd::View => self.view(&e, tok)?,
                Cmd::Background => {
                    let c = self.vec3(&e, "3 numbers (r g b)", 0)?;
                    self.background = self.color(&e, c.into())?;
                    self.counts.backgrounds += 1;
                }
                Cmd::Light => self.light(&e)?,
                Cmd::Fill => self.fill(&e)?,
                Cmd::Sphere => self.sphere(&e)?,
                Cmd::Cone => self.cone(&e)?,
                Cmd::Polygon | Cmd::Patch => self.polygon(&e)?,
            }
            previous = Some(e);
        }
        Ok(())
    }

    fn color(&self, e: &Entity, c: Color) -> Res<Color> {
        if c.min_element() >= 0.0 {
            Ok(c)
        } else {
            Err(self.at(e, format!("colour components must be >= 0 (got {c})")))
        }
    }

    fn view(&mut self, e: &Entity, v: Tok) -> Res<()> {
        if let Some((_, [first, ..])) = &self.view {
            return Err(self.at(e, format!("a second view (the first is on line {})", first.line)));
        }
        let label = |p: &mut Self, name: &'static str, optional: bool| -> Res<Option<Tok>> {
            let next = p.peek()?;
            match next {
                Some(t) if p.lex.text(t) == name.as_bytes() => {
                    p.lex.bump(t);
                    Ok(Some(t))
                }
                _ if optional => Ok(None),
                Some(t) => {
                    let m = format!(
                        "expected the line `{name}` of the view, found `{}` on line {}",
                        show(p.lex.text(t)),
                        t.line
                    );
                    Err(p.at(e, m))
                }
                None => Err(p.at(e, format!("expected the line `{name}` of the view, found the end of the file"))),
            }
        };
        let sub = |t: Tok| Entity { cmd: Cmd::View, line: t.line, column: t.column() };
        let t_from = label(self, "from", false)?.expect("required");
        let from = self.vec3(&sub(t_from), "3 numbers after `from`", 0)?;
        let t_at = label(self, "at", false)?.expect("required");
        let at = self.vec3(&sub(t_at), "3 numbers after `at`", 0)?;
        let t_up = label(self, "up", false)?.expect("required");
        let up = self.vec3(&sub(t_up), "3 numbers after `up`", 0)?;
        let t_angle = label(self, "angle", false)?.expect("required");
        let angle = self.number(&sub(t_angle), "1 number after `angle`", 0)?;
        if let Some(t) = label(self, "hither", true)? {
            self.number(&sub(t), "1 number after `hither`", 0)?;
        }
        let (mut w, mut h) = (DEFAULT_RESOLUTION, DEFAULT_RESOLUTION);
        if let Some(t) = label(self, "resolution", true)? {
            let max = super::MAX_RESOLUTION as u64;
            w = self.count(&sub(t), "the resolution's width", 1, max)? as u32;
            h = self.count(&sub(t), "the resolution's height", 1, max)? as u32;
        }
        let camera = Camera::new(from, at, up, angle, w, h);
        if let Err(err) = camera.rig() {
            let t = match err {
                CameraError::ZeroDirection => t_at,
                CameraError::BadUp => t_up,
                CameraError::BadFov => t_angle,
            };
            return Err(self.at(&sub(t), err.to_string().replace("look_at", "at").replace("field of view", "angle")));
        }
        self.view = Some((camera, [v, t_at, t_up, t_angle]));
        self.counts.views += 1;
        Ok(())
    }

    fn light(&mut self, e: &Entity) -> Res<()> {
        let want = "3 numbers (x y z) or 6 (x y z r g b)";
        let position = self.vec3(e, want, 0)?;
        let next = self.peek()?;
        let color = match next {
            Some(t) if parse_f32(self.lex.text(t)).is_some() => {
                let c = self.vec3(e, want, 3)?;
                Some(self.color(e, c.into())?)
            }
            _ => None,
        };
        self.lights.push((position, color));
        self.counts.lights += 1;
        Ok(())
    }

    fn fill(&mut self, e: &Entity) -> Res<()> {
        let want = "8 numbers (r g b Kd Ks Shine T ior)";
        let mut v = [0.0f32; 8];
        for (i, x) in v.iter_mut().enumerate() {
            *x = self.number(e, want, i)?;
        }
        let [r, g, b, kd, ks, shine, t, ior] = v;
        let color = self.color(e, Color::new(r, g, b))?;
        for (value, what) in [(kd, "Kd"), (ks, "Ks"), (shine, "Shine"), (t, "T")] {
            if value < 0.0 {
                return Err(self.at(e, format!("{what} must be >= 0 (got {value})")));
            }
        }
        if t > 0.0 && ior <= 0.0 {
            return Err(
                self.at(e, format!("a transmitting material (T = {t}) needs an index of refraction > 0 (got {ior})"))
            );
        }
        self.counts.fills += 1;
        // Identical lines (SPD repeats them) share a material and so a mesh.
        let key = v.map(f32::to_bits);
        if let Some(&id) = self.material_ids.get(&key) {
            self.current = Some(id);
            return Ok(());
        }
        let (material, changed) = nff_material(color, kd, ks, shine, t, ior);
        if changed {
            self.shares.add(e.line);
        }
        self.made.push((Some(key), e.line, changed));
        self.materials.push(material);
        let id = MaterialId(self.materials.len() as u32 - 1);
        self.material_ids.insert(key, id);
        self.current = Some(id);
        Ok(())
    }

    /// The material of the next object: the last `f`, or white and matte before any.
    fn material(&mut self, e: &Entity) -> MaterialId {
        if let Some(id) = self.current {
            return id;
        }
        self.no_material.add(e.line);
        let (m, _) = nff_material(Color::ONE, 1.0, 0.0, 0.0, 0.0, 1.0);
        self.made.push((None, e.line, false));
        self.materials.push(m);
        let id = MaterialId(self.materials.len() as u32 - 1);
        self.current = Some(id);
        id
    }

    fn sphere(&mut self, e: &Entity) -> Res<()> {
        let want = "4 numbers (x y z radius)";
        let center = self.vec3(e, want, 0)?;
        let radius = self.number(e, want, 3)?.abs();
        self.counts.spheres += 1;
        if radius == 0.0 {
            self.zero_size.add(e.line);
            return Ok(());
        }
        let material = self.material(e);
        self.spheres.push(Object { shape: Sphere::new(center, radius).into(), material });
        Ok(())
    }

    fn cone(&mut self, e: &Entity) -> Res<()> {
        let want = "8 numbers (base x y z radius, apex x y z radius)";
        let mut base = self.vec3(e, want, 0)?;
        let mut base_r = self.number(e, want, 3)?;
        let mut apex = self.vec3(e, want, 4)?;
        let mut apex_r = self.number(e, want, 7)?;
        self.counts.cones += 1;
        if (base_r < 0.0 && apex_r > 0.0) || (base_r > 0.0 && apex_r < 0.0) {
            return Err(self.at(e, format!("the radii must have the same sign (got {base_r} and {apex_r})")));
        }
        let axis = apex - base;
        let height = axis.length();
        if !height.is_finite() || height <= 0.0 {
            return Err(self.at(e, "the base and apex points must differ"));
        }
        (base_r, apex_r) = (base_r.abs(), apex_r.abs());
        if base_r == 0.0 && apex_r == 0.0 {
            self.zero_size.add(e.line);
            return Ok(());
        }
        let material = self.material(e);
        if base_r == apex_r {
            self.cylinders.push(Object { shape: Cylinder::new(base, axis, base_r, height, false).into(), material });
            return Ok(());
        }
        if apex_r > base_r {
            (base, apex, base_r, apex_r) = (apex, base, apex_r, base_r);
        }
        let cone = Cone::truncated(base, apex - base, base_r, apex_r, height, false, false);
        self.cones.push(Object { shape: cone.into(), material });
        Ok(())
    }

    fn polygon(&mut self, e: &Entity) -> Res<()> {
        let smooth = e.cmd == Cmd::Patch;
        // Past a million vertices a polygon is refused up front rather than half-read:
        // faces that large belong in an OBJ mesh.
        let n = self.count(e, "the vertex count", 3, MAX_POLYGON_VERTICES)? as usize;
        let per = if smooth { 6 } else { 3 };
        // Written out only in a message: formatting it for every polygon took an eighth
        // of the time to read a scene of triangles.
        let want = Vertices { n, smooth };
        self.points.clear();
        self.normals.clear();
        for i in 0..n {
            let p = self.vec3(e, &want, per * i)?;
            self.points.push(p);
            if smooth {
                let normal = self.vec3(e, &want, per * i + 3)?;
                self.normals.push(normal.normalize_or_zero());
            }
        }
        if smooth {
            self.counts.patches += 1;
        } else {
            self.counts.polygons += 1;
        }
        let material = self.material(e);
        let index = *self.mesh_ids.entry((material, smooth)).or_insert_with(|| {
            self.meshes.push((material, smooth, MeshBuilder::default()));
            self.meshes.len() - 1
        });
        let mesh = &mut self.meshes[index].2;
        if mesh.positions.len() + n > u32::MAX as usize {
            return Err(self.at(e, "more than 4 billion vertices in one material's mesh"));
        }
        let before = mesh.triangles.len();
        match triangulate(&self.points, mesh.positions.len() as u32, &mut mesh.triangles) {
            None => {
                self.zero_area.add(e.line);
                return Ok(());
            }
            Some(Split::FanFallback) => self.crossing.add(e.line),
            Some(_) => {}
        }
        // Every triangle below the area tolerance (a polygon of very many vertices,
        // each sliver too thin): say so rather than dropping it silently.
        if mesh.triangles.len() == before {
            self.zero_area.add(e.line);
            return Ok(());
        }
        // Triangles left out as (nearly) flat: harmless for collinear corners, but the
        // slivers of a huge polygon leave part of it uncovered. Say so where the
        // triangles cover less than the outline does (Newell's area, in f64).
        if mesh.triangles.len() - before < self.points.len() - 2 {
            let p = |i: usize| self.points[i].as_dvec3();
            let n = self.points.len();
            let outline = (0..n).fold(glam::DVec3::ZERO, |a, i| a + p(i).cross(p((i + 1) % n))).length() / 2.0;
            let base = mesh.positions.len() as u32;
            let covered: f64 = mesh.triangles[before..]
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|i| p((i - base) as usize));
                    (b - a).cross(c - a).length() / 2.0
                })
                .sum();
            if covered < outline * (1.0 - 1e-4) {
                self.thin.add(e.line);
            }
        }
        mesh.polygons += 1;
        if !smooth && mesh.polygons <= FEW_QUADS && mesh.quads.len() + 1 == mesh.polygons {
            mesh.quads.extend(parallelogram(&self.points));
        }
        mesh.positions.extend_from_slice(&self.points);
        mesh.normals.extend_from_slice(&self.normals);
        self.counts.triangles += mesh.triangles.len() - before;
        Ok(())
    }

    fn finish(mut self) -> Res<Nff> {
        self.counts.lines = self.lex.line;
        self.counts.bytes = self.lex.bytes;
        let Some((camera, _)) = self.view else {
            return Err(self.error(
                self.lex.line.max(1),
                1,
                "v",
                "the file has no `v` view (from, at, up, angle...): NFF needs one",
            ));
        };
        let mut scene = Scene::new(camera);
        scene.settings.background = self.background;
        let n = self.lights.len();
        if n > 0 {
            // The SPD docs' relative intensity for each of N lights and for ambient.
            let share = (n as f32).sqrt() / (2.0 * n as f32);
            scene.settings.ambient = share;
            for (position, color) in self.lights {
                scene.add_light(PointLight::new(position, color.unwrap_or(Color::splat(share))));
            }
        }
        scene.materials = self.materials;
        let mut warnings = Vec::new();
        let mut warn = |t: &Tally, what: &str| {
            if t.count > 0 {
                let s = if t.count == 1 { "" } else { "s" };
                warnings.push(format!("{}: {} {what}{s} (the first on line {})", self.name, t.count, t.first_line));
            }
        };
        warn(&self.zero_area, "zero-area polygon skipped");
        warn(&self.thin, "polygon partly uncovered (slivers of too little area left out)");
        warn(&self.zero_size, "zero-size sphere or cone skipped");
        warn(&self.crossing, "self-crossing or very large concave polygon fanned");
        warn(&self.shares, "material with Ks + T > 1 (scaled to sum to 1) or no room for Kd");
        warn(&self.no_material, "object before any `f`, made white and matte");
        // The spheres' list becomes the objects' (most of a scene's, often): a copy
        // into a fresh list would write as many new pages, each a page fault.
        let mut objects = std::mem::take(&mut self.spheres);
        objects.append(&mut self.cylinders);
        objects.append(&mut self.cones);
        for (material, smooth, m) in self.meshes {
            if m.triangles.is_empty() {
                continue;
            }
            if m.quads.len() == m.polygons {
                self.counts.quads += m.quads.len();
                self.counts.triangles -= m.triangles.len();
                objects.extend(m.quads.into_iter().map(|q| Object { shape: q.into(), material }));
                continue;
            }
            let normals = if smooth { m.normals } else { Vec::new() };
            let mesh = Mesh::new(m.positions, normals, Vec::new(), m.triangles, smooth)
                .map_err(|e| SceneError::File { file: self.name.to_owned(), message: e.to_string() })?;
            objects.push(Object { shape: Shape::from(mesh), material });
        }
        scene.objects = objects;
        Ok(Nff { scene, warnings, counts: self.counts })
    }
}

/// Four corners `a b c d` that make a parallelogram (`a + c = b + d` to a millionth of
/// its size) with area, as a [`Quad`] (see [`FEW_QUADS`]).
fn parallelogram(points: &[Vec3]) -> Option<Quad> {
    let &[a, b, c, d] = points else { return None };
    let (u, v) = (b - a, d - a);
    let size = u.length().max(v.length());
    let off = (a + c - b - d).length();
    let area = u.cross(v).length();
    (off <= 1e-6 * size && area > 1e-6 * size * size).then(|| Quad::new(a, u, v))
}

/// What a polygon of `n` vertices needs, for "expected ...".
struct Vertices {
    n: usize,
    smooth: bool,
}

impl fmt::Display for Vertices {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = self.n;
        match self.smooth {
            true => write!(f, "{n} vertices of 6 numbers (x y z nx ny nz): {} numbers", 6 * n),
            false => write!(f, "{n} vertices of 3 numbers (x y z): {} numbers", 3 * n),
        }
    }
}

/// What an entity with a fixed count of numbers takes, for "too many numbers".
fn takes(cmd: Cmd) -> &'static str {
    match cmd {
        Cmd::Background => "3 (r g b)",
        Cmd::Fill => "8 (r g b Kd Ks Shine T ior)",
        Cmd::Cone => "8 (base x y z radius, apex x y z radius)",
        Cmd::Sphere => "4 (x y z radius)",
        _ => "numbers",
    }
}

#[cfg(test)]
mod tests;
