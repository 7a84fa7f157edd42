//! A big NFF file read in chunks, one thread each: the file is cut before lines that
//! start an entity (`s`, `f`, `p`, `pp`, `c`, `l` or `b`: never inside one, whose
//! other lines start with numbers or a view's labels), each chunk streams through a
//! parser of its own, and the parsers are joined in file order into what one parser
//! reading the whole file makes: the same objects, materials (numbered in order of
//! first use), meshes, counts and warnings. Where a join could differ (an error in any
//! chunk, two views, objects before any `f` past the first chunk) there is no answer
//! here, and the caller reads the file in one pass, which gives the exact error.

use super::{FEW_QUADS, MaterialId, MeshBuilder, Nff, Parser, SceneError};
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

/// In a chunk after the first, the material current where the chunk starts, known only
/// once the chunks before it are joined.
const INHERITED: u32 = u32::MAX;

/// Bytes looked through past a cut's aim for a line that starts an entity.
const WINDOW: usize = 1 << 16;

/// The file at `path` (`len` bytes, `name` in messages) read as `chunks` chunks in
/// parallel, or `None` where it must be read in one pass (see the module's notes).
pub(super) fn read_chunked(path: &Path, name: &str, len: u64, chunks: usize) -> Option<Result<Nff, SceneError>> {
    use rayon::prelude::*;
    let cuts = cuts(path, len, chunks)?;
    let parsers: Vec<_> = cuts
        .par_windows(2)
        .map(|w| {
            let mut file = File::open(path).ok()?;
            file.seek(SeekFrom::Start(w[0])).ok()?;
            let mut p = Parser::new(BufReader::with_capacity(1 << 16, file.take(w[1] - w[0])), name);
            if w[0] > 0 {
                p.current = Some(MaterialId(INHERITED));
            }
            p.run().ok()?;
            Some(p)
        })
        .collect::<Option<_>>()?;
    join(parsers).map(Parser::finish)
}

/// Where the chunks start, and the file's end: `0`, then about every `len / chunks`
/// bytes the next line that starts an entity.
fn cuts(path: &Path, len: u64, chunks: usize) -> Option<Vec<u64>> {
    let mut file = File::open(path).ok()?;
    let mut cuts = vec![0];
    let mut window = Vec::with_capacity(WINDOW);
    for k in 1..chunks as u64 {
        // From the byte before the aim, so that a line starting at the aim is found.
        let from = (len * k / chunks as u64).saturating_sub(1).max(*cuts.last().expect("0 is first"));
        file.seek(SeekFrom::Start(from)).ok()?;
        window.clear();
        (&mut file).take(WINDOW as u64).read_to_end(&mut window).ok()?;
        if let Some(at) = entity_line(&window) {
            cuts.push(from + at as u64);
        }
    }
    cuts.push(len);
    Some(cuts)
}

/// The start of the first whole line of `bytes` (after a line break in it) whose first
/// word is an entity other than `v`, followed by a space or the line's end.
fn entity_line(bytes: &[u8]) -> Option<usize> {
    let mut at = memchr::memchr(b'\n', bytes)? + 1;
    while at < bytes.len() {
        let line = &bytes[at..];
        let word_at = line.iter().position(|&b| b != b' ' && b != b'\t')?;
        let word = &line[word_at..];
        let end = word.iter().position(|b| b.is_ascii_whitespace()).unwrap_or(word.len());
        // The word must end inside the window, so that it is not the start of a longer one.
        if end < word.len() && matches!(&word[..end], b"s" | b"f" | b"p" | b"pp" | b"c" | b"l" | b"b") {
            return Some(at);
        }
        at += memchr::memchr(b'\n', line)? + 1;
    }
    None
}

/// The chunks' parsers joined into the first, as if it had read them all.
fn join<R>(parsers: Vec<Parser<'_, R>>) -> Option<Parser<'_, R>> {
    let mut parsers = parsers.into_iter();
    let mut into = parsers.next()?;
    for c in parsers {
        // Lines before this chunk: its lines and the ones its tallies name are its own.
        let offset = into.lex.line;
        if let Some((camera, mut toks)) = c.view {
            if into.view.is_some() {
                return None;
            }
            for t in &mut toks {
                t.line += offset;
            }
            into.view = Some((camera, toks));
        }
        if c.counts.backgrounds > 0 {
            into.background = c.background;
        }
        into.lights.extend(c.lights);
        // The chunk's materials numbered after the ones before: an `f` line met before
        // is the same material, as in one pass.
        let mut ids = Vec::with_capacity(c.materials.len());
        for (material, (key, line, changed)) in c.materials.into_iter().zip(c.made) {
            let id = match key.and_then(|k| into.material_ids.get(&k).copied()) {
                Some(id) => id,
                None => {
                    into.materials.push(material);
                    let id = MaterialId(into.materials.len() as u32 - 1);
                    if let Some(k) = key {
                        into.material_ids.insert(k, id);
                    }
                    if changed {
                        into.shares.add(line + offset);
                    }
                    into.made.push((key, line + offset, changed));
                    id
                }
            };
            ids.push(id);
        }
        let inherited = into.current;
        let id = |m: MaterialId| if m.0 == INHERITED { inherited } else { Some(ids[m.0 as usize]) };
        into.current = c.current.and_then(id);
        for (list, objects) in
            [(&mut into.spheres, c.spheres), (&mut into.cylinders, c.cylinders), (&mut into.cones, c.cones)]
        {
            list.reserve(objects.len());
            for mut o in objects {
                o.material = id(o.material)?;
                list.push(o);
            }
        }
        for (material, smooth, mesh) in c.meshes {
            let key = (id(material)?, smooth);
            match into.mesh_ids.get(&key) {
                Some(&k) => append(&mut into.meshes[k].2, mesh)?,
                None => {
                    into.meshes.push((key.0, smooth, mesh));
                    into.mesh_ids.insert(key, into.meshes.len() - 1);
                }
            }
        }
        for (a, b) in [
            (&mut into.zero_area, &c.zero_area),
            (&mut into.thin, &c.thin),
            (&mut into.zero_size, &c.zero_size),
            (&mut into.crossing, &c.crossing),
            (&mut into.no_material, &c.no_material),
        ] {
            if b.count > 0 {
                if a.count == 0 {
                    a.first_line = b.first_line + offset;
                }
                a.count += b.count;
            }
        }
        let (n, m) = (&mut into.counts, &c.counts);
        n.views += m.views;
        n.backgrounds += m.backgrounds;
        n.lights += m.lights;
        n.fills += m.fills;
        n.spheres += m.spheres;
        n.cones += m.cones;
        n.polygons += m.polygons;
        n.patches += m.patches;
        n.triangles += m.triangles;
        into.lex.line += c.lex.line;
        into.lex.bytes += c.lex.bytes;
    }
    Some(into)
}

/// Mesh `b`'s triangles after `a`'s, as one builder reading both would have them.
fn append(a: &mut MeshBuilder, b: MeshBuilder) -> Option<()> {
    let base = a.positions.len();
    if base + b.positions.len() > u32::MAX as usize {
        return None;
    }
    // Read as quads only while every polygon so far is one (`Parser::polygon`): the
    // joined builder's quads stand for its polygons only where both halves' did.
    if a.quads.len() == a.polygons && b.quads.len() == b.polygons && a.polygons + b.polygons <= FEW_QUADS {
        a.quads.extend(b.quads);
    }
    a.triangles.extend(b.triangles.iter().map(|t| t.map(|v| v + base as u32)));
    a.positions.extend(b.positions);
    a.normals.extend(b.normals);
    a.polygons += b.polygons;
    Some(())
}
