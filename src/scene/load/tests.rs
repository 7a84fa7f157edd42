//! The TOML reader's own tests (the scene-level ones are in `tests/`).

use super::*;

const CAMERA: &str = "[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, -1]\nfov = 40\n";

fn load(body: &str) -> R<Scene> {
    load_str(&format!("{CAMERA}{body}"), "t.toml", Path::new("."))
}

#[test]
fn inline_meshes_load_with_their_normals() {
    let s = load(
        "[[mesh]]\npositions = [[0, 0, -5], [1, 0, -5], [0, 1, -5], [1, 1, -5]]\n\
         normals = [[0, 0, 1], [0, 0, 1], [0.6, 0, 0.8], [0, 0, 1]]\ntriangles = [[0, 1, 2], [1, 3, 2]]\n\
         material = { color = [1, 1, 1] }\n",
    )
    .unwrap();
    let Shape::Mesh(m) = &s.objects[0].shape else { panic!("not a mesh") };
    assert_eq!(m.triangles(), &[[0, 1, 2], [1, 3, 2]]);
    assert_eq!(m.normals()[2], Vec3::new(0.6, 0.0, 0.8));
    // smooth = false drops the normals.
    let s = load(
        "[[mesh]]\npositions = [[0, 0, -5], [1, 0, -5], [0, 1, -5]]\nnormals = [[0, 0, 1], [0, 0, 1], [0, 0, 1]]\n\
         triangles = [[0, 1, 2]]\nsmooth = false\nmaterial = { color = [1, 1, 1] }\n",
    )
    .unwrap();
    let Shape::Mesh(m) = &s.objects[0].shape else { panic!("not a mesh") };
    assert!(!m.is_smooth());
}

#[test]
fn bad_inline_meshes_are_located() {
    let field = |body: &str| match load(body).unwrap_err() {
        SceneError::At { line, field, .. } => (line, field),
        e => panic!("{e}"),
    };
    let m = "material = { color = [1, 1, 1] }\n";
    assert_eq!(field(&format!("[[mesh]]\n{m}")), (5, "file".into()));
    assert_eq!(field(&format!("[[mesh]]\npositions = [[0, 0, 0]]\n{m}")), (6, "triangles".into()));
    assert_eq!(field(&format!("[[mesh]]\ntriangles = [[0, 1, 2]]\n{m}")), (6, "triangles".into()));
    assert_eq!(
        field(&format!("[[mesh]]\npositions = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]\ntriangles = [[]]\n{m}")),
        (7, "triangles".into())
    );
    assert_eq!(
        field(&format!("[[mesh]]\npositions = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]\ntriangles = []\n{m}")),
        (7, "triangles".into())
    );
}

#[test]
fn glass_fields_load_and_bad_ones_are_located() {
    let s = load("[material.g]\ntransparency = 0.9\nfresnel = true\nabsorption = [0.5, 0, 2]\n").unwrap();
    assert!(s.materials[0].fresnel);
    assert_eq!(s.materials[0].absorption, Color::new(0.5, 0.0, 2.0));
    let s = load("[material.g]\ntransparency = 0.9\n").unwrap();
    assert!(!s.materials[0].fresnel && s.materials[0].absorption == Color::ZERO);
    let field = |body: &str| match load(body).unwrap_err() {
        SceneError::At { line, field, .. } => (line, field),
        e => panic!("{e}"),
    };
    assert_eq!(field("[material.g]\nabsorption = [1, 0, 0]\n"), (6, "absorption".into()));
    assert_eq!(field("[material.g]\ntransparency = 0.5\nabsorption = [1, -1, 0]\n"), (7, "absorption".into()));
    assert_eq!(field("[material.g]\ntransparency = 0.5\nabsorption = [1, inf, 0]\n"), (7, "absorption".into()));
    assert_eq!(field("[material.g]\nfresnel = 1\n"), (6, "fresnel".into()));
    // No absorption is fine without transparency.
    assert!(load("[material.g]\nabsorption = [0, 0, 0]\n").is_ok());
}

#[test]
fn colour_settings_and_texture_colour_spaces_are_read_and_checked() {
    let s = load("[settings]\ncolor = \"srgb\"\n").unwrap();
    assert_eq!(s.settings.color, ColorEncoding::Srgb);
    assert_eq!(load("").unwrap().settings.color, ColorEncoding::Linear);
    let e = load("[settings]\ncolor = \"gamma\"\n").unwrap_err();
    assert!(matches!(&e, SceneError::At { line: 6, field, .. } if field == "color"), "{e}");

    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("grey.png");
    ImageMap::from_fn(1, 1, |_, _| Color::splat(188.0 / 255.0)).save_png(&png).unwrap();
    let texel = |space: &str| {
        let src = format!(
            "{CAMERA}[[sphere]]\ncenter = [0, 0, -5]\nradius = 1\n\
             material = {{ texture = {{ kind = \"image\", path = \"grey.png\"{space} }} }}\n"
        );
        let s = load_str(&src, "t.toml", dir.path()).unwrap();
        match &s.materials[0].texture {
            Texture::Image { map, .. } => map.texel(0, 0).x,
            _ => panic!("not an image"),
        }
    };
    assert!((texel("") - 188.0 / 255.0).abs() < 1e-6, "linear: as stored");
    assert!((texel(", color_space = \"srgb\"") - 0.5028).abs() < 1e-3, "sRGB 188 decodes to 0.5028");
    let src = format!(
        "{CAMERA}[[sphere]]\ncenter = [0, 0, -5]\nradius = 1\n\
         material = {{ texture = {{ kind = \"image\", path = \"grey.png\", color_space = \"rgb\" }} }}\n"
    );
    let e = load_str(&src, "t.toml", dir.path()).unwrap_err();
    assert!(matches!(&e, SceneError::At { field, .. } if field == "color_space"), "{e}");
}

#[test]
fn truncated_cones_load_closed_by_default() {
    let s = load("[[cone]]\nbase = [0, 0, -5]\naxis = [0, 1, 0]\nradius = 1\ntop_radius = 0.5\nheight = 2\nmaterial = { color = [1, 1, 1] }\n").unwrap();
    let Shape::Cone(c) = &s.objects[0].shape else { panic!("not a cone") };
    assert_eq!((c.top_radius, c.cap, c.top_cap), (0.5, true, true));
    let s = load(
        "[[cone]]\nbase = [0, 0, -5]\naxis = [0, 1, 0]\nradius = 1\nheight = 2\nmaterial = { color = [1, 1, 1] }\n",
    )
    .unwrap();
    let Shape::Cone(c) = &s.objects[0].shape else { panic!("not a cone") };
    assert_eq!((c.top_radius, c.top_cap), (0.0, false));
}
