//! `[[mesh]]` tables ([`Mesh`]): an OBJ `file`, or `positions`, `normals` and
//! `triangles` written inline.

use super::{Ctx, Keys, MaterialRef, ObjectKey, R, S, TransformDesc, V3};
use crate::geometry::Mesh;
use crate::math::Vec3;
use crate::scene::SceneError;
use serde::Deserialize;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MeshDesc {
    /// Names the mesh for `[[instance]]`.
    pub(super) name: Option<S<String>>,
    /// An OBJ file, or else the data inline in the next three fields.
    pub(super) file: Option<S<String>>,
    pub(super) positions: Option<S<Vec<V3>>>,
    /// One per position; without them smooth meshes compute their own.
    pub(super) normals: Option<S<Vec<V3>>>,
    /// Indices into `positions`, from 0.
    pub(super) triangles: Option<S<Vec<[i64; 3]>>>,
    pub(super) smooth: Option<bool>,
    pub(super) material: S<MaterialRef>,
    pub(super) transform: Option<S<TransformDesc>>,
    pub(super) keys: Keys<ObjectKey>,
    pub(super) interpolation: Option<S<String>>,
}

impl Ctx<'_> {
    /// A mesh from its OBJ file or from the arrays written inline.
    pub(super) fn mesh(&self, desc: &S<MeshDesc>) -> R<Mesh> {
        let m = desc.get_ref();
        let smooth = m.smooth.unwrap_or(true);
        let Some(positions) = &m.positions else {
            if let Some(n) = &m.normals {
                return Err(self.err(n, "normals", "inline `normals` need inline `positions`"));
            }
            if let Some(t) = &m.triangles {
                return Err(self.err(t, "triangles", "inline `triangles` need inline `positions`"));
            }
            let Some(file) = &m.file else {
                return Err(self.err(desc, "file", "a mesh needs a `file`, or `positions` and `triangles`"));
            };
            let path = self.base_dir.join(file.get_ref());
            return crate::scene::obj::load_obj(&path, smooth).map_err(|e| match e {
                // A mesh that cannot be opened is reported where the scene names it.
                SceneError::File { message, .. } if !path.is_file() => {
                    self.err(file, "file", format!("{}: {message}", path.display()))
                }
                other => other,
            });
        };
        if let Some(file) = &m.file {
            return Err(self.err(file, "file", "give a mesh either a `file` or inline `positions`, not both"));
        }
        let Some(triangles) = &m.triangles else {
            return Err(self.err(positions, "triangles", "inline `positions` need `triangles` to join them"));
        };
        let points = |v: &S<Vec<V3>>, field: &str| -> R<Vec<Vec3>> {
            v.get_ref()
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    let p = Vec3::from_array(*p);
                    if p.is_finite() {
                        Ok(p)
                    } else {
                        Err(self.err(v, field, format!("entry {i} ({p}) is not finite")))
                    }
                })
                .collect()
        };
        let pos = points(positions, "positions")?;
        let normals = match &m.normals {
            None => Vec::new(),
            Some(n) => {
                let normals = points(n, "normals")?;
                if normals.len() != pos.len() {
                    let message =
                        format!("{} normals for {} positions: give one per position", normals.len(), pos.len());
                    return Err(self.err(n, "normals", message));
                }
                normals
            }
        };
        let mut tris = Vec::with_capacity(triangles.get_ref().len());
        for (i, t) in triangles.get_ref().iter().enumerate() {
            if let Some(&bad) = t.iter().find(|&&v| v < 0 || v as usize >= pos.len()) {
                let message =
                    format!("triangle {i} refers to vertex {bad}, but there are {} (counted from 0)", pos.len());
                return Err(self.err(triangles, "triangles", message));
            }
            tris.push(t.map(|v| v as u32));
        }
        Mesh::new(pos, normals, vec![], tris, smooth).map_err(|e| self.err(triangles, "triangles", e.to_string()))
    }
}
