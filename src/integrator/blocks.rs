//! Blocks of eight camera rays whose hits all lie on one matte quad (a wall, the floor,
//! the ceiling: two thirds of the room's camera rays), shaded in lanes straight from the
//! hits the eight-lane tests found. Through the per-node passes such a hit cost about
//! 26 ns (its surface, light frame, light and shading each unpacked on its own); in
//! lanes the work is a few vector operations per block.
//!
//! Each lane performs the operations of the per-node path in the same order
//! ([`crate::geometry::Quad::surface`], `leaving`, [`towards_lanes`], `local`), so the
//! colours, and the ray counts, are the same to the bit.

use super::{Integrator, RayStats, towards_lanes};
use crate::accel::Best8;
use crate::geometry::Shape;
use crate::math::{Aabb, Color, Ray, Vec3};
use crate::texture::Texture;

/// Eight hits on one quad, nodes `node..node + 8` of a tile, ready to be lit: where
/// their shadow rays leave from, the normal on the rays' side, and the texel.
#[derive(Clone, Debug)]
pub struct QuadBlock {
    node: u32,
    object: u32,
    from: [[f32; 8]; 3],
    normal: [[f32; 8]; 3],
    base: [[f32; 8]; 3],
    /// The lanes whose texel is not black: only they look at the lights, as in `local`.
    lit: u32,
}

impl QuadBlock {
    /// The block's first node.
    pub fn node(&self) -> usize {
        self.node as usize
    }
}

/// A row of eight: lane by lane, `f(lane)`.
#[inline(always)]
fn lanes(f: impl FnMut(usize) -> f32) -> [f32; 8] {
    std::array::from_fn(f)
}

/// The texels of a solid-space texture at eight points, as [`Texture::color`] finds
/// them; `None` for image textures, or where a pattern coordinate is too large for
/// the 32-bit floor taken here (the scalar one is 64-bit).
#[inline(always)]
fn texels(texture: &Texture, p: &[[f32; 8]; 3]) -> Option<[[f32; 8]; 3]> {
    let pick = |odd: [bool; 8], colors: &[Color; 2]| {
        std::array::from_fn(|c| lanes(|lane| if odd[lane] { colors[1][c] } else { colors[0][c] }))
    };
    // `parity` of the crate's textures, on i32: the same for |t| < 2³¹, false for NaN.
    let fits = |t: &[f32; 8]| t.iter().all(|t| t.abs() < 2_147_483_648.0);
    let odd = |t: [f32; 8]| -> [bool; 8] {
        std::array::from_fn(|lane| {
            let i = t[lane] as i32;
            let floor = if (i as f32) > t[lane] { i.wrapping_sub(1) } else { i };
            floor & 1 != 0
        })
    };
    match texture {
        Texture::Solid(c) => Some(std::array::from_fn(|k| [c[k]; 8])),
        Texture::Stripes { axis, width, colors } => {
            let t = lanes(|lane| ((p[0][lane] * axis.x) + (p[1][lane] * axis.y) + (p[2][lane] * axis.z)) / *width);
            fits(&t).then(|| pick(odd(t), colors))
        }
        Texture::Checker { size, offset, colors } => {
            let q: [[f32; 8]; 3] = std::array::from_fn(|k| lanes(|lane| (p[k][lane] + offset[k]) / *size));
            if !q.iter().all(fits) {
                return None;
            }
            let [x, y, z] = q.map(odd);
            Some(pick(std::array::from_fn(|lane| x[lane] ^ y[lane] ^ z[lane]), colors))
        }
        Texture::Image { .. } => None,
    }
}

impl Integrator<'_, '_> {
    /// Whether hits on object `index` can be shaded in a [`QuadBlock`]: a quad whose
    /// material sends no rays on, has no highlight, has a diffuse term and a solid-space
    /// texture, shaded two-sided.
    pub fn lane_shaded(&self, index: u32) -> bool {
        let scene = self.world.scene();
        let object = &scene.objects[index as usize];
        let m = scene.material(object.material);
        !self.one_sided
            && matches!(object.shape, Shape::Quad(_))
            && m.reflectivity == 0.0
            && m.transparency == 0.0
            && !(m.specular > 0.0)
            && m.diffuse != 0.0
            && !m.texture.uses_uv()
    }

    /// The eight `rays` (nodes `node..node + 8`) as a [`QuadBlock`], when their hits
    /// `hits` all lie on one object that `shaded` marks ([`Integrator::lane_shaded`]),
    /// with the box round their hit points `ray.at(t)` (as the per-node path boxes them).
    #[inline(always)]
    pub fn quad_block<T>(
        &self,
        node: u32,
        rays: &[(Ray, T)],
        hits: &Best8,
        shaded: &[bool],
    ) -> Option<(QuadBlock, Aabb)> {
        let object = hits.index[0];
        if rays.len() != 8 || hits.index.iter().any(|&i| i != object) || !shaded.get(object as usize).copied()? {
            return None;
        }
        let scene = self.world.scene();
        let Shape::Quad(quad) = &scene.objects[object as usize].shape else { return None };
        let material = scene.material(scene.objects[object as usize].material);
        let (c, eu, ev) = (quad.corner, quad.edge_u, quad.edge_v);
        let n = quad.normal();
        let (o, d): ([[f32; 8]; 3], [[f32; 8]; 3]) = (
            std::array::from_fn(|k| lanes(|lane| rays[lane].0.origin[k])),
            std::array::from_fn(|k| lanes(|lane| rays[lane].0.dir[k])),
        );
        // `Quad::surface`: `corner + u·edge_u + v·edge_v`.
        let point: [[f32; 8]; 3] =
            std::array::from_fn(|k| lanes(|lane| (c[k] + hits.u[lane] * eu[k]) + hits.v[lane] * ev[k]));
        let base = texels(&material.texture, &point)?;
        // `leaving`: the normal on the ray's side, and the point just off the surface.
        let away: [bool; 8] =
            std::array::from_fn(|lane| ((d[0][lane] * n.x) + (d[1][lane] * n.y) + (d[2][lane] * n.z)) < 0.0);
        let normal: [[f32; 8]; 3] = std::array::from_fn(|k| lanes(|lane| if away[lane] { n[k] } else { -n[k] }));
        let offset = lanes(|lane| {
            let max = |a: f32, b: f32| if a > b { a } else { b };
            1e-4 * (1.0 + max(max(point[0][lane].abs(), point[1][lane].abs()), point[2][lane].abs()))
        });
        let from = std::array::from_fn(|k| lanes(|lane| point[k][lane] + offset[lane] * normal[k][lane]));
        let lit = (0..8).fold(0u32, |lit, lane| lit | ((base.iter().any(|row| row[lane] != 0.0) as u32) << lane));
        // `Ray::at`: `origin + t·dir`.
        let at: [[f32; 8]; 3] = std::array::from_fn(|k| lanes(|lane| o[k][lane] + hits.t[lane] * d[k][lane]));
        let (lo, hi) = (
            at.map(|r| r.into_iter().fold(f32::INFINITY, f32::min)),
            at.map(|r| r.into_iter().fold(f32::NEG_INFINITY, f32::max)),
        );
        let bounds = Aabb { min: Vec3::from(lo), max: Vec3::from(hi) };
        Some((QuadBlock { node, object, from, normal, base, lit }, bounds))
    }

    /// The colours of `blocks`, lit by every light, eight to a block, appended to
    /// `colors`: the shadow rays to light `i` tested against `blockers[i]` where given
    /// (as in [`Integrator::look_at_light`]), and counted in `stats`.
    pub fn shade_blocks(
        &self,
        blocks: &[QuadBlock],
        blockers: &[Option<Vec<u32>>],
        colors: &mut Vec<[[f32; 8]; 3]>,
        stats: &mut RayStats,
    ) {
        let scene = self.world.scene();
        for b in blocks {
            let material = scene.material(scene.objects[b.object as usize].material);
            let mut diffuse = [[0.0f32; 8]; 3];
            for (i, light) in scene.lights.iter().enumerate() {
                let seen = towards_lanes(light.position, &b.from, &b.normal);
                let mut live = 0u32;
                for lane in 0..8 {
                    live |= ((seen.n_dot_l[lane] > 0.0) as u32) << lane;
                }
                live &= b.lit;
                stats.shadow += live.count_ones() as u64;
                let visible = self.visible_lanes(blockers.get(i).and_then(|b| b.as_deref()), &b.from, &seen, live);
                for (k, sum) in diffuse.iter_mut().enumerate() {
                    for lane in 0..8 {
                        // `local`: lanes behind the surface, black or in full shadow add nothing.
                        let s = (visible[lane] * material.diffuse) * seen.n_dot_l[lane];
                        let add = (s * b.base[k][lane]) * light.color[k];
                        let on = live >> lane & 1 != 0 && visible[lane] != 0.0;
                        sum[lane] = if on { sum[lane] + add } else { sum[lane] };
                    }
                }
            }
            let share = material.local_share();
            colors.push(std::array::from_fn(|k| {
                lanes(|lane| share * ((self.ambient * b.base[k][lane]) + diffuse[k][lane]) + 0.0)
            }));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec2;

    #[test]
    fn texels_in_lanes_are_the_textures_colours() {
        let colors = [Color::new(1.0, 1.0, 0.5), Color::new(0.0, 1.0, 0.0)];
        let textures = [
            Texture::Solid(Color::new(0.2, 0.4, 0.6)),
            Texture::Stripes { axis: Vec3::new(0.6, 0.0, 0.8), width: 0.7, colors },
            Texture::Checker { size: 0.5, offset: Vec3::new(0.0, 0.25, 0.0), colors },
        ];
        let mut r = crate::sampler::Rng::new(9);
        for round in 0..4000 {
            // Points on band edges (whole multiples) as well as between them.
            let scale = [3.0, 40.0, 1e6][round % 3];
            let mut p = [[0.0f32; 8]; 3];
            for lane in 0..8 {
                for row in &mut p {
                    let x = (r.next_f32() - 0.5) * scale;
                    row[lane] = if lane % 3 == 0 { (x * 2.0).round() * 0.5 } else { x };
                }
            }
            for texture in &textures {
                let got = texels(texture, &p).expect("points in range");
                for lane in 0..8 {
                    let point = Vec3::new(p[0][lane], p[1][lane], p[2][lane]);
                    let want = texture.color(point, Vec2::ZERO);
                    assert_eq!([got[0][lane], got[1][lane], got[2][lane]], want.to_array(), "{texture:?} at {point}");
                }
            }
        }
        // Beyond 2³¹ bands, or NaN, the lanes decline: the per-node path shades those.
        let far = [[3e9; 8], [0.0; 8], [0.0; 8]];
        assert!(texels(&textures[1], &far).is_none() && texels(&textures[2], &far).is_none());
        assert!(texels(&textures[2], &[[f32::NAN; 8], [0.0; 8], [0.0; 8]]).is_none());
        assert!(texels(&textures[0], &far).is_some());
    }
}
