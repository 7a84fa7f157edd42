use super::*;
use crate::camera::Camera;
use crate::geometry::{Cone, Cylinder, Mesh, Polygon, Quad, Sphere, Triangle};
use crate::material::Material;
use crate::math::Vec3;
use crate::math::{Aabb, Color};
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

/// Shadow rays through the lights' buffers get the answers of testing every object:
/// opaque and glass objects of every kind, spheres in packs, 4- and 8-wide trees, lights
/// outside the objects, among them and inside an object's box; rays from anywhere,
/// also from points on the edges between the buffer's faces, with the last blocker
/// carried or picked at random. Both kinds of cell are met: listed and crowded.
#[test]
fn shadow_rays_through_light_buffers_get_the_answers_of_testing_everything() {
    for (seed, width) in [(5u64, 4), (6, 8)] {
        let mut scene = random_scene(seed, 150);
        let mut r = Rng::new(700 + seed);
        add_spheres(&mut scene, &mut r, 600, (0.05, 0.5));
        let (opaque, glass) = (crate::scene::MaterialId(0), crate::scene::MaterialId(1));
        // A crowd: many small spheres in a narrow cone of one light's directions.
        for i in 0..400 {
            scene.add(
                Sphere::new(Vec3::new(30.0, 0.0, 0.0) + v(&mut r, 1.0), 0.05),
                if i % 3 == 0 { glass } else { opaque },
            );
        }
        let inside = scene.objects[7].shape.bounds().center();
        let lights = [Vec3::new(40.0, 0.5, 0.3), Vec3::new(-3.0, 25.0, 10.0), v(&mut r, 10.0), inside];
        for &at in &lights {
            scene.add_light(crate::light::PointLight::new(at, Color::ONE));
        }
        let (bvh, brute) =
            (World::with_width(&scene, AccelKind::Bvh, Some(width)), World::new(&scene, AccelKind::None));
        let buffers: Vec<_> = bvh
            .light_buffers
            .iter()
            .enumerate()
            .map(|(k, b)| b.as_ref().unwrap_or_else(|| panic!("no buffer for light {k}, {} entries", bvh.leaves.len())))
            .collect();
        let entries = bvh.leaves.len() as u32;
        let (mut listed, mut crowded, mut blocked, mut through) = (0, 0, 0, 0);
        let mut last = LastBlocker::default();
        for i in 0..60_000u32 {
            let k = (i / 64) as usize % lights.len();
            let at = lights[k];
            if i % 64 == 0 {
                last = LastBlocker::default();
            }
            let from = match i % 8 {
                // On an edge or a corner of the cube of faces, as nearly as f32 goes.
                0 => {
                    let d = 1.0 + 10.0 * r.next_f32();
                    let s = |r: &mut Rng| if r.below(2) == 0 { -d } else { d };
                    let mut w = Vec3::new(s(&mut r), s(&mut r), s(&mut r));
                    w[r.below(3) as usize] *= 1.0 + (r.next_f32() - 0.5) * 1e-6;
                    at + w
                }
                // Near the crowd, so the crowded cells are met.
                1 | 2 => Vec3::new(34.0, 0.0, 0.0) + v(&mut r, 6.0),
                _ => v(&mut r, 30.0),
            };
            let ray = Ray::new(from, at - from);
            let t_max = (at - from).length();
            match buffers[k].cell_of(from) {
                Some(list) if !list.is_empty() => listed += 1,
                Some(_) => {}
                None => crowded += 1,
            }
            let want = brute.transmittance(&ray, t_max);
            assert_eq!(bvh.transmittance_towards(k, &ray, t_max, &mut last), want, "seed {seed}, ray {i}");
            blocked += (want == 0.0) as u32;
            through += (want > 0.0 && want < 1.0) as u32;
            if i % 7 == 0 {
                last = LastBlocker::at(r.below(entries));
            }
        }
        assert!(listed > 20_000 && crowded > 1000, "seed {seed}: {listed} listed, {crowded} crowded");
        assert!(blocked > 5000 && through > 1000, "seed {seed}: {blocked} blocked, {through} through glass");
    }
}

/// Eight shadow rays at once through the lights' buffers get the answers of testing
/// every object, lane by lane: from anywhere, and from points just off quads and
/// triangles on the light's side, which then are not tested against the object they
/// leave. Each lane's cell is the one [`LightBuffer::cell_of`] finds.
#[test]
fn eight_shadow_rays_through_light_buffers_get_the_answers_of_testing_everything() {
    let mut scene = random_scene(11, 400);
    let mut r = Rng::new(711);
    add_spheres(&mut scene, &mut r, 600, (0.05, 0.5));
    let lights = [Vec3::new(40.0, 0.5, 0.3), Vec3::new(-3.0, 25.0, 10.0), v(&mut r, 10.0)];
    for &at in &lights {
        scene.add_light(crate::light::PointLight::new(at, Color::ONE));
    }
    let (bvh, brute) = (World::new(&scene, AccelKind::Bvh), World::new(&scene, AccelKind::None));
    let flat: Vec<u32> = (0..scene.objects.len() as u32)
        .filter(|&i| matches!(scene.objects[i as usize].shape, Shape::Quad(_) | Shape::Triangle(_)))
        .collect();
    let (mut left, mut blocked) = (0, 0);
    for group in 0..6000 {
        let k = group % lights.len();
        let at = lights[k];
        let mut last = LastBlocker::default();
        let (mut from, mut dirs, mut t_max, mut leaving) = ([[0f32; 8]; 3], [[0f32; 8]; 3], [0f32; 8], [NONE; 8]);
        let live = r.below(256);
        for lane in 0..8 {
            let (p, object) = match r.below(40) {
                0..=12 => (v(&mut r, 30.0), NONE),
                // Now and then a lane with no cell: not finite, or at the light itself.
                13 => ([Vec3::splat(f32::NAN), Vec3::new(1.0, f32::INFINITY, 0.0), at][r.below(3) as usize], NONE),
                _ => {
                    // Just off a flat object, on the light's side, as shading leaves it.
                    let i = flat[r.below(flat.len() as u32) as usize];
                    let (a, b) = (r.next_f32(), r.next_f32());
                    let (p, n) = match scene.objects[i as usize].shape {
                        Shape::Quad(q) => (q.corner + a * q.edge_u + b * q.edge_v, q.normal()),
                        Shape::Triangle(t) => {
                            let (a, b) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
                            (t.v0 + a * (t.v1 - t.v0) + b * (t.v2 - t.v0), (t.v1 - t.v0).cross(t.v2 - t.v0).normalize())
                        }
                        _ => unreachable!(),
                    };
                    let side = if n.dot(at - p) < 0.0 { -n } else { n };
                    (p + crate::math::surface_offset(p) * side, i)
                }
            };
            let l = at - p;
            for axis in 0..3 {
                (from[axis][lane], dirs[axis][lane]) = (p[axis], (l / l.length())[axis]);
            }
            (t_max[lane], leaving[lane]) = (l.length(), object);
        }
        let buffer = bvh.light_buffers[k].as_ref().expect("a buffer");
        let words = buffer.words_of_lanes(&from);
        let rays = ShadowLanes { from: &from, dirs: &dirs, t_max, live, leaving };
        let got = bvh.transmittance_towards_lanes(k, &rays, &mut last);
        for lane in 0..8 {
            let origin = Vec3::new(from[0][lane], from[1][lane], from[2][lane]);
            assert_eq!(buffer.list_of(words[lane]), buffer.cell_of(origin), "group {group}, lane {lane}");
            let ray = Ray { origin, dir: Vec3::new(dirs[0][lane], dirs[1][lane], dirs[2][lane]) };
            let want = if live >> lane & 1 == 0 { 0.0 } else { brute.transmittance(&ray, t_max[lane]) };
            assert_eq!(got[lane], want, "group {group}, lane {lane}");
            left += (live >> lane & 1 != 0 && leaving[lane] != NONE) as u32;
            blocked += (want == 0.0 && live >> lane & 1 != 0) as u32;
        }
    }
    assert!(left > 10_000 && blocked > 3000, "{left} rays leave flat objects, {blocked} blocked");
}

/// However many lights a scene has, at most [`light_buffer::MAX_LIGHTS`] get a buffer:
/// lights cost time, not memory.
#[test]
fn light_buffers_are_bounded_in_number() {
    let mut scene = random_scene(9, 300);
    let without = World::new(&scene, AccelKind::Bvh).memory_bytes();
    for k in 0..40 {
        scene.add_light(crate::light::PointLight::new(Vec3::new(k as f32, 30.0, 0.0), Color::ONE));
    }
    let world = World::new(&scene, AccelKind::Bvh);
    assert_eq!(world.light_buffers.iter().flatten().count(), light_buffer::MAX_LIGHTS);
    assert!(world.memory_bytes() > without);
    // A directional light has no position to centre one on.
    let mut scene = random_scene(9, 300);
    scene.add_light(crate::light::DirectionalLight::new(Vec3::NEG_Y, Color::ONE));
    assert!(World::new(&scene, AccelKind::Bvh).light_buffers.iter().all(Option::is_none));
}

/// Light buffers list an opaque mesh by the leaves of its tree ([`LeafItem::Piece`]), a
/// glass mesh whole: shadow rays through them, one or eight at a time, from anywhere
/// and from just above the wavy opaque sheet (which shadows itself), with the last
/// blocker carried or picked at random among all entries, pieces too, get the answers
/// of testing every object.
#[test]
fn light_buffers_listing_a_meshs_leaves_get_the_answers_of_testing_everything() {
    for width in [4, 8] {
        let mut scene = random_scene(31, 120);
        let mut r = Rng::new(3100);
        add_spheres(&mut scene, &mut r, 300, (0.05, 0.5));
        let n = 40u32;
        let height = |x: f32, z: f32| (x * 0.7).sin() + (z * 0.5).cos();
        for (k, material) in [(0, crate::scene::MaterialId(0)), (1, crate::scene::MaterialId(1))] {
            let pos = (0..=n)
                .flat_map(|i| (0..=n).map(move |j| (i as f32 - 20.0, j as f32 - 20.0)))
                .map(|(x, z)| Vec3::new(x, height(x, z) + k as f32 * 6.0 - 3.0, z))
                .collect();
            let quads = (0..n).flat_map(|i| (0..n).map(move |j| i * (n + 1) + j));
            let tris = quads.flat_map(|a| [[a, a + 1, a + n + 1], [a + 1, a + n + 2, a + n + 1]]).collect();
            scene.add(Mesh::new(pos, vec![], vec![], tris, false).expect("a mesh"), material);
        }
        let lights = [Vec3::new(3.0, 30.0, -2.0), Vec3::new(-25.0, 8.0, 4.0), Vec3::new(0.5, -20.0, 1.0)];
        for &at in &lights {
            scene.add_light(crate::light::PointLight::new(at, Color::ONE));
        }
        let (bvh, brute) =
            (World::with_width(&scene, AccelKind::Bvh, Some(width)), World::new(&scene, AccelKind::None));
        let (opaque, glass) = (scene.objects.len() as u32 - 2, scene.objects.len() as u32 - 1);
        let pieces_of =
            |object| bvh.leaves.iter().filter(|l| matches!(l, LeafItem::Piece(i, ..) if *i == object)).count();
        let sheet = bvh.opaque_object_mesh(opaque as usize).expect("the opaque sheet");
        let mut leaves = 0;
        sheet.pieces(|_, _| leaves += 1);
        assert!(leaves > 100, "width {width}: {leaves} leaves");
        assert_eq!(pieces_of(opaque), leaves, "width {width}: the opaque sheet in its leaves");
        assert_eq!(pieces_of(glass), 0, "width {width}: the glass sheet whole");
        let entries = bvh.leaves.len() as u32;
        let (mut blocked, mut through, mut piece_blocked) = (0, 0, 0);
        let mut last = LastBlocker::default();
        for group in 0..5000u32 {
            let k = group as usize % lights.len();
            let at = lights[k];
            let (mut from, mut dirs, mut t_max) = ([[0f32; 8]; 3], [[0f32; 8]; 3], [0f32; 8]);
            for lane in 0..8 {
                let p = match r.below(3) {
                    0 => v(&mut r, 22.0),
                    // Just above or below the opaque sheet.
                    _ => {
                        let (x, z) = (r.next_f32() * 40.0 - 20.0, r.next_f32() * 40.0 - 20.0);
                        let side = if r.below(2) == 0 { 0.05 } else { -0.05 };
                        Vec3::new(x, height(x, z) - 3.0 + side, z)
                    }
                };
                let l = at - p;
                for axis in 0..3 {
                    (from[axis][lane], dirs[axis][lane]) = (p[axis], (l / l.length())[axis]);
                }
                t_max[lane] = l.length();
            }
            let live = r.below(256);
            let rays = ShadowLanes { from: &from, dirs: &dirs, t_max, live, leaving: [NONE; 8] };
            let mut eight_last = last;
            let eight = bvh.transmittance_towards_lanes(k, &rays, &mut eight_last);
            for lane in 0..8 {
                let origin = Vec3::new(from[0][lane], from[1][lane], from[2][lane]);
                let ray = Ray { origin, dir: Vec3::new(dirs[0][lane], dirs[1][lane], dirs[2][lane]) };
                let want = brute.transmittance(&ray, t_max[lane]);
                assert_eq!(bvh.transmittance_towards(k, &ray, t_max[lane], &mut last), want, "group {group}");
                if live >> lane & 1 != 0 {
                    assert_eq!(eight[lane], want, "width {width}, group {group}, lane {lane}");
                }
                blocked += (want == 0.0) as u32;
                through += (want > 0.0 && want < 1.0) as u32;
                piece_blocked += (want == 0.0 && matches!(bvh.leaves[last.0 as usize], LeafItem::Piece(..))) as u32;
            }
            if group % 5 == 0 {
                last = LastBlocker::at(r.below(entries));
            }
        }
        assert!(blocked > 8000 && through > 2000, "width {width}: {blocked} blocked, {through} through glass");
        assert!(piece_blocked > 3000, "width {width}: {piece_blocked} blocked by a piece");
    }
}

/// A light buffer takes at most three pieces per entry of the tree: a mesh much finer
/// than the rest of the scene is listed whole, a coarser one by its leaves.
#[test]
fn a_mesh_much_finer_than_the_rest_is_listed_whole() {
    for (n, pieces) in [(120u32, false), (20, true)] {
        let mut scene = random_scene(41, 200);
        let pos = (0..=n)
            .flat_map(|i| {
                (0..=n)
                    .map(move |j| Vec3::new(i as f32 * 40.0 / n as f32 - 20.0, 0.0, j as f32 * 40.0 / n as f32 - 20.0))
            })
            .collect();
        let quads = (0..n).flat_map(|i| (0..n).map(move |j| i * (n + 1) + j));
        let tris = quads.flat_map(|a| [[a, a + 1, a + n + 1], [a + 1, a + n + 2, a + n + 1]]).collect();
        scene.add(Mesh::new(pos, vec![], vec![], tris, false).expect("a mesh"), crate::scene::MaterialId(0));
        scene.add_light(crate::light::PointLight::new(Vec3::new(1.0, 30.0, 2.0), Color::ONE));
        let world = World::new(&scene, AccelKind::Bvh);
        assert!(world.light_buffers[0].is_some(), "{n}: a buffer");
        let sheet = scene.objects.len() as u32 - 1;
        let of_sheet = world.leaves.iter().filter(|l| matches!(l, LeafItem::Piece(i, ..) if *i == sheet)).count();
        let all = world.leaves.iter().filter(|l| matches!(l, LeafItem::Piece(..))).count();
        assert_eq!(of_sheet > 0, pieces, "{n}: {of_sheet} pieces of the sheet");
        assert!(all <= 3 * (world.leaves.len() - all), "{all} pieces for {} entries", world.leaves.len() - all);
    }
}
