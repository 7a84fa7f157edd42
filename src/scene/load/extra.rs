//! Checks of the TOML reader kept apart from the field-by-field ones: the names the
//! file gives (for messages about its materials and objects), polygons that need
//! triangulating, and locating nesting too deep for the parser.

use super::*;

impl Ctx<'_> {
    /// The file's names for the materials and objects, in the order `build` adds them:
    /// named materials, then inline ones object by object; objects kind by kind.
    pub(super) fn labels(&self, desc: &FileDesc) -> crate::scene::Labels {
        let kind = |t: &Option<S<TextureDesc>>| t.as_ref().map(|t| t.get_ref().kind.get_ref().clone());
        let mut labels = crate::scene::Labels::default();
        for (name, m) in &desc.material {
            labels.materials.push(crate::scene::MaterialLabel {
                name: Some(name.clone()),
                owner: None,
                line: self.line_col(m.span().start).0,
                texture: kind(&m.get_ref().texture),
            });
        }
        let mut object = |table: &'static str, index: usize, at: usize, material: &S<MaterialRef>| {
            let label = crate::scene::ObjectLabel { table, index: index + 1, line: self.line_col(at).0 };
            if let MaterialRef::Inline(d) = material.get_ref() {
                labels.materials.push(crate::scene::MaterialLabel {
                    name: None,
                    owner: Some(format!("[[{table}]] {}", index + 1)),
                    line: self.line_col(material.span().start).0,
                    texture: kind(&d.texture),
                });
            }
            labels.objects.push(label);
        };
        macro_rules! each {
            ($list:expr, $table:literal) => {
                for (i, o) in $list.iter().enumerate() {
                    object($table, i, o.span().start, &o.get_ref().material);
                }
            };
        }
        each!(desc.sphere, "sphere");
        each!(desc.quad, "quad");
        each!(desc.polygon, "polygon");
        each!(desc.cylinder, "cylinder");
        each!(desc.cone, "cone");
        each!(desc.triangle, "triangle");
        each!(desc.mesh, "mesh");
        labels
    }

    /// A convex polygon as it is; a concave one ear-clipped into a flat mesh, as NFF
    /// polygons are; one whose outline crosses itself refused, naming the edges.
    pub(super) fn polygon(&self, at: &S<Vec<V3>>, vertices: Vec<Vec3>) -> R<Shape> {
        use crate::geometry::PolygonError;
        use crate::geometry::triangulate::{MAX_EAR_CLIPPING, first_crossing, triangulate};
        match Polygon::new(vertices.clone()) {
            Ok(p) => Ok(p.into()),
            Err(PolygonError::NotConvex { .. }) => {
                let n = vertices.len();
                if n > MAX_EAR_CLIPPING {
                    let message = format!(
                        "a concave polygon may have at most {MAX_EAR_CLIPPING} vertices (got {n}); use a [[mesh]]"
                    );
                    return Err(self.err(at, "vertices", message));
                }
                if let Some((i, j)) = first_crossing(&vertices) {
                    let message = format!(
                        "the outline crosses itself: the edge from vertex {j} to {} crosses the edge from \
                         vertex {i} to {} (counted from 0)",
                        (j + 1) % n,
                        i + 1
                    );
                    return Err(self.err(at, "vertices", message));
                }
                let mut triangles = Vec::new();
                if triangulate(&vertices, 0, &mut triangles).is_none() || triangles.is_empty() {
                    return Err(self.err(at, "vertices", "the polygon has no area"));
                }
                let mesh = Mesh::new(vertices, vec![], vec![], triangles, false)
                    .map_err(|e| self.err(at, "vertices", e.to_string()))?;
                Ok(mesh.into())
            }
            Err(e) => Err(self.err(at, "vertices", e.to_string())),
        }
    }

    /// The start of the first line with 50 or more levels of dotted key, `[` or `{`.
    pub(super) fn deeply_nested_line(&self) -> Option<usize> {
        let mut start = 0;
        for line in self.src.split_inclusive('\n') {
            let (mut depth, mut deepest, mut dots) = (0i32, 0i32, 0);
            for c in line.chars() {
                match c {
                    '[' | '{' => {
                        depth += 1;
                        deepest = deepest.max(depth);
                    }
                    ']' | '}' => depth -= 1,
                    '.' => dots += 1,
                    '#' => break,
                    _ => {}
                }
            }
            if deepest >= 50 || dots >= 50 {
                return Some(start);
            }
            start += line.len();
        }
        None
    }
}
