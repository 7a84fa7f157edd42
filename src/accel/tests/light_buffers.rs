//! Light buffers against testing every object: lists, crowded cells, lanes, meshes listed
//! by their leaves.

use super::*;

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
        let (mut listed, mut crowded, mut seen) = (0, 0, (0, 0));
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
            match buffers[k].cell_of(from) {
                Some(list) if !list.is_empty() => listed += 1,
                Some(_) => {}
                None => crowded += 1,
            }
            agrees(&bvh, &brute, (k, at), from, &mut last, &mut seen, &format!("seed {seed}, ray {i}"));
            if i % 7 == 0 {
                last = LastBlocker::at(r.below(entries));
            }
        }
        assert!(listed > 20_000 && crowded > 250, "seed {seed}: {listed} listed, {crowded} crowded");
        assert!(seen.0 > 5000 && seen.1 > 1000, "seed {seed}: {seen:?} blocked and through glass");
    }
}

/// A shadow ray from `from` to light `k` at `at`, through its buffer, gets the answer of
/// testing every object; counted in `seen` as blocked or as through glass.
fn agrees(
    bvh: &World,
    brute: &World,
    (k, at): (usize, Vec3),
    from: Vec3,
    last: &mut LastBlocker,
    seen: &mut (u32, u32),
    what: &str,
) {
    let ray = Ray::new(from, at - from);
    let t_max = (at - from).length();
    let want = brute.transmittance(&ray, t_max);
    assert_eq!(bvh.transmittance_towards(k, &ray, t_max, last), want, "{what}");
    seen.0 += (want == 0.0) as u32;
    seen.1 += (want > 0.0 && want < 1.0) as u32;
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
/// A cluster of small spheres far from the lights, each in a cell or two of a light's
/// buffer (as a sphereflake's): the cells regroup them into packs of their own, and
/// shadow rays through those get the answers of testing every object, opaque and
/// glass, from 4- and 8-wide trees, with the last blocker carried or picked at random.
#[test]
fn spheres_regrouped_by_cell_get_the_answers_of_testing_everything() {
    for (seed, width) in [(11u64, 4), (12, 8)] {
        let mut scene = random_scene(seed, 40);
        let mut r = Rng::new(900 + seed);
        let (opaque, glass) = (crate::scene::MaterialId(0), crate::scene::MaterialId(1));
        for i in 0..3000 {
            let s = Sphere::new(Vec3::new(0.0, 2.0, 0.0) + v(&mut r, 2.0), 0.01 + 0.05 * r.next_f32());
            scene.add(s, if i % 5 == 0 { glass } else { opaque });
        }
        let lights = [Vec3::new(20.0, 25.0, 10.0), Vec3::new(-30.0, 5.0, 2.0), Vec3::new(3.0, -20.0, -25.0)];
        for &at in &lights {
            scene.add_light(crate::light::PointLight::new(at, Color::ONE));
        }
        let (bvh, brute) =
            (World::with_width(&scene, AccelKind::Bvh, Some(width)), World::new(&scene, AccelKind::None));
        for (k, buffer) in bvh.light_buffers.iter().enumerate() {
            let made = buffer.as_ref().map_or(0, |b| b.made());
            assert!(made > 20, "seed {seed}: light {k}'s cells made {made} packs");
        }
        let entries = bvh.leaves.len() as u32;
        let (mut last, mut seen) = (LastBlocker::default(), (0, 0));
        for i in 0..30_000u32 {
            let k = (i / 64) as usize % lights.len();
            if i % 64 == 0 {
                last = LastBlocker::default();
            }
            // Behind the cluster as a light sees it, inside it, and anywhere.
            let from = match i % 4 {
                0 | 1 => {
                    Vec3::new(0.0, 2.0, 0.0) - (lights[k] - Vec3::new(0.0, 2.0, 0.0)) * 0.3 * r.next_f32()
                        + v(&mut r, 2.5)
                }
                2 => Vec3::new(0.0, 2.0, 0.0) + v(&mut r, 2.0),
                _ => v(&mut r, 30.0),
            };
            agrees(&bvh, &brute, (k, lights[k]), from, &mut last, &mut seen, &format!("seed {seed}, ray {i}"));
            if i % 7 == 0 {
                last = LastBlocker::at(r.below(entries));
            }
        }
        assert!(seen.0 > 3000 && seen.1 > 300, "seed {seed}: {seen:?} blocked and through glass");
    }
}

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
