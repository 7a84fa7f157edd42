use super::*;
use crate::camera::Camera;
use crate::geometry::{Cone, Cylinder, Mesh, Polygon, Quad, Sphere, Triangle};
use crate::material::Material;
use crate::math::Vec3;
use crate::math::{Aabb, Color};
use crate::sampler::Rng;

mod light_buffers;

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

/// Calls `f((tx, ty), (x0, y0), seen)` for each 4 x 4 pixel tile of the scene's
/// image whose cone of camera rays culls the objects to `seen`.
fn culled_tiles(world: &World, rig: &crate::camera::CameraRig, mut f: impl FnMut((u32, u32), (f32, f32), &[u32])) {
    let camera = world.scene().camera;
    let mut seen = Vec::new();
    for (ty, tx) in (0..camera.height.div_ceil(4)).flat_map(|ty| (0..camera.width.div_ceil(4)).map(move |tx| (ty, tx)))
    {
        let (x0, y0) = (tx as f32 * 4.0, ty as f32 * 4.0);
        let (apex, edges) = rig.cone(x0, y0, x0 + 4.0, y0 + 4.0);
        if world.seen_from(apex, edges, &mut seen) {
            f((tx, ty), (x0, y0), &seen);
        }
    }
}

#[test]
fn camera_rays_through_a_tile_test_only_what_its_cone_sees_and_find_the_same() {
    // Small random scenes seen by cameras from outside and from inside; every
    // 4 x 4 pixel tile culls to its cone, and each ray, through the pixel centre
    // and through the tile's corners, must find what the tree finds, alone and
    // eight at a time (81 rays: a short last group).
    let (mut culled, mut hits, mut dropped) = (0, 0, 0);
    for seed in 0..12u64 {
        let mut scene = random_scene(seed, 14);
        let mut r = Rng::new(seed + 100);
        let eye = if seed % 2 == 0 { v(&mut r, 60.0) } else { v(&mut r, 8.0) };
        scene.camera = Camera::new(eye, v(&mut r, 5.0), Vec3::Y, 30.0 + 60.0 * r.next_f32(), 32, 24);
        let world = World::new(&scene, AccelKind::Bvh);
        let rig = scene.camera.rig().unwrap();
        culled_tiles(&world, &rig, |(tx, ty), (x0, y0), seen| {
            culled += 1;
            dropped += scene.objects.len() - seen.len();
            assert!(seen.windows(2).all(|w| w[0] < w[1]));
            let at = (0..=8).flat_map(|j| (0..=8).map(move |i| (i as f32 * 0.5, j as f32 * 0.5)));
            let mut each: Vec<_> = at.clone().map(|(sx, sy)| (rig.ray(x0 + sx, y0 + sy), None)).collect();
            world.closest_among_each(seen, &mut each);
            for ((sx, sy), (ray, together)) in at.zip(&each) {
                let want = world.closest(ray, 0.0, f32::INFINITY);
                let got = world.closest_among(seen, ray, 0.0, f32::INFINITY);
                assert_eq!(got, want, "seed {seed}, tile ({tx}, {ty}), at ({sx}, {sy})");
                assert_eq!(*together, want, "eight at a time: seed {seed}, tile ({tx}, {ty}), at ({sx}, {sy})");
                hits += want.is_some() as u32;
            }
        });
    }
    assert!(culled > 100 && hits > 1000 && dropped > 1000, "{culled} tiles, {hits} hits, {dropped} objects culled");
    // Not for big scenes, nor without a tree.
    let big = random_scene(1, 100);
    let rig = big.camera.rig().unwrap();
    let (apex, edges) = rig.cone(0.0, 0.0, 1.0, 1.0);
    assert!(!World::new(&big, AccelKind::Bvh).seen_from(apex, edges, &mut Vec::new()));
    let small = random_scene(1, 3);
    assert!(!World::new(&small, AccelKind::None).seen_from(apex, edges, &mut Vec::new()));
}

#[test]
fn rays_from_nearby_points_in_nearby_directions_test_only_what_they_may_meet_and_find_the_same() {
    // Bundles of rays as a tile's reflections send on: origins within a small box
    // (sometimes a single point, or one coordinate shared, as on an axis-aligned
    // mirror), directions within a narrow cone, some with a zero component. Where
    // the bundle culls, each ray must find what the tree finds.
    let (mut culled, mut hits, mut dropped) = (0, 0, 0);
    let mut seen = Vec::new();
    for seed in 0..10u64 {
        let scene = random_scene(seed, 20);
        let world = World::new(&scene, AccelKind::Bvh);
        let mut r = Rng::new(seed + 300);
        for bundle in 0..400 {
            let centre = v(&mut r, 25.0);
            let spread = [0.0, 0.05, 1.0][bundle % 3];
            let aim = unit(&mut r);
            let aim = if bundle % 5 == 0 { Vec3::new(aim.x, 0.0, aim.z).normalize() } else { aim };
            let width = [0.01, 0.1, 0.3][bundle % 4 % 3];
            let rays: Vec<(Ray, ())> = (0..24)
                .map(|_| {
                    let mut o = centre + v(&mut r, spread);
                    if bundle % 7 == 0 {
                        o.y = centre.y;
                    }
                    let mut d = aim + v(&mut r, width);
                    if bundle % 5 == 0 && r.below(2) == 0 {
                        d.y = 0.0;
                    }
                    (Ray::new(o, d), ())
                })
                .collect();
            if !world.seen_along(&rays, &mut seen) {
                continue;
            }
            culled += 1;
            dropped += scene.objects.len() - seen.len();
            assert!(seen.windows(2).all(|w| w[0] < w[1]));
            for (ray, ()) in &rays {
                let want = world.closest(ray, 0.0, f32::INFINITY);
                assert_eq!(world.closest_among(&seen, ray, 0.0, f32::INFINITY), want, "seed {seed}, {ray:?}");
                hits += want.is_some() as u32;
            }
        }
    }
    assert!(
        culled > 1000 && hits > 5000 && dropped > 10_000,
        "{culled} bundles, {hits} hits, {dropped} objects culled"
    );
}

#[test]
fn shadow_rays_from_a_tiles_hits_need_only_the_objects_that_may_shadow_them() {
    // As a render does: a tile's camera hits, boxed per object; for lights here and
    // there, the shadow ray from each hit (pushed off its surface towards the light)
    // must pass the same light testing the culled list as testing everything.
    let (mut checked, mut culled_lists, mut dropped, mut partial) = (0, 0, 0, 0);
    for seed in 0..16u64 {
        let mut scene = random_scene(seed, 12);
        // Walls too: quads are culled by their planes.
        let wall = scene.objects[0].material;
        for (c, u, v) in
            [(Vec3::new(-30.0, -30.0, -30.0), Vec3::X, Vec3::Y), (Vec3::new(-30.0, -30.0, -30.0), Vec3::Z, Vec3::X)]
        {
            scene.add(Quad::new(c, u * 60.0, v * 60.0), wall);
        }
        let mut r = Rng::new(seed + 7);
        scene.camera = Camera::new(v(&mut r, 25.0), v(&mut r, 5.0), Vec3::Y, 50.0, 24, 16);
        let lights: Vec<Vec3> = (0..4).map(|_| v(&mut r, 28.0)).collect();
        let world = World::new(&scene, AccelKind::Bvh);
        let rig = scene.camera.rig().unwrap();
        culled_tiles(&world, &rig, |(tx, ty), (x0, y0), seen| {
            let mut found = Vec::new();
            let mut boxes: Vec<(u32, Aabb)> = Vec::new();
            for (sx, sy) in (0..8).flat_map(|j| (0..8).map(move |i| (i as f32 * 0.5 + 0.25, j as f32 * 0.5 + 0.25))) {
                let ray = rig.ray(x0 + sx, y0 + sy);
                if let Some((h, i)) = world.closest_among(seen, &ray, 0.0, f32::INFINITY) {
                    match boxes.iter_mut().find(|(o, _)| *o == i) {
                        Some((_, b)) => *b = b.grow(ray.at(h.t)),
                        None => boxes.push((i, Aabb::EMPTY.grow(ray.at(h.t)))),
                    }
                    found.push((ray, h, i));
                }
            }
            for &light in &lights {
                let mut few = Vec::new();
                if !world.may_shadow(&boxes, light, &mut few) {
                    continue;
                }
                culled_lists += 1;
                dropped += scene.objects.len() - few.len();
                let mut shadows = Vec::new();
                for (ray, h, i) in &found {
                    let s = scene.objects[*i as usize].shape.surface(ray, h);
                    let side = if ray.dir.dot(s.normal) < 0.0 { s.normal } else { -s.normal };
                    let from = s.point + crate::math::surface_offset(s.point) * side;
                    let (to, distance) = ((light - from).normalize(), (light - from).length());
                    if side.dot(to) <= 0.0 {
                        continue; // shading sends no shadow ray
                    }
                    let shadow = Ray { origin: from, dir: to };
                    let (want, got) =
                        (world.transmittance(&shadow, distance), world.transmittance_among(&few, &shadow, distance));
                    assert_eq!(got.to_bits(), want.to_bits(), "seed {seed}, tile ({tx}, {ty}), light {light}");
                    shadows.push(((shadow, distance), want));
                    checked += 1;
                }
                // And all of them together, eight at a time, one lane in three dead.
                for (g, group) in shadows.chunks(8).enumerate() {
                    let (mut origins, mut dirs, mut t_max) = ([[0.0; 8]; 3], [[0.0; 8]; 3], [0.0; 8]);
                    for (lane, ((ray, t), _)) in group.iter().enumerate() {
                        for axis in 0..3 {
                            (origins[axis][lane], dirs[axis][lane]) = (ray.origin[axis], ray.dir[axis]);
                        }
                        t_max[lane] = *t;
                    }
                    let live = (0..group.len()).filter(|lane| (g + lane) % 3 != 0).fold(0, |m, l| m | 1 << l);
                    let got = world.transmittance_among_lanes(&few, &origins, &dirs, t_max, live);
                    for (lane, (_, want)) in group.iter().enumerate() {
                        let want = if live >> lane & 1 == 0 { 0.0 } else { *want };
                        assert_eq!(
                            got[lane].to_bits(),
                            want.to_bits(),
                            "seed {seed}, tile ({tx}, {ty}), light {light}"
                        );
                    }
                }
                partial += (shadows.iter().any(|&(_, v)| v > 0.0 && v < 1.0)) as u32;
            }
        });
    }
    assert!(
        checked > 5000 && culled_lists > 100 && dropped > 500 && partial > 20,
        "{checked} rays, {culled_lists} lists, {dropped} dropped, {partial} with light through glass"
    );
}

#[test]
fn bvh_and_brute_force_agree_on_random_rays_of_every_kind() {
    let mut rays = 0;
    for seed in 0..6u64 {
        let scene = random_scene(seed, 70 + 40 * seed as usize);
        // Even seeds walk 4-wide trees, odd ones 8-wide where the processor can.
        let width = Some(if seed % 2 == 0 { 4 } else { 8 });
        let (bvh, brute) = (World::with_width(&scene, AccelKind::Bvh, width), World::new(&scene, AccelKind::None));
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

/// A scene of nearly only spheres takes the packed path (four spheres a test): it
/// must still give the brute-force answers, ties between coincident spheres included.
#[test]
fn sphere_packs_agree_with_testing_every_object() {
    let mut scene = random_scene(9, 14);
    let mut r = Rng::new(77);
    let opaque = scene.add_material(Material::color(Color::ONE));
    let glass = scene.add_material(Material::color(Color::ONE).transparent(0.7, 1.0));
    for i in 0..600 {
        let s = Sphere::new(v(&mut r, 20.0), 0.1 + r.next_f32() * 1.5);
        let m = if r.below(3) == 0 { glass } else { opaque };
        scene.add(s, m);
        if i % 50 == 0 {
            scene.add(s, opaque); // the same sphere again: the lower index must win
        }
    }
    // A floor under it all, twice: packets of camera rays test its entry together.
    let floor = Quad::new(Vec3::new(-100.0, -21.0, 100.0), Vec3::X * 200.0, Vec3::NEG_Z * 200.0);
    scene.add(floor, glass);
    scene.add(floor, opaque);
    #[cfg(target_arch = "x86_64")]
    let packets_before = super::eight_rays::QUAD_PACKETS.load(std::sync::atomic::Ordering::Relaxed);
    for width in [4, 8] {
        sphere_packs_agree(&scene, width, &mut r);
    }
    // Where the eight-lane code runs (not with `WHITTED_PORTABLE=1`, as CI's second run).
    #[cfg(target_arch = "x86_64")]
    if super::lanes::avx2() {
        let after = super::eight_rays::QUAD_PACKETS.load(std::sync::atomic::Ordering::Relaxed);
        assert!(after > packets_before, "no packet tested the floor's entry at once");
    }
}

fn sphere_packs_agree(scene: &Scene, width: usize, r: &mut Rng) {
    let (bvh, brute) = (World::with_width(scene, AccelKind::Bvh, Some(width)), World::new(scene, AccelKind::None));
    let packs = bvh.leaves.iter().filter(|l| matches!(l, LeafItem::Spheres(_) | LeafItem::Spheres8(_))).count();
    assert!(packs > 0 && packs * 2 < scene.objects.len(), "spheres not packed");
    // Packs of eight exactly where the 8-wide tree is walked.
    let eights = bvh.leaves.iter().any(|l| matches!(l, LeafItem::Spheres8(_)));
    assert_eq!(eights, bvh.top4.width() == 8, "packs of eight in a {}-wide tree", bvh.top4.width());
    for i in 0..40_000 {
        let ray = Ray::new(v(r, 30.0), unit(r));
        let (a, b) = (bvh.closest(&ray, 0.0, f32::INFINITY), brute.closest(&ray, 0.0, f32::INFINITY));
        assert_eq!(a, b, "ray {i}: {ray:?}");
        let t_max = 5.0 + 20.0 * r.next_f32();
        assert_eq!(bvh.transmittance(&ray, t_max), brute.transmittance(&ray, t_max), "ray {i}");
    }
    // Rays eight at a time: from one eye over a grid (packets), and scattered.
    let eye = v(r, 30.0);
    let mut found: Vec<(Ray, Option<(Hit, u32)>)> = (0..64 * 64)
        .map(|i| {
            let d = -eye + Vec3::new((i % 64) as f32 * 0.6 - 19.0, (i / 64) as f32 * 0.6 - 19.0, 0.0);
            (Ray::new(eye, d), None)
        })
        .chain((0..1000).map(|_| (Ray::new(v(r, 30.0), unit(r)), None)))
        .collect();
    bvh.closest_found(&mut found);
    let hits = found.iter().filter(|(_, h)| h.is_some()).count();
    assert!(hits > 500 && hits + 500 < found.len(), "{hits} of {} hit", found.len());
    for (i, (ray, hit)) in found.iter().enumerate() {
        assert_eq!(*hit, brute.closest(ray, 0.0, f32::INFINITY), "ray {i} of eight at a time");
    }
}

#[test]
fn mesh_bvh_agrees_with_testing_every_triangle() {
    let mesh = crate::scene::generate::cube_sphere(24);
    for width in [4, 8] {
        mesh_bvh_agrees(&mesh, width);
    }
}

/// Meshes small enough to be tested without their tree ([`MeshBvh::direct`]): an
/// octahedron (8 triangles, two packs), its top half, one triangle.
#[test]
fn small_meshes_tested_directly_agree_with_testing_every_triangle() {
    let p = [Vec3::X, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Y, Vec3::Z, Vec3::NEG_Z].map(|v| v * 1.5).to_vec();
    let faces = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]];
    for n in [8, 4, 1] {
        let mesh = Mesh::new(p.clone(), Vec::new(), Vec::new(), faces[..n].to_vec(), false).expect("a mesh");
        for width in [4, 8] {
            assert!(MeshBvh::build(&mesh, Some(width)).direct());
            mesh_bvh_agrees(&mesh, width);
        }
    }
}

fn mesh_bvh_agrees(mesh: &Mesh, width: usize) {
    let tree = MeshBvh::build(mesh, Some(width));
    let mut r = Rng::new(5);
    for i in 0..100_000 {
        let ray = Ray::new(v(&mut r, 3.0), unit(&mut r));
        let a = tree.closest(&ray, 0.0, f32::INFINITY);
        let b = mesh.intersect(&ray, 0.0, f32::INFINITY);
        assert_eq!(a, b, "ray {i}: {ray:?}");
        assert_eq!(tree.occluded(&ray, 0.0, 1.0), mesh.occluded(&ray, 0.0, 1.0), "ray {i}");
    }
}

/// Shadow rays and closest hits in a world of one mesh, batched, as one by one:
/// from points on and around the mesh, blocked and not, opaque and glass, both tree
/// widths.
#[test]
fn rays_in_batches_match_one_by_one() {
    let mut r = Rng::new(9);
    for (transparency, width) in [(0.0, 8), (0.6, 8), (0.0, 4)] {
        let mut scene = Scene::new(Camera::new(Vec3::ZERO, Vec3::NEG_Z, Vec3::Y, 40.0, 8, 8));
        let m = scene.add_material(Material::color(Color::ONE).transparent(transparency, 1.0));
        scene.add(crate::scene::generate::cube_sphere(12), m);
        let world = World::with_width(&scene, AccelKind::Bvh, Some(width));
        // Lengths up to 6 (rays from outside the unit sphere may end before it).
        let rays: Vec<(Ray, f32)> =
            (0..3001).map(|_| (Ray::new(v(&mut r, 1.5), unit(&mut r)), 6.0 * r.next_f32())).collect();
        let want: Vec<f32> = rays.iter().map(|(ray, t)| world.transmittance(ray, *t)).collect();
        let mut got = vec![0.0; rays.len()];
        world.transmittance_each(&rays, &mut got);
        assert_eq!(got, want, "transparency {transparency}, width {width}");
        // And closest hits likewise, within the same lengths and without bound.
        for t_max in [2.5, f32::INFINITY] {
            let rays: Vec<Ray> = rays.iter().map(|(ray, _)| *ray).collect();
            let want: Vec<_> = rays.iter().map(|ray| world.closest(ray, 0.0, t_max)).collect();
            let mut got = vec![None; rays.len()];
            world.closest_each(&rays, 0.0, t_max, &mut got);
            assert_eq!(got, want, "width {width}, t_max {t_max}");
            let hits = want.iter().filter(|h| h.is_some()).count();
            assert!(hits > 300 && hits < 2990, "{hits} of {} hit", want.len());
        }
        let blocked = want.iter().filter(|&&l| l < 1.0).count();
        assert!(blocked > 300 && blocked < 2700, "{blocked} of {} blocked", want.len());
        // Bundles of eight, as packets take them: camera rays from one eye, and
        // shadow rays from points close together to one light.
        let eye = Vec3::new(0.3, 0.4, 3.0);
        let camera: Vec<Ray> = (0..64 * 64)
            .map(|i| Ray::new(eye, Vec3::new((i % 64) as f32 / 64.0 - 0.5, (i / 64) as f32 / 64.0 - 0.5, -1.5)))
            .collect();
        let want: Vec<_> = camera.iter().map(|ray| world.closest(ray, 0.0, f32::INFINITY)).collect();
        let mut got = vec![None; camera.len()];
        world.closest_each(&camera, 0.0, f32::INFINITY, &mut got);
        assert_eq!(got, want, "camera rays, width {width}");
        let light = Vec3::new(3.0, 1.0, 0.5);
        let shadow: Vec<(Ray, f32)> = want
            .iter()
            .zip(&camera)
            .filter_map(|(hit, ray)| hit.map(|(h, _)| ray.at(h.t) - 1e-3 * ray.dir))
            .map(|p| (Ray::new(p, light - p), (light - p).length() * 0.999))
            .collect();
        let want: Vec<f32> = shadow.iter().map(|(ray, t)| world.transmittance(ray, *t)).collect();
        let mut got = vec![0.0; shadow.len()];
        world.transmittance_each(&shadow, &mut got);
        assert_eq!(got, want, "shadow rays, width {width}");
        let blocked = want.iter().filter(|&&l| l < 1.0).count();
        assert!(blocked > 100 && blocked + 100 < want.len(), "{blocked} of {} blocked", want.len());
    }
}

/// `count` spheres added to a [`random_scene`] in a 12-unit box, radii from `min` to
/// `min + spread`, one in four of glass.
fn add_spheres(scene: &mut Scene, r: &mut Rng, count: usize, (min, spread): (f32, f32)) {
    let (opaque, glass) = (crate::scene::MaterialId(0), crate::scene::MaterialId(1));
    for i in 0..count {
        let s = Sphere::new(v(r, 12.0), min + spread * r.next_f32());
        scene.add(s, if i % 4 == 0 { glass } else { opaque });
    }
}

/// Shadow rays that try first the leaf entry that blocked the ray before (as the wave
/// carries a [`LastBlocker`] from ray to ray), or an entry picked at random, get the
/// answers of testing every object: opaque and glass objects of every kind, spheres in
/// packs, 4- and 8-wide trees.
#[test]
fn a_shadow_rays_last_blocker_changes_no_answer() {
    for (seed, width) in [(3u64, 4), (4, 8)] {
        let mut scene = random_scene(seed, 150);
        let mut r = Rng::new(500 + seed);
        add_spheres(&mut scene, &mut r, 400, (0.2, 1.0));
        let (bvh, brute) =
            (World::with_width(&scene, AccelKind::Bvh, Some(width)), World::new(&scene, AccelKind::None));
        let entries = bvh.leaves.len() as u32;
        let (mut last, mut settled, mut blocked) = (LastBlocker::default(), 0, 0);
        for i in 0..40_000 {
            // Rays from points in a small region towards one light, so that what blocked
            // one ray often blocks the next; a new region and light every 64 rays.
            if i % 64 == 0 {
                last = LastBlocker::default();
            }
            let (region, light) = {
                let mut q = Rng::new(i / 64);
                (v(&mut q, 24.0), v(&mut q, 40.0))
            };
            let from = region + v(&mut r, 2.0);
            let ray = Ray::new(from, light - from);
            let t_max = (light - from).length();
            let mut alone = 1.0f64;
            settled += (last.0 != u32::MAX && bvh.leaf_stops(last.0 as usize, &ray, t_max, &mut alone)) as u32;
            let want = brute.transmittance(&ray, t_max);
            assert_eq!(bvh.transmittance_hinted(&ray, t_max, &mut last), want, "seed {seed}, ray {i}");
            blocked += (want == 0.0) as u32;
            if i % 5 == 0 {
                last = LastBlocker::at(r.below(entries)); // any entry, glass or opaque, hit or not
            }
        }
        // The hint answered for many rays, and many were blocked some other way.
        assert!(settled > 2000 && settled + 2000 < blocked, "seed {seed}: {settled} settled, {blocked} blocked");
    }
}

/// Shadow rays past opaque and glass meshes, carrying the last blocker and with it the
/// leaf of the mesh's tree that blocked (or a run of its packs picked at random, which
/// may block or not), get the answers of testing every object, and the leaf settles
/// many of them.
#[test]
fn a_meshs_blocking_leaf_changes_no_answer() {
    for width in [4, 8] {
        let mut scene = random_scene(21, 60);
        let mut r = Rng::new(2100);
        // Two wavy sheets of 3,200 triangles each across the middle: opaque, then glass.
        let n = 40u32;
        for (k, material) in [(0, crate::scene::MaterialId(0)), (1, crate::scene::MaterialId(1))] {
            let pos = (0..=n)
                .flat_map(|i| (0..=n).map(move |j| (i as f32, j as f32)))
                .map(|(i, j)| Vec3::new(i - 20.0, (i * 0.7).sin() + (j * 0.5).cos() + k as f32 * 6.0 - 3.0, j - 20.0))
                .collect();
            let quads = (0..n).flat_map(|i| (0..n).map(move |j| i * (n + 1) + j));
            let tris = quads.flat_map(|a| [[a, a + 1, a + n + 1], [a + 1, a + n + 2, a + n + 1]]).collect();
            scene.add(Mesh::new(pos, vec![], vec![], tris, false).expect("a mesh"), material);
        }
        let (bvh, brute) =
            (World::with_width(&scene, AccelKind::Bvh, Some(width)), World::new(&scene, AccelKind::None));
        let sheet = (0..bvh.leaves.len()).find(|&at| bvh.opaque_mesh(at).is_some()).expect("the opaque sheet");
        let packs = bvh.opaque_mesh(sheet).expect("a mesh").packs.len() as u32;
        let (mut last, mut settled, mut blocked) = (LastBlocker::default(), 0, 0);
        for i in 0..40_000 {
            // From points below the sheets towards a light above them; a new region and
            // light every 64 rays.
            if i % 64 == 0 {
                last = LastBlocker::default();
            }
            let (region, light) = {
                let mut q = Rng::new(1000 + i / 64);
                (v(&mut q, 15.0) - Vec3::Y * 12.0, v(&mut q, 15.0) + Vec3::Y * 30.0)
            };
            let from = region + v(&mut r, 1.0);
            let ray = Ray::new(from, light - from);
            let t_max = (light - from).length();
            let part = last.1 as usize..last.2 as usize;
            settled += (last.0 as usize == sheet
                && !part.is_empty()
                && bvh.opaque_mesh(sheet).expect("a mesh").packs_block(part, &ray, t_max))
                as u32;
            let want = brute.transmittance(&ray, t_max);
            assert_eq!(bvh.transmittance_hinted(&ray, t_max, &mut last), want, "width {width}, ray {i}");
            blocked += (want == 0.0) as u32;
            if i % 7 == 0 {
                let start = r.below(packs);
                last = LastBlocker(sheet as u32, start, (start + 1 + r.below(3)).min(packs));
            }
        }
        assert!(settled > 10_000 && blocked > settled, "width {width}: {settled} settled, {blocked} blocked");
    }
}

#[test]
fn memory_is_reported_per_structure() {
    let scene = random_scene(1, 50);
    assert!(World::new(&scene, AccelKind::Bvh).memory_bytes() > 0);
    assert_eq!(World::new(&scene, AccelKind::None).memory_bytes(), 0);
}
