//! Vectors, rays and boxes: the vocabulary every other module speaks.

pub mod lanes;

pub use glam::{Vec2, Vec3};

/// Linear RGB; components are not clamped until the film writes them out.
///
/// Four floats in one SIMD register (the fourth unused), so that shading's sums and
/// products are one instruction, not three: the same IEEE operations lane by lane, so
/// the same colours as three separate floats (docs/performance.md, stop 57). Large
/// buffers (the film, texture maps) keep three floats a colour.
pub type Color = glam::Vec3A;

/// A half-line `origin + t * dir`. `dir` is kept unit length so `t` is a distance,
/// which the shading code and the epsilon offsets rely on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
}

impl Ray {
    /// Builds a ray, normalising `dir`.
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Ray { origin, dir: dir.normalize() }
    }

    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + t * self.dir
    }
}

/// Axis-aligned bounding box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb { min: Vec3::splat(f32::INFINITY), max: Vec3::splat(f32::NEG_INFINITY) };

    pub fn from_points(points: impl IntoIterator<Item = Vec3>) -> Self {
        points.into_iter().fold(Aabb::EMPTY, |b, p| b.grow(p))
    }

    pub fn grow(self, p: Vec3) -> Self {
        Aabb { min: self.min.min(p), max: self.max.max(p) }
    }

    pub fn union(self, o: Aabb) -> Self {
        Aabb { min: self.min.min(o.min), max: self.max.max(o.max) }
    }

    pub fn center(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }
}

/// How far a new ray's origin is pushed off the surface it starts on, so it does not
/// hit that surface again (shadow acne). Relative to the point's magnitude because f32
/// spacing grows with it: about 12 ulps at any scale.
/// (Worked in `Vec3A`, which takes the same largest component, for callers that hold
/// the point in one already.)
#[inline(always)]
pub fn surface_offset(p: impl Into<glam::Vec3A>) -> f32 {
    1e-4 * (1.0 + p.into().abs().max_element())
}

/// `v` scaled to unit length (`fallback` if it cannot be), or `v` itself when it already
/// is unit length to within rounding. Normalising is not idempotent in f32 (a third of
/// normalised vectors move by an ulp when normalised again), and an axis written to a
/// scene file and read back must come back bit for bit.
pub fn unit_or(v: Vec3, fallback: Vec3) -> Vec3 {
    if (v.length_squared() - 1.0).abs() <= 8.0 * f32::EPSILON { v } else { v.normalize_or(fallback) }
}

/// Mirror reflection of `d` about the normal `n` (both unit).
pub fn reflect(d: Vec3, n: Vec3) -> Vec3 {
    d - 2.0 * d.dot(n) * n
}

/// Snell refraction of unit `d` through a surface with unit normal `n` facing against
/// `d`, `eta` = index on the incoming side / index on the far side. `None` past the
/// critical angle (total internal reflection).
pub fn refract(d: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let cos_i = -d.dot(n);
    let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
    // Not `k < 0.0`: with an index of 1e30 `eta * eta` is infinite and `k` may be NaN.
    if !(k >= 0.0) {
        return None;
    }
    // Straight on where the sum cancels to nothing (head-on into an enormous index).
    Some((eta * d + (eta * cos_i - k.sqrt()) * n).try_normalize().unwrap_or(d))
}

/// An orthonormal pair perpendicular to unit `n` (Duff et al. 2017, branchless).
pub fn orthonormal_basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x), Vec3::new(b, sign + n.y * n.y * a, -n.y))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_or_is_idempotent() {
        let mut rng = crate::sampler::Rng::new(3);
        for _ in 0..100_000 {
            let v = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32() - 0.5) * 7.0;
            let a = unit_or(v, Vec3::Y);
            assert!((a.length() - 1.0).abs() < 1e-6);
            assert_eq!(unit_or(a, Vec3::Y), a);
        }
        assert_eq!(unit_or(Vec3::ZERO, Vec3::Y), Vec3::Y);
        assert_eq!(unit_or(Vec3::new(0.0, 3.0, 0.0), Vec3::X), Vec3::Y);
    }
}
