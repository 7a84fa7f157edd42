//! A view for models that come without one (an OBJ file, a glTF file without a camera
//! or lights): a camera framing their bounds from the front and above, and a light
//! over the camera's shoulder.

use super::Scene;
use crate::camera::Camera;
use crate::light::PointLight;
use crate::math::{Aabb, Color, Vec3};

/// Vertical field of view of the default camera, degrees.
const FOV: f32 = 40.0;
/// Image size of the default camera.
pub const WIDTH: u32 = 800;
pub const HEIGHT: u32 = 600;

/// The bounds of everything in the scene (`None` when it is empty).
pub fn scene_bounds(scene: &Scene) -> Option<Aabb> {
    scene.objects.iter().map(|o| o.shape.bounds()).reduce(Aabb::union)
}

/// A camera looking at `bounds` from the front (+z) and above (about 27°), far enough
/// that the bounding sphere fits the narrower field of view with a margin.
pub fn default_view(bounds: Aabb, width: u32, height: u32) -> Camera {
    let center = bounds.center();
    let radius = ((bounds.max - bounds.min).length() * 0.5).max(1e-3);
    let vertical = FOV.to_radians() * 0.5;
    let horizontal = (vertical.tan() * width as f32 / height as f32).atan();
    let distance = radius * 1.05 / vertical.min(horizontal).sin();
    let position = center + Vec3::new(0.0, 0.5, 1.0).normalize() * distance;
    Camera::new(position, center, Vec3::Y, FOV, width, height)
}

/// A white light above and to the left of the camera, a little behind it, so that the
/// model is lit from the front with shadows falling down and to the right.
pub fn shoulder_light(camera: &Camera) -> PointLight {
    let back = camera.position - camera.look_at;
    let distance = back.length();
    let forward = -back / distance;
    let right = forward.cross(camera.up).normalize_or(Vec3::X);
    let up = right.cross(forward);
    let position = camera.position + (0.6 * up - 0.5 * right - 0.2 * forward) * distance;
    PointLight::new(position, Color::ONE)
}

/// Gives `scene` the default camera (if `camera` is false) and light (if it has none),
/// saying so in `notes`.
pub fn complete(scene: &mut Scene, camera: bool, what: &str, notes: &mut Vec<String>) {
    let Some(bounds) = scene_bounds(scene) else { return };
    if !camera {
        scene.camera = default_view(bounds, WIDTH, HEIGHT);
        let p = scene.camera.position;
        notes.push(format!(
            "{what} has no camera: viewing its bounds from the front and above, from ({:.3}, {:.3}, {:.3})",
            p.x, p.y, p.z
        ));
    }
    if scene.lights.is_empty() {
        scene.add_light(shoulder_light(&scene.camera));
        notes.push(format!("{what} has no lights: adding a white one over the camera's shoulder"));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_view_sees_every_corner_of_the_bounds() {
        let b = Aabb { min: Vec3::new(-3.0, 0.0, -1.0), max: Vec3::new(5.0, 2.0, 4.0) };
        let cam = default_view(b, 800, 600);
        assert!(cam.position.y > b.center().y && cam.position.z > b.max.z, "front and above");
        let forward = (cam.look_at - cam.position).normalize();
        let right = forward.cross(Vec3::Y).normalize();
        let up = right.cross(forward);
        let half_h = (cam.fov.to_radians() * 0.5).tan();
        for i in 0..8 {
            let c = Vec3::new(
                if i & 1 == 0 { b.min.x } else { b.max.x },
                if i & 2 == 0 { b.min.y } else { b.max.y },
                if i & 4 == 0 { b.min.z } else { b.max.z },
            );
            let d = c - cam.position;
            let (x, y) = (d.dot(right) / d.dot(forward), d.dot(up) / d.dot(forward));
            assert!(d.dot(forward) > 0.0, "corner {c} behind the camera");
            assert!(x.abs() < half_h * 800.0 / 600.0 && y.abs() < half_h, "corner {c} outside the view ({x}, {y})");
        }
        let light = shoulder_light(&cam);
        assert!(light.position.y > cam.position.y, "above the camera");
    }
}
