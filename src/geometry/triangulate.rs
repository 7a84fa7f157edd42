//! Splitting planar polygons into triangles, for formats (NFF) whose polygons may be
//! concave: gears has 144-vertex faces. Convex polygons are fanned from their first
//! vertex; concave ones are ear-clipped in the plane they lie in. Both keep the
//! polygon's winding, so the triangles face the way the polygon did.

use crate::math::Vec3;

/// How a polygon was split.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Split {
    /// Convex: a fan from the first vertex.
    Fan,
    /// Concave: ear clipping.
    Ears,
    /// No ear could be found (the outline crosses itself) or the polygon was too large
    /// to clip ([`MAX_EAR_CLIPPING`] vertices): the rest was fanned, which may cover
    /// area outside the outline.
    FanFallback,
}

/// Concave polygons with more vertices than this are fanned: ear clipping as done here
/// costs O(n²) to O(n³).
pub const MAX_EAR_CLIPPING: usize = 4096;

/// Appends to `out` triangles (indices into `points`, offset by `base`) covering the
/// simple planar polygon `points`. Returns `None`, appending nothing, when the polygon
/// has no area (fewer than 3 vertices, all on a line or a point, or not finite).
/// Triangles of zero area (from collinear runs of vertices) are left out.
pub fn triangulate(points: &[Vec3], base: u32, out: &mut Vec<[u32; 3]>) -> Option<Split> {
    let n = points.len();
    if n < 3 || !points.iter().all(|p| p.is_finite()) {
        return None;
    }
    if n == 3 {
        let (a, b, c) = (points[0], points[1], points[2]);
        let extent = (b - a).length_squared().max((c - a).length_squared());
        let area2 = (b - a).cross(c - a).length_squared();
        if area2.is_nan() || area2 <= 1e-14 * extent * extent {
            return None;
        }
        out.push([base, base + 1, base + 2]);
        return Some(Split::Fan);
    }
    // Newell's normal on centred coordinates, in f64: robust to collinear runs and to
    // concave outlines (its length is twice the area).
    let p: Vec<[f64; 3]> = points.iter().map(|v| [v.x as f64, v.y as f64, v.z as f64]).collect();
    let mut centre = [0.0f64; 3];
    for v in &p {
        for k in 0..3 {
            centre[k] += v[k] / n as f64;
        }
    }
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    let mut normal = [0.0f64; 3];
    for i in 0..n {
        let a: [f64; 3] = std::array::from_fn(|k| p[i][k] - centre[k]);
        let b: [f64; 3] = std::array::from_fn(|k| p[(i + 1) % n][k] - centre[k]);
        normal[0] += (a[1] - b[1]) * (a[2] + b[2]);
        normal[1] += (a[2] - b[2]) * (a[0] + b[0]);
        normal[2] += (a[0] - b[0]) * (a[1] + b[1]);
        for k in 0..3 {
            lo[k] = lo[k].min(p[i][k]);
            hi[k] = hi[k].max(p[i][k]);
        }
    }
    let extent2: f64 = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum();
    let length = normal.iter().map(|x| x * x).sum::<f64>().sqrt();
    // Zero up to f32 rounding of the input.
    if length.is_nan() || length <= 1e-7 * extent2 {
        return None;
    }
    // Project along the normal's largest component, mirrored if need be so that the
    // outline runs counter-clockwise in 2D.
    let k = (0..3).max_by(|&a, &b| normal[a].abs().total_cmp(&normal[b].abs())).unwrap_or(2);
    let (u, v) = ((k + 1) % 3, (k + 2) % 3);
    let flip = if normal[k] < 0.0 { -1.0 } else { 1.0 };
    let q: Vec<(f64, f64)> = p.iter().map(|x| (x[u], flip * x[v])).collect();
    // Twice the area below which a corner counts as straight: the input's f32 rounding
    // (relative to the coordinates' magnitude) moves cross products by about this much.
    let magnitude = lo.iter().chain(&hi).fold(0.0f64, |m, x| m.max(x.abs()));
    let eps = 1e-6 * extent2 + 1e-6 * magnitude * extent2.sqrt();
    let cross =
        |a: usize, b: usize, c: usize| (q[b].0 - q[a].0) * (q[c].1 - q[b].1) - (q[b].1 - q[a].1) * (q[c].0 - q[b].0);
    let convex = (0..n).all(|i| cross(i, (i + 1) % n, (i + 2) % n) >= -eps);
    // A triangle is dropped as straight when its area is within rounding of zero for
    // its own edges, not the polygon's size: a polygon of a million vertices is all
    // slivers that are each tiny beside the whole, and must still be covered.
    let len = |a: usize, b: usize| ((q[b].0 - q[a].0).powi(2) + (q[b].1 - q[a].1).powi(2)).sqrt();
    let push = |out: &mut Vec<[u32; 3]>, a: usize, b: usize, c: usize| {
        let (ab, bc) = (len(a, b), len(b, c));
        let tri_eps = 1e-6 * ab * bc + 1e-6 * magnitude * (ab + bc);
        if cross(a, b, c) > tri_eps.min(eps) {
            out.push([base + a as u32, base + b as u32, base + c as u32]);
        }
    };
    if convex || n > MAX_EAR_CLIPPING {
        for i in 1..n - 1 {
            push(out, 0, i, i + 1);
        }
        return Some(if convex { Split::Fan } else { Split::FanFallback });
    }

    // Ear clipping over a circular doubly linked list of the remaining vertices.
    let mut next: Vec<usize> = (0..n).map(|i| (i + 1) % n).collect();
    let mut prev: Vec<usize> = (0..n).map(|i| (i + n - 1) % n).collect();
    let (mut remaining, mut i, mut misses) = (n, 0usize, 0usize);
    let inside = |a: usize, b: usize, c: usize, x: usize| {
        // On the boundary counts as inside, except for a copy of a corner.
        let same = |s: usize| q[s] == q[x];
        if same(a) || same(b) || same(c) {
            return false;
        }
        let side = |s: usize, t: usize| (q[t].0 - q[s].0) * (q[x].1 - q[s].1) - (q[t].1 - q[s].1) * (q[x].0 - q[s].0);
        side(a, b) >= -eps && side(b, c) >= -eps && side(c, a) >= -eps
    };
    while remaining > 3 {
        let (a, c) = (prev[i], next[i]);
        let turn = cross(a, i, c);
        let is_ear = turn.abs() <= eps || {
            turn > 0.0 && {
                let mut j = next[c];
                let mut clear = true;
                while j != a {
                    if inside(a, i, c, j) {
                        clear = false;
                        break;
                    }
                    j = next[j];
                }
                clear
            }
        };
        if is_ear {
            // A straight or doubled-back corner is dropped without a triangle.
            push(out, a, i, c);
            next[a] = c;
            prev[c] = a;
            remaining -= 1;
            i = c;
            misses = 0;
        } else {
            i = c;
            misses += 1;
            if misses > remaining {
                let start = i;
                let mut j = next[start];
                while next[j] != start {
                    push(out, start, j, next[j]);
                    j = next[j];
                }
                return Some(Split::FanFallback);
            }
        }
    }
    push(out, prev[i], i, next[i]);
    Some(Split::Ears)
}

/// The first pair of edges that cross, as `(i, j)` with `i < j`: the edge from vertex
/// `j` to the next crosses the edge from vertex `i` to the next (counted from 0). Ear
/// clipping needs an outline that does not cross itself; readers that can refuse such a
/// polygon (TOML) use this to say where it crosses. O(n²): call it on polygons of at
/// most [`MAX_EAR_CLIPPING`] vertices.
pub fn first_crossing(points: &[Vec3]) -> Option<(usize, usize)> {
    let n = points.len();
    if n < 4 {
        return None;
    }
    let p: Vec<[f64; 3]> = points.iter().map(|v| [v.x as f64, v.y as f64, v.z as f64]).collect();
    let mut normal = [0.0f64; 3];
    for i in 0..n {
        let (a, b) = (p[i], p[(i + 1) % n]);
        normal[0] += (a[1] - b[1]) * (a[2] + b[2]);
        normal[1] += (a[2] - b[2]) * (a[0] + b[0]);
        normal[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    let k = (0..3).max_by(|&a, &b| normal[a].abs().total_cmp(&normal[b].abs())).unwrap_or(2);
    let (u, v) = ((k + 1) % 3, (k + 2) % 3);
    let q: Vec<(f64, f64)> = p.iter().map(|x| (x[u], x[v])).collect();
    let side = |a: (f64, f64), b: (f64, f64), c: (f64, f64)| (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0);
    // Proper crossings only: edges that merely touch at a point are left to the clipper.
    let crosses = |a: (f64, f64), b: (f64, f64), c: (f64, f64), d: (f64, f64)| {
        let (d1, d2) = (side(a, b, c), side(a, b, d));
        let (d3, d4) = (side(c, d, a), side(c, d, b));
        d1 * d2 < 0.0 && d3 * d4 < 0.0
    };
    for j in 2..n {
        for i in 0..j - 1 {
            if i == 0 && j == n - 1 {
                continue; // neighbours through vertex 0
            }
            if crosses(q[i], q[i + 1], q[j], q[(j + 1) % n]) {
                return Some((i, j));
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area(points: &[Vec3], tris: &[[u32; 3]]) -> Vec3 {
        tris.iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| points[i as usize]);
                0.5 * (b - a).cross(c - a)
            })
            .sum()
    }

    fn xy(points: &[(f32, f32)]) -> Vec<Vec3> {
        points.iter().map(|&(x, y)| Vec3::new(x, y, 0.0)).collect()
    }

    #[test]
    fn convex_polygons_are_fanned_keeping_the_winding() {
        let square = xy(&[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]);
        let mut out = Vec::new();
        assert_eq!(triangulate(&square, 10, &mut out), Some(Split::Fan));
        assert_eq!(out, vec![[10, 11, 12], [10, 12, 13]]);
        let local: Vec<[u32; 3]> = out.iter().map(|t| t.map(|i| i - 10)).collect();
        assert_eq!(area(&square, &local), Vec3::Z);
        // Clockwise: the triangles face -z.
        let mut cw = square.clone();
        cw.reverse();
        out.clear();
        triangulate(&cw, 0, &mut out).unwrap();
        assert_eq!(area(&cw, &out), -Vec3::Z);
    }

    #[test]
    fn concave_polygons_are_ear_clipped_inside_the_outline() {
        // An L shape and a comb, in a tilted plane, both windings.
        let l = xy(&[(0.0, 0.0), (2.0, 0.0), (2.0, 1.0), (1.0, 1.0), (1.0, 2.0), (0.0, 2.0)]);
        let mut comb = vec![(0.0, 0.0), (7.0, 0.0), (7.0, 3.0)];
        for k in (0..3).rev() {
            let x = 2.0 * k as f32;
            comb.extend([(x + 2.0, 3.0), (x + 2.0, 1.0), (x + 1.0, 1.0), (x + 1.0, 3.0)]);
        }
        comb.push((0.0, 3.0));
        let comb = xy(&comb);
        let tilt = glam::Quat::from_euler(glam::EulerRot::XYZ, 0.4, -0.7, 0.2);
        for (shape, expected_area) in [(l, 3.0), (comb, 15.0)] {
            for reverse in [false, true] {
                let mut pts: Vec<Vec3> = shape.iter().map(|&p| tilt * p + Vec3::new(5.0, -2.0, 1.0)).collect();
                if reverse {
                    pts.reverse();
                }
                let mut out = Vec::new();
                assert_eq!(triangulate(&pts, 0, &mut out), Some(Split::Ears));
                // n − 2 at most: clipping may line up straight runs, which add nothing.
                assert!(out.len() <= pts.len() - 2 && out.len() >= pts.len() / 2, "{}", out.len());
                let a = area(&pts, &out);
                let sign = if reverse { -1.0 } else { 1.0 };
                assert!((a - sign * expected_area * (tilt * Vec3::Z)).length() < 1e-4, "{a}");
                // Every triangle faces the same way: none folds over outside the outline.
                for t in &out {
                    let [p0, p1, p2] = t.map(|i| pts[i as usize]);
                    assert!((p1 - p0).cross(p2 - p0).dot(sign * (tilt * Vec3::Z)) > 0.0);
                }
            }
        }
    }

    #[test]
    fn a_gear_outline_of_144_vertices_keeps_its_area() {
        // 36 teeth of 4 vertices each, alternating radii 1 and 1.2.
        let pts: Vec<Vec3> = (0..144)
            .map(|i| {
                let a = std::f32::consts::TAU * i as f32 / 144.0;
                let r = if (i / 2) % 2 == 0 { 1.0 } else { 1.2 };
                Vec3::new(r * a.cos(), r * a.sin(), 0.5)
            })
            .collect();
        let mut out = Vec::new();
        assert_eq!(triangulate(&pts, 0, &mut out), Some(Split::Ears));
        let expected: f32 = (0..144)
            .map(|i| {
                let (a, b) = (pts[i], pts[(i + 1) % 144]);
                0.5 * (a.x * b.y - b.x * a.y)
            })
            .sum();
        assert!((area(&pts, &out).z - expected).abs() < 1e-4);
    }

    #[test]
    fn zero_area_polygons_give_nothing() {
        let mut out = Vec::new();
        for pts in [
            xy(&[(0.0, 0.0), (1.0, 0.0)]),
            xy(&[(0.0, 0.0), (1.0, 1.0), (2.0, 2.0)]),
            xy(&[(0.0, 0.0), (1.0, 1.0), (2.0, 2.0), (3.0, 3.0)]),
            xy(&[(1.0, 1.0); 5]),
            vec![Vec3::ZERO, Vec3::X, Vec3::new(f32::NAN, 0.0, 0.0)],
        ] {
            assert_eq!(triangulate(&pts, 0, &mut out), None, "{pts:?}");
        }
        assert!(out.is_empty());
    }

    #[test]
    fn collinear_runs_add_no_slivers() {
        let pts = xy(&[(0.0, 0.0), (1.0, 0.0), (2.0, 0.0), (2.0, 2.0), (1.0, 1.0), (0.0, 2.0)]);
        let mut out = Vec::new();
        triangulate(&pts, 0, &mut out).unwrap();
        assert!((area(&pts, &out).z - 3.0).abs() < 1e-5);
        for t in &out {
            let [a, b, c] = t.map(|i| pts[i as usize]);
            assert!((b - a).cross(c - a).z > 1e-6, "sliver {t:?}");
        }
    }

    #[test]
    fn self_crossing_outlines_terminate() {
        // A bow tie: no ear exists after the first cuts; the rest is fanned.
        let pts = xy(&[(0.0, 0.0), (2.0, 2.0), (2.0, 0.0), (0.0, 2.0), (-1.0, 1.0)]);
        let mut out = Vec::new();
        assert!(triangulate(&pts, 0, &mut out).is_some());
    }

    #[test]
    fn crossing_outlines_are_found() {
        let v = |x: f32, y: f32| Vec3::new(x, y, 0.0);
        // A bow tie: edge 2 (from vertex 2) crosses edge 0.
        assert_eq!(first_crossing(&[v(0.0, 0.0), v(1.0, 1.0), v(1.0, 0.0), v(0.0, 1.0)]), Some((0, 2)));
        // An L shape is concave but simple.
        let l = [v(0.0, 0.0), v(2.0, 0.0), v(2.0, 1.0), v(1.0, 1.0), v(1.0, 2.0), v(0.0, 2.0)];
        assert_eq!(first_crossing(&l), None);
    }
}
