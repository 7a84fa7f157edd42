//! Shadows through absorbing glass: the light that gets through takes the glass's
//! colour, by the length of the shadow ray inside it (Beer–Lambert).

use super::World;
use crate::material::beer_lambert;
use crate::math::{Color, Ray};

/// Crossings of absorbing surfaces looked at along one shadow ray at most (a closed
/// shape is crossed twice): the rest pass as clear glass.
const MAX_CROSSINGS: usize = 64;

impl World<'_> {
    /// Whether any object absorbs light inside it.
    #[inline]
    pub fn absorbs(&self) -> bool {
        !self.absorbing.is_empty()
    }

    /// [`World::transmittance`] as a colour: times what absorbing glass lets through
    /// along the segment, by the rule rays follow ([`crate::integrator::Integrator::arriving`]):
    /// where the segment leaves an absorbing surface (meets it from the inside), the
    /// stretch since the last absorbing surface it crossed (or its start) was inside
    /// that material. So a box of six absorbing quads absorbs as a closed solid does.
    pub fn transmittance_color(&self, ray: &Ray, t_max: f32) -> Color {
        let light = self.transmittance(ray, t_max);
        if light == 0.0 || self.absorbing.is_empty() {
            return Color::splat(light);
        }
        // The crossings of absorbing surfaces: distance, whether leaving, object.
        let mut crossings = [(0f32, false, 0u32); MAX_CROSSINGS];
        let mut n = 0;
        for &i in &self.absorbing {
            let shape = &self.scene.objects[i as usize].shape;
            if !meets(shape.bounds(), ray, t_max) {
                continue;
            }
            let mut t = 0.0f32;
            while n < MAX_CROSSINGS {
                let Some(hit) = self.intersect_object(i as usize, ray, t, t_max) else { break };
                crossings[n] = (hit.t, ray.dir.dot(shape.surface(ray, &hit).normal) > 0.0, i);
                n += 1;
                t = hit.t.next_up();
            }
        }
        let crossings = &mut crossings[..n];
        crossings.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        let (mut color, mut since) = (Color::splat(light), 0.0f32);
        for &(t, leaving, i) in crossings.iter() {
            if leaving {
                let material = self.scene.material(self.scene.objects[i as usize].material);
                color *= beer_lambert(material.absorption, t - since);
            }
            since = t;
        }
        color
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
