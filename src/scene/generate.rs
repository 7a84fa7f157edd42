//! Procedural geometry for tests and benchmarks, so no large files need committing.

use crate::geometry::Mesh;
use crate::math::Vec3;

/// Radius of the displaced sphere at unit direction (x, y, z): a few octaves of products
/// of sines. The same formula as the Embree comparison harness (`$WHITTED_TOOLS/embree-bench`, docs/performance.md) (`--gen-cubesphere`), so
/// both tracers see the same mesh.
fn displacement(x: f64, y: f64, z: f64) -> f64 {
    let (mut r, mut amp, mut f) = (1.0, 0.08, 3.0);
    for k in 0..5 {
        let k = k as f64;
        r += amp * (f * x + 1.7 * k).sin() * (f * y + 0.9 * k).sin() * (f * z + 2.3 * k).sin();
        amp *= 0.45;
        f *= 2.3;
    }
    r
}

/// A bumpy sphere made from a cube whose six faces are each split into n × n quads:
/// 12·n² triangles (n = 289 gives 1,002,252; n = 913 about 10 million). Vertex and
/// triangle order match the Embree benchmark's generator.
pub fn cube_sphere(n: u32) -> Mesh {
    const FACES: [[f64; 9]; 6] = [
        [1.0, -1.0, -1.0, 0.0, 2.0, 0.0, 0.0, 0.0, 2.0],
        [-1.0, -1.0, -1.0, 0.0, 0.0, 2.0, 0.0, 2.0, 0.0],
        [-1.0, 1.0, -1.0, 0.0, 0.0, 2.0, 2.0, 0.0, 0.0],
        [-1.0, -1.0, -1.0, 2.0, 0.0, 0.0, 0.0, 0.0, 2.0],
        [-1.0, -1.0, 1.0, 2.0, 0.0, 0.0, 0.0, 2.0, 0.0],
        [-1.0, -1.0, -1.0, 0.0, 2.0, 0.0, 2.0, 0.0, 0.0],
    ];
    use rayon::prelude::*;
    let n = n.max(1);
    let per = ((n + 1) * (n + 1)) as usize;
    let positions: Vec<Vec3> = (0..6 * per)
        .into_par_iter()
        .map(|v| {
            let o = &FACES[v / per];
            let (j, i) = ((v % per) / (n as usize + 1), (v % per) % (n as usize + 1));
            let (a, b) = (i as f64 / n as f64, j as f64 / n as f64);
            let (x, y, z) = (o[0] + a * o[3] + b * o[6], o[1] + a * o[4] + b * o[7], o[2] + a * o[5] + b * o[8]);
            let l = (x * x + y * y + z * z).sqrt();
            let (x, y, z) = (x / l, y / l, z / l);
            let r = displacement(x, y, z);
            Vec3::new((x * r) as f32, (y * r) as f32, (z * r) as f32)
        })
        .collect();
    let mut triangles = Vec::with_capacity(12 * (n * n) as usize);
    for f in 0..6u32 {
        for j in 0..n {
            for i in 0..n {
                let a = f * per as u32 + j * (n + 1) + i;
                let (b, c) = (a + 1, a + n + 1);
                let d = c + 1;
                triangles.push([a, b, d]);
                triangles.push([a, d, c]);
            }
        }
    }
    Mesh::new(positions, vec![], vec![], triangles, false).expect("generated mesh is valid")
}

/// C's `printf("%g")`: six significant digits, trailing zeros dropped, exponent form
/// below 1e-4 and from 1e6. The SPD generators write their numbers this way, so files
/// made here have the same size and precision as theirs.
pub fn fmt_g(x: f64) -> String {
    if x == 0.0 {
        return if x.is_sign_negative() { "-0".into() } else { "0".into() };
    }
    if !x.is_finite() {
        return format!("{x}");
    }
    let strip = |s: String| -> String {
        if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_owned() } else { s }
    };
    let sci = format!("{x:.5e}");
    let (mantissa, exp) = sci.split_once('e').expect("{:e} always has an exponent");
    let exp: i32 = exp.parse().expect("{:e} exponents are integers");
    if (-4..6).contains(&exp) {
        strip(format!("{:.*}", (5 - exp) as usize, x))
    } else {
        format!("{}e{}{:02}", strip(mantissa.to_owned()), if exp < 0 { '-' } else { '+' }, exp.abs())
    }
}

/// Spheres in a sphereflake of recursion `level`: 1 + 9 + ... + 9^level.
pub fn sphereflake_spheres(level: u32) -> u64 {
    (9u64.pow(level + 1) - 1) / 8
}

/// Rotation of `v` by `angle` radians about the unit `axis`, right-handed (Rodrigues).
fn rotate(v: [f64; 3], axis: [f64; 3], angle: f64) -> [f64; 3] {
    let (s, c) = angle.sin_cos();
    let dot = axis[0] * v[0] + axis[1] * v[1] + axis[2] * v[2];
    let cross = [axis[1] * v[2] - axis[2] * v[1], axis[2] * v[0] - axis[0] * v[2], axis[0] * v[1] - axis[1] * v[0]];
    std::array::from_fn(|k| v[k] * c + cross[k] * s + axis[k] * dot * (1.0 - c))
}

/// Writes Eric Haines' sphereflake (the SPD's "balls") at recursion `level` as NFF: a
/// sphere of radius 0.5 at the origin, and on every sphere nine touching children of a
/// third of its radius (six around, three on top, turned away from the parent), down to
/// `level` generations; 7,381 spheres at level 4 (the SPD default), 597,871 at 6. Also
/// the SPD scene around it: sky-blue background, the view from (2.1, 1.3, 1.7), three
/// lights and a beige floor square, with the SPD's materials, in the order and `%g`
/// number format the SPD generator writes them.
pub fn sphereflake(level: u32, out: &mut impl std::io::Write) -> std::io::Result<()> {
    writeln!(out, "b 0.078 0.361 0.753")?;
    writeln!(out, "v\nfrom 2.1 1.3 1.7\nat 0 0 0\nup 0 0 1\nangle 45\nhither 0.01\nresolution 512 512")?;
    writeln!(out, "l 4 3 2\nl 1 -4 4\nl -3 1 5")?;
    // Floor: Kd 0.8, no reflection, no highlight; spheres: Kd 0.5, half mirror, a
    // highlight of half-angle 37° (exponent ln 0.5 / ln cos 37°).
    writeln!(out, "f 1 0.75 0.33 0.8 0 100000 0 1")?;
    writeln!(out, "p 4\n12 12 -0.5\n-12 12 -0.5\n-12 -12 -0.5\n12 -12 -0.5")?;
    let shine = 0.5f64.ln() / 37f64.to_radians().cos().ln();
    writeln!(out, "f 1 0.9 0.7 0.5 0.5 {} 0 1", fmt_g(shine))?;

    // The nine child directions around +z: three tilted out of the xy plane, then
    // copies turned by 120° and 240° about z.
    let d = 0.5f64.sqrt();
    let tilt_axis = [d, -d, 0.0];
    let tilt = (2.0 / 6f64.sqrt()).asin();
    let trio = [[d, d, 0.0], [d, 0.0, -d], [0.0, d, -d]].map(|v| rotate(v, tilt_axis, tilt));
    let dirs: Vec<[f64; 3]> =
        (0..3).flat_map(|k| trio.map(|v| rotate(v, [0.0, 0.0, 1.0], k as f64 * std::f64::consts::TAU / 3.0))).collect();

    fn flake(
        out: &mut impl std::io::Write,
        dirs: &[[f64; 3]],
        depth: u32,
        center: [f64; 3],
        radius: f64,
        dir: [f64; 3],
    ) -> std::io::Result<()> {
        let [x, y, z] = center.map(fmt_g);
        writeln!(out, "s {x} {y} {z} {}", fmt_g(radius))?;
        if depth == 0 {
            return Ok(());
        }
        // The rotation taking +z to the direction away from the parent.
        let turn = |v: [f64; 3]| -> [f64; 3] {
            if dir[2] >= 0.9999 {
                v
            } else if dir[2] <= -0.9999 {
                [-v[0], v[1], -v[2]]
            } else {
                let (ax, ay) = (-dir[1], dir[0]);
                let len = ax.hypot(ay);
                rotate(v, [ax / len, ay / len, 0.0], dir[2].clamp(-1.0, 1.0).acos())
            }
        };
        let scale = radius * (1.0 + 1.0 / 3.0);
        for &v in dirs {
            let t = turn(v);
            let child = std::array::from_fn(|k| t[k] * scale + center[k]);
            let child_dir = std::array::from_fn(|k| (child[k] - center[k]) / scale);
            flake(out, dirs, depth - 1, child, radius / 3.0, child_dir)?;
        }
        Ok(())
    }
    flake(out, &dirs, level, [0.0; 3], 0.5, [0.0, 0.0, 1.0])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fmt_g_matches_c() {
        for (x, s) in [
            (0.0, "0"),
            (1.0, "1"),
            (-0.5, "-0.5"),
            (3.08270, "3.0827"),
            (100000.0, "100000"),
            (1e6, "1e+06"),
            (1234567.0, "1.23457e+06"),
            (1e-5, "1e-05"),
            (-2.55836e-17, "-2.55836e-17"),
            (0.0001234, "0.0001234"),
            (0.333333333, "0.333333"),
            (999999.5, "1e+06"),
            (0.078, "0.078"),
        ] {
            assert_eq!(fmt_g(x), s, "{x}");
        }
    }

    #[test]
    fn sphereflake_has_the_spd_counts_and_touching_children() {
        assert_eq!(sphereflake_spheres(4), 7381);
        assert_eq!(sphereflake_spheres(6), 597_871);
        let mut text = Vec::new();
        sphereflake(2, &mut text).unwrap();
        let text = String::from_utf8(text).unwrap();
        let spheres: Vec<[f64; 4]> = text
            .lines()
            .filter_map(|l| l.strip_prefix("s "))
            .map(|l| {
                let v: Vec<f64> = l.split(' ').map(|w| w.parse().unwrap()).collect();
                [v[0], v[1], v[2], v[3]]
            })
            .collect();
        assert_eq!(spheres.len() as u64, sphereflake_spheres(2));
        assert_eq!(spheres[0], [0.0, 0.0, 0.0, 0.5]);
        // Children (six digits, as %g writes them) touch the root, around its equator
        // or on top, never underneath where the parent would be.
        let near = |a: f64, b: f64| (a - b).abs() < 1e-6;
        for c in &spheres[1..] {
            assert!(near(c[3], 0.5 / 3.0) || near(c[3], 0.5 / 9.0), "{c:?}");
        }
        let children: Vec<&[f64; 4]> = spheres.iter().filter(|c| near(c[3], 0.5 / 3.0)).collect();
        assert_eq!(children.len(), 9);
        for c in children {
            let d = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
            assert!((d - (0.5 + 0.5 / 3.0)).abs() < 1e-5, "{c:?}");
            assert!(c[2] > -0.5 / 3.0, "{c:?}");
        }
    }

    #[test]
    fn cube_sphere_has_twelve_n_squared_triangles_around_the_unit_sphere() {
        let m = cube_sphere(10);
        assert_eq!(m.triangle_count(), 1200);
        assert_eq!(m.positions().len(), 6 * 11 * 11);
        for p in m.positions() {
            let r = p.length();
            assert!((0.8..1.2).contains(&r), "{r}");
        }
    }

    #[test]
    fn cube_sphere_faces_point_outwards() {
        let m = cube_sphere(6);
        let outward = (0..m.triangle_count())
            .filter(|&i| {
                let [a, b, c] = m.corners(i);
                (b - a).cross(c - a).dot(a + b + c) > 0.0
            })
            .count();
        // The generator's winding is the benchmark's; record which way it goes.
        assert!(outward == 0 || outward == m.triangle_count(), "mixed winding: {outward}");
    }
}
