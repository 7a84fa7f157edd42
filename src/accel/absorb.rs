//! Shadows through absorbing glass: the light that gets through takes the glass's
//! colour, by the length of the shadow ray inside it (Beer–Lambert).

use super::World;
use crate::material::beer_lambert;
use crate::math::{Color, Ray};

/// Crossings of one object looked at along a shadow ray at most (a closed shape is
/// crossed twice; a mesh may be crossed more often).
const MAX_CROSSINGS: usize = 64;

impl World<'_> {
    /// Whether any object absorbs light inside it.
    #[inline]
    pub fn absorbs(&self) -> bool {
        !self.absorbing.is_empty()
    }

    /// [`World::transmittance`] as a colour: times, for each absorbing object, what its
    /// material lets through over the length of the segment inside it. Where nothing
    /// absorbs, the transmittance itself in every channel.
    pub fn transmittance_color(&self, ray: &Ray, t_max: f32) -> Color {
        let light = self.transmittance(ray, t_max);
        if light == 0.0 || self.absorbing.is_empty() {
            return Color::splat(light);
        }
        let mut color = Color::splat(light);
        for &i in &self.absorbing {
            let inside = self.length_inside(i as usize, ray, t_max);
            if inside > 0.0 {
                let object = &self.scene.objects[i as usize];
                color *= beer_lambert(self.scene.material(object.material).absorption, inside);
            }
        }
        color
    }

    /// How much of the segment from `ray.origin` to distance `t_max` lies inside object
    /// `i`, told by which side of its surface each crossing meets (the outward normal):
    /// a segment whose first crossing leaves started inside.
    fn length_inside(&self, i: usize, ray: &Ray, t_max: f32) -> f32 {
        let shape = &self.scene.objects[i].shape;
        if !meets(shape.bounds(), ray, t_max) {
            return 0.0;
        }
        let (mut t, mut inside, mut entered) = (0.0f32, 0.0f32, None);
        for _ in 0..MAX_CROSSINGS {
            let Some(hit) = self.intersect_object(i, ray, t, t_max) else { break };
            let leaving = ray.dir.dot(shape.surface(ray, &hit).normal) > 0.0;
            if leaving {
                inside += hit.t - entered.unwrap_or(0.0);
                entered = None;
            } else {
                entered = Some(hit.t);
            }
            t = hit.t.next_up();
        }
        if let Some(from) = entered {
            inside += t_max - from;
        }
        inside
    }
}

/// Whether the segment may meet box `b` (slab test, the box widened a little so that
/// rounding cannot pass over a crossing).
fn meets(b: crate::math::Aabb, ray: &Ray, t_max: f32) -> bool {
    let margin = 1e-4 * (1.0 + b.min.abs().max(b.max.abs()).max_element());
    let inv = ray.dir.recip();
    let (a, c) = ((b.min - margin - ray.origin) * inv, (b.max + margin - ray.origin) * inv);
    let (near, far) = (a.min(c).max_element(), a.max(c).min_element());
    // NaN (a direction along a face) keeps the box.
    !(near > far || far < 0.0 || near > t_max)
}
