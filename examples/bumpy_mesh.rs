//! Writes a procedurally generated bumpy sphere as OBJ and renders a scene that loads
//! it, smooth-shaded, above a mirror floor.
//!
//!     cargo run --release --example bumpy_mesh -- out.png

use whitted::prelude::*;
use whitted::scene::{self, generate, obj};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args().nth(1).unwrap_or_else(|| "bumpy_mesh.png".into());
    let dir = std::env::temp_dir().join("whitted-bumpy-mesh");
    std::fs::create_dir_all(&dir)?;
    obj::write_obj(
        &generate::cube_sphere(64),
        &mut std::io::BufWriter::new(std::fs::File::create(dir.join("bumpy.obj"))?),
    )?;
    std::fs::write(
        dir.join("bumpy.toml"),
        r#"
[camera]
position = [0, 0.8, 3.4]
look_at = [0, -0.1, 0]
fov = 40
width = 640
height = 480

[settings]
samples = 4

[[light]]
position = [4, 5, 6]

[[light]]
position = [-5, 3, 2]
color = [0.3, 0.35, 0.5]

[[mesh]]
file = "bumpy.obj"
material = { color = [0.9, 0.55, 0.25], shininess = 40 }
transform = { rotate = [0, 30, 0] }

[[quad]]
corner = [-6, -1.2, 6]
edge_u = [12, 0, 0]
edge_v = [0, 0, -12]
material = { texture = { kind = "checker", size = 0.5, offset = [0, 0.25, 0], colors = [[0.2, 0.2, 0.25], [0.8, 0.8, 0.8]] }, reflectivity = 0.3, specular = 0 }
"#,
    )?;
    let scene = scene::load_file(&dir.join("bumpy.toml"))?;
    let image = Renderer::new(&scene)?.render();
    write_png(&image, std::path::Path::new(&out))?;
    println!("wrote {out}");
    Ok(())
}
