//! Wavefront OBJ meshes. Our own reader rather than a crate's, because a broken file must
//! be reported by line: `v`, `vt`, `vn` and `f` (polygons fanned into triangles,
//! `v`, `v/t`, `v//n` and `v/t/n` references, negative ones counting back). Grouping,
//! material and curve statements are skipped; anything else is an error, which also
//! catches a file that is not OBJ at all. Read line by line, so files of any size
//! stream through a fixed buffer. Texture coordinates are flipped on read (`v` becomes
//! `1 - v`): OBJ puts `v = 0` at the bottom of the image, the renderer at the top row.

use super::SceneError;
use crate::geometry::{Mesh, MeshError};
use crate::math::{Vec2, Vec3};
use std::collections::HashMap;
use std::io::BufRead;
use std::path::Path;

/// Statements of the OBJ specification that carry nothing a ray tracer of triangle
/// meshes uses.
const SKIPPED: &[&str] = &[
    "o",
    "g",
    "s",
    "mg",
    "usemtl",
    "mtllib",
    "l",
    "p",
    "vp",
    "cstype",
    "deg",
    "bmat",
    "step",
    "curv",
    "curv2",
    "surf",
    "parm",
    "trim",
    "hole",
    "scrv",
    "sp",
    "end",
    "con",
    "bevel",
    "c_interp",
    "d_interp",
    "lod",
    "shadow_obj",
    "trace_obj",
    "ctech",
    "stech",
    "maplib",
    "usemap",
];

/// Loads an OBJ file into a mesh; `smooth` as in [`Mesh::new`].
pub fn load_obj(path: &Path, smooth: bool) -> Result<Mesh, SceneError> {
    let file = super::limits::open_regular(path, "mesh")?;
    read_obj(std::io::BufReader::new(file), &path.display().to_string(), smooth)
}

/// Where each unified vertex comes from: position, texture and normal indices (-1: none).
type Corner = (u32, i64, i64);

/// Reads OBJ text; `name` is used in messages.
pub fn read_obj(mut input: impl BufRead, name: &str, smooth: bool) -> Result<Mesh, SceneError> {
    let mut positions: Vec<Vec3> = Vec::new();
    let mut normals: Vec<Vec3> = Vec::new();
    let mut uvs: Vec<Vec2> = Vec::new();
    let mut corners: Vec<Corner> = Vec::new();
    let mut corner_ids: HashMap<Corner, u32> = HashMap::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut uses_attributes = false;
    let mut face: Vec<u32> = Vec::with_capacity(8);
    let mut line = String::new();
    let mut raw = Vec::new();
    let mut number = 0;
    let err = |number: usize, column: usize, field: &str, message: String| SceneError::At {
        file: name.to_owned(),
        line: number,
        column,
        field: field.to_owned(),
        message,
    };
    loop {
        line.clear();
        number += 1;
        raw.clear();
        let read = super::limits::read_line(&mut input, &mut raw, name, number)?;
        if read == 0 {
            break;
        }
        line = match std::str::from_utf8(&raw) {
            Ok(text) => text.to_owned(),
            Err(e) => return Err(err(number, e.valid_up_to() + 1, "text", "not UTF-8 text (binary data?)".into())),
        };
        let text = line.split('#').next().unwrap_or("");
        let mut words = text.split_whitespace();
        let Some(keyword) = words.next() else { continue };
        let column_of = |word: &str| word.as_ptr() as usize - line.as_ptr() as usize + 1;
        let floats = |words: std::str::SplitWhitespace, min: usize, max: usize| -> Result<Vec<f32>, SceneError> {
            let mut v = Vec::with_capacity(max);
            for w in words {
                let x: f32 = w.parse().map_err(|_| {
                    err(number, column_of(w), keyword, format!("{:?} is not a number", super::limits::show(w)))
                })?;
                if !x.is_finite() {
                    return Err(err(number, column_of(w), keyword, format!("{w} is not a finite number")));
                }
                v.push(x);
            }
            if v.len() < min || v.len() > max {
                let want = if min == max { format!("{min}") } else { format!("{min} to {max}") };
                return Err(err(
                    number,
                    column_of(keyword),
                    keyword,
                    format!("expected {want} numbers, got {}", v.len()),
                ));
            }
            Ok(v)
        };
        match keyword {
            "v" => {
                let v = floats(words, 3, 4)?;
                positions.push(Vec3::new(v[0], v[1], v[2]));
            }
            "vn" => {
                let v = floats(words, 3, 3)?;
                normals.push(Vec3::new(v[0], v[1], v[2]));
            }
            "vt" => {
                let v = floats(words, 1, 3)?;
                // OBJ's v runs up the image (0 at the bottom row); ours runs down.
                uvs.push(Vec2::new(v[0], 1.0 - v.get(1).copied().unwrap_or(0.0)));
            }
            "f" => {
                face.clear();
                for w in words {
                    let at = column_of(w);
                    let mut parts = w.split('/');
                    let index = |part: Option<&str>, count: usize, what: &str| -> Result<i64, SceneError> {
                        match part {
                            None | Some("") => Ok(-1),
                            Some(s) => {
                                let i: i64 = s
                                    .parse()
                                    .map_err(|_| err(number, at, "f", format!("{w:?} is not a vertex reference")))?;
                                let resolved = if i < 0 { count as i64 + i } else { i - 1 };
                                if i == 0 || resolved < 0 || resolved >= count as i64 {
                                    return Err(err(
                                        number,
                                        at,
                                        "f",
                                        format!("{what} index {i} is out of range: {count} defined so far"),
                                    ));
                                }
                                Ok(resolved)
                            }
                        }
                    };
                    let v = index(parts.next(), positions.len(), "vertex")?;
                    if v < 0 {
                        return Err(err(number, at, "f", format!("{w:?} has no vertex index")));
                    }
                    let t = index(parts.next(), uvs.len(), "texture coordinate")?;
                    let n = index(parts.next(), normals.len(), "normal")?;
                    if parts.next().is_some() {
                        return Err(err(number, at, "f", format!("{w:?} has more than three indices")));
                    }
                    uses_attributes |= t >= 0 || n >= 0;
                    let corner = (v as u32, t, n);
                    let id = *corner_ids.entry(corner).or_insert_with(|| {
                        corners.push(corner);
                        corners.len() as u32 - 1
                    });
                    face.push(id);
                }
                if face.len() < 3 {
                    return Err(err(
                        number,
                        column_of(keyword),
                        "f",
                        format!("a face needs at least 3 vertices, got {}", face.len()),
                    ));
                }
                for k in 2..face.len() {
                    triangles.push([face[0], face[k - 1], face[k]]);
                }
            }
            k if SKIPPED.contains(&k) => {}
            other => {
                let shown = super::limits::show(other);
                return Err(err(number, column_of(other), &shown, format!("unknown OBJ statement {shown:?}")));
            }
        }
    }
    let mesh = if uses_attributes {
        let pos = corners.iter().map(|c| positions[c.0 as usize]).collect();
        let nor = if corners.iter().any(|c| c.2 >= 0) {
            // Corners without a normal get NaN, which makes Mesh::new compute them all.
            corners.iter().map(|c| if c.2 >= 0 { normals[c.2 as usize] } else { Vec3::NAN }).collect()
        } else {
            vec![]
        };
        let tex = if corners.iter().any(|c| c.1 >= 0) {
            corners.iter().map(|c| if c.1 >= 0 { uvs[c.1 as usize] } else { Vec2::ZERO }).collect()
        } else {
            vec![]
        };
        Mesh::new(pos, nor, tex, triangles, smooth)
    } else {
        // Plain `f a b c` files index positions directly: no remapping.
        let remapped = triangles.iter().map(|t| t.map(|c| corners[c as usize].0)).collect();
        Mesh::new(positions, vec![], vec![], remapped, smooth)
    };
    mesh.map_err(|e| match e {
        MeshError::Empty => SceneError::File { file: name.to_owned(), message: "the mesh has no faces".into() },
        other => SceneError::File { file: name.to_owned(), message: other.to_string() },
    })
}

/// Writes a mesh as OBJ (positions, normals when smooth, triangles).
pub fn write_obj(mesh: &Mesh, out: &mut impl std::io::Write) -> std::io::Result<()> {
    writeln!(out, "# written by whitted: {} triangles", mesh.triangle_count())?;
    for p in mesh.positions() {
        writeln!(out, "v {} {} {}", p.x, p.y, p.z)?;
    }
    for n in mesh.normals() {
        writeln!(out, "vn {} {} {}", n.x, n.y, n.z)?;
    }
    let smooth = !mesh.normals().is_empty();
    for t in mesh.triangles() {
        let [a, b, c] = t.map(|i| i + 1);
        if smooth {
            writeln!(out, "f {a}//{a} {b}//{b} {c}//{c}")?;
        } else {
            writeln!(out, "f {a} {b} {c}")?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<Mesh, SceneError> {
        read_obj(text.as_bytes(), "t.obj", true)
    }

    fn at(text: &str) -> (usize, usize, String) {
        match read(text).unwrap_err() {
            SceneError::At { line, column, field, .. } => (line, column, field),
            e => panic!("expected a located error, got {e}"),
        }
    }

    #[test]
    fn reads_a_quad_with_normals_and_uvs_as_two_triangles() {
        let m = read(
            "# a quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n\
             g quad\nusemtl x\nf 1/1/1 2/2/1 3/3/1 4/4/1\n",
        )
        .unwrap();
        assert_eq!(m.triangle_count(), 2);
        assert!(m.is_smooth());
    }

    #[test]
    fn negative_indices_count_back_and_plain_faces_share_vertices() {
        let m = read("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 1 1 0\nf 2 4 3\n").unwrap();
        assert_eq!(m.triangle_count(), 2);
        assert_eq!(m.positions().len(), 4);
        assert_eq!(m.triangles(), &[[0, 1, 2], [1, 3, 2]]);
    }

    #[test]
    fn errors_name_line_column_and_statement() {
        assert_eq!(at("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n"), (4, 7, "f".into()));
        assert_eq!(at("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n"), (4, 7, "f".into()));
        assert_eq!(at("v 0 0 0\nv 1 nan 0\n"), (2, 5, "v".into()));
        assert_eq!(at("v 0 0 zero\n"), (1, 7, "v".into()));
        assert_eq!(at("v 0 0\n"), (1, 1, "v".into()));
        assert_eq!(at("v 0 0 0\nv 1 0 0\nf 1 2\n"), (3, 1, "f".into()));
        assert_eq!(at("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//3 2 3\n"), (4, 3, "f".into()));
        assert_eq!(at("\u{89}PNG\n"), (1, 1, "\u{89}PNG".into()));
    }

    #[test]
    fn written_meshes_read_back_the_same() {
        let mesh = crate::scene::generate::cube_sphere(3);
        let smooth = Mesh::new(mesh.positions().to_vec(), vec![], vec![], mesh.triangles().to_vec(), true).unwrap();
        for m in [mesh, smooth] {
            let mut text = Vec::new();
            write_obj(&m, &mut text).unwrap();
            let back = read_obj(text.as_slice(), "w.obj", m.is_smooth()).unwrap();
            assert_eq!(back.triangle_count(), m.triangle_count());
            for i in 0..m.triangle_count() {
                assert_eq!(back.corners(i), m.corners(i));
            }
            assert_eq!(back.is_smooth(), m.is_smooth());
        }
    }

    #[test]
    fn a_file_without_faces_is_an_error() {
        assert!(matches!(read("v 0 0 0\n"), Err(SceneError::File { .. })));
    }
}
