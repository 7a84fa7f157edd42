//! NFF, the Neutral File Format of Eric Haines' Standard Procedural Databases (SPD):
//! sphereflake (balls), gears, mount, rings, teapot, tetra, tree. The format is
//! described in Eric Haines' SPD documentation (`nff.doc`); this is what each entity becomes here.
//!
//! Reading: whitespace-separated tokens, which may run over several lines (the spec's
//! `c` takes 3 lines, SPD writes it on one), `#` to the end of a line is a comment. The
//! file streams through one reused buffer of a chunk of lines, so size is limited by
//! the scene's memory, not the file's. Every error names the file, line, column and the
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

use super::limits::MAX_LINE;
use super::{MaterialId, Object, Scene, SceneError};
use crate::camera::{Camera, CameraError};
use crate::geometry::triangulate::{Split, triangulate};
use crate::geometry::{Cone, Cylinder, Mesh, Shape, Sphere};
use crate::light::PointLight;
use crate::material::Material;
use crate::math::{Color, Vec3};
use crate::texture::Texture;
use std::collections::HashMap;
use std::fmt;
use std::io::BufRead;
use std::path::Path;

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
}

/// Most vertices one `p` polygon or `pp` patch may have.
pub const MAX_POLYGON_VERTICES: u64 = 1_000_000;

/// Reads an NFF file.
pub fn load_nff(path: &Path) -> Result<Nff, SceneError> {
    let name = path.display().to_string();
    let file = super::limits::open_regular(path, "scene")?;
    read_nff(std::io::BufReader::with_capacity(1 << 16, file), &name)
}

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

/// The NFF entities.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Cmd {
    View,
    Background,
    Light,
    Fill,
    Cone,
    Sphere,
    Polygon,
    Patch,
}

impl Cmd {
    fn parse(word: &[u8]) -> Option<Cmd> {
        Some(match word {
            b"v" => Cmd::View,
            b"b" => Cmd::Background,
            b"l" => Cmd::Light,
            b"f" => Cmd::Fill,
            b"c" => Cmd::Cone,
            b"s" => Cmd::Sphere,
            b"p" => Cmd::Polygon,
            b"pp" => Cmd::Patch,
            _ => return None,
        })
    }

    fn name(self) -> &'static str {
        match self {
            Cmd::View => "v",
            Cmd::Background => "b",
            Cmd::Light => "l",
            Cmd::Fill => "f",
            Cmd::Cone => "c",
            Cmd::Sphere => "s",
            Cmd::Polygon => "p",
            Cmd::Patch => "pp",
        }
    }
}

/// The labels inside a `v` entity.
const VIEW_LABELS: [&[u8]; 6] = [b"from", b"at", b"up", b"angle", b"hither", b"resolution"];

/// A word that starts an entity or a `v` line: met where a number was expected, it
/// means numbers are missing rather than that one is malformed.
fn is_keyword(word: &[u8]) -> bool {
    Cmd::parse(word).is_some() || VIEW_LABELS.contains(&word)
}

/// A token of the current line: its byte range in the lexer's buffer and where it
/// starts in the file.
#[derive(Clone, Copy, Debug)]
struct Tok {
    start: usize,
    end: usize,
    line: usize,
    column: usize,
}

impl Tok {
    fn column(&self) -> usize {
        self.column
    }
}

/// Bytes read from the input at a time; lines are found inside the chunk, not copied
/// out one by one (which took a tenth of the time to read a scene of triangles).
const CHUNK: usize = 1 << 16;

/// Whitespace-separated tokens, line by line, over a buffer of whole lines read a chunk
/// at a time: memory stays at a chunk (or the longest line) whatever the file's size.
struct Lexer<R> {
    input: R,
    /// Input read but not yet lexed past: `buf[..filled]`, whose lines from `next` on
    /// are still to come.
    buf: Vec<u8>,
    filled: usize,
    /// Where the current line starts, where its content ends (before any `#` comment
    /// or the line break) and where the next line starts.
    start: usize,
    end: usize,
    next: usize,
    pos: usize,
    line: usize,
    bytes: u64,
    eof: bool,
}

impl<R: BufRead> Lexer<R> {
    fn new(input: R) -> Self {
        Lexer {
            input,
            buf: vec![0; CHUNK],
            filled: 0,
            start: 0,
            end: 0,
            next: 0,
            pos: 0,
            line: 0,
            bytes: 0,
            eof: false,
        }
    }

    /// The next token, not consumed; `None` at the end of the input. Stays valid until
    /// [`Lexer::bump`] and the next `peek`.
    fn peek(&mut self, name: &str) -> Result<Option<Tok>, SceneError> {
        loop {
            while self.pos < self.end && self.buf[self.pos].is_ascii_whitespace() {
                self.pos += 1;
            }
            if self.pos < self.end {
                let start = self.pos;
                let mut end = start;
                while end < self.end && !self.buf[end].is_ascii_whitespace() {
                    end += 1;
                }
                return Ok(Some(Tok { start, end, line: self.line, column: start - self.start + 1 }));
            }
            if !self.next_line(name)? {
                return Ok(None);
            }
        }
    }

    /// Moves to the next line, reading more input when the buffer holds no whole line;
    /// `false` at the end of the input. A line past [`MAX_LINE`] is an error.
    fn next_line(&mut self, name: &str) -> Result<bool, SceneError> {
        if self.next_line_read() {
            return Ok(true);
        }
        // No whole line left in the buffer: read until there is one.
        let end = loop {
            if self.filled - self.next > MAX_LINE {
                return Err(SceneError::At {
                    file: name.to_owned(),
                    line: self.line + 1,
                    column: 1,
                    field: "line".to_owned(),
                    message: format!("longer than {} MiB: not a text file of this format?", MAX_LINE >> 20),
                });
            }
            if self.eof {
                if self.next == self.filled {
                    return Ok(false);
                }
                break self.filled; // a last line without a line break
            }
            // Keep the partial line, read more after it.
            self.buf.copy_within(self.next..self.filled, 0);
            (self.filled, self.next) = (self.filled - self.next, 0);
            if self.filled == self.buf.len() {
                self.buf.resize(self.buf.len() * 2, 0);
            }
            let chunk = self.input.fill_buf().map_err(|e| SceneError::File {
                file: name.to_owned(),
                message: format!("cannot read line {}: {e}", self.line + 1),
            })?;
            let n = chunk.len().min(self.buf.len() - self.filled);
            self.buf[self.filled..self.filled + n].copy_from_slice(&chunk[..n]);
            self.input.consume(n);
            self.filled += n;
            self.eof = n == 0;
            if let Some(i) = memchr::memchr(b'\n', &self.buf[self.next..self.filled]) {
                break self.next + i + 1;
            }
        };
        self.enter_line(end);
        Ok(true)
    }

    /// Moves to the next line if the buffer holds all of it already (no reading, so no
    /// error): `false` if not.
    #[inline(always)]
    fn next_line_read(&mut self) -> bool {
        match memchr::memchr(b'\n', &self.buf[self.next..self.filled]) {
            Some(i) => {
                self.enter_line(self.next + i + 1);
                true
            }
            None => false,
        }
    }

    /// Makes the line from `next` to `end` the current one.
    #[inline(always)]
    fn enter_line(&mut self, end: usize) {
        (self.start, self.pos, self.next) = (self.next, self.next, end);
        self.end = memchr::memchr(b'#', &self.buf[self.start..end]).map_or(end, |i| self.start + i);
        self.line += 1;
        self.bytes += (end - self.start) as u64;
    }

    /// The next token as a number, consumed, where that is quick to tell: it is on the
    /// current line and [`fast_f32`] reads it (nearly every number of a real file).
    /// Else `None`, and nothing consumed. Reading a scene of triangles spent a quarter
    /// of its time getting numbers through [`Lexer::peek`] before this.
    #[inline(always)]
    fn quick_number(&mut self) -> Option<f32> {
        let mut at = self.pos;
        loop {
            while at < self.end && self.buf[at].is_ascii_whitespace() {
                at += 1;
            }
            if at < self.end {
                break;
            }
            // The line is used up: go on to the next if it is in the buffer already.
            if !self.next_line_read() {
                self.pos = at;
                return None;
            }
            at = self.pos;
        }
        let line = &self.buf[..self.end];
        let start = at;
        while at < line.len() && !line[at].is_ascii_whitespace() {
            at += 1;
        }
        let x = fast_f32(&line[start..at])?;
        self.pos = at;
        Some(x)
    }

    fn bump(&mut self, tok: Tok) {
        self.pos = tok.end;
    }

    fn text(&self, tok: Tok) -> &[u8] {
        &self.buf[tok.start..tok.end]
    }
}

/// A token as it appears in messages: lossy, and shortened.
fn show(word: &[u8]) -> String {
    let s = String::from_utf8_lossy(word);
    if s.chars().count() > 24 { format!("{}...", s.chars().take(24).collect::<String>()) } else { s.into_owned() }
}

fn parse_f32(word: &[u8]) -> Option<f32> {
    fast_f32(word).or_else(|| std::str::from_utf8(word).ok()?.parse().ok())
}

/// Powers of ten that are exact in f32.
const POW10: [f32; 11] = [1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10];

/// Clinger's fast path: a decimal whose digits fit in 24 bits, scaled by at most 10^10
/// either way, is one exactly represented integer times or over one exact power of
/// ten, so a single correctly rounded f32 operation gives the same value as the full
/// parser. Numbers written with `%g` (six digits) nearly all qualify; anything else
/// (`None`) goes to `str::parse`.
#[inline(always)]
fn fast_f32(w: &[u8]) -> Option<f32> {
    let (negative, mut i) = match w.first()? {
        b'-' => (true, 1),
        b'+' => (false, 1),
        _ => (false, 0),
    };
    let (mut m, mut exp, mut digits) = (0u32, 0i32, 0);
    let mut digit = |c: u8, m: &mut u32| -> Option<()> {
        *m = m.checked_mul(10)?.checked_add((c - b'0') as u32)?;
        digits += 1;
        (*m <= 1 << 24).then_some(())
    };
    while i < w.len() && w[i].is_ascii_digit() {
        digit(w[i], &mut m)?;
        i += 1;
    }
    if i < w.len() && w[i] == b'.' {
        i += 1;
        while i < w.len() && w[i].is_ascii_digit() {
            digit(w[i], &mut m)?;
            exp -= 1;
            i += 1;
        }
    }
    if digits == 0 {
        return None;
    }
    if i < w.len() && (w[i] == b'e' || w[i] == b'E') {
        i += 1;
        let sign = match w.get(i) {
            Some(b'-') => {
                i += 1;
                -1
            }
            Some(b'+') => {
                i += 1;
                1
            }
            _ => 1,
        };
        let start = i;
        let mut e = 0i32;
        while i < w.len() && w[i].is_ascii_digit() && i - start < 4 {
            e = e * 10 + (w[i] - b'0') as i32;
            i += 1;
        }
        if i == start {
            return None;
        }
        exp += sign * e;
    }
    if i != w.len() || !(-10..=10).contains(&exp) {
        return None;
    }
    let x = if exp >= 0 { m as f32 * POW10[exp as usize] } else { m as f32 / POW10[(-exp) as usize] };
    Some(if negative { -x } else { x })
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
}

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
                    self.background = self.color(&e, c)?;
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
                Some(self.color(e, c)?)
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
        let mut objects = Vec::new();
        objects.append(&mut self.spheres);
        objects.append(&mut self.cylinders);
        objects.append(&mut self.cones);
        for (material, smooth, m) in self.meshes {
            if m.triangles.is_empty() {
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
mod tests {
    use super::*;

    const VIEW: &str = "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 40\nhither 0.01\nresolution 32 24\n";

    fn read(text: &str) -> Result<Nff, SceneError> {
        read_nff(text.as_bytes(), "t.nff")
    }

    fn at(text: &str) -> (usize, usize, String, String) {
        match read(text).unwrap_err() {
            SceneError::At { line, column, field, message, .. } => (line, column, field, message),
            e => panic!("expected a located error, got {e}"),
        }
    }

    #[test]
    fn every_entity_is_read() {
        let text = format!(
            "# comment\nb 0.1 0.2 0.3\n{VIEW}l 1 2 3\nl 4 5 6 0.5 0.5 0.5\nf 1 0 0 0.5 0.5 3.0827 0 1\n\
             s 0 0 0 1\nc 0 0 0 1 0 1 0 0.5\nc 0 0 0 1\n 0 2 0 1\nc 1 1 1 0 1 2 1 1\n\
             p 3\n0 0 0\n1 0 0\n0 1 0\npp 3\n0 0 1 0 0 1\n1 0 1 0 0 1\n0 1 1 0.6 0 0.8\n\
             f 1 1 1 0 0.1 100000 0.9 1.5\ns 2 0 0 0.5 # trailing comment\n"
        );
        let nff = read(&text).unwrap();
        let c = nff.counts;
        assert_eq!(
            (c.views, c.backgrounds, c.lights, c.fills, c.spheres, c.cones, c.polygons, c.patches, c.triangles),
            (1, 1, 2, 2, 2, 3, 1, 1, 2)
        );
        assert_eq!(c.lines, 27);
        let s = &nff.scene;
        assert_eq!(s.settings.background, Vec3::new(0.1, 0.2, 0.3));
        assert_eq!((s.camera.width, s.camera.height, s.camera.fov), (32, 24, 40.0));
        assert_eq!(s.camera.position, Vec3::new(0.0, 0.0, 5.0));
        let share = 2f32.sqrt() / 4.0;
        assert_eq!(s.lights[0].color(), Vec3::splat(share));
        assert_eq!(s.lights[1].color(), Vec3::splat(0.5));
        assert_eq!(s.settings.ambient, share);
        assert_eq!(s.materials.len(), 2);
        // Grouped by kind: 2 spheres, 1 cylinder, 2 cones, 2 meshes (flat, smooth).
        let kinds: Vec<&str> = s
            .objects
            .iter()
            .map(|o| match &o.shape {
                Shape::Sphere(_) => "s",
                Shape::Cylinder(_) => "y",
                Shape::Cone(_) => "c",
                Shape::Mesh(m) if m.is_smooth() => "pp",
                Shape::Mesh(_) => "p",
                _ => "?",
            })
            .collect();
        assert_eq!(kinds, ["s", "s", "y", "c", "c", "p", "pp"]);
        assert_eq!(s.objects[1].material, MaterialId(1));
        let Shape::Cone(cone) = &s.objects[3].shape else { unreachable!() };
        assert_eq!((cone.radius, cone.top_radius, cone.height, cone.cap, cone.top_cap), (1.0, 0.5, 1.0, false, false));
        let Shape::Cone(pointed) = &s.objects[4].shape else { unreachable!() };
        // `c 1 1 1 0 1 2 1 1`: the wide end is the base, pointing down to the apex.
        assert_eq!((pointed.radius, pointed.top_radius, pointed.height, pointed.axis), (1.0, 0.0, 1.0, -Vec3::Y));
        let Shape::Mesh(patch) = &s.objects[6].shape else { unreachable!() };
        assert_eq!(patch.normals()[2], Vec3::new(0.6, 0.0, 0.8));
        assert!(nff.warnings.is_empty(), "{:?}", nff.warnings);
    }

    #[test]
    fn materials_map_onto_the_formats_weights() {
        let (m, changed) = nff_material(Color::new(1.0, 0.9, 0.7), 0.5, 0.5, 3.0827, 0.0, 1.0);
        assert!(!changed);
        assert_eq!((m.reflectivity, m.transparency, m.specular, m.shininess, m.ior), (0.5, 0.0, 0.5, 3.0827, 1.0));
        // The integrator's own share times diffuse gives back Kd.
        assert!((m.local_share() * m.diffuse - 0.5).abs() < 1e-7);
        let (glass, changed) = nff_material(Color::ONE, 0.1, 0.1, 30.0, 0.8, 1.5);
        assert!(!changed);
        assert_eq!((glass.transparency, glass.ior), (0.8, 1.5));
        assert!((glass.local_share() * glass.diffuse - 0.1).abs() < 1e-6);
        // Opaque materials write ior 0: not used.
        assert_eq!(nff_material(Color::ONE, 0.8, 0.0, 100000.0, 0.0, 0.0).0.ior, 1.0);
        // Ks + T > 1: scaled to sum to 1, Kd has no room.
        let (m, changed) = nff_material(Color::ONE, 0.5, 0.8, 10.0, 0.8, 1.5);
        assert!(changed);
        assert_eq!((m.reflectivity, m.transparency, m.diffuse), (0.5, 0.5, 0.0));
        // A perfect mirror without diffuse is fine.
        assert!(!nff_material(Color::ONE, 0.0, 1.0, 10.0, 0.0, 0.0).1);
    }

    #[test]
    fn polygons_of_a_material_share_one_mesh_and_skip_zero_area() {
        let text = format!(
            "{VIEW}l 0 0 9\nf 1 1 1 1 0 0 0 0\np 4\n0 0 0 1 0 0 1 1 0 0 1 0\np 3 0 0 0 1 1 1 2 2 2\n\
             f 1 1 1 1 0 0 0 0\np 6 0 0 1 2 0 1 2 1 1 1 1 1 1 2 1 0 2 1\n"
        );
        let nff = read(&text).unwrap();
        assert_eq!(nff.scene.objects.len(), 1);
        assert_eq!(nff.scene.materials.len(), 1);
        let Shape::Mesh(m) = &nff.scene.objects[0].shape else { unreachable!() };
        assert_eq!(m.triangle_count(), 2 + 4);
        assert!(!m.is_smooth());
        assert_eq!(nff.warnings.len(), 1, "{:?}", nff.warnings);
        assert!(nff.warnings[0].contains("1 zero-area polygon skipped (the first on line 12)"), "{}", nff.warnings[0]);
    }

    #[test]
    fn spheres_and_cones_are_normalised() {
        let text = format!(
            "{VIEW}f 1 1 1 1 0 0 0 0\ns 0 0 0 -2\ns 0 0 0 0\nc 0 2 0 0.5 0 0 0 1\nc 0 0 0 -1 0 1 0 -0.5\nc 0 0 0 0 0 1 0 0\n"
        );
        let nff = read(&text).unwrap();
        let s = &nff.scene;
        assert_eq!(s.objects.len(), 3);
        let Shape::Sphere(sp) = &s.objects[0].shape else { unreachable!() };
        assert_eq!(sp.radius, 2.0);
        // The wide end at y = 0 becomes the base.
        let Shape::Cone(c) = &s.objects[1].shape else { unreachable!() };
        assert_eq!((c.base, c.axis, c.radius, c.top_radius), (Vec3::ZERO, Vec3::Y, 1.0, 0.5));
        let Shape::Cone(c) = &s.objects[2].shape else { unreachable!() };
        assert_eq!((c.radius, c.top_radius), (1.0, 0.5));
        assert!(nff.warnings[0].contains("2 zero-size sphere or cone skipped"), "{:?}", nff.warnings);
        assert!(!nff.warnings.iter().any(|w| w.contains("before any `f`")));
    }

    #[test]
    fn objects_before_any_fill_are_white_and_warned_about() {
        let nff = read(&format!("{VIEW}s 0 0 0 1\n")).unwrap();
        assert_eq!(nff.scene.materials.len(), 1);
        assert!(nff.warnings[0].contains("before any `f`"));
    }

    #[test]
    fn view_defaults_and_optional_lines() {
        let nff = read("v from 1 2 3 at 0 0 0 up 0 0 1 angle 45\ns 0 0 0 1\n").unwrap();
        assert_eq!((nff.scene.camera.width, nff.scene.camera.height), (512, 512));
        assert_eq!(nff.scene.camera.up, Vec3::Z);
    }

    /// Lines split across reads and across chunks, a line longer than a chunk, CRLF
    /// line ends, comments and a last line without a break: read a few bytes at a time
    /// or all at once, the same scene, and errors on the same line and column.
    #[test]
    fn lines_are_found_across_reads_and_chunks() {
        let ring = (0..6000).map(|i| {
            let a = i as f32 * std::f32::consts::TAU / 6000.0;
            format!("{:.6} {:.6} 0 ", a.cos(), a.sin())
        });
        let body = format!(
            "f 1 0 0 1 0 0 0 0\r\ns 0 0 0 1 # a comment\r\np 6000 {}\r\n# only a comment\ns 1 1 1 0.5\np 3\n0 0 0\n1 0 0\n1 1 0",
            ring.collect::<String>()
        );
        let text = format!("{VIEW}{body}");
        assert!(text.lines().any(|l| l.len() > CHUNK), "a line longer than a chunk");
        let whole = read(&text).expect("reads");
        let trickle = read_nff(std::io::BufReader::with_capacity(7, text.as_bytes()), "t.nff").expect("reads");
        for nff in [&whole, &trickle] {
            assert_eq!((nff.counts.spheres, nff.counts.polygons, nff.counts.lines), (2, 2, VIEW.lines().count() + 9));
            assert_eq!(nff.counts.bytes, text.len() as u64);
        }
        assert_eq!(format!("{:?}", whole.scene.objects), format!("{:?}", trickle.scene.objects));
        let bad = format!("{text}\ns 0 0 x 1\n");
        let error = |r: Result<Nff, SceneError>| match r {
            Err(SceneError::At { line, column, .. }) => (line, column),
            other => panic!("{:?}", other.map(|n| n.counts)),
        };
        let expected = (VIEW.lines().count() + 10, 7);
        assert_eq!(error(read(&bad)), expected);
        assert_eq!(error(read_nff(std::io::BufReader::with_capacity(5, bad.as_bytes()), "t.nff")), expected);
    }

    #[test]
    fn errors_name_line_column_and_command() {
        let v = VIEW.lines().count();
        let cases: &[(&str, usize, usize, &str, &str)] = &[
            ("s 0 0 0\n", v + 1, 1, "s", "expected 4 numbers"),
            ("s 0 0 0\ns 1 1 1 1\n", v + 1, 1, "s", "before `s` on line"),
            ("s 0 0 0 1 2\n", v + 1, 11, "s", "more numbers after `s`"),
            ("s 0 0 x 1\n", v + 1, 7, "s", "\"x\" is not a number"),
            ("s 0 0 nan 1\n", v + 1, 7, "s", "not a finite number"),
            ("s 0 0 1e39 1\n", v + 1, 7, "s", "not a finite number"),
            ("q 1 2 3\n", v + 1, 1, "q", "unknown NFF command"),
            ("p 4\n0 0 0\n1 0 0\n1 1 0\ns 0 0 0 1\n", v + 1, 1, "p", "expected 4 vertices"),
            ("p 3\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n", v + 5, 1, "p", "vertex count"),
            ("p 2\n0 0 0\n1 0 0\n", v + 1, 3, "p", "at least 3"),
            ("p 3.5\n", v + 1, 3, "p", "whole number"),
            ("p three\n", v + 1, 3, "p", "not a whole number"),
            ("pp 3\n0 0 0 0 0 1\n1 0 0 0 0 1\n1 1 0 0 0\n", v + 1, 1, "pp", "expected 3 vertices of 6 numbers"),
            ("f 1 1 1 0.5 0.5 3 0.5\ns 0 0 0 1\n", v + 1, 1, "f", "expected 8 numbers"),
            ("f 1 1 1 0.5 0.5 3 0.5 0\n", v + 1, 1, "f", "index of refraction"),
            ("f 1 -1 1 0.5 0.5 3 0 0\n", v + 1, 1, "f", "colour"),
            ("c 0 0 0 1 0 0 0 0.5\n", v + 1, 1, "c", "must differ"),
            ("c 0 0 0 1 0 1 0 -0.5\n", v + 1, 1, "c", "same sign"),
            ("l 1 2 3 4 5\n", v + 1, 1, "l", "3 numbers (x y z) or 6"),
            ("b 1 1\n", v + 1, 1, "b", "expected 3 numbers"),
            ("v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 40\n", v + 1, 1, "v", "a second view"),
        ];
        for &(body, line, column, field, message) in cases {
            let (l, c, f, m) = at(&format!("{VIEW}{body}"));
            assert_eq!((l, c, f.as_str()), (line, column, field), "{body:?}: {m}");
            assert!(m.contains(message), "{body:?}: {m:?} lacks {message:?}");
        }
    }

    #[test]
    fn view_errors_point_at_the_faulty_line() {
        let (l, _, f, m) = at("v\nfrom 0 0 5\nat 0 0 5\nup 0 1 0\nangle 40\n");
        assert_eq!((l, f.as_str()), (3, "v"), "{m}");
        let (l, _, _, m) = at("v\nfrom 0 0 5\nat 0 0 0\nup 0 0 1\nangle 40\n");
        assert_eq!(l, 4, "{m}");
        let (l, _, _, m) = at("v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 180\n");
        assert_eq!(l, 5, "{m}");
        let (l, _, _, m) = at("v\nfrom 0 0 5\nup 0 1 0\n");
        assert_eq!(l, 1, "{m}");
        assert!(m.contains("`at`"), "{m}");
        let (l, _, _, m) = at("v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 40\nresolution 0 10\n");
        assert_eq!(l, 6, "{m}");
        let (l, c, f, m) = at("s 0 0 0 1\n\n");
        assert_eq!((l, c, f.as_str()), (2, 1, "v"), "{m}");
    }

    #[test]
    fn the_fast_number_path_agrees_with_the_full_parser() {
        let mut r = crate::sampler::Rng::new(11);
        let mut fast = 0;
        for i in 0..300_000u32 {
            let x = f32::from_bits(r.next_u32());
            let y = (r.next_f32() - 0.5) * [1e-6, 1e-3, 1.0, 1e3, 1e7][i as usize % 5];
            let texts = [
                format!("{x}"),
                format!("{y}"),
                format!("{y:e}"),
                crate::scene::generate::fmt_g(y as f64),
                format!("{:.3}", y),
                format!("{}", r.next_u32() % 100_000_000),
            ];
            for t in texts {
                let full: Option<f32> = t.parse().ok();
                let quick = fast_f32(t.as_bytes());
                if let Some(q) = quick {
                    fast += 1;
                    assert_eq!(Some(q.to_bits()), full.map(f32::to_bits), "{t}");
                }
                assert_eq!(parse_f32(t.as_bytes()).map(f32::to_bits), full.map(f32::to_bits), "{t}");
            }
        }
        assert!(fast > 500_000, "{fast}");
        for t in ["", "-", "+", ".", "e5", "1e", "1e+", "--1", "1.2.3", "0x10", "1,5", "inf", "nan", "16777217", "1e11"]
        {
            assert_eq!(fast_f32(t.as_bytes()), None, "{t}");
        }
        for (t, x) in
            [("-0", -0.0f32), ("+.5", 0.5), ("5.", 5.0), ("1e-05", 1e-5), ("-2.5E+3", -2500.0), ("0.000000", 0.0)]
        {
            assert_eq!(fast_f32(t.as_bytes()).map(f32::to_bits), Some(x.to_bits()), "{t}");
        }
    }

    #[test]
    fn entities_may_span_lines_share_one_and_use_crlf() {
        let mut text = Vec::new();
        crate::scene::generate::sphereflake(2, &mut text).unwrap();
        let text = String::from_utf8(text).unwrap();
        let reference = read(&text).unwrap();
        let one_line = text.replace('\n', " ");
        let crlf = text.replace('\n', "\r\n");
        let one_number_a_line = text.replace(' ', "\n");
        for variant in [one_line, crlf, one_number_a_line] {
            let nff = read(&variant).unwrap();
            assert_eq!(nff.scene.objects.len(), reference.scene.objects.len());
            for (a, b) in nff.scene.objects.iter().zip(&reference.scene.objects) {
                assert_eq!(a.shape, b.shape);
            }
            assert_eq!(nff.scene.camera, reference.scene.camera);
        }
        assert_eq!(read(&text.replace('\n', " ")).unwrap().counts.lines, 1);
    }

    #[test]
    fn binary_junk_is_an_unknown_command() {
        let (l, _, f, _) = at("\u{89}PNG\r\n\u{1a}\n");
        assert_eq!((l, f.as_str()), (1, "\u{89}PNG"));
        let bytes = b"v\xff\xfe 1 2\n";
        match read_nff(&bytes[..], "b.nff").unwrap_err() {
            SceneError::At { line, field, .. } => assert_eq!((line, field.as_str()), (1, "v\u{fffd}\u{fffd}")),
            e => panic!("{e}"),
        }
    }
}
