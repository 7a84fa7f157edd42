//! Ray queries over all objects of a scene: the nearest hit, and how much light gets
//! through along a shadow ray.
//!
//! Two levels: a [`Bvh`] over the scene's objects, and inside each mesh object a BVH
//! over its triangles, whose vertices are copied in leaf order so a leaf's triangles
//! are read from one contiguous run of memory. With [`AccelKind::None`] every object,
//! and every triangle of every mesh, is tested; both paths use the same intersection
//! routines and break ties the same way (the lower index wins), so they produce
//! identical images.

pub mod bvh;
mod tri4;
pub mod wide;

pub use bvh::{Bvh, Node, Visit};
pub use wide::Bvh4;

use crate::geometry::{Hit, Mesh, Shape, part};
use crate::math::{Ray, Vec2};
use crate::scene::Scene;
use std::time::{Duration, Instant};
use tri4::{Ray4, Tri4};

/// Which acceleration structure answers ray queries.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AccelKind {
    /// Bounding volume hierarchy (binned SAH).
    #[default]
    Bvh,
    /// Test every object (and every triangle).
    None,
}

impl std::fmt::Display for AccelKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl AccelKind {
    /// Every structure this build has, for toggles that cycle through them.
    pub const ALL: &'static [AccelKind] = &[AccelKind::Bvh, AccelKind::None];

    pub fn name(self) -> &'static str {
        match self {
            AccelKind::Bvh => "bvh",
            AccelKind::None => "none",
        }
    }
}

/// A mesh's own BVH, with its triangles copied in leaf order into packs of four; a
/// wide-tree leaf names a run of packs.
#[derive(Debug)]
struct MeshBvh {
    tree: Bvh4,
    packs: Vec<Tri4>,
}

impl MeshBvh {
    fn build(mesh: &Mesh) -> MeshBvh {
        let bounds: Vec<_> =
            (0..mesh.triangle_count()).map(|i| crate::math::Aabb::from_points(mesh.corners(i))).collect();
        let bvh = Bvh::build_packed(&bounds, 4);
        let mut tree = Bvh4::from_binary(&bvh);
        let mut packs = Vec::with_capacity(mesh.triangle_count() / 3);
        let mut chunk = Vec::with_capacity(4);
        tree.map_leaves(|first, count| {
            let start = packs.len() as u32;
            for ids in bvh.indices[first as usize..(first + count) as usize].chunks(4) {
                chunk.clear();
                chunk.extend(ids.iter().map(|&id| {
                    let [v0, v1, v2] = mesh.corners(id as usize);
                    (v0, v1 - v0, v2 - v0, id)
                }));
                packs.push(Tri4::pack(&chunk));
            }
            (start, packs.len() as u32 - start)
        });
        packs.shrink_to_fit();
        MeshBvh { tree, packs }
    }

    fn memory_bytes(&self) -> usize {
        self.tree.memory_bytes() + self.packs.capacity() * std::mem::size_of::<Tri4>()
    }

    #[inline]
    fn closest(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        let r4 = Ray4::new(ray);
        let mut best: Option<Hit> = None;
        self.tree.traverse(ray, t_min, t_max, |range, mut t_cur| {
            for pack in &self.packs[range] {
                // Once something is hit the bound is inclusive, so an equally distant
                // triangle with a lower id wins, as when every triangle is tested in order.
                let limit = if best.is_some() { t_cur.next_up() } else { t_cur };
                let (mut mask, t, b1, b2) = pack.intersect(&r4, t_min, limit);
                while mask != 0 {
                    let lane = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    let id = pack.ids[lane];
                    if best.as_ref().is_none_or(|b| t[lane] < b.t || (t[lane] == b.t && id < b.prim)) {
                        t_cur = t[lane];
                        best = Some(Hit { t: t[lane], uv: Vec2::new(b1[lane], b2[lane]), part: part::SIDE, prim: id });
                    }
                }
            }
            Visit::Continue(t_cur)
        });
        best
    }

    #[inline]
    fn occluded(&self, ray: &Ray, t_min: f32, t_max: f32) -> bool {
        let r4 = Ray4::new(ray);
        let mut hit = false;
        self.tree.traverse_any(ray, t_min, t_max, |range, t_cur| {
            if self.packs[range].iter().any(|p| p.intersect(&r4, t_min, t_max).0 != 0) {
                hit = true;
                Visit::Stop
            } else {
                Visit::Continue(t_cur)
            }
        });
        hit
    }
}

/// An object as the top-level tree's leaves see it. Spheres, the commonest object in
/// big scenes, are copied here in leaf order, so testing a leaf reads one run of memory
/// instead of reaching into the scene's object list for each.
#[derive(Clone, Copy, Debug)]
enum LeafObject {
    Sphere(crate::geometry::Sphere, u32),
    Other(u32),
}

impl LeafObject {
    fn index(&self) -> u32 {
        match *self {
            LeafObject::Sphere(_, i) | LeafObject::Other(i) => i,
        }
    }
}

/// The read-only ray-query structure shared by all render threads.
#[derive(Debug)]
pub struct World<'s> {
    scene: &'s Scene,
    kind: AccelKind,
    /// Over objects; empty with `AccelKind::None`. Leaf positions index `leaves`.
    top4: Bvh4,
    leaves: Vec<LeafObject>,
    /// Per object: the BVH of a mesh object (with `AccelKind::Bvh`).
    meshes: Vec<Option<MeshBvh>>,
    /// Per object, the share of light its material lets through (0 = opaque), looked
    /// up once here rather than through the material on every shadow ray.
    transmission: Vec<f32>,
    build_time: Duration,
}

impl<'s> World<'s> {
    pub fn new(scene: &'s Scene, kind: AccelKind) -> Self {
        let start = Instant::now();
        let transmission = scene.objects.iter().map(|o| scene.material(o.material).transparency).collect();
        let (top, meshes) = match kind {
            AccelKind::None => (Bvh { nodes: vec![], indices: vec![] }, scene.objects.iter().map(|_| None).collect()),
            AccelKind::Bvh => {
                use rayon::prelude::*;
                let bounds: Vec<_> = scene.objects.iter().map(|o| o.shape.bounds()).collect();
                let meshes = scene
                    .objects
                    .par_iter()
                    .map(|o| match &o.shape {
                        Shape::Mesh(m) => Some(MeshBvh::build(m)),
                        _ => None,
                    })
                    .collect();
                (Bvh::build(&bounds), meshes)
            }
        };
        let top4 = if top.nodes.is_empty() { Bvh4::default() } else { Bvh4::from_binary(&top) };
        let leaves = top
            .indices
            .iter()
            .map(|&i| match &scene.objects[i as usize].shape {
                Shape::Sphere(s) => LeafObject::Sphere(*s, i),
                _ => LeafObject::Other(i),
            })
            .collect();
        World { scene, kind, top4, leaves, meshes, transmission, build_time: start.elapsed() }
    }

    pub fn scene(&self) -> &'s Scene {
        self.scene
    }

    pub fn kind(&self) -> AccelKind {
        self.kind
    }

    /// Time spent building the acceleration structures.
    pub fn build_time(&self) -> Duration {
        self.build_time
    }

    /// Bytes held by the acceleration structures (not the scene's own geometry).
    pub fn memory_bytes(&self) -> usize {
        self.leaves.capacity() * std::mem::size_of::<LeafObject>()
            + self.top4.memory_bytes()
            + self.meshes.iter().flatten().map(MeshBvh::memory_bytes).sum::<usize>()
    }

    /// Objects whose boxes the ray enters, nearest first; `test(object, t_max)` as in
    /// [`Bvh::traverse`].
    #[inline]
    fn traverse_objects(&self, ray: &Ray, t_min: f32, t_max: f32, mut test: impl FnMut(&LeafObject, f32) -> Visit) {
        self.top4.traverse(ray, t_min, t_max, |range, mut t_cur| {
            for i in &self.leaves[range] {
                match test(i, t_cur) {
                    Visit::Continue(t) => t_cur = t,
                    Visit::Stop => return Visit::Stop,
                }
            }
            Visit::Continue(t_cur)
        })
    }

    #[inline]
    fn intersect_leaf(&self, leaf: &LeafObject, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        match leaf {
            LeafObject::Sphere(s, _) => s.intersect(ray, t_min, t_max),
            LeafObject::Other(i) => self.intersect_object(*i as usize, ray, t_min, t_max),
        }
    }

    #[inline]
    fn intersect_object(&self, i: usize, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        match &self.meshes[i] {
            Some(m) => m.closest(ray, t_min, t_max),
            None => self.scene.objects[i].shape.intersect(ray, t_min, t_max),
        }
    }

    #[inline]
    fn blocks(&self, i: usize, ray: &Ray, t_max: f32) -> bool {
        match (&self.meshes[i], &self.scene.objects[i].shape) {
            (Some(m), _) => m.occluded(ray, 0.0, t_max),
            (None, Shape::Mesh(m)) => m.occluded(ray, 0.0, t_max),
            (None, s) => s.intersect(ray, 0.0, t_max).is_some(),
        }
    }

    /// The nearest hit in `(t_min, t_max)` and the index of the object hit.
    #[inline]
    pub fn closest(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<(Hit, u32)> {
        let mut best: Option<(Hit, u32)> = None;
        match self.kind {
            AccelKind::None => {
                let mut t_max = t_max;
                for i in 0..self.scene.objects.len() {
                    if let Some(h) = self.intersect_object(i, ray, t_min, t_max) {
                        t_max = h.t;
                        best = Some((h, i as u32));
                    }
                }
            }
            AccelKind::Bvh => self.traverse_objects(ray, t_min, t_max, |leaf, t_cur| {
                // Once something is hit the bound is inclusive, so an object at exactly
                // the same distance with a lower index wins, as in the brute-force loop.
                let limit = if best.is_some() { t_cur.next_up() } else { t_cur };
                let i = leaf.index();
                match self.intersect_leaf(leaf, ray, t_min, limit) {
                    Some(h) if best.as_ref().is_none_or(|(b, bi)| h.t < b.t || i < *bi) => {
                        let t = h.t;
                        best = Some((h, i));
                        Visit::Continue(t)
                    }
                    _ => Visit::Continue(t_cur),
                }
            }),
        }
        best
    }

    /// The share of light that travels from `ray.origin` a distance `t_max` along the
    /// ray: the product of the transmission of every object in the way, each counted
    /// once however many of its surfaces the segment crosses (two overlapping 70 %
    /// spheres pass 0.49). Stops at the first opaque object. The product is kept in
    /// f64 so that the order objects are met in does not change the f32 result.
    #[inline]
    pub fn transmittance(&self, ray: &Ray, t_max: f32) -> f32 {
        let mut light = 1.0f64;
        match self.kind {
            AccelKind::None => {
                for i in 0..self.scene.objects.len() {
                    if self.blocks(i, ray, t_max) {
                        light *= self.transmission[i] as f64;
                        if light == 0.0 {
                            return 0.0;
                        }
                    }
                }
            }
            AccelKind::Bvh => self.traverse_objects(ray, 0.0, t_max, |leaf, _| {
                let i = leaf.index();
                let blocked = match leaf {
                    LeafObject::Sphere(s, _) => s.intersect(ray, 0.0, t_max).is_some(),
                    LeafObject::Other(_) => self.blocks(i as usize, ray, t_max),
                };
                if blocked {
                    light *= self.transmission[i as usize] as f64;
                    if light == 0.0 {
                        return Visit::Stop;
                    }
                }
                // Every object along the whole segment counts, not just the nearest.
                Visit::Continue(t_max)
            }),
        }
        light as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Camera;
    use crate::geometry::{Cone, Cylinder, Polygon, Quad, Sphere, Triangle};
    use crate::material::Material;
    use crate::math::Color;
    use crate::math::Vec3;
    use crate::sampler::Rng;

    fn v(r: &mut Rng, scale: f32) -> Vec3 {
        Vec3::new(r.next_f32() - 0.5, r.next_f32() - 0.5, r.next_f32() - 0.5) * scale
    }

    fn unit(r: &mut Rng) -> Vec3 {
        loop {
            let d = v(r, 2.0);
            if d.length_squared() > 1e-3 && d.length_squared() <= 1.0 {
                return d.normalize();
            }
        }
    }

    /// `n` objects of every kind scattered in a 20-unit box, some transparent.
    fn random_scene(seed: u64, n: usize) -> Scene {
        let mut r = Rng::new(seed);
        let mut scene = Scene::new(Camera::new(Vec3::ZERO, Vec3::NEG_Z, Vec3::Y, 40.0, 8, 8));
        let opaque = scene.add_material(Material::color(Color::ONE));
        let glass = scene.add_material(Material::color(Color::ONE).transparent(0.6, 1.0));
        for i in 0..n {
            let c = v(&mut r, 20.0);
            let size = 0.2 + r.next_f32() * 2.0;
            let shape: Shape = match i % 7 {
                0 => Sphere::new(c, size).into(),
                1 => Quad::new(c, unit(&mut r) * size, unit(&mut r) * size).into(),
                2 => {
                    let (a, b) = crate::math::orthonormal_basis(unit(&mut r));
                    let k = 3 + (r.below(5) as usize);
                    let pts = (0..k)
                        .map(|j| {
                            let ang = j as f32 / k as f32 * std::f32::consts::TAU;
                            c + size * (ang.cos() * a + ang.sin() * b)
                        })
                        .collect();
                    Polygon::new(pts).unwrap().into()
                }
                3 => Cylinder::new(c, unit(&mut r), size * 0.5, size * 2.0, r.below(2) == 0).into(),
                4 => {
                    // Pointed or truncated (narrowing or widening), open or closed.
                    let top = [0.0, 0.4, 1.6][r.below(3) as usize] * size;
                    let closed = r.below(2) == 0;
                    Cone::truncated(c, unit(&mut r), size, top, size * 1.5, closed, closed).into()
                }
                5 => Triangle::new(c, c + v(&mut r, 3.0), c + v(&mut r, 3.0)).into(),
                _ => {
                    // A small random triangle soup, as a mesh.
                    let pos: Vec<Vec3> = (0..30).map(|_| c + v(&mut r, 4.0)).collect();
                    let tris = (0..10).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
                    Mesh::new(pos, vec![], vec![], tris, r.below(2) == 0).unwrap().into()
                }
            };
            let m = if r.below(4) == 0 { glass } else { opaque };
            scene.add(shape, m);
        }
        scene
    }

    #[test]
    fn bvh_and_brute_force_agree_on_random_rays_of_every_kind() {
        let mut rays = 0;
        for seed in 0..6u64 {
            let scene = random_scene(seed, 70 + 40 * seed as usize);
            let (bvh, brute) = (World::new(&scene, AccelKind::Bvh), World::new(&scene, AccelKind::None));
            let mut r = Rng::new(1000 + seed);
            for i in 0..40_000 {
                let origin = v(&mut r, 30.0);
                let ray = Ray::new(origin, unit(&mut r));
                let (a, b) = (bvh.closest(&ray, 0.0, f32::INFINITY), brute.closest(&ray, 0.0, f32::INFINITY));
                assert_eq!(a, b, "seed {seed} ray {i}: {ray:?}");
                let t_max = 5.0 + 20.0 * r.next_f32();
                assert_eq!(bvh.transmittance(&ray, t_max), brute.transmittance(&ray, t_max), "seed {seed} ray {i}");
                rays += 1;
            }
        }
        assert_eq!(rays, 240_000);
    }

    #[test]
    fn mesh_bvh_agrees_with_testing_every_triangle() {
        let mesh = crate::scene::generate::cube_sphere(24);
        let tree = MeshBvh::build(&mesh);
        let mut r = Rng::new(5);
        for i in 0..100_000 {
            let ray = Ray::new(v(&mut r, 3.0), unit(&mut r));
            let a = tree.closest(&ray, 0.0, f32::INFINITY);
            let b = mesh.intersect(&ray, 0.0, f32::INFINITY);
            assert_eq!(a, b, "ray {i}: {ray:?}");
            assert_eq!(tree.occluded(&ray, 0.0, 1.0), mesh.occluded(&ray, 0.0, 1.0), "ray {i}");
        }
    }

    #[test]
    fn memory_is_reported_per_structure() {
        let scene = random_scene(1, 50);
        assert!(World::new(&scene, AccelKind::Bvh).memory_bytes() > 0);
        assert_eq!(World::new(&scene, AccelKind::None).memory_bytes(), 0);
    }
}
