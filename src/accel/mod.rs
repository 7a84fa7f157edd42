//! Ray queries over all objects of a scene: the nearest hit, and how much light gets
//! through along a shadow ray. Today every object is tested (brute force); the
//! bounding volume hierarchy slots in behind the same two calls.

use crate::geometry::Hit;
use crate::math::Ray;
use crate::scene::Scene;

/// Which acceleration structure answers ray queries.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AccelKind {
    /// Test every object.
    #[default]
    None,
}

impl AccelKind {
    /// Every structure this build has, for toggles that cycle through them.
    pub const ALL: &'static [AccelKind] = &[AccelKind::None];
}

/// The read-only ray-query structure shared by all render threads.
#[derive(Debug)]
pub struct World<'s> {
    scene: &'s Scene,
    /// Per object, the share of light its material lets through (0 = opaque), looked
    /// up once here rather than through the material on every shadow ray.
    transmission: Vec<f32>,
}

impl<'s> World<'s> {
    pub fn new(scene: &'s Scene, _kind: AccelKind) -> Self {
        let transmission = scene
            .objects
            .iter()
            .map(|o| scene.material(o.material).transparency)
            .collect();
        World { scene, transmission }
    }

    pub fn scene(&self) -> &'s Scene {
        self.scene
    }

    /// The nearest hit in `(t_min, t_max)` and the index of the object hit.
    #[inline]
    pub fn closest(&self, ray: &Ray, t_min: f32, mut t_max: f32) -> Option<(Hit, u32)> {
        let mut best = None;
        for (i, o) in self.scene.objects.iter().enumerate() {
            if let Some(h) = o.shape.intersect(ray, t_min, t_max) {
                t_max = h.t;
                best = Some((h, i as u32));
            }
        }
        best
    }

    /// The share of light that travels from `ray.origin` a distance `t_max` along the
    /// ray: the product of the transmission of every object in the way, each counted
    /// once however many of its surfaces the segment crosses (two overlapping 70 %
    /// spheres pass 0.49). Stops at the first opaque object.
    #[inline]
    pub fn transmittance(&self, ray: &Ray, t_max: f32) -> f32 {
        let mut light = 1.0;
        for (i, o) in self.scene.objects.iter().enumerate() {
            if o.shape.intersect(ray, 0.0, t_max).is_some() {
                light *= self.transmission[i];
                if light == 0.0 {
                    return 0.0;
                }
            }
        }
        light
    }
}
