//! Culling for small scenes: a tile's camera rays, a bundle of reflections or a
//! level's shadow rays to one light tested against only the few objects they may meet,
//! eight rays at a time, instead of walking the tree.

#[cfg(target_arch = "x86_64")]
use super::lanes::Best8;
#[cfg(target_arch = "x86_64")]
use super::packet8;
use super::{NONE, World};
use crate::geometry::{Hit, Shape};
use crate::math::{Aabb, Ray, Vec2, Vec3};
use glam::DVec3;

/// Bounds on the distances `t` at which `o + t d` lies in the slab `[b_lo, b_hi]` of one
/// axis, for any `o` in `[o_lo, o_hi]` and `d` in `[d_lo, d_hi]`: `(-inf, inf)` when `d`
/// may be 0, else found from the extreme origins and directions.
fn axis_reach(b_lo: f64, b_hi: f64, o_lo: f64, o_hi: f64, d_lo: f64, d_hi: f64) -> (f64, f64) {
    if d_lo > 0.0 {
        // Entering at (b_lo - o) / d, least for the farthest origin; leaving at
        // (b_hi - o) / d, most for the nearest. Either divided by the direction that
        // makes it least, or most.
        let (n_in, n_out) = (b_lo - o_hi, b_hi - o_lo);
        (n_in / if n_in >= 0.0 { d_hi } else { d_lo }, n_out / if n_out >= 0.0 { d_lo } else { d_hi })
    } else if d_hi < 0.0 {
        // The mirror image of the case above.
        axis_reach(-b_hi, -b_lo, -o_hi, -o_lo, -d_hi, -d_lo)
    } else {
        (f64::NEG_INFINITY, f64::INFINITY)
    }
}

/// Scenes of at most this many objects cull them per image tile for camera rays
/// ([`World::seen_from`]): a test per object per tile, cheap while objects are few...
const CONE_MAX_OBJECTS: usize = 64;
/// ...and worth it while a tile sees few of them: past this the tree does better.
const CONE_MAX_SEEN: usize = 6;

/// Whether `scene` is small enough for its objects to be culled per group of rays.
pub(super) fn small(scene: &crate::scene::Scene) -> bool {
    scene.objects.len() <= CONE_MAX_OBJECTS
}

/// An object's bounds as the culling tests use them, worked out once per world: its box,
/// that box in f64 widened by 1e-3 (relative) to cover the rounding of the f32 tests, and
/// the sphere round the widened box.
#[derive(Clone, Copy, Debug)]
pub(super) struct CullBounds {
    b: Aabb,
    lo: DVec3,
    hi: DVec3,
    centre: DVec3,
    radius: f64,
}

impl CullBounds {
    pub(super) fn of(b: Aabb) -> Self {
        let (lo, hi) = margin(b);
        let (centre, radius) = sphere((lo, hi));
        CullBounds { b, lo, hi, centre, radius }
    }
}

/// Box `b` in f64, widened by 1e-3 (relative) for rounding.
fn margin(b: Aabb) -> (DVec3, DVec3) {
    let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
    let m = 1e-3 * (1.0 + lo.abs().max(hi.abs()).max_element());
    (lo - m, hi + m)
}

/// The centre and radius of the sphere round a box.
fn sphere((lo, hi): (DVec3, DVec3)) -> (DVec3, f64) {
    ((lo + hi) * 0.5, (hi - lo).length() * 0.5)
}

impl World<'_> {
    /// Whether groups of rays may be tested against only the objects they may meet
    /// ([`World::seen_from`], [`World::seen_along`], [`World::may_shadow`]): in a small
    /// scene with a tree asked for. In a large one the tree does better.
    #[inline]
    pub fn culls(&self) -> bool {
        !self.cull.is_empty()
    }

    /// The objects whose boxes meet the cone of rays from `apex` within the four edge
    /// directions `edges` (see [`crate::camera::CameraRig::cone`]), in index order, into
    /// `seen`; `false` (and `seen` left unusable) when that would not pay: no tree was
    /// asked for, the scene is not small, or the cone sees many objects. Camera rays
    /// through an image tile then test only these, with [`World::closest_among`].
    pub fn seen_from(&self, apex: Vec3, edges: [Vec3; 4], seen: &mut Vec<u32>) -> bool {
        seen.clear();
        if !self.culls() {
            return false;
        }
        // Inward normals of the cone's four sides, in f64 so that the test cannot
        // round a box out that a ray of the cone reaches.
        let e = edges.map(|v| v.as_dvec3());
        let axis = e[0] + e[1] + e[2] + e[3];
        let sides: [DVec3; 4] = std::array::from_fn(|i| {
            let n = e[i].cross(e[(i + 1) % 4]);
            if n.dot(axis) < 0.0 { -n } else { n }
        });
        let apex = apex.as_dvec3();
        for (i, o) in self.cull.iter().enumerate() {
            let b = o.b;
            let (centre, half) = ((b.min + b.max).as_dvec3() * 0.5 - apex, (b.max - b.min).as_dvec3() * 0.5);
            // Wholly behind one side: no ray of the cone reaches it. (NaN keeps it.)
            if !sides.iter().any(|n| n.dot(centre) + n.abs().dot(half) < 0.0) {
                if seen.len() == CONE_MAX_SEEN {
                    return false;
                }
                seen.push(i as u32);
            }
        }
        true
    }

    /// The objects that any of `rays` (from their origins on) may meet, in index order,
    /// into `seen`; `false` (and `seen` unusable) when that would not pay, as in
    /// [`World::seen_from`]. For rays of one kind sent on from one object's hits in an
    /// image tile, which leave from nearby points in nearby directions, it is a few;
    /// [`World::closest_among`] them then finds what the tree finds.
    ///
    /// Per axis, interval arithmetic in f64 bounds the distances at which a ray with
    /// origin in the rays' box and direction in theirs can be within an object's slab
    /// (its box widened by 1e-3, relative, for rounding); an object is passed over when
    /// no distance past 0 lies within all three.
    pub fn seen_along<T>(&self, rays: &[(Ray, T)], seen: &mut Vec<u32>) -> bool {
        seen.clear();
        if !self.culls() {
            return false;
        }
        let (mut o_lo, mut o_hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        let (mut d_lo, mut d_hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for (r, _) in rays {
            let (o, d) = (r.origin.as_dvec3(), r.dir.as_dvec3());
            (o_lo, o_hi, d_lo, d_hi) = (o_lo.min(o), o_hi.max(o), d_lo.min(d), d_hi.max(d));
        }
        if !(o_lo.is_finite() && o_hi.is_finite() && d_lo.is_finite() && d_hi.is_finite()) {
            return false;
        }
        for (i, &CullBounds { lo: b_lo, hi: b_hi, .. }) in self.cull.iter().enumerate() {
            // NaN bounds keep the object.
            let (mut enter, mut leave) = (0.0f64, f64::INFINITY);
            for k in 0..3 {
                let (lo, hi) = axis_reach(b_lo[k], b_hi[k], o_lo[k], o_hi[k], d_lo[k], d_hi[k]);
                (enter, leave) = (enter.max(lo), leave.min(hi));
            }
            if !(enter > leave) {
                if seen.len() == CONE_MAX_SEEN {
                    return false;
                }
                seen.push(i as u32);
            }
        }
        true
    }

    /// The objects that could stand between a point of the boxes `from` and the point
    /// `light`, in index order, into `blockers`; `false` (and `blockers` unusable) when
    /// that would not pay or cannot be bounded, as in [`World::seen_from`]. `from` pairs
    /// an object with a box round the points its shadow rays leave from (just off its
    /// hits in an image tile, on the side the rays came from), which then test only the
    /// objects found here, with [`World::transmittance_among`].
    ///
    /// Two conservative tests, in f64 with margins of 1e-3 (relative) that cover the
    /// rounding of the f32 ones. A quad is passed over when the light and every point
    /// not on the quad itself lie strictly on one side of its plane (a point on it
    /// starts its shadow ray off the plane on the light's side: true of two-sided
    /// shading, not of [`crate::integrator::Integrator::one_sided`]). Any object is passed
    /// over when its bounding sphere misses the cone, apex at the light, that the
    /// segments to the points' bounding sphere fill, or lies beyond its reach.
    pub fn may_shadow(&self, from: &[(u32, Aabb)], light: Vec3, blockers: &mut Vec<u32>) -> bool {
        blockers.clear();
        if !self.culls() {
            return false;
        }
        let union = |skip: Option<u32>| {
            from.iter().filter(|(o, _)| Some(*o) != skip).fold(Aabb::EMPTY, |b, (_, p)| b.union(*p))
        };
        let light = light.as_dvec3();
        let (centre, radius) = sphere(margin(union(None)));
        let axis = centre - light;
        let reach = axis.length();
        // The light inside (or nearly) the points' sphere: no cone to speak of.
        if !(radius.is_finite() && reach.is_finite() && radius < 0.9 * reach) {
            return false;
        }
        // The cone's half angle, with 1e-3 for rounding, as its cosine and sine: an
        // object's sphere meets the cone when the angle between its centre and the axis
        // is at most that plus the angle the sphere spans, compared here as cosines
        // (both angles lie in [0, pi), where the cosine falls).
        let spread = (radius / reach).asin() + 1e-3;
        let (sin_spread, cos_spread) = spread.sin_cos();
        for (i, o) in self.scene.objects.iter().enumerate() {
            let CullBounds { centre: c, radius: r, .. } = self.cull[i];
            let v = c - light;
            let e = v.length();
            let near = !(r.is_finite() && e.is_finite()) || e <= r;
            if !near {
                let (sin_span, cos_span) = (r / e, (1.0 - (r / e) * (r / e)).sqrt());
                let cos_angle = (v.dot(axis) / (e * reach)).clamp(-1.0, 1.0);
                if e - r > reach + radius || cos_angle < cos_spread * cos_span - sin_spread * sin_span {
                    continue;
                }
            }
            if let Shape::Quad(q) = &o.shape {
                let (normal, d) = q.plane();
                let (n, d) = (normal.as_dvec3(), d as f64);
                let side = |x: DVec3| n.dot(x) - d;
                let others = union(Some(i as u32));
                let (lo, hi) = margin(others);
                let corners =
                    (0..8).map(|k| DVec3::new([lo.x, hi.x][k & 1], [lo.y, hi.y][k >> 1 & 1], [lo.z, hi.z][k >> 2]));
                let l = side(light);
                let tol = 1e-3 * (1.0 + n.abs().dot(light.abs()) + d.abs());
                if others.min.x > others.max.x || (l.abs() > tol && corners.into_iter().all(|c| side(c) * l > 0.0)) {
                    continue;
                }
            }
            if blockers.len() == CONE_MAX_SEEN {
                return false;
            }
            blockers.push(i as u32);
        }
        true
    }

    /// [`World::transmittance`] counting objects `ids` (in index order) only: for
    /// shadow rays no other object can block ([`World::may_shadow`]).
    #[inline]
    pub fn transmittance_among(&self, ids: &[u32], ray: &Ray, t_max: f32) -> f32 {
        self.transmittance_of(ids.iter().copied(), ray, t_max)
    }

    /// Testing objects `ids` one by one, in the order given.
    #[inline(always)]
    pub(super) fn transmittance_of(&self, ids: impl IntoIterator<Item = u32>, ray: &Ray, t_max: f32) -> f32 {
        let mut light = 1.0f64;
        for i in ids {
            if self.blocks(i as usize, ray, t_max) {
                light *= self.transmission[i as usize] as f64;
                if light == 0.0 {
                    return 0.0;
                }
            }
        }
        light as f32
    }

    /// [`World::closest`] among objects `ids` (in index order) only: for rays that can
    /// reach no others ([`World::seen_from`]), the same answer without the tree.
    #[inline(always)]
    pub fn closest_among(&self, ids: &[u32], ray: &Ray, t_min: f32, t_max: f32) -> Option<(Hit, u32)> {
        self.closest_of(ids.iter().copied(), ray, t_min, t_max)
    }

    /// [`World::closest_among`] `ids` for each ray of `found`, its answer written beside
    /// it: with AVX2, eight rays at a time, object by object (the same answers).
    pub fn closest_among_each(&self, ids: &[u32], found: &mut [(Ray, Option<(Hit, u32)>)]) {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            for rays in found.chunks_mut(8) {
                // SAFETY: `avx2` is set only where the processor has AVX2.
                #[allow(unsafe_code)]
                unsafe {
                    self.closest_among_8(ids, rays)
                };
            }
            return;
        }
        for (ray, hit) in found {
            *hit = self.closest_among(ids, ray, 0.0, f32::INFINITY);
        }
    }

    /// [`World::transmittance_among`] `ids` for eight shadow rays given lane by lane
    /// (origins, unit directions, lengths), in the lanes `live` (the others are 0): with
    /// AVX2, the eight tested together, object by object (the same answers).
    pub fn transmittance_among_lanes(
        &self,
        ids: &[u32],
        origins: &[[f32; 8]; 3],
        dirs: &[[f32; 8]; 3],
        t_max: [f32; 8],
        live: u32,
    ) -> [f32; 8] {
        if ids.is_empty() {
            // Nothing may stand in the way (half of the room's shadow rays): every live
            // lane sees all of the light, as the tests below would find.
            return std::array::from_fn(|lane| if live >> lane & 1 != 0 { 1.0 } else { 0.0 });
        }
        let ray = |lane: usize| Ray {
            origin: Vec3::new(origins[0][lane], origins[1][lane], origins[2][lane]),
            dir: Vec3::new(dirs[0][lane], dirs[1][lane], dirs[2][lane]),
        };
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only where the processor has AVX2.
            #[allow(unsafe_code)]
            return unsafe {
                self.transmittance_among_8(ids, &packet8::Rays8::from_lanes(origins, dirs), ray, t_max, live)
            };
        }
        std::array::from_fn(|lane| {
            if live >> lane & 1 == 0 { 0.0 } else { self.transmittance_among(ids, &ray(lane), t_max[lane]) }
        })
    }

    /// The eight rays of [`World::transmittance_among_lanes`] (`ray` gives them one by
    /// one): each live lane's light is multiplied by each object's transmission, in the
    /// order given, where the object lies across it, as in [`World::transmittance_of`].
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn transmittance_among_8(
        &self,
        ids: &[u32],
        wide: &packet8::Rays8,
        ray: impl Fn(usize) -> Ray,
        t_max: [f32; 8],
        live: u32,
    ) -> [f32; 8] {
        let mut light = [1.0f64; 8];
        for &i in ids {
            let mut best = Best8::within(t_max);
            let mut blocked = 0u32;
            if let Some(mesh) = self.plain_mesh(i as usize) {
                blocked = mesh.occluded_lanes(&ray, t_max, live);
            } else if !self.eight_lanes(i, wide, live, &mut best) {
                for lane in crate::math::lanes::set_lanes(live) {
                    blocked |= (self.blocks(i as usize, &ray(lane), t_max[lane]) as u32) << lane;
                }
            }
            // Each object has a fresh `best`: the lanes it holds are those it blocks.
            blocked |= best.taken_by(i);
            while blocked != 0 {
                let lane = blocked.trailing_zeros() as usize;
                blocked &= blocked - 1;
                light[lane] *= self.transmission[i as usize] as f64;
            }
        }
        std::array::from_fn(|lane| if live >> lane & 1 == 0 { 0.0 } else { light[lane] as f32 })
    }

    /// Object `i` against the lanes `live` of `rays`, where it has an eight-lane test
    /// (quads, spheres, cylinders, pointed cones): the lanes that hit it before their
    /// bound in `best` keep it there. `false`, and nothing done, for other shapes.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn eight_lanes(&self, i: u32, rays: &packet8::Rays8, live: u32, best: &mut Best8) -> bool {
        match (&self.meshes[i as usize], &self.scene.objects[i as usize].shape) {
            (None, Shape::Quad(q)) => packet8::quad(q, rays, live, best, i),
            (None, Shape::Sphere(s)) => packet8::sphere(s, rays, live, best, i),
            (None, Shape::Cylinder(c)) => packet8::cylinder(c, rays, live, best, i),
            (None, Shape::Cone(c)) if c.top_radius == 0.0 => packet8::pointed_cone(c, rays, live, best, i),
            _ => return false,
        }
        true
    }

    /// Up to eight rays of [`World::closest_among_each`]: objects with an eight-lane
    /// test ([`World::eight_lanes`]) tested once, others ray by ray. Each ray meets the
    /// objects in the order given, with the bound its earlier hits set, as in
    /// [`World::closest_of`].
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn closest_among_8(&self, ids: &[u32], rays: &mut [(Ray, Option<(Hit, u32)>)]) {
        let live = (1u32 << rays.len()) - 1;
        let wide = packet8::Rays8::new(rays);
        let mut best = Best8::new();
        for &i in ids {
            if let Some(mesh) = self.plain_mesh(i as usize) {
                let found = mesh.closest_lanes(|lane| rays[lane].0, best.t, live);
                for (lane, h) in found.into_iter().enumerate() {
                    if let Some(h) = h {
                        best.set(lane, h, i);
                    }
                }
            } else if !self.eight_lanes(i, &wide, live, &mut best) {
                for (lane, (ray, _)) in rays.iter().enumerate() {
                    if let Some(h) = self.intersect_object(i as usize, ray, 0.0, best.t[lane]) {
                        best.set(lane, h, i);
                    }
                }
            }
        }
        for (lane, (_, hit)) in rays.iter_mut().enumerate() {
            *hit = (best.index[lane] != NONE).then(|| best.get(lane));
        }
    }

    /// Testing objects `ids` one by one, in the order given; the first of equally near
    /// hits wins.
    #[inline(always)]
    pub(super) fn closest_of(
        &self,
        ids: impl IntoIterator<Item = u32>,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
    ) -> Option<(Hit, u32)> {
        // Field by field, as in `closest`.
        let (mut t_max, mut best, mut index) = (t_max, Hit { t: 0.0, uv: Vec2::ZERO, part: 0, prim: 0 }, NONE);
        for i in ids {
            if let Some(h) = self.intersect_object(i as usize, ray, t_min, t_max) {
                t_max = h.t;
                (best.t, best.uv, best.part, best.prim, index) = (h.t, h.uv, h.part, h.prim, i);
            }
        }
        (index != NONE).then_some((best, index))
    }
}
