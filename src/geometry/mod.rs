//! Shapes and their ray intersections. One file per shape; [`Shape`] is the closed set
//! the renderer dispatches over with a `match` (no trait objects on the hot path).
//!
//! Every shape answers two questions, in two steps, so that the cheap one runs for every
//! candidate and the dearer one only for the winner:
//! 1. [`Shape::intersect`]: the nearest `t` in `(t_min, t_max)`, plus whatever the shape
//!    needs later (which part was hit, barycentrics) in [`Hit`];
//! 2. [`Shape::surface`]: point, outward normal and texture coordinates at that hit.

mod cone;
mod cylinder;
mod mesh;
mod polygon;
mod quad;
mod sphere;
mod transformed;
mod triangle;
pub mod triangulate;

pub use cone::Cone;
pub use cylinder::Cylinder;
pub use mesh::{Mesh, MeshError, intersect_triangle, triangle_hits};
pub use polygon::{Polygon, PolygonError};
pub use quad::Quad;
pub use sphere::{Sphere, hits as sphere_hits};
pub use transformed::{Transformed, affine, apply as transform, instance};
pub use triangle::Triangle;

use crate::math::lanes::Lanes;
use crate::math::{Aabb, Ray, Vec2, Vec3};

/// The result of an intersection test, before shading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the (unit) ray direction.
    pub t: f32,
    /// Shape-specific parameters of the hit (barycentrics for triangles, for instance).
    pub uv: Vec2,
    /// Which part of a compound shape was hit (side wall, base cap, top cap).
    pub part: u8,
    /// Which element of a shape made of many was hit (a mesh's triangle).
    pub prim: u32,
}

/// Geometry at a hit, for shading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surface {
    pub point: Vec3,
    /// Unit normal facing out of a closed shape, or along the winding of a flat one
    /// (right-hand rule). Not flipped towards the ray: refraction needs to know which
    /// side the ray came from.
    pub normal: Vec3,
    /// Texture coordinates in [0, 1]².
    pub uv: Vec2,
}

/// Part ids used in [`Hit::part`].
pub mod part {
    pub const SIDE: u8 = 0;
    pub const BASE_CAP: u8 = 1;
    pub const TOP_CAP: u8 = 2;
}

#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    Sphere(Sphere),
    Quad(Quad),
    Polygon(Polygon),
    Cylinder(Cylinder),
    Cone(Cone),
    Triangle(Triangle),
    /// Shared, since meshes can be large and scenes are cloned.
    Mesh(std::sync::Arc<Mesh>),
    /// A shape that its transform could not simply rebuild (see [`transform`]).
    Transformed(Box<Transformed>),
}

impl Shape {
    /// Nearest hit with `t_min < t < t_max`, whatever side the ray comes from.
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        match self {
            Shape::Sphere(s) => s.intersect(ray, t_min, t_max),
            Shape::Quad(s) => s.intersect(ray, t_min, t_max),
            Shape::Polygon(s) => s.intersect(ray, t_min, t_max),
            Shape::Cylinder(s) => s.intersect(ray, t_min, t_max),
            Shape::Cone(s) => s.intersect(ray, t_min, t_max),
            Shape::Triangle(s) => s.intersect(ray, t_min, t_max),
            Shape::Mesh(s) => s.intersect(ray, t_min, t_max),
            Shape::Transformed(s) => s.intersect(ray, t_min, t_max),
        }
    }

    pub fn surface(&self, ray: &Ray, hit: &Hit) -> Surface {
        self.surface_uv(ray, hit, true)
    }

    /// [`Shape::surface`], with `uv` left zero where computing it costs trigonometry
    /// (sphere, cylinder, cone) unless `uv` is set: most textures never read it.
    /// Always inlined: returned through memory, the surface was written in pieces and
    /// read back wider, which stalls store forwarding in the shading that follows.
    #[inline(always)]
    pub fn surface_uv(&self, ray: &Ray, hit: &Hit, uv: bool) -> Surface {
        self.surface_as(ray, hit, uv)
    }

    /// [`Shape::surface_uv`] converted to `T` in each shape's own branch: a form held in
    /// registers (such as vectors) then leaves the match without being assembled on the
    /// stack and copied out wider than written.
    #[inline(always)]
    pub fn surface_as<T: From<Surface>>(&self, ray: &Ray, hit: &Hit, uv: bool) -> T {
        match self {
            Shape::Sphere(s) => s.surface_uv(ray, hit, uv).into(),
            Shape::Quad(s) => s.surface(ray, hit).into(),
            Shape::Polygon(s) => s.surface(ray, hit).into(),
            Shape::Cylinder(s) => s.surface_uv(ray, hit, uv).into(),
            Shape::Cone(s) => s.surface_uv(ray, hit, uv).into(),
            Shape::Triangle(s) => s.surface(ray, hit).into(),
            Shape::Mesh(s) => s.surface(ray, hit).into(),
            Shape::Transformed(s) => s.surface_uv(ray, hit, uv).into(),
        }
    }

    pub fn bounds(&self) -> Aabb {
        match self {
            Shape::Sphere(s) => s.bounds(),
            Shape::Quad(s) => s.bounds(),
            Shape::Polygon(s) => s.bounds(),
            Shape::Cylinder(s) => s.bounds(),
            Shape::Cone(s) => s.bounds(),
            Shape::Triangle(s) => s.bounds(),
            Shape::Mesh(s) => s.bounds(),
            Shape::Transformed(s) => s.bounds(),
        }
    }
}

/// Keeps the nearest accepted candidate, lane by lane ([`Lanes`]: one ray, or several
/// against one shape): the shapes made of several surfaces must return the closest one
/// whatever order they are tested in. The part taken is kept as a number, -1 where none
/// was, so that the wide lanes carry it as they carry `t`.
pub(crate) struct Nearest<L: Lanes> {
    t_min: L,
    /// The nearest distance taken, else `t_max`.
    pub(crate) t: L,
    /// The [`part`] of that candidate, else -1.
    pub(crate) part: L,
}

impl<L: Lanes> Nearest<L> {
    #[inline(always)]
    pub(crate) fn new(t_min: L, t_max: L) -> Self {
        Nearest { t_min, t: t_max, part: L::splat(-1.0) }
    }

    /// Where `t` is in range and nearer than the best so far; the caller then checks the
    /// surface's own bounds and calls [`Nearest::take`] with both.
    #[inline(always)]
    pub(crate) fn improves(&self, t: L) -> L::Mask {
        t.gt(self.t_min) & t.lt(self.t)
    }

    /// Takes distance `t` as part `part` in the lanes of `ok`.
    #[inline(always)]
    pub(crate) fn take(&mut self, ok: L::Mask, t: L, part: u8) {
        self.t = L::select(ok, t, self.t);
        self.part = L::select(ok, L::splat(part as f32), self.part);
    }

    /// The lanes where a candidate was taken.
    #[inline(always)]
    pub(crate) fn taken(&self) -> L::Mask {
        self.part.ge(L::splat(0.0))
    }
}

impl Nearest<f32> {
    #[inline(always)]
    pub(crate) fn hit(self) -> Option<Hit> {
        self.taken().then_some(Hit { prim: 0, t: self.t, uv: Vec2::ZERO, part: self.part as u8 })
    }
}

/// Box of a disc: along world axis `i` a disc with unit normal `axis` reaches
/// `radius * sqrt(1 - axis_i²)` from its center, which is tighter than a sphere's box.
pub(crate) fn disc_bounds(center: Vec3, axis: Vec3, radius: f32) -> Aabb {
    let reach = radius * (Vec3::ONE - axis * axis).max(Vec3::ZERO).sqrt();
    Aabb { min: center - reach, max: center + reach }
}

/// Angle of `v` around an axis as a fraction of a turn in [0, 1), measured in the
/// plane spanned by the basis `(e1, e2)`.
pub(crate) fn turn_fraction(v: Vec3, e1: Vec3, e2: Vec3) -> f32 {
    let u = v.dot(e2).atan2(v.dot(e1)) * (0.5 * std::f32::consts::FRAC_1_PI);
    // atan2 gives [-π, π]; fold the negative half up. `u + 1.0` can round to exactly
    // 1.0 for tiny negative u, hence the clamp.
    let u = if u < 0.0 { u + 1.0 } else { u };
    u.clamp(0.0, 1.0)
}

/// Helpers shared by the shapes' unit tests.
#[cfg(test)]
pub(crate) mod test_util {
    use super::{Shape, Surface};
    use crate::math::{Ray, Vec3, reflect, surface_offset};

    /// Shadow acne check for a closed shape: rays that leave a hit point pushed off by
    /// `surface_offset` never meet the same shape again, whether reflected outwards or
    /// sent on through the solid and out of its far side. `may_not_exit` names the hits
    /// (at a rim or apex) where the ray into the solid may find no far side.
    pub fn assert_offset_rays_do_not_hit_again(
        shape: impl Into<Shape>,
        seed: u64,
        may_not_exit: impl Fn(&Surface) -> bool,
    ) {
        let shape = shape.into();
        let b = shape.bounds();
        let mut rng = Rng::new(seed);
        let mut hits = 0;
        for _ in 0..1000 {
            let origin = rng.in_box(Vec3::splat(-10.0), Vec3::splat(10.0));
            let r = Ray::new(origin, rng.in_box(b.min, b.max) - origin);
            let Some(h) = shape.intersect(&r, 0.0, f32::INFINITY) else {
                continue;
            };
            hits += 1;
            let s = shape.surface(&r, &h);
            let eps = surface_offset(s.point);
            let bounce = Ray::new(s.point + eps * s.normal, reflect(r.dir, s.normal));
            assert_eq!(shape.intersect(&bounce, 0.0, f32::INFINITY), None, "{r:?} {h:?}");
            let inner = Ray::new(s.point - eps * s.normal, r.dir);
            let Some(exit_hit) = shape.intersect(&inner, 0.0, f32::INFINITY) else {
                assert!(may_not_exit(&s), "no far side: {r:?} {h:?}");
                continue;
            };
            let exit = shape.surface(&inner, &exit_hit);
            let out = Ray::new(exit.point + surface_offset(exit.point) * exit.normal, r.dir);
            assert_eq!(shape.intersect(&out, 0.0, f32::INFINITY), None, "{r:?} {h:?}");
        }
        assert!(hits > 300, "{hits} hits");
    }

    /// xorshift64*: deterministic and dependency-free, plenty for spraying rays.
    pub struct Rng(u64);

    impl Rng {
        pub fn new(seed: u64) -> Self {
            Rng(seed.max(1))
        }

        pub fn next_u64(&mut self) -> u64 {
            let mut x = self.0;
            x ^= x >> 12;
            x ^= x << 25;
            x ^= x >> 27;
            self.0 = x;
            x.wrapping_mul(0x2545_F491_4F6C_DD1D)
        }

        /// Uniform in [0, 1).
        pub fn unit(&mut self) -> f32 {
            (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
        }

        pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
            lo + (hi - lo) * self.unit()
        }

        pub fn in_box(&mut self, lo: Vec3, hi: Vec3) -> Vec3 {
            Vec3::new(self.range(lo.x, hi.x), self.range(lo.y, hi.y), self.range(lo.z, hi.z))
        }

        /// Uniform direction on the unit sphere.
        pub fn direction(&mut self) -> Vec3 {
            let z = self.range(-1.0, 1.0);
            let phi = self.range(0.0, std::f32::consts::TAU);
            let r = (1.0 - z * z).max(0.0).sqrt();
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        }

        /// Half the rays aim at a point of `[lo, hi]` so most of them hit something.
        pub fn ray(&mut self, lo: Vec3, hi: Vec3, spread: f32) -> Ray {
            let pad = Vec3::splat(spread);
            let origin = self.in_box(lo - pad, hi + pad);
            let dir = if self.unit() < 0.5 { self.in_box(lo, hi) - origin } else { self.direction() };
            if dir.length_squared() < 1e-12 {
                return Ray::new(origin, Vec3::X);
            }
            Ray::new(origin, dir)
        }
    }

    #[track_caller]
    pub fn assert_close(a: f32, b: f32, tol: f32) {
        assert!((a - b).abs() <= tol, "{a} != {b} (tolerance {tol})");
    }

    #[track_caller]
    pub fn assert_vec_close(a: Vec3, b: Vec3, tol: f32) {
        assert!((a - b).abs().max_element() <= tol, "{a} != {b} (tolerance {tol})");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shape_dispatches_to_each_variant() {
        let ray = Ray::new(Vec3::new(0.0, 0.0, 5.0), -Vec3::Z);
        let square = vec![
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        ];
        let shapes = [
            Shape::Sphere(Sphere::new(Vec3::ZERO, 1.0)),
            Shape::Quad(Quad::new(Vec3::new(-1.0, -1.0, 0.0), 2.0 * Vec3::X, 2.0 * Vec3::Y)),
            Shape::Polygon(Polygon::new(square).unwrap()),
            Shape::Cylinder(Cylinder::new(Vec3::new(0.0, 0.0, -1.0), Vec3::Z, 1.0, 2.0, true)),
            Shape::Cone(Cone::new(Vec3::new(0.0, 0.0, -1.0), Vec3::Z, 1.0, 2.0, true)),
            Shape::Triangle(Triangle::new(Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::Y)),
        ];
        let expected_t = [4.0, 5.0, 5.0, 4.0, 4.0, 5.0];
        for (shape, t) in shapes.iter().zip(expected_t) {
            let hit = shape.intersect(&ray, 0.0, f32::INFINITY).unwrap();
            assert!((hit.t - t).abs() < 1e-4, "{shape:?}: t = {}", hit.t);
            let s = shape.surface(&ray, &hit);
            assert!((s.normal - Vec3::Z).length() < 1e-4, "{shape:?}: normal {}", s.normal);
            let b = shape.bounds();
            assert!(s.point.cmpge(b.min - 1e-5).all() && s.point.cmple(b.max + 1e-5).all());
        }
    }

    #[test]
    fn surface_without_uv_keeps_point_and_normal() {
        let shapes: [Shape; 4] = [
            Sphere::new(Vec3::new(0.5, -0.25, 1.0), 1.5).into(),
            Cylinder::new(Vec3::new(0.0, -1.0, 0.5), Vec3::new(0.2, 1.0, 0.1), 1.0, 2.0, true).into(),
            Cone::truncated(Vec3::new(0.0, -1.0, 0.5), Vec3::new(0.1, 1.0, -0.2), 1.5, 0.5, 2.0, true, true).into(),
            Cone::new(Vec3::new(0.0, -1.0, 0.5), Vec3::Y, 1.5, 2.0, true).into(),
        ];
        let mut rng = test_util::Rng::new(5);
        for shape in &shapes {
            let b = shape.bounds();
            for _ in 0..2000 {
                let r = rng.ray(b.min, b.max, 3.0);
                let Some(h) = shape.intersect(&r, 0.0, f32::INFINITY) else {
                    continue;
                };
                let (full, bare) = (shape.surface(&r, &h), shape.surface_uv(&r, &h, false));
                assert_eq!((full.point, full.normal), (bare.point, bare.normal), "{shape:?} {r:?}");
                assert_eq!(bare.uv, Vec2::ZERO);
            }
        }
    }

    #[test]
    fn turn_fraction_covers_a_full_turn() {
        let (e1, e2) = (Vec3::X, Vec3::Y);
        assert_eq!(turn_fraction(Vec3::X, e1, e2), 0.0);
        assert!((turn_fraction(Vec3::Y, e1, e2) - 0.25).abs() < 1e-6);
        assert!((turn_fraction(-Vec3::Y, e1, e2) - 0.75).abs() < 1e-6);
        let just_below = turn_fraction(Vec3::new(1.0, -1e-30, 0.0), e1, e2);
        assert!((0.0..=1.0).contains(&just_below));
    }
}

macro_rules! shape_from {
    ($($t:ident),*) => {$(
        impl From<$t> for Shape {
            fn from(s: $t) -> Shape {
                Shape::$t(s)
            }
        }
    )*};
}
shape_from!(Sphere, Quad, Polygon, Cylinder, Cone, Triangle);

impl From<Mesh> for Shape {
    fn from(m: Mesh) -> Shape {
        Shape::Mesh(std::sync::Arc::new(m))
    }
}
