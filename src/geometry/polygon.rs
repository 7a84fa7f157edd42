use super::{Hit, Surface, part};
use crate::math::{Aabb, Ray, Vec2, Vec3};
use std::fmt;

/// Why a vertex list is not a usable convex planar polygon.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PolygonError {
    TooFewVertices,
    /// Zero area: all vertices (nearly) coincide or lie on one line.
    Degenerate,
    NotPlanar {
        vertex: usize,
    },
    NotConvex {
        vertex: usize,
    },
    NonFinite,
}

impl fmt::Display for PolygonError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PolygonError::TooFewVertices => write!(f, "a polygon needs at least 3 vertices"),
            PolygonError::Degenerate => write!(f, "polygon has zero area (collinear or coincident vertices)"),
            PolygonError::NotPlanar { vertex } => {
                write!(f, "polygon vertex {vertex} is off the polygon's plane")
            }
            PolygonError::NotConvex { vertex } => {
                write!(f, "polygon is not convex at vertex {vertex}")
            }
            PolygonError::NonFinite => write!(f, "polygon vertex has a NaN or infinite coordinate"),
        }
    }
}

impl std::error::Error for PolygonError {}

/// In-plane half-space of one edge: `inward · p >= offset` on the polygon's side.
#[derive(Clone, Copy, Debug, PartialEq)]
struct EdgePlane {
    inward: Vec3,
    offset: f32,
}

/// Convex planar polygon.
///
/// Fields are private because [`Polygon::new`] validates convexity and planarity and
/// caches the edge planes: a mutable vertex list would bypass both.
#[derive(Clone, Debug, PartialEq)]
pub struct Polygon {
    vertices: Box<[Vec3]>,
    normal: Vec3,
    plane_d: f32,
    edges: Box<[EdgePlane]>,
    /// Slack for the inside test so points on an edge are not lost to rounding.
    tolerance: f32,
    /// In-plane basis for uv, and the map from basis coordinates onto [0, 1]².
    e1: Vec3,
    e2: Vec3,
    uv_min: Vec2,
    uv_scale: Vec2,
}

impl Polygon {
    /// Vertices in order; the normal follows them by the right-hand rule. Collinear
    /// vertices along an edge and repeated consecutive vertices are accepted.
    pub fn new(vertices: Vec<Vec3>) -> Result<Polygon, PolygonError> {
        let n = vertices.len();
        if n < 3 {
            return Err(PolygonError::TooFewVertices);
        }
        if !vertices.iter().all(|v| v.is_finite()) {
            return Err(PolygonError::NonFinite);
        }
        let bounds = Aabb::from_points(vertices.iter().copied());
        let extent = (bounds.max - bounds.min).length();
        let magnitude = bounds.min.abs().max(bounds.max.abs()).max_element();
        // Input rounding is relative to the coordinates' magnitude, shape checks are
        // relative to the polygon's size: allow for both.
        let tolerance = 1e-5 * extent + 4.0 * f32::EPSILON * magnitude;

        // Newell's method on centred coordinates (centring keeps precision for polygons
        // far from the origin); robust to collinear runs of vertices.
        let centroid = vertices.iter().copied().sum::<Vec3>() / n as f32;
        let mut newell = Vec3::ZERO;
        for (i, &a) in vertices.iter().enumerate() {
            let (a, b) = (a - centroid, vertices[(i + 1) % n] - centroid);
            newell += Vec3::new((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
        }
        // |newell| is twice the area.
        // Written so that a NaN (overflowing coordinates) also counts as degenerate.
        let has_area = newell.length() > 1e-6 * extent * extent;
        if !has_area {
            return Err(PolygonError::Degenerate);
        }
        let normal = newell.normalize();
        let plane_d = normal.dot(centroid);

        // Newell's plane is a best fit, so report the worst vertex, not the first one off.
        let (vertex, off) = vertices
            .iter()
            .map(|v| (normal.dot(*v) - plane_d).abs())
            .enumerate()
            .fold((0, 0.0f32), |best, (i, d)| if d > best.1 { (i, d) } else { best });
        if off > tolerance {
            return Err(PolygonError::NotPlanar { vertex });
        }

        // A reflex corner turns against the normal...
        for i in 0..n {
            let (a, b, c) = (vertices[i], vertices[(i + 1) % n], vertices[(i + 2) % n]);
            let (ab, bc) = (b - a, c - b);
            if ab.cross(bc).dot(normal) < -tolerance * (ab.length() + bc.length()) {
                return Err(PolygonError::NotConvex { vertex: (i + 1) % n });
            }
        }
        // ...but a star (pentagram) or a path that doubles back turns the right way at
        // every corner, so also require every vertex to be inside every edge.
        let mut edges = Vec::with_capacity(n);
        for i in 0..n {
            let (a, b) = (vertices[i], vertices[(i + 1) % n]);
            let Some(inward) = normal.cross(b - a).try_normalize() else {
                continue;
            };
            let offset = inward.dot(a);
            if let Some(vertex) = vertices.iter().position(|v| inward.dot(*v) - offset < -tolerance) {
                return Err(PolygonError::NotConvex { vertex });
            }
            edges.push(EdgePlane { inward, offset });
        }

        let first_edge = (0..n).map(|i| vertices[(i + 1) % n] - vertices[i]).find(|e| e.length() > tolerance);
        // Cannot fail: a polygon with area has an edge longer than the tolerance.
        let e1 = first_edge.unwrap_or(Vec3::X).normalize_or(Vec3::X);
        let e2 = normal.cross(e1);
        let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        for v in &vertices {
            let c = Vec2::new((*v - vertices[0]).dot(e1), (*v - vertices[0]).dot(e2));
            lo = lo.min(c);
            hi = hi.max(c);
        }
        let size = hi - lo;
        let uv_scale =
            Vec2::new(if size.x > 0.0 { 1.0 / size.x } else { 0.0 }, if size.y > 0.0 { 1.0 / size.y } else { 0.0 });
        // Keep uv relative to v0 so `surface` does not need the vertex list.
        let uv_min = lo + Vec2::new(vertices[0].dot(e1), vertices[0].dot(e2));

        Ok(Polygon {
            vertices: vertices.into_boxed_slice(),
            normal,
            plane_d,
            edges: edges.into_boxed_slice(),
            tolerance,
            e1,
            e2,
            uv_min,
            uv_scale,
        })
    }

    pub fn vertices(&self) -> &[Vec3] {
        &self.vertices
    }

    pub fn normal(&self) -> Vec3 {
        self.normal
    }

    /// Two-sided. Points on an edge (within rounding) are inside; a ray parallel to the
    /// plane misses.
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        let denom = self.normal.dot(ray.dir);
        if denom.abs() <= 1e-9 {
            return None;
        }
        let t = (self.plane_d - self.normal.dot(ray.origin)) / denom;
        if !(t > t_min && t < t_max) {
            return None;
        }
        let p = ray.at(t);
        if self.edges.iter().any(|e| e.inward.dot(p) - e.offset < -self.tolerance) {
            return None;
        }
        Some(Hit { prim: 0, t, uv: Vec2::ZERO, part: part::SIDE })
    }

    pub fn surface(&self, ray: &Ray, hit: &Hit) -> Surface {
        let p = ray.at(hit.t);
        // Project onto the plane: removes the rounding of `origin + t dir` along the normal.
        let point = p - (self.normal.dot(p) - self.plane_d) * self.normal;
        let c = Vec2::new(point.dot(self.e1), point.dot(self.e2));
        let uv = ((c - self.uv_min) * self.uv_scale).clamp(Vec2::ZERO, Vec2::ONE);
        Surface { point, normal: self.normal, uv }
    }

    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(self.vertices.iter().copied())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Quad;
    use crate::geometry::test_util::{Rng, assert_close, assert_vec_close};
    use crate::math::{reflect, surface_offset};
    use std::f32::consts::TAU;

    fn v(x: f32, y: f32, z: f32) -> Vec3 {
        Vec3::new(x, y, z)
    }

    fn ray(o: [f32; 3], d: [f32; 3]) -> Ray {
        Ray::new(Vec3::from(o), Vec3::from(d))
    }

    /// Regular pentagon of circumradius 1 around (0, 0, -5), counter-clockwise seen from
    /// +z, first vertex at +y.
    fn pentagon() -> Polygon {
        let verts = (0..5)
            .map(|i| {
                let a = TAU * i as f32 / 5.0;
                v(-a.sin(), a.cos(), -5.0)
            })
            .collect();
        Polygon::new(verts).unwrap()
    }

    #[test]
    fn too_few_vertices_is_rejected() {
        assert_eq!(Polygon::new(vec![]), Err(PolygonError::TooFewVertices));
        assert_eq!(Polygon::new(vec![Vec3::ZERO, Vec3::X]), Err(PolygonError::TooFewVertices));
    }

    #[test]
    fn collinear_vertices_are_degenerate() {
        let r = Polygon::new(vec![v(0.0, 0.0, 0.0), v(1.0, 1.0, 1.0), v(3.0, 3.0, 3.0)]);
        assert_eq!(r, Err(PolygonError::Degenerate));
        let r = Polygon::new(vec![Vec3::ONE; 4]);
        assert_eq!(r, Err(PolygonError::Degenerate));
    }

    #[test]
    fn lifted_vertex_is_not_planar() {
        let r = Polygon::new(vec![v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(1.0, 1.0, 0.0), v(0.0, 1.0, 0.1)]);
        // Newell's plane is a best fit, so the bent square is off it at some vertex.
        assert!(matches!(r, Err(PolygonError::NotPlanar { .. })), "{r:?}");
        let r = Polygon::new(vec![
            v(0.0, 0.0, 0.0),
            v(2.0, 0.0, 0.0),
            v(2.0, 1.0, 0.0),
            v(1.0, 2.0, 0.3),
            v(0.0, 1.0, 0.0),
        ]);
        assert_eq!(r, Err(PolygonError::NotPlanar { vertex: 3 }));
    }

    #[test]
    fn reflex_vertex_is_not_convex() {
        // A square with its top edge pushed in to (1, 0.5): reflex at vertex 3.
        let r = Polygon::new(vec![
            v(0.0, 0.0, 0.0),
            v(2.0, 0.0, 0.0),
            v(2.0, 2.0, 0.0),
            v(1.0, 0.5, 0.0),
            v(0.0, 2.0, 0.0),
        ]);
        assert_eq!(r, Err(PolygonError::NotConvex { vertex: 3 }));
    }

    #[test]
    fn pentagram_is_not_convex() {
        let verts = (0..5)
            .map(|i| {
                let a = TAU * (2 * i) as f32 / 5.0;
                v(a.cos(), a.sin(), 0.0)
            })
            .collect();
        assert!(matches!(Polygon::new(verts), Err(PolygonError::NotConvex { .. })));
    }

    #[test]
    fn non_finite_vertex_is_rejected() {
        let r = Polygon::new(vec![v(0.0, 0.0, 0.0), v(1.0, f32::NAN, 0.0), v(0.0, 1.0, 0.0)]);
        assert_eq!(r, Err(PolygonError::NonFinite));
        let r = Polygon::new(vec![v(0.0, 0.0, 0.0), v(f32::INFINITY, 0.0, 0.0), v(0.0, 1.0, 0.0)]);
        assert_eq!(r, Err(PolygonError::NonFinite));
    }

    #[test]
    fn errors_display_and_box_as_std_error() {
        let e: Box<dyn std::error::Error> = Box::new(PolygonError::NotConvex { vertex: 4 });
        assert!(e.to_string().contains('4'));
        assert!(PolygonError::NotPlanar { vertex: 2 }.to_string().contains('2'));
    }

    #[test]
    fn collinear_and_repeated_vertices_are_accepted() {
        let p = Polygon::new(vec![
            v(0.0, 0.0, 0.0),
            v(1.0, 0.0, 0.0),
            v(1.0, 0.0, 0.0),
            v(2.0, 0.0, 0.0),
            v(2.0, 2.0, 0.0),
            v(0.0, 2.0, 0.0),
        ])
        .unwrap();
        assert_vec_close(p.normal(), Vec3::Z, 1e-6);
        assert!(p.intersect(&ray([1.9, 0.1, 1.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY).is_some());
    }

    #[test]
    fn normal_follows_winding() {
        let ccw = Polygon::new(vec![v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)]).unwrap();
        assert_vec_close(ccw.normal(), Vec3::Z, 1e-6);
        let cw = Polygon::new(vec![v(0.0, 0.0, 0.0), v(0.0, 1.0, 0.0), v(1.0, 0.0, 0.0)]).unwrap();
        assert_vec_close(cw.normal(), -Vec3::Z, 1e-6);
    }

    #[test]
    fn pentagon_hit_inside_from_front() {
        let p = pentagon();
        assert_vec_close(p.normal(), Vec3::Z, 1e-6);
        let r = ray([0.2, -0.3, 0.0], [0.0, 0.0, -1.0]);
        let h = p.intersect(&r, 0.0, f32::INFINITY).unwrap();
        assert_close(h.t, 5.0, 1e-5);
        let s = p.surface(&r, &h);
        assert_vec_close(s.normal, Vec3::Z, 1e-6);
        assert_vec_close(s.point, v(0.2, -0.3, -5.0), 1e-5);
        assert!((0.0..=1.0).contains(&s.uv.x) && (0.0..=1.0).contains(&s.uv.y));
    }

    #[test]
    fn pentagon_miss_outside() {
        let p = pentagon();
        // Inside the circumcircle but past the edge between vertices 0 and 1: the edge's
        // midpoint is at distance cos 36° ≈ 0.809 from the centre.
        let mid = 0.5 * (p.vertices()[0] + p.vertices()[1]);
        let out = mid.truncate() * 1.05;
        assert!(out.length() < 1.0);
        assert_eq!(p.intersect(&ray([out.x, out.y, 0.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY), None);
        let inside = mid.truncate() * 0.95;
        assert!(p.intersect(&ray([inside.x, inside.y, 0.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY).is_some());
    }

    #[test]
    fn hit_from_back_keeps_winding_normal() {
        let p = pentagon();
        let r = ray([0.0, 0.0, -7.0], [0.0, 0.0, 1.0]);
        let h = p.intersect(&r, 0.0, f32::INFINITY).unwrap();
        assert_close(h.t, 2.0, 1e-5);
        assert_vec_close(p.surface(&r, &h).normal, Vec3::Z, 1e-6);
    }

    #[test]
    fn grazing_edges_and_vertices_are_inclusive() {
        let p = pentagon();
        let down = [0.0, 0.0, -1.0];
        let at = |q: Vec3| ray([q.x, q.y, 0.0], down);
        // Exactly on a vertex and on an edge midpoint: hit (within rounding).
        assert!(p.intersect(&at(p.vertices()[0]), 0.0, f32::INFINITY).is_some());
        let mid = 0.5 * (p.vertices()[2] + p.vertices()[3]);
        assert!(p.intersect(&at(mid), 0.0, f32::INFINITY).is_some());
        // 1e-3 beyond the edge: miss.
        let out = mid + 1e-3 * mid.truncate().normalize().extend(0.0);
        assert_eq!(p.intersect(&at(out), 0.0, f32::INFINITY), None);
        // In the plane: parallel, miss.
        assert_eq!(p.intersect(&ray([-3.0, 0.0, -5.0], [1.0, 0.0, 0.0]), 0.0, f32::INFINITY), None);
    }

    #[test]
    fn polygon_behind_origin_is_missed() {
        let p = pentagon();
        assert_eq!(p.intersect(&ray([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]), 0.0, f32::INFINITY), None);
    }

    #[test]
    fn respects_t_max() {
        let p = pentagon();
        let r = ray([0.0, 0.0, 0.0], [0.0, 0.0, -1.0]);
        assert_eq!(p.intersect(&r, 0.0, 4.99), None);
        assert!(p.intersect(&r, 0.0, 5.01).is_some());
    }

    #[test]
    fn offset_rays_do_not_hit_again() {
        // A hexagon in a tilted plane, away from the origin.
        let (e1, e2) = (v(0.8, 0.6, 0.0), v(-0.36, 0.48, 0.8));
        let centre = v(10.0, -3.0, -30.0);
        let verts = (0..6)
            .map(|i| {
                let a = TAU * i as f32 / 6.0;
                centre + 3.0 * (a.cos() * e1 + a.sin() * e2)
            })
            .collect();
        let p = Polygon::new(verts).unwrap();
        let mut rng = Rng::new(3);
        let mut hits = 0;
        for _ in 0..500 {
            let target = centre + rng.range(-2.0, 2.0) * e1 + rng.range(-2.0, 2.0) * e2;
            let origin = rng.in_box(Vec3::splat(-20.0), Vec3::splat(20.0));
            let r = Ray::new(origin, target - origin);
            let Some(h) = p.intersect(&r, 0.0, f32::INFINITY) else {
                continue;
            };
            hits += 1;
            let s = p.surface(&r, &h);
            let side = -r.dir.dot(s.normal).signum() * s.normal;
            let bounce = Ray::new(s.point + surface_offset(s.point) * side, reflect(r.dir, s.normal));
            assert_eq!(p.intersect(&bounce, 0.0, f32::INFINITY), None);
            let through = Ray::new(s.point - surface_offset(s.point) * side, r.dir);
            assert_eq!(p.intersect(&through, 0.0, f32::INFINITY), None);
        }
        assert!(hits > 300);
    }

    #[test]
    fn uv_spans_the_unit_square() {
        // Axis-aligned rectangle starting along +x: uv is the normalised position.
        let p = Polygon::new(vec![v(0.0, 0.0, 0.0), v(4.0, 0.0, 0.0), v(4.0, 2.0, 0.0), v(0.0, 2.0, 0.0)]).unwrap();
        let r = ray([1.0, 1.5, 1.0], [0.0, 0.0, -1.0]);
        let uv = p.surface(&r, &p.intersect(&r, 0.0, f32::INFINITY).unwrap()).uv;
        assert_close(uv.x, 0.25, 1e-5);
        assert_close(uv.y, 0.75, 1e-5);
    }

    #[test]
    fn bounds_are_vertex_box() {
        let p = pentagon();
        let b = p.bounds();
        assert_close(b.max.y, 1.0, 1e-6);
        assert_close(b.min.z, -5.0, 1e-6);
        assert_close(b.max.z, -5.0, 1e-6);
        assert_close(b.max.x, (TAU / 5.0).sin(), 1e-6);
    }

    #[test]
    fn agrees_with_quad_on_random_rays() {
        let (c, eu, ev) = (v(-1.0, 0.5, 0.2), v(2.0, 0.5, -0.5), v(0.3, 0.0, 1.5));
        let q = Quad::new(c, eu, ev);
        let p = Polygon::new(vec![c, c + eu, c + eu + ev, c + ev]).unwrap();
        assert_vec_close(p.normal(), q.normal(), 1e-6);
        let b = q.bounds();
        let mut rng = Rng::new(1234);
        let mut hits = 0;
        for _ in 0..4000 {
            let r = rng.ray(b.min, b.max, 2.0);
            let (hq, hp) = (q.intersect(&r, 0.0, f32::INFINITY), p.intersect(&r, 0.0, f32::INFINITY));
            match (hq, hp) {
                (Some(a), Some(b)) => {
                    hits += 1;
                    assert_close(a.t, b.t, 1e-4 * (1.0 + a.t));
                }
                (None, None) => {}
                // Only rays through the very boundary may disagree.
                (Some(a), None) => {
                    assert!(a.uv.min_element() < 1e-4 || a.uv.max_element() > 1.0 - 1e-4)
                }
                (None, Some(h)) => {
                    let rel = r.at(h.t) - c;
                    let n = eu.cross(ev);
                    let a = rel.cross(ev).dot(n) / n.length_squared();
                    let b = eu.cross(rel).dot(n) / n.length_squared();
                    assert!(a.min(b) > -1e-4 && a.max(b) < 1.0 + 1e-4, "polygon hit far outside quad");
                }
            }
        }
        assert!(hits > 1000);
    }
}
