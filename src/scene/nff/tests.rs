use super::lexer::{CHUNK, fast_f32};
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
    assert_eq!(s.settings.background, Color::new(0.1, 0.2, 0.3));
    assert_eq!((s.camera.width, s.camera.height, s.camera.fov), (32, 24, 40.0));
    assert_eq!(s.camera.position, Vec3::new(0.0, 0.0, 5.0));
    let share = 2f32.sqrt() / 4.0;
    assert_eq!(s.lights[0].color(), Color::splat(share));
    assert_eq!(s.lights[1].color(), Color::splat(0.5));
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
        "{VIEW}l 0 0 9\nf 1 1 1 1 0 0 0 0\np 4\n0 0 0 2 0 0 1 1 0 0 1 0\np 3 0 0 0 1 1 1 2 2 2\n\
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
fn a_materials_few_flat_parallelograms_are_read_as_quads_and_other_polygons_as_triangles() {
    let square = |x: f32| format!("p 4 {x} 0 0 {} 0 0 {} 1 0 {x} 1 0\n", x + 1.0, x + 1.0);
    let text = format!(
        // A parallelogram alone in its material (the SPD floors); a square given as a
        // pp patch; a kite; a parallelogram sharing its material with a kite; five
        // squares of one material.
        "{VIEW}f 1 1 1 1 0 0 0 0\np 4 1 0 0 3 0 0 4 2 0 2 2 0\n\
         pp 4 0 0 0 0 0 1 1 0 0 0 0 1 1 1 0 0 0 1 0 1 0 0 0 1\n\
         f 1 0 1 1 0 0 0 0\np 4 0 0 0 1 -1 0 2 0 0 1 3 0\n\
         f 1 1 0 1 0 0 0 0\n{}p 4 0 0 0 1 -1 0 2 0 0 1 3 0\n\
         f 0 1 1 1 0 0 0 0\n{}",
        square(0.0),
        (0..5).map(|k| square(k as f32)).collect::<String>()
    );
    let nff = read(&text).unwrap();
    let shapes: Vec<&Shape> = nff.scene.objects.iter().map(|o| &o.shape).collect();
    assert_eq!(shapes.len(), 5, "{shapes:?}");
    let Shape::Quad(q) = shapes[0] else { panic!("{:?}", shapes[0]) };
    assert_eq!(
        (q.corner, q.edge_u, q.edge_v),
        (Vec3::new(1.0, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0), Vec3::new(1.0, 2.0, 0.0))
    );
    assert_eq!(q.normal(), Vec3::Z);
    let triangles = |s: &Shape| match s {
        Shape::Mesh(m) => (m.is_smooth(), m.triangle_count()),
        other => panic!("{other:?}"),
    };
    // Meshes in the order of their materials: the patch, the kite, square and kite,
    // the five squares.
    assert_eq!(
        shapes[1..].iter().map(|s| triangles(s)).collect::<Vec<_>>(),
        [(true, 2), (false, 2), (false, 4), (false, 10)]
    );
    assert_eq!((nff.counts.polygons, nff.counts.quads, nff.counts.triangles), (9, 1, 18));
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
        ("s 0 0 1.5x 1\n", v + 1, 7, "s", "\"1.5x\" is not a number"),
        ("s 0 0 2e1.5 1\n", v + 1, 7, "s", "\"2e1.5\" is not a number"),
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
    for t in ["", "-", "+", ".", "e5", "1e", "1e+", "--1", "1.2.3", "0x10", "1,5", "inf", "nan", "16777217", "1e11"] {
        assert_eq!(fast_f32(t.as_bytes()), None, "{t}");
    }
    for (t, x) in [("-0", -0.0f32), ("+.5", 0.5), ("5.", 5.0), ("1e-05", 1e-5), ("-2.5E+3", -2500.0), ("0.000000", 0.0)]
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

/// `text` in a file of its own, read in `chunks` chunks where that path answers.
fn read_in_chunks(text: &str, chunks: usize) -> Option<Result<Nff, SceneError>> {
    static FILES: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let k = FILES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let path = std::env::temp_dir().join(format!("whitted-chunks-{}-{k}.nff", std::process::id()));
    std::fs::write(&path, text).unwrap();
    let got = super::chunks::read_chunked(&path, "t.nff", text.len() as u64, chunks);
    std::fs::remove_file(&path).unwrap();
    got
}

/// Entities of every kind, materials met again in later chunks, objects whose material
/// comes from a chunk before, a material's few parallelograms cut apart, warnings past
/// the first chunk: read in 2 to 12 chunks, the same scene, counts and warnings as in
/// one pass, to the bit.
#[test]
fn a_file_read_in_chunks_is_what_one_pass_reads() {
    let square = |x: f32| format!("p 4 {x} 0 0 {} 0 0 {} 1 0 {x} 1 0\n", x + 1.0, x + 1.0);
    let mut text = format!("# chunks\n{VIEW}l 1 2 3\nf 1 0 0 0.5 0.5 3.0827 0 1\n");
    for k in 0..40 {
        let x = k as f32 * 0.37;
        text += &format!("s {x} 0 0 0.25\nc {x} 1 0 0.2 {x} 2 0 0.1\nc {x} 0 1 0.3\n {x} 0 2 0.3\n");
        text += &format!("pp 3\n{x} 0 1 0 0 1\n{} 0 1 0 0 1\n{x} 1 1 0.6 0 0.8\n", x + 1.0);
        match k % 8 {
            0 => text += "f 1 1 1 0 0.1 100000 0.9 1.5\n",
            1 => text += &square(x),
            // A material changed to fit (Ks + T > 1), first met past the middle.
            2 if k > 20 => text += &format!("f 0.2 0.4 0.6 0.5 0.7 20 0.6 1.3\ns {x} 5 0 0\nl {x} 9 9 0.5 0.5 0.5\n"),
            3 => text += &format!("f 1 0 0 0.5 0.5 3.0827 0 1\nb 0.1 0.2 {}\n", k as f32 / 100.0),
            4 => text += &format!("p 3 {x} 0 0 {x} 0 0 {x} 0 0\nf 0 1 0 1 0 0 0 0\n{}", square(x)),
            5 => text += &format!("p 5 0 0 {x} 2 0 {x} 1 1 {x} 2 2 {x} 0 2 {x}\n"),
            _ => {}
        }
    }
    let one = read(&text).unwrap();
    assert!(one.warnings.len() >= 3, "{:?}", one.warnings);
    let mut joined = 0;
    for chunks in 2..=12 {
        if let Some(got) = read_in_chunks(&text, chunks) {
            assert_eq!(format!("{:?}", got.unwrap()), format!("{one:?}"), "{chunks} chunks");
            joined += 1;
        }
    }
    assert!(joined >= 10, "read in chunks {joined} times of 11");
}

/// Where joining chunks could not give what one pass gives, the chunked path gives no
/// answer, and the caller reads the file in one pass.
#[test]
fn chunks_give_way_to_one_pass_where_they_would_differ() {
    let filler = "s 0 0 0 1\n".repeat(400);
    // An error in a later chunk (its message names a line only one pass counts).
    let text = format!("{VIEW}f 1 1 1 1 0 0 0 0\n{filler}s 1 2 3\n{filler}");
    assert!(read_in_chunks(&text, 2).is_none());
    assert!(read(&text).is_err());
    // A second view, and a later chunk's objects with no `f` and no object before them
    // (the white material is made for the first object of the file).
    let comments = "# nothing\n".repeat(800);
    for text in [format!("{VIEW}f 1 1 1 1 0 0 0 0\n{filler}{VIEW}{filler}"), format!("{VIEW}{comments}{filler}")] {
        assert!(read_in_chunks(&text, 2).is_none());
    }
    // Objects before any `f` in the first chunk, whose white material the next chunk's
    // objects keep until an `f`: joined.
    for text in [format!("{VIEW}{filler}{filler}"), format!("{VIEW}s 0 0 0 1\n{filler}f 1 1 1 1 0 0 0 0\n{filler}")] {
        let got = read_in_chunks(&text, 2).expect("joined").unwrap();
        assert_eq!(format!("{got:?}"), format!("{:?}", read(&text).unwrap()));
    }
}
