//! Blocks of eight rays (camera rays, or rays sent on from one object) whose hits all lie
//! on one quad, taken straight from the eight-lane tests that found them rather than
//! passed node by node, where each hit's surface, light frame, light and shading were
//! unpacked on their own (about 26 ns a hit):
//! - on a matte quad (a wall, the floor, the ceiling: two thirds of the room's camera
//!   rays), shaded in lanes ([`QuadBlock`]): the room's frame went from 55.2 to 48.8 ms
//!   of CPU time on one thread;
//! - on a perfect mirror, their hits put back and their reflected rays made when their
//!   level sends rays on, past the surface and light passes ([`MirrorBlock`]): 47.1 to
//!   45.6 ms.
//!
//! Each lane performs the operations of the per-node path in the same order
//! ([`crate::geometry::Quad::surface`], `leaving`, [`towards_lanes`], `local`,
//! `reflected`), so the colours, and the ray counts, are the same to the bit.

use super::{Integrator, RayStats, leaving, reflected, towards_light_lanes};
use crate::accel::Best8;
use crate::geometry::{Hit, Shape, part};
use crate::math::{Aabb, Ray, Vec2, Vec3, surface_offset};
use crate::texture::Texture;

/// How hits on an object can be handled eight at a time ([`Integrator::block_kind`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BlockKind {
    /// Node by node.
    None,
    /// Shaded in lanes: [`QuadBlock`].
    Matte,
    /// Reflected ray by ray, past the per-node passes: [`MirrorBlock`].
    Mirror,
}

/// Eight hits on one perfect mirror quad, nodes `node..node + 8` of a tile. Their own
/// share is black and they look at no light, so they skip the per-node passes for
/// surfaces and lights: [`Integrator::mirror_rays`] puts their hits back and sends
/// their reflected rays on.
#[derive(Clone, Debug)]
pub struct MirrorBlock {
    node: u32,
    object: u32,
    t: [f32; 8],
    u: [f32; 8],
    v: [f32; 8],
}

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

    /// The object its eight hits lie on.
    pub fn object(&self) -> u32 {
        self.object
    }
}

/// `parity` of the crate's textures for eight coordinates, as a bit mask, on i32: the
/// same as the scalar one (on i64) where every |t| < 2³¹; `None` elsewhere or for NaN.
#[inline(always)]
fn odd(t: &[f32; 8]) -> Option<u32> {
    let mut fits = true;
    let mut odd = 0u32;
    for (lane, &t) in t.iter().enumerate() {
        fits &= t.abs() < 2_147_483_648.0;
        let i = t as i32;
        let floor = if (i as f32) > t { i.wrapping_sub(1) } else { i };
        odd |= ((floor & 1) as u32) << lane;
    }
    fits.then_some(odd)
}

/// The texels of a solid-space texture at eight points, as [`Texture::color`] finds
/// them, into `base`; `None` for image textures, or where a pattern coordinate is too
/// large for the 32-bit floor taken here ([`odd`]).
#[inline(always)]
fn texels(texture: &Texture, p: &[[f32; 8]; 3], base: &mut [[f32; 8]; 3]) -> Option<()> {
    let odd = match texture {
        Texture::Solid(c) => {
            for (row, c) in base.iter_mut().zip(c.to_array()) {
                *row = [c; 8];
            }
            return Some(());
        }
        Texture::Stripes { axis, width, .. } => {
            let mut t = [0.0; 8];
            for (lane, t) in t.iter_mut().enumerate() {
                *t = ((p[0][lane] * axis.x) + (p[1][lane] * axis.y) + (p[2][lane] * axis.z)) / *width;
            }
            odd(&t)?
        }
        Texture::Checker { size, offset, .. } => {
            let mut odd_all = 0;
            for (row, offset) in p.iter().zip(offset.to_array()) {
                let mut q = [0.0; 8];
                for (q, p) in q.iter_mut().zip(row) {
                    *q = (p + offset) / *size;
                }
                odd_all ^= odd(&q)?;
            }
            odd_all
        }
        Texture::Image { .. } => return None,
    };
    let (Texture::Stripes { colors, .. } | Texture::Checker { colors, .. }) = texture else { return None };
    for (k, row) in base.iter_mut().enumerate() {
        for (lane, x) in row.iter_mut().enumerate() {
            *x = if odd >> lane & 1 != 0 { colors[1][k] } else { colors[0][k] };
        }
    }
    Some(())
}

impl Integrator<'_, '_> {
    /// How hits on object `index` can be handled eight at a time: in a [`QuadBlock`], a
    /// quad whose material sends no rays on, has no highlight, has a diffuse term and a
    /// solid-space texture, shaded two-sided; in a [`MirrorBlock`], a quad that is a
    /// perfect mirror (it reflects all, without a highlight).
    pub fn block_kind(&self, index: u32) -> BlockKind {
        let scene = self.world.scene();
        let object = &scene.objects[index as usize];
        let m = scene.material(object.material);
        if !matches!(object.shape, Shape::Quad(_)) || m.specular > 0.0 || m.transparency != 0.0 {
            return BlockKind::None;
        }
        if m.reflectivity == 1.0 {
            BlockKind::Mirror
        } else if !self.one_sided && m.reflectivity == 0.0 && m.diffuse != 0.0 && !m.texture.uses_uv() {
            BlockKind::Matte
        } else {
            BlockKind::None
        }
    }

    /// The eight `rays` (nodes `node..node + 8`) as a [`MirrorBlock`], when their hits
    /// `hits` all lie on one object of that kind (`kinds`, from [`Integrator::block_kind`]).
    #[inline(always)]
    pub fn mirror_block<T>(
        &self,
        node: u32,
        rays: &[(Ray, T)],
        hits: &Best8,
        kinds: &[BlockKind],
    ) -> Option<MirrorBlock> {
        let object = hits.one_object()?;
        if rays.len() != 8 || kinds.get(object as usize) != Some(&BlockKind::Mirror) {
            return None;
        }
        Some(MirrorBlock { node, object, t: hits.t, u: hits.u, v: hits.v })
    }

    /// The hits of `block` put back into `found`, and the rays they reflect, if the
    /// `depth`-th rays of their chains send rays on, into `sent` (as `send_on` keys them:
    /// the object, slot 0, the node), counted in `stats`: [`Integrator::sent_on`]'s.
    pub fn mirror_rays(
        &self,
        block: &MirrorBlock,
        found: &mut [(Ray, Option<(Hit, u32)>)],
        depth: u32,
        sent: &mut Vec<((u32, u32), u32, Ray)>,
        stats: &mut RayStats,
    ) {
        let object = block.object;
        let Shape::Quad(quad) = &self.world.scene().objects[object as usize].shape else { return };
        let sends = self.sends(object, depth);
        for lane in 0..8 {
            let node = block.node as usize + lane;
            let (ray, hit) = &mut found[node];
            let h = Hit { t: block.t[lane], uv: Vec2::new(block.u[lane], block.v[lane]), part: part::SIDE, prim: 0 };
            *hit = Some((h, object));
            if sends {
                let (side, from) = leaving(ray, &quad.surface(ray, &h));
                stats.reflection += 1;
                sent.push(((object, 0), node as u32, reflected(ray, side, from)));
            }
        }
    }

    /// The eight `rays` (nodes `node..node + 8`) as a [`QuadBlock`], when their hits
    /// `hits` all lie on one object of that kind (`kinds`, from [`Integrator::block_kind`]),
    /// with the box round their hit points `ray.at(t)` (as the per-node path boxes them).
    #[inline(always)]
    #[allow(clippy::needless_range_loop)] // each lane reads and writes several rows
    pub fn quad_block<T>(
        &self,
        node: u32,
        rays: &[(Ray, T)],
        hits: &Best8,
        kinds: &[BlockKind],
    ) -> Option<(QuadBlock, Aabb)> {
        let object = hits.one_object()?;
        if rays.len() != 8 || kinds.get(object as usize) != Some(&BlockKind::Matte) {
            return None;
        }
        let scene = self.world.scene();
        let Shape::Quad(quad) = &scene.objects[object as usize].shape else { return None };
        let material = scene.material(scene.objects[object as usize].material);
        let (c, eu, ev, n) = (quad.corner, quad.edge_u, quad.edge_v, quad.normal());
        let mut b = QuadBlock { node, object, from: [[0.0; 8]; 3], normal: [[0.0; 8]; 3], base: [[0.0; 8]; 3], lit: 0 };
        // `Quad::surface`: `corner + u·edge_u + v·edge_v`.
        let mut point = [[0.0f32; 8]; 3];
        for (k, row) in point.iter_mut().enumerate() {
            for (lane, x) in row.iter_mut().enumerate() {
                *x = (c[k] + hits.u[lane] * eu[k]) + hits.v[lane] * ev[k];
            }
        }
        texels(&material.texture, &point, &mut b.base)?;
        // `Ray::at`: `origin + t·dir`, for the box.
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for (lane, (ray, _)) in rays.iter().enumerate() {
            let p = ray.origin + hits.t[lane] * ray.dir;
            (lo, hi) = (lo.min(p), hi.max(p));
            // `leaving`: the normal on the ray's side, and the point just off the surface.
            let side = if ray.dir.dot(n) < 0.0 { n } else { -n };
            for k in 0..3 {
                b.normal[k][lane] = side[k];
            }
        }
        for lane in 0..8 {
            let offset = surface_offset(Vec3::new(point[0][lane], point[1][lane], point[2][lane]));
            for k in 0..3 {
                b.from[k][lane] = point[k][lane] + offset * b.normal[k][lane];
            }
            let black = b.base[0][lane] == 0.0 && b.base[1][lane] == 0.0 && b.base[2][lane] == 0.0;
            b.lit |= (!black as u32) << lane;
        }
        let bounds = Aabb { min: lo, max: hi };
        Some((b, bounds))
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
                let (seen, color) = (towards_light_lanes(light, &b.from, &b.normal), light.color());
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
                        let add = (s * b.base[k][lane]) * color[k];
                        let on = live >> lane & 1 != 0 && visible[lane] != 0.0;
                        sum[lane] = if on { sum[lane] + add } else { sum[lane] };
                    }
                }
            }
            let share = material.local_share();
            for (sum, base) in diffuse.iter_mut().zip(&b.base) {
                for (x, base) in sum.iter_mut().zip(base) {
                    // `local`'s last step, whose highlight here is +0.
                    *x = share * ((self.ambient * base) + *x) + 0.0;
                }
            }
            colors.push(diffuse);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{Color, Vec2};

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
                let mut got = [[0.0; 8]; 3];
                texels(texture, &p, &mut got).expect("points in range");
                for lane in 0..8 {
                    let point = Vec3::new(p[0][lane], p[1][lane], p[2][lane]);
                    let want = texture.color(point, Vec2::ZERO);
                    assert_eq!([got[0][lane], got[1][lane], got[2][lane]], want.to_array(), "{texture:?} at {point}");
                }
            }
        }
        // Beyond 2³¹ bands, or NaN, the lanes decline: the per-node path shades those.
        let (far, base) = ([[3e9; 8], [0.0; 8], [0.0; 8]], &mut [[0.0; 8]; 3]);
        assert!(texels(&textures[1], &far, base).is_none() && texels(&textures[2], &far, base).is_none());
        assert!(texels(&textures[2], &[[f32::NAN; 8], [0.0; 8], [0.0; 8]], base).is_none());
        assert!(texels(&textures[0], &far, base).is_some());
    }
}
