//! Procedural geometry for tests and benchmarks, so no large files need committing.

use crate::geometry::Mesh;
use crate::math::Vec3;

/// Radius of the displaced sphere at unit direction (x, y, z): a few octaves of products
/// of sines. The same formula as `../shared/tools/embree-bench` (`--gen-cubesphere`), so
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

#[cfg(test)]
mod tests {
    use super::*;

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
