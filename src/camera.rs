//! The pinhole camera.
//!
//! ```toml
//! [camera]
//! position = [0, 0, 0]
//! look_at = [0, 0, -1]
//! up = [0, 1, 0]
//! fov = 43.6028   # vertical field of view, degrees
//! width = 800
//! height = 800
//! ```

use crate::math::{Ray, Vec2, Vec3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub position: Vec3,
    pub look_at: Vec3,
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub fov: f32,
    pub width: u32,
    pub height: u32,
}

/// Why a camera cannot be built; the scene loader adds file positions.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum CameraError {
    #[error("look_at is the camera position: no viewing direction")]
    ZeroDirection,
    #[error("up is zero or parallel to the viewing direction")]
    BadUp,
    #[error("field of view must be in (0, 180) degrees")]
    BadFov,
}

/// A camera with its frame precomputed, ready to generate rays.
#[derive(Clone, Copy, Debug)]
pub struct CameraRig {
    origin: Vec3,
    /// Image-plane vectors at unit distance: one pixel step to the right and downwards.
    pixel_dx: Vec3,
    pixel_dy: Vec3,
    /// Direction through the top-left corner of the image.
    corner: Vec3,
}

impl Camera {
    pub fn new(position: Vec3, look_at: Vec3, up: Vec3, fov: f32, width: u32, height: u32) -> Self {
        Camera { position, look_at, up, fov, width, height }
    }

    pub fn rig(&self) -> Result<CameraRig, CameraError> {
        let forward = self.look_at - self.position;
        if !(forward.length_squared() > 0.0) {
            return Err(CameraError::ZeroDirection);
        }
        let w = forward.normalize();
        let right = w.cross(self.up);
        if !(right.length_squared() > 1e-12 * self.up.length_squared()) || self.up == Vec3::ZERO {
            return Err(CameraError::BadUp);
        }
        if !(self.fov > 0.0 && self.fov < 180.0) {
            return Err(CameraError::BadFov);
        }
        let u = right.normalize();
        let v = u.cross(w);
        let half_h = (self.fov.to_radians() * 0.5).tan();
        let half_w = half_h * self.width as f32 / self.height as f32;
        let pixel_dx = u * (2.0 * half_w / self.width as f32);
        let pixel_dy = -v * (2.0 * half_h / self.height as f32);
        Ok(CameraRig { origin: self.position, pixel_dx, pixel_dy, corner: w - half_w * u + half_h * v })
    }
}

impl CameraRig {
    /// The apex and four edge directions (in order round the rim) of a cone that holds
    /// every ray [`CameraRig::ray`] makes for positions in `[x0, x1] × [y0, y1]`. It is
    /// a pixel wider on each side, far more than rounding can move a ray.
    pub fn cone(&self, x0: f32, y0: f32, x1: f32, y1: f32) -> (Vec3, [Vec3; 4]) {
        let d = |x: f32, y: f32| self.corner + x * self.pixel_dx + y * self.pixel_dy;
        let (x0, y0, x1, y1) = (x0 - 1.0, y0 - 1.0, x1 + 1.0, y1 + 1.0);
        (self.origin, [d(x0, y0), d(x1, y0), d(x1, y1), d(x0, y1)])
    }

    /// The ray through image position (`x`, `y`) in pixels, (0, 0) the top-left corner
    /// of the image and (width, height) the bottom-right one.
    #[inline]
    pub fn ray(&self, x: f32, y: f32) -> Ray {
        Ray::new(self.origin, self.corner + x * self.pixel_dx + y * self.pixel_dy)
    }

    /// [`CameraRig::ray`] through each of `points`, in order, added to `out`. Eight at
    /// a time, lane by lane, so that the compiler computes them together (one at a time,
    /// each waited for its square root and division): glam's operations in glam's
    /// order, so each ray is the same to the bit. Added eight at a time too, with one
    /// check of `out`'s room for the eight rather than one a ray.
    pub fn rays(&self, points: &[Vec2], out: &mut Vec<Ray>) {
        let (c, dx, dy) = (self.corner.to_array(), self.pixel_dx.to_array(), self.pixel_dy.to_array());
        for chunk in points.chunks(8) {
            let (mut x, mut y) = ([0f32; 8], [0f32; 8]);
            for (lane, p) in chunk.iter().enumerate() {
                (x[lane], y[lane]) = (p.x, p.y);
            }
            let mut d = [[0f32; 8]; 3];
            for lane in 0..8 {
                for axis in 0..3 {
                    d[axis][lane] = (c[axis] + x[lane] * dx[axis]) + y[lane] * dy[axis];
                }
                // `normalize`: times the reciprocal of the length.
                let length = ((d[0][lane] * d[0][lane]) + (d[1][lane] * d[1][lane]) + (d[2][lane] * d[2][lane])).sqrt();
                let recip = 1.0 / length;
                for row in &mut d {
                    row[lane] *= recip;
                }
            }
            let [x, y, z] = d;
            let rays: [Ray; 8] = std::array::from_fn(|k| Ray { origin: self.origin, dir: Vec3::new(x[k], y[k], z[k]) });
            out.extend(rays.into_iter().take(chunk.len()));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam() -> Camera {
        Camera::new(Vec3::ZERO, Vec3::NEG_Z, Vec3::Y, 2.0 * (10.0f32 / 25.0).atan().to_degrees(), 800, 800)
    }

    #[test]
    fn rays_eight_at_a_time_are_those_one_at_a_time() {
        let mut r = crate::sampler::Rng::new(5);
        for camera in
            [cam(), Camera::new(Vec3::new(1.0, 2.0, 3.0), Vec3::new(-4.0, 0.5, -7.0), Vec3::Y, 61.0, 333, 200)]
        {
            let rig = camera.rig().unwrap();
            // 21 points: two whole chunks of eight and a part one.
            let points: Vec<Vec2> = (0..21).map(|_| Vec2::new(r.next_f32() * 900.0, r.next_f32() * 900.0)).collect();
            let mut got = Vec::new();
            rig.rays(&points, &mut got);
            assert_eq!(got.len(), points.len());
            for (ray, p) in got.iter().zip(&points) {
                let one = rig.ray(p.x, p.y);
                assert_eq!(ray.origin, one.origin);
                assert_eq!(ray.dir.to_array().map(f32::to_bits), one.dir.to_array().map(f32::to_bits));
            }
        }
    }

    #[test]
    fn centre_ray_looks_at_target() {
        let r = cam().rig().unwrap().ray(400.0, 400.0);
        assert!((r.dir - Vec3::NEG_Z).length() < 1e-6);
    }

    #[test]
    fn corners_span_the_seed_image_plane() {
        // The seed's image plane at distance 25 spans [-10, 10] both ways.
        let rig = cam().rig().unwrap();
        let tl = rig.ray(0.0, 0.0).dir;
        let p = tl * (25.0 / -tl.z);
        assert!((p - Vec3::new(-10.0, 10.0, -25.0)).length() < 1e-3, "{p}");
        let br = rig.ray(800.0, 800.0).dir;
        let p = br * (25.0 / -br.z);
        assert!((p - Vec3::new(10.0, -10.0, -25.0)).length() < 1e-3, "{p}");
    }

    #[test]
    fn degenerate_cameras_are_errors() {
        let mut c = cam();
        c.look_at = c.position;
        assert_eq!(c.rig().unwrap_err(), CameraError::ZeroDirection);
        let mut c = cam();
        c.up = Vec3::NEG_Z * 3.0;
        assert_eq!(c.rig().unwrap_err(), CameraError::BadUp);
        let mut c = cam();
        c.up = Vec3::ZERO;
        assert_eq!(c.rig().unwrap_err(), CameraError::BadUp);
        let mut c = cam();
        c.fov = 180.0;
        assert_eq!(c.rig().unwrap_err(), CameraError::BadFov);
    }
}
