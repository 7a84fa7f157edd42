//! The Whitted integrator: local Phong shading from every light with shadows that pass
//! through transparent objects, plus mirror reflection and transmission (straight
//! through, bent by Snell's law, or totally reflected).
//!
//! One ray's way: [`Wave`] takes a batch of camera rays level by level (every ray of a
//! level asks the [`World`] for its hit together with the others, so the acceleration
//! structure can answer them as a batch), and past a per-sample budget a ray's subtree
//! is traced depth first by [`Integrator::trace_path`]. Both shade a hit with the same
//! three steps, [`Integrator::shading`], [`Integrator::add_light`] per light and
//! [`Integrator::own_color`], and send rays on with [`Integrator::scatter`]. Colours
//! flow forward: each ray carries the share of its sample's colour it brings back
//! (its weight), so nothing waits for its children and memory does not grow with depth.

mod stats;
mod wave;

pub use stats::RayStats;
pub use wave::{PER_SAMPLE, WAVE_RAYS, Wave};

use crate::accel::World;
use crate::geometry::{Hit, Surface};
use crate::light::Light;
use crate::material::{Material, beer_lambert, fresnel_reflectance};
use crate::math::{Color, Ray, Vec2, Vec3, reflect, refract, surface_offset};
use glam::Vec4;

/// The index of refraction of the space between objects.
pub const OUTSIDE_IOR: f32 = 1.0;

/// Traces rays through a [`World`].
#[derive(Clone, Copy, Debug)]
pub struct Integrator<'w, 's> {
    world: &'w World<'s>,
    max_depth: u32,
    background: Color,
    ambient: f32,
    one_sided: bool,
    cutoff: f32,
}

/// A ray on its way: the share of its sample's colour it brings back (`weight`, the
/// product of the reflected and transmitted shares along its chain) and its place in
/// the chain (the camera ray is 1).
#[derive(Clone, Copy, Debug)]
pub struct Path {
    pub ray: Ray,
    pub weight: Color,
    pub depth: u32,
}

impl Path {
    pub fn camera(ray: Ray) -> Path {
        Path { ray, weight: Color::ONE, depth: 1 }
    }
}

/// How a ray continues from a hit ([`Integrator::scatter`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sent {
    Reflected,
    Refracted,
    TotalInternalReflection,
}

/// A hit being shaded: what the lights need, found once, and the light gathered so
/// far ([`Integrator::shading`], [`Integrator::add_light`]).
#[derive(Clone, Copy, Debug, Default)]
pub struct Shading {
    /// The surface's colour there (texture looked up).
    pub base: Color,
    /// Where shadow rays leave from: just off the surface on the ray's side.
    pub from: Vec3,
    /// The normal lights are judged by.
    pub n: Vec3,
    /// Whether lights can change the colour (else no shadow rays are needed).
    pub lit: bool,
    /// Whether the surface shows anything of its own (a perfect mirror does not).
    pub own: bool,
    pub diffuse: Color,
    pub specular: Color,
}

impl<'w, 's> Integrator<'w, 's> {
    pub fn new(world: &'w World<'s>, max_depth: u32) -> Self {
        let s = &world.scene().settings;
        Integrator {
            world,
            max_depth,
            background: s.background,
            ambient: s.ambient,
            one_sided: false,
            cutoff: s.cutoff,
        }
    }

    /// Shade opaque surfaces one-sided, as the SPD benchmark allows (its rule 2): with
    /// their own normal even when seen from behind, so their back is lit only by lights
    /// behind it, and a light is skipped without a shadow ray whenever that normal faces
    /// away from it (rule 10). Transmitting surfaces stay two-sided. Off by default:
    /// every surface is then shaded from the side the ray arrives on.
    pub fn one_sided(mut self, on: bool) -> Self {
        self.one_sided = on;
        self
    }

    /// Rays whose share of their pixel (largest channel) falls below `cutoff` are not
    /// followed; 0 follows every ray to the depth limit.
    pub fn cutoff(mut self, cutoff: f32) -> Self {
        self.cutoff = cutoff;
        self
    }

    pub fn world(&self) -> &'w World<'s> {
        self.world
    }

    pub fn background(&self) -> Color {
        self.background
    }

    #[inline(always)]
    fn material(&self, index: u32) -> &'s Material {
        self.world.material(index)
    }

    /// The colour seen along a camera ray.
    pub fn trace_primary(&self, ray: &Ray, stats: &mut RayStats) -> Color {
        stats.primary += 1;
        self.trace_path(Path::camera(*ray), &mut Vec::new(), stats)
    }

    /// The colour seen along `ray`, the `depth`-th ray of its chain.
    pub fn trace(&self, ray: &Ray, depth: u32, stats: &mut RayStats) -> Color {
        self.trace_path(Path { ray: *ray, weight: Color::ONE, depth }, &mut Vec::new(), stats)
    }

    /// The colour `path` brings back, weight included: its ray and every ray it sends
    /// on, one at a time, depth first. `stack` holds the rays waiting (at most one per
    /// level beyond the first): no recursion, so no depth limit or index of refraction
    /// can overflow the thread's stack.
    pub fn trace_path(&self, path: Path, stack: &mut Vec<Path>, stats: &mut RayStats) -> Color {
        let lights = &self.world.scene().lights;
        let mut color = Color::ZERO;
        let bottom = stack.len();
        stack.push(path);
        while stack.len() > bottom {
            let p = stack.pop().expect("above bottom");
            let Some((hit, index)) = self.world.closest(&p.ray, 0.0, f32::INFINITY) else {
                color += p.weight * self.background;
                continue;
            };
            let surface = self.surface(&p.ray, &hit, index).get();
            let material = self.material(index);
            let p = Path { weight: self.arriving(p.weight, &p.ray, hit.t, &surface, index), ..p };
            let mut shading = self.shading(&p.ray, &surface, index);
            if shading.lit {
                for light in lights {
                    let (l, distance, n_dot_l) = towards_light(light, shading.from, shading.n);
                    let falloff = if n_dot_l > 0.0 { light.falloff(l, distance) } else { 0.0 };
                    if falloff > 0.0 {
                        stats.shadow += 1;
                        let visible = self.world.transmittance_color(&Ray { origin: shading.from, dir: l }, distance);
                        self.add_light(
                            &mut shading,
                            material,
                            p.ray.dir,
                            (l, n_dot_l, visible * falloff),
                            light.color(),
                        );
                    }
                }
            }
            color += p.weight * self.own_color(&shading, material);
            // The transmitted ray waits under the reflected one, which goes first.
            let [r, t] = self.scatter(&p, &surface, index);
            for (child, kind) in [t, r].into_iter().flatten() {
                stats.count(kind);
                stack.push(child);
            }
        }
        color
    }

    /// The surface that shading sees where `ray` hit object `index`. Inlined (always):
    /// called, it was 5 % of a room render on its own, its answer returned through memory.
    #[inline(always)]
    pub fn surface(&self, ray: &Ray, hit: &Hit, index: u32) -> PackedSurface {
        let shape = &self.world.scene().objects[index as usize].shape;
        shape.surface_as(ray, hit, self.material(index).texture.uses_uv())
    }

    /// Step one of shading a hit of `ray` on object `index` at `surface`: the colour
    /// there, where shadow rays leave from and the normal lights are judged by.
    #[inline(always)]
    pub fn shading(&self, ray: &Ray, surface: &Surface, index: u32) -> Shading {
        let material = self.material(index);
        let (side, from) = leaving(ray, surface);
        let n = if self.one_sided && material.transparency == 0.0 { surface.normal } else { side };
        // A surface with no own share and no highlight (a perfect mirror) shows nothing
        // the lights could change: no texture lookup, no shadow rays.
        let own = material.local_share() != 0.0 || material.specular > 0.0;
        if !own {
            return Shading { from, n, ..Shading::default() };
        }
        let base = material.texture.color(surface.point, surface.uv);
        // Lights act through the diffuse term and the highlight only: a black texel
        // without a highlight needs no shadow rays.
        let lit = material.specular > 0.0 || (base != Color::ZERO && material.diffuse != 0.0);
        Shading { base, from, n, lit, own, diffuse: Color::ZERO, specular: Color::ZERO }
    }

    /// Step two, once per light in front of the surface: its diffuse term and highlight,
    /// given its unit direction `l`, the cosine `n_dot_l` (positive) and the share of it
    /// that reaches the surface (`visible`: what its shadow ray lets through, coloured
    /// by absorbing glass, times the light's falloff: [`Light::falloff`]), and the
    /// light's colour ([`Light::color`], taken once per light by the caller).
    #[inline(always)]
    pub fn add_light(
        &self,
        shading: &mut Shading,
        material: &Material,
        view: Vec3,
        (l, n_dot_l, visible): (Vec3, f32, Color),
        light_color: Color,
    ) {
        if visible == Color::ZERO {
            return;
        }
        shading.diffuse += (visible * material.diffuse * n_dot_l) * shading.base * light_color;
        if material.specular > 0.0 {
            let r_dot_v = reflect(-l, shading.n).dot(-view);
            if r_dot_v > 0.0 {
                shading.specular += (visible * material.specular * r_dot_v.powf(material.shininess)) * light_color;
            }
        }
    }

    /// Step three: the hit's own colour, `(1 − ρ − τ)·(ambient + diffuse) + specular`,
    /// the original's blending rules (ρ reflectivity, τ transparency); the highlight is
    /// added last, unscaled, as in the original. What the reflected and transmitted
    /// rays bring comes through their weights ([`Integrator::scatter`]).
    #[inline(always)]
    pub fn own_color(&self, shading: &Shading, material: &Material) -> Color {
        if !shading.own {
            return Color::ZERO;
        }
        material.local_share() * (self.ambient * shading.base + shading.diffuse) + shading.specular
    }

    /// The weight of a ray `weight` as it arrives at its hit at distance `t`: less what
    /// absorbing glass took on the way, where the ray hits the inside of an absorbing
    /// object (so travelled through it: Beer–Lambert over `t`). Objects are taken as
    /// not nested: what a ray crosses inside one glass object is not looked at.
    #[inline(always)]
    pub fn arriving(&self, weight: Color, ray: &Ray, t: f32, surface: &Surface, index: u32) -> Color {
        // One test for a scene without absorbing glass, not three per hit.
        if !self.world.absorbs() {
            return weight;
        }
        let material = self.material(index);
        if !material.absorbs() || ray.dir.dot(surface.normal) <= 0.0 {
            return weight;
        }
        weight * beer_lambert(material.absorption, t)
    }

    /// Whether a hit on object `index` by the `depth`-th ray of a chain sends rays on.
    #[inline]
    pub fn sends(&self, index: u32, depth: u32) -> bool {
        let material = self.material(index);
        depth < self.max_depth && (material.reflectivity > 0.0 || material.transparency > 0.0)
    }

    /// The rays a hit of `path` on object `index` (at `surface`) sends on, reflected
    /// and transmitted, each with its weight: the path's times the material's share.
    /// A ray whose weight falls below the cutoff, or past the depth limit, is not sent.
    ///
    /// Inlined: called, its two-slot answer went through memory written in pieces and
    /// read back wider, which stalls store forwarding (about 7 % of a room render).
    #[inline(always)]
    pub fn scatter(&self, path: &Path, surface: &Surface, index: u32) -> [Option<(Path, Sent)>; 2] {
        if !self.sends(index, path.depth) {
            return [None, None];
        }
        let material = self.material(index);
        let depth = path.depth + 1;
        let worth = |w: Color| !(w.max_element() < self.cutoff);
        // With `fresnel`, the transmitted share is split by the Fresnel reflectance.
        let (reflectivity, transparency) = if material.fresnel && material.transparency > 0.0 {
            let cos = path.ray.dir.dot(surface.normal);
            let (from, to) = if cos < 0.0 { (OUTSIDE_IOR, material.ior) } else { (material.ior, OUTSIDE_IOR) };
            material.split(fresnel_reflectance(cos, from, to))
        } else {
            (material.reflectivity, material.transparency)
        };
        let reflected = (reflectivity > 0.0).then(|| path.weight * reflectivity).filter(|&w| worth(w)).map(|weight| {
            let (side, from) = leaving(&path.ray, surface);
            (Path { ray: reflected(&path.ray, side, from), weight, depth }, Sent::Reflected)
        });
        let transmitted =
            (transparency > 0.0).then(|| path.weight * transparency).filter(|&w| worth(w)).map(|weight| {
                let (ray, kind) = transmitted_ray(&path.ray, surface, material.ior);
                let kind = match kind {
                    Transmission::Refracted => Sent::Refracted,
                    Transmission::TotalInternalReflection => Sent::TotalInternalReflection,
                };
                (Path { ray, weight, depth }, kind)
            });
        [reflected, transmitted]
    }
}

/// A [`Surface`] as two 4-lane vectors, so that it is stored whole from registers: a
/// `Surface` written to a buffer was first assembled piece by piece on the stack and
/// then copied 16 bytes at a time, which stalls store forwarding (a tenth of a frame).
#[derive(Clone, Copy, Debug, Default)]
pub struct PackedSurface([Vec4; 2]);

impl From<Surface> for PackedSurface {
    #[inline(always)]
    fn from(s: Surface) -> Self {
        let (p, n, uv) = (s.point, s.normal, s.uv);
        PackedSurface([Vec4::new(p.x, p.y, p.z, n.x), Vec4::new(n.y, n.z, uv.x, uv.y)])
    }
}

impl PackedSurface {
    #[inline(always)]
    pub fn get(&self) -> Surface {
        let [a, b] = self.0;
        Surface { point: a.truncate(), normal: Vec3::new(a.w, b.x, b.y), uv: Vec2::new(b.z, b.w) }
    }
}

/// The hits of one level of a [`Wave`] that lights may change, eight to a block, lane
/// by lane (the layout [`towards_lanes`] reads): per block, the hits' indices in the
/// level, the objects they are on ([`crate::accel::NONE`] in the lanes past the last),
/// where their shadow rays leave from and the normals lights are judged by.
#[derive(Clone, Debug, Default)]
pub struct LightFrames {
    /// Hits pushed so far.
    len: usize,
    blocks: Vec<FrameBlock>,
}

/// Eight hits of [`LightFrames`], lane by lane: one block, so that a hit is added with
/// one bounds check rather than one per array, and its lanes are read without any.
#[derive(Clone, Copy, Debug)]
pub struct FrameBlock {
    /// The hits' indices in the level (the lanes past `lanes` unused).
    pub nodes: [u32; 8],
    /// Lanes in use, 1 to 8.
    pub lanes: usize,
    pub objects: [u32; 8],
    pub from: [[f32; 8]; 3],
    pub normal: [[f32; 8]; 3],
}

impl FrameBlock {
    const EMPTY: FrameBlock = FrameBlock {
        nodes: [0; 8],
        lanes: 0,
        objects: [crate::accel::NONE; 8],
        from: [[0.0; 8]; 3],
        normal: [[0.0; 8]; 3],
    };
}

impl LightFrames {
    pub fn clear(&mut self) {
        self.len = 0;
        self.blocks.clear();
    }

    #[inline(always)]
    pub fn push(&mut self, node: u32, object: u32, (from, normal): (Vec3, Vec3)) {
        let lane = self.len % 8;
        if lane == 0 {
            self.blocks.push(FrameBlock::EMPTY);
        }
        let block = self.blocks.last_mut().expect("pushed");
        (block.nodes[lane], block.objects[lane], block.lanes) = (node, object, lane + 1);
        for (axis, (a, b)) in from.to_array().into_iter().zip(normal.to_array()).enumerate() {
            (block.from[axis][lane], block.normal[axis][lane]) = (a, b);
        }
        self.len += 1;
    }

    /// The hits eight at a time.
    pub fn blocks(&self) -> &[FrameBlock] {
        &self.blocks
    }
}

/// Lane `lane` of three rows of eight.
#[inline(always)]
fn lane_of(rows: &[[f32; 8]; 3], lane: usize) -> Vec3 {
    Vec3::new(rows[0][lane], rows[1][lane], rows[2][lane])
}

/// `towards` for eight points and normals, lane by lane.
#[derive(Clone, Copy, Debug, Default)]
pub struct Towards8 {
    pub l: [[f32; 8]; 3],
    pub distance: [f32; 8],
    pub n_dot_l: [f32; 8],
}

/// `towards` for eight points `from` and normals `n`, lane by lane: glam's operations
/// in glam's order, so each lane is bit-identical to `towards`, written on plain
/// arrays so that the compiler computes the lanes together (one hit at a time, each
/// square root and division waited for the one before).
#[inline]
pub fn towards_lanes(light: Vec3, from: &[[f32; 8]; 3], n: &[[f32; 8]; 3]) -> Towards8 {
    let mut out = Towards8::default();
    for lane in 0..8 {
        let to = [light.x - from[0][lane], light.y - from[1][lane], light.z - from[2][lane]];
        let distance = ((to[0] * to[0]) + (to[1] * to[1]) + (to[2] * to[2])).sqrt();
        let l = [to[0] / distance, to[1] / distance, to[2] / distance];
        out.n_dot_l[lane] = (n[0][lane] * l[0]) + (n[1][lane] * l[1]) + (n[2][lane] * l[2]);
        out.distance[lane] = distance;
        for (row, l) in out.l.iter_mut().zip(l) {
            row[lane] = l;
        }
    }
    out
}

/// [`towards_lanes`] for any light: a light with a position as there (bit for bit),
/// a directional one with [`Light::toward`] lane by lane. Cone and attenuation are
/// not applied here (see [`Light::falloff`]).
#[inline]
pub fn towards_light_lanes(light: &Light, from: &[[f32; 8]; 3], n: &[[f32; 8]; 3]) -> Towards8 {
    if let Some(position) = light.position() {
        return towards_lanes(position, from, n);
    }
    let mut out = Towards8::default();
    for lane in 0..8 {
        let (l, distance) = light.toward(lane_of(from, lane));
        out.n_dot_l[lane] = lane_of(n, lane).dot(l);
        out.distance[lane] = distance;
        for (row, l) in out.l.iter_mut().zip(l.to_array()) {
            row[lane] = l;
        }
    }
    out
}

/// [`towards`] for any light: a light with a position as there (bit for bit), a
/// directional one with [`Light::toward`].
#[inline(always)]
fn towards_light(light: &Light, from: Vec3, n: Vec3) -> (Vec3, f32, f32) {
    match light.position() {
        Some(position) => towards(position, from, n),
        None => {
            let (l, distance) = light.toward(from);
            (l, distance, n.dot(l))
        }
    }
}

/// Direction and distance to `light` from `from`, and the cosine with normal `n`.
#[inline(always)]
fn towards(light: Vec3, from: Vec3, n: Vec3) -> (Vec3, f32, f32) {
    let to_light = light - from;
    let distance = to_light.length();
    let l = to_light / distance;
    (l, distance, n.dot(l))
}

/// The normal on the ray's side of the surface, and the point just off the surface on
/// that side, where reflected and shadow rays leave from.
#[inline(always)]
fn leaving(ray: &Ray, surface: &Surface) -> (Vec3, Vec3) {
    use glam::Vec3A;
    let (d, n, p) = (Vec3A::from(ray.dir), Vec3A::from(surface.normal), Vec3A::from(surface.point));
    let side = if d.dot(n) < 0.0 { n } else { -n };
    (side.into(), (p + surface_offset(p) * side).into())
}

#[inline(always)]
fn reflected(ray: &Ray, side: Vec3, lit_from: Vec3) -> Ray {
    Ray { origin: lit_from, dir: reflect(ray.dir, side) }
}

/// How a ray continued through a transparent surface.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transmission {
    Refracted,
    TotalInternalReflection,
}

/// The ray that continues through a transparent surface of index `ior` hit by `ray`.
///
/// Whether the ray enters or leaves is read from the outward normal: entering it goes
/// from [`OUTSIDE_IOR`] into `ior`, leaving it goes from `ior` back to the outside (the
/// original passed the index as an integer and bent exiting rays as if entering again).
/// Past the critical angle the ray is reflected instead. With `ior` 1 the direction is
/// kept exactly: plain transparency.
///
/// Inlined always, as [`crate::texture::ImageMap::sample`] is, for the same reason.
#[inline(always)]
pub fn transmitted_ray(ray: &Ray, surface: &Surface, ior: f32) -> (Ray, Transmission) {
    let entering = ray.dir.dot(surface.normal) < 0.0;
    let n: Vec3 = if entering { surface.normal } else { -surface.normal };
    let offset = surface_offset(surface.point) * n;
    if ior == OUTSIDE_IOR {
        return (Ray { origin: surface.point - offset, dir: ray.dir }, Transmission::Refracted);
    }
    let eta = if entering { OUTSIDE_IOR / ior } else { ior / OUTSIDE_IOR };
    match refract(ray.dir, n, eta) {
        Some(dir) => (Ray { origin: surface.point - offset, dir }, Transmission::Refracted),
        None => {
            (Ray { origin: surface.point + offset, dir: reflect(ray.dir, n) }, Transmission::TotalInternalReflection)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn light_directions_eight_at_a_time_are_those_one_at_a_time() {
        let mut r = crate::sampler::Rng::new(3);
        let mut v = |scale: f32| Vec3::new(r.next_f32() - 0.5, r.next_f32() - 0.5, r.next_f32() - 0.5) * scale;
        for _ in 0..2000 {
            let light = v(40.0);
            let (points, normals): (Vec<Vec3>, Vec<Vec3>) = (0..8).map(|_| (v(30.0), v(2.0).normalize())).unzip();
            let rows = |p: &[Vec3]| std::array::from_fn(|axis| std::array::from_fn(|lane| p[lane][axis]));
            let got = towards_lanes(light, &rows(&points), &rows(&normals));
            for lane in 0..8 {
                let (l, distance, n_dot_l) = towards(light, points[lane], normals[lane]);
                let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                assert_eq!(bits(lane_of(&got.l, lane)), bits(l));
                assert_eq!(
                    (got.distance[lane].to_bits(), got.n_dot_l[lane].to_bits()),
                    (distance.to_bits(), n_dot_l.to_bits())
                );
            }
        }
    }
    use crate::accel::{AccelKind, World};
    use crate::camera::Camera;
    use crate::geometry::{Quad, Shape, Sphere};
    use crate::light::PointLight;
    use crate::material::Material;
    use crate::scene::Scene;

    fn shape_surface(shape: &Shape, ray: &Ray) -> Surface {
        let hit = shape.intersect(ray, 0.0, f32::INFINITY).expect("ray should hit");
        shape.surface(ray, &hit)
    }

    /// A glass slab between z = 0 and z = -1, outward normals +z and -z.
    fn slab() -> (Shape, Shape) {
        let top =
            Shape::Quad(Quad::new(Vec3::new(-10.0, -10.0, 0.0), Vec3::new(20.0, 0.0, 0.0), Vec3::new(0.0, 20.0, 0.0)));
        let bottom =
            Shape::Quad(Quad::new(Vec3::new(-10.0, -10.0, -1.0), Vec3::new(0.0, 20.0, 0.0), Vec3::new(20.0, 0.0, 0.0)));
        (top, bottom)
    }

    #[test]
    fn ray_through_glass_slab_leaves_parallel_to_incoming() {
        let (top, bottom) = slab();
        let incoming = Ray::new(Vec3::new(0.0, 0.0, 5.0), Vec3::new(0.6, 0.0, -1.0));
        let (inside, kind) = transmitted_ray(&incoming, &shape_surface(&top, &incoming), 1.5);
        assert_eq!(kind, Transmission::Refracted);
        // Bent towards the normal inside the glass.
        assert!(inside.dir.x < incoming.dir.x * 0.9, "{:?}", inside.dir);
        let (out, kind) = transmitted_ray(&inside, &shape_surface(&bottom, &inside), 1.5);
        assert_eq!(kind, Transmission::Refracted);
        assert!((out.dir - incoming.dir).length() < 1e-5, "{:?} vs {:?}", out.dir, incoming.dir);
        // ...and displaced sideways, as a real slab does.
        assert!(out.origin.x > 0.6 * 5.0 / 1.0 * 1.0 + 0.1);
    }

    #[test]
    fn ray_through_glass_sphere_exits_at_its_entry_angle() {
        // By symmetry a ray leaves a sphere at the angle it came in: the exit index
        // must be glass → air. Bending as if entering again (the original's bug)
        // breaks this.
        let sphere = Shape::Sphere(Sphere::new(Vec3::new(0.0, 0.0, -10.0), 2.0));
        let incoming = Ray::new(Vec3::new(1.2, 0.3, 0.0), Vec3::NEG_Z);
        let entry = shape_surface(&sphere, &incoming);
        let (inside, _) = transmitted_ray(&incoming, &entry, 1.5);
        let exit = shape_surface(&sphere, &inside);
        let (out, kind) = transmitted_ray(&inside, &exit, 1.5);
        assert_eq!(kind, Transmission::Refracted);
        let angle_in = (-incoming.dir).dot(entry.normal).acos();
        let angle_out = out.dir.dot(exit.normal).acos();
        assert!((angle_in - angle_out).abs() < 2e-3, "{angle_in} vs {angle_out}");
        // A central ray goes straight through, parallel to where it came from.
        let central = Ray::new(Vec3::ZERO, Vec3::new(0.0, 0.0, -1.0));
        let (inside, _) = transmitted_ray(&central, &shape_surface(&sphere, &central), 1.5);
        let (out, _) = transmitted_ray(&inside, &shape_surface(&sphere, &inside), 1.5);
        assert!((out.dir - central.dir).length() < 1e-6);
    }

    #[test]
    fn total_internal_reflection_past_the_critical_angle_and_not_before() {
        // Inside glass of index 1.5 under the surface z = 0 (outward normal +z): the
        // critical angle is asin(1 / 1.5) = 41.81°.
        let (top, _) = slab();
        let at = |degrees: f32| {
            let a = degrees.to_radians();
            let ray = Ray::new(Vec3::new(0.0, 0.0, -0.5), Vec3::new(a.sin(), 0.0, a.cos()));
            transmitted_ray(&ray, &shape_surface(&top, &ray), 1.5)
        };
        let (r, kind) = at(40.0);
        assert_eq!(kind, Transmission::Refracted);
        assert!(r.dir.z > 0.0, "refracted out of the glass");
        let (r, kind) = at(41.5);
        assert_eq!(kind, Transmission::Refracted);
        assert!(r.dir.z > 0.0);
        let (r, kind) = at(42.2);
        assert_eq!(kind, Transmission::TotalInternalReflection);
        assert!(r.dir.z < 0.0 && r.origin.z < 0.0, "reflected back into the glass");
        let (_, kind) = at(60.0);
        assert_eq!(kind, Transmission::TotalInternalReflection);
        // Entering glass from air never reflects totally.
        let a = 89f32.to_radians();
        let grazing = Ray::new(Vec3::new(0.0, 0.0, 0.05), Vec3::new(a.sin(), 0.0, -a.cos()));
        assert_eq!(transmitted_ray(&grazing, &shape_surface(&top, &grazing), 1.5).1, Transmission::Refracted);
    }

    /// A floor lit from straight above, with `spheres` (transmission 0.7 each) in between.
    fn floor_under(spheres: &[Vec3]) -> Scene {
        let mut scene = Scene::new(Camera::new(Vec3::new(0.0, 5.0, 5.0), Vec3::ZERO, Vec3::Y, 40.0, 8, 8));
        scene.settings.ambient = 0.0;
        let floor = scene.add_material(Material::color(Color::ONE).matte());
        let glass = scene.add_material(Material::color(Color::ONE).transparent(0.7, 1.0));
        scene.add(Quad::new(Vec3::new(-5.0, 0.0, 5.0), Vec3::new(10.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -10.0)), floor);
        for &c in spheres {
            scene.add(Sphere::new(c, 1.0), glass);
        }
        scene.add_light(PointLight::new(Vec3::new(0.0, 10.0, 0.0), Color::ONE));
        scene
    }

    #[test]
    fn shadow_through_two_overlapping_transparent_spheres_is_scaled_by_both() {
        let eye_to_floor = Ray::new(Vec3::new(0.0, 0.5, 0.0) + Vec3::new(0.0, 0.0, 0.0), Vec3::NEG_Y);
        let brightness = |spheres: &[Vec3]| {
            let scene = floor_under(spheres);
            let world = World::new(&scene, AccelKind::default());
            // Looking straight down at the floor point under the light, from below the spheres.
            let c = Integrator::new(&world, 1).trace(&eye_to_floor, 1, &mut RayStats::default());
            let lit_point = Ray::new(Vec3::new(0.0, 1e-3, 0.0), Vec3::Y);
            (c.x, world.transmittance(&lit_point, 10.0 - 1e-3))
        };
        let (open, t_open) = brightness(&[]);
        let (one, t_one) = brightness(&[Vec3::new(0.0, 4.0, 0.0)]);
        let (two, t_two) = brightness(&[Vec3::new(0.0, 4.0, 0.0), Vec3::new(0.0, 4.8, 0.0)]);
        assert_eq!((t_open, t_one), (1.0, 0.7));
        assert!((t_two - 0.49).abs() < 1e-6, "two overlapping 70 % spheres pass {t_two}, not 0.49");
        assert!(open > 0.9, "{open}");
        assert!((one / open - 0.7).abs() < 1e-5, "{one} / {open}");
        assert!((two / open - 0.49).abs() < 1e-5, "{two} / {open}");
    }

    #[test]
    fn opaque_occluder_leaves_only_ambient() {
        let mut scene = floor_under(&[]);
        scene.settings.ambient = 0.2;
        let wall = scene.add_material(Material::color(Color::ONE));
        scene.add(Sphere::new(Vec3::new(0.0, 4.0, 0.0), 1.0), wall);
        let world = World::new(&scene, AccelKind::default());
        let c = Integrator::new(&world, 1).trace(
            &Ray::new(Vec3::new(0.0, 0.5, 0.0), Vec3::NEG_Y),
            1,
            &mut RayStats::default(),
        );
        assert!((c - Color::splat(0.2)).abs().max_element() < 1e-6, "{c}");
    }

    #[test]
    fn one_sided_shading_leaves_the_back_of_an_opaque_surface_unlit() {
        // A floor facing down (normal -y) lit from above, seen from above.
        let mut scene = floor_under(&[]);
        scene.objects[0].shape =
            Quad::new(Vec3::new(-5.0, 0.0, 5.0), Vec3::new(0.0, 0.0, -10.0), Vec3::new(10.0, 0.0, 0.0)).into();
        scene.settings.ambient = 0.1;
        let world = World::new(&scene, AccelKind::default());
        let down = Ray::new(Vec3::new(0.0, 5.0, 0.0), Vec3::NEG_Y);
        let mut stats = RayStats::default();
        let two_sided = Integrator::new(&world, 5).trace_primary(&down, &mut stats);
        assert_eq!(stats.shadow, 1);
        let mut stats = RayStats::default();
        let one_sided = Integrator::new(&world, 5).one_sided(true).trace_primary(&down, &mut stats);
        assert_eq!(stats.shadow, 0, "no shadow ray when the normal faces away from the light");
        assert!(two_sided.x > 0.9, "{two_sided}");
        assert!((one_sided - Color::splat(0.1)).abs().max_element() < 1e-6, "{one_sided}");
        // A transmitter stays two-sided.
        let glass = scene.add_material(Material::color(Color::ONE).transparent(0.5, 1.0));
        scene.objects[0].material = glass;
        let world = World::new(&scene, AccelKind::default());
        let mut stats = RayStats::default();
        Integrator::new(&world, 5).one_sided(true).trace_primary(&down, &mut stats);
        assert_eq!(stats.shadow, 1);
    }

    #[test]
    fn facing_mirrors_recurse_to_the_depth_limit() {
        // Two parallel mirrors; a ray between them bounces until max_depth.
        let mut scene = Scene::new(Camera::new(Vec3::ZERO, Vec3::NEG_Z, Vec3::Y, 40.0, 8, 8));
        let mirror = scene.add_material(Material::color(Color::splat(0.5)).reflective(1.0).matte());
        let (a, b) = slab();
        scene.add(a, mirror).add(b, mirror);
        let world = World::new(&scene, AccelKind::default());
        let mut stats = RayStats::default();
        Integrator::new(&world, 10).trace_primary(&Ray::new(Vec3::new(0.0, 0.0, -0.5), Vec3::Z), &mut stats);
        assert_eq!(stats.primary, 1);
        assert_eq!(stats.reflection, 9, "the primary ray is step 1 of 10");
    }

    #[test]
    fn black_matte_surface_sends_no_shadow_rays() {
        let mut scene = floor_under(&[]);
        let black = scene.add_material(Material::color(Color::ZERO).matte());
        scene.objects[0].material = black;
        let world = World::new(&scene, AccelKind::default());
        let mut stats = RayStats::default();
        let c = Integrator::new(&world, 5).trace_primary(&Ray::new(Vec3::new(0.0, 5.0, 0.0), Vec3::NEG_Y), &mut stats);
        assert_eq!((stats.shadow, c), (0, Color::ZERO));
    }

    #[test]
    fn perfect_mirror_sends_no_shadow_rays() {
        let mut scene = floor_under(&[]);
        let mirror = scene.add_material(Material::color(Color::splat(0.5)).reflective(1.0).matte());
        scene.objects[0].material = mirror;
        let world = World::new(&scene, AccelKind::default());
        let mut stats = RayStats::default();
        let c = Integrator::new(&world, 5).trace_primary(&Ray::new(Vec3::new(0.0, 5.0, 0.0), Vec3::NEG_Y), &mut stats);
        assert_eq!((stats.shadow, stats.reflection), (0, 1));
        assert_eq!(c, Color::ZERO, "it reflects the black background");
        // With a highlight it still needs them.
        scene.materials[mirror.0 as usize].specular = 1.0;
        let world = World::new(&scene, AccelKind::default());
        let mut stats = RayStats::default();
        Integrator::new(&world, 5).trace_primary(&Ray::new(Vec3::new(0.0, 5.0, 0.0), Vec3::NEG_Y), &mut stats);
        assert_eq!(stats.shadow, 1);
    }
}
