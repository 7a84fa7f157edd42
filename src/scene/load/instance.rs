//! `[[instance]]`: a named `[[mesh]]` or `[[gltf]]` asset placed again.
//!
//! ```toml
//! [[mesh]]
//! name = "ball"
//! file = "ball.obj"
//! material = "clay"
//!
//! [[instance]]
//! of = "ball"
//! transform = { translate = [3, 0, 0], rotate = [0, 45, 0] }
//! material = "gold"        # optional: else the asset's own materials
//! keys = [{ frame = 0, transform = { rotate = [0, 0, 0] } }, { frame = 60, transform = { rotate = [0, 360, 0] } }]
//! ```
//! An instance places the asset as if it were written again with the instance's
//! `transform` in place of its own. Its triangles are shared, not copied
//! ([`crate::geometry::instance`]).

use super::*;
use glam::Affine3A;

/// A named asset: the objects it added and the transform they were placed with.
pub(super) struct Named {
    objects: std::ops::Range<usize>,
    placed: Affine3A,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct InstanceDesc {
    of: S<String>,
    transform: Option<S<TransformDesc>>,
    material: Option<S<MaterialRef>>,
    keys: Keys<ObjectKey>,
    interpolation: Option<S<String>>,
}

impl Ctx<'_> {
    /// Records that `objects` of the scene were added under `name`, placed by `placed`.
    pub(super) fn name_asset(
        &self,
        named: &mut HashMap<String, Named>,
        name: &Option<S<String>>,
        objects: std::ops::Range<usize>,
        placed: Affine3A,
    ) -> R<()> {
        let Some(name) = name else { return Ok(()) };
        if named.contains_key(name.get_ref()) {
            return Err(self.err(
                name,
                "name",
                format!("{:?} names another mesh or glTF asset already", name.get_ref()),
            ));
        }
        named.insert(name.get_ref().clone(), Named { objects, placed });
        Ok(())
    }

    /// Adds the objects of instance `i`, and to `keyed` their keys if it has any;
    /// `resolve` turns a material reference into a material of the scene.
    pub(super) fn instance(
        &self,
        scene: &mut Scene,
        named: &HashMap<String, Named>,
        i: &S<InstanceDesc>,
        resolve: impl FnOnce(&mut Scene, &S<MaterialRef>) -> R<MaterialId>,
        (keyed, range): (&mut Vec<crate::scene::animation::ObjectKeys>, Option<(u32, u32)>),
    ) -> R<()> {
        let i = i.get_ref();
        let Some(asset) = named.get(i.of.get_ref()) else {
            let mut known: Vec<_> = named.keys().map(String::as_str).collect();
            known.sort_unstable();
            let known =
                if known.is_empty() { "none: give a [[mesh]] or [[gltf]] a `name`".into() } else { known.join(", ") };
            return Err(self.err(
                &i.of,
                "of",
                format!("no mesh or glTF asset named {:?} (named: {known})", i.of.get_ref()),
            ));
        };
        let placed = match &i.transform {
            Some(t) => self.transform(t.get_ref())?,
            None => Affine3A::IDENTITY,
        };
        let material = match &i.material {
            Some(m) => Some(resolve(scene, m)?),
            None => None,
        };
        for k in asset.objects.clone() {
            let o = &scene.objects[k];
            let Shape::Mesh(mesh) = &o.shape else { continue };
            // The asset's mesh back where it was made: the instance's transform, keyed
            // or not, then places it as a transform places any shape (sharing it).
            let base = geometry::instance(mesh, &asset.placed.inverse());
            let material = material.unwrap_or(o.material);
            let index = scene.objects.len();
            keyed.extend(self.object_keys(index, &base, &i.transform, &i.keys, &i.interpolation, range)?);
            let shape = geometry::transform(base, &placed).map_err(|e| self.err(&i.of, "of", e.to_string()))?;
            scene.objects.push(Object { shape, material });
        }
        Ok(())
    }
}
