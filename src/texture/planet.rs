//! A procedural Earth-like planet map, standing in for the Earth photograph the original
//! scene used (which we cannot ship).
//!
//! Every texel is coloured from fractal noise evaluated at its *direction on the sphere*,
//! not at its (u, v): so the map has no seam at the date line and no pinching at the
//! poles, whatever its resolution.
//!
//! Two passes: the first finds each texel's elevation (the expensive noise), the second
//! colours it, lit by the slope between neighbouring elevations (shaded relief), which is
//! what makes flat colour bands read as terrain.

use std::f32::consts::{FRAC_PI_2, PI, TAU};

use rayon::prelude::*;

use super::ImageMap;
use super::noise::{Fbm, mix_seed};
use crate::math::{Color, Vec3};

/// Share of the sphere's area above sea level (Earth: 29 %; more reads better as "planet"
/// on a small sphere).
const LAND_FRACTION: f32 = 0.40;

/// Lattice spacings, in texels. The smoothest fields (warp, climate, ice edge) vary over
/// 50 texels or more at 1024 across and are computed every 8 texels; the low height
/// octaves and the ranges every 4; the next octave every 2; only the finest at every
/// texel. That cuts the noise evaluations per texel from about twenty to one or less.
const SMOOTH_STEP: usize = 8;
const COARSE_STEP: usize = 4;
const DETAIL_STEP: usize = 2;

/// Octaves of the height noise: those below [`COARSE_OCTAVES`] go on the coarse lattice,
/// the next up to [`DETAIL_OCTAVES`] on the detail one, the rest at every texel. Each
/// lattice samples its octaves at least three times per noise cell (at 1024 across the
/// cells of octave 3 span 14 texels, of octave 4 seven, of octave 5 three and a half),
/// so interpolating them loses nothing visible.
const OCTAVES: usize = 6;
const COARSE_OCTAVES: usize = 4;
const DETAIL_OCTAVES: usize = 5;

/// Depth (0 at the shore, 1 in the deepest trenches) below which the sea is one colour,
/// so the fine octaves need not be computed there.
const ABYSS: f32 = 0.45;

/// Half-width, in radians of latitude, of the ice caps' edge.
const ICE_BLUR: f32 = 0.008;
/// How much further from the pole, in radians, ice reaches on land than on sea.
const LAND_ICE: f32 = 0.07;

/// Half-width, in elevation (or depth) units, of the blend between sea and shore.
const COAST: f32 = 0.006;

/// Equirectangular map (longitude across, latitude down) of an Earth-like planet:
/// oceans, continents, mountains, ice caps. The same `seed` gives the same planet on any
/// number of threads, and the same continents at any size.
///
/// Uses the sphere's uv convention, `u = 0.5 + atan2(d.x, d.z) / 2π`,
/// `v = 0.5 - asin(d.y) / π`, so the map wraps the shape as intended.
///
/// # Panics
/// If `width` or `height` is 0.
pub fn planet(width: u32, height: u32, seed: u64) -> ImageMap {
    assert!(width > 0 && height > 0, "planet map must not be empty ({width}x{height})");
    let (w, h) = (width as usize, height as usize);
    let world = World::new(seed);
    let direction = |x: usize, y: usize| {
        let (sin_lat, cos_lat) = latitude(y, h).sin_cos();
        let (sin_lon, cos_lon) = (((x as f32 + 0.5) / w as f32 - 0.5) * TAU).sin_cos();
        Vec3::new(cos_lat * sin_lon, sin_lat, cos_lat * cos_lon)
    };
    let smooth = Lattice::<Smooth, SMOOTH_STEP>::build(w, h, |x, y| world.smooth(direction(x, y)));
    let coarse = Lattice::<Coarse, COARSE_STEP>::build(w, h, |x, y| world.coarse(direction(x, y), &smooth.at(x, y)));
    let detail = Lattice::<Coarse, DETAIL_STEP>::build(w, h, |x, y| world.detail(coarse.at(x, y)));

    let mut cells = vec![Cell::default(); w * h];
    cells.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let lat = latitude(y, h);
        let fields = detail.row(y);
        for (x, cell) in row.iter_mut().enumerate() {
            *cell = world.cell(&detail.along(&fields, x), lat);
        }
    });

    let mut texels = vec![Vec3::ZERO; w * h];
    texels.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let lat = latitude(y, h);
        let at = |y: usize| &cells[y * w..][..w];
        let (above, here, below) = (at(y.saturating_sub(1)), at(y), at((y + 1).min(h - 1)));
        // Texel spacing in radians of arc, east-west (shrinking towards the poles, but
        // not to zero) and north-south.
        let dx = TAU / w as f32 * lat.cos().max(0.05);
        let dy = PI / h as f32;
        let band = Band::new(lat);
        for (x, texel) in row.iter_mut().enumerate() {
            let (left, right) = (if x == 0 { w - 1 } else { x - 1 }, if x + 1 == w { 0 } else { x + 1 });
            let slope_east = (here[right].elevation - here[left].elevation) / (2.0 * dx);
            let slope_north = (above[x].elevation - below[x].elevation) / (2.0 * dy);
            *texel = shade(&here[x], slope_east, slope_north, &band).into();
        }
    });
    ImageMap::from_texels(width, height, texels)
}

/// Latitude in radians of the centre of texel row `y` of `height`.
fn latitude(y: usize, height: usize) -> f32 {
    (0.5 - (y as f32 + 0.5) / height as f32) * PI
}

/// Values that can be interpolated linearly.
trait Blend: Copy + Default + Send + Sync {
    fn blend(&self, other: &Self, t: f32) -> Self;
}

/// Samples of a field on texel centres every `STEP` texels, read back bilinearly at any
/// texel. Wraps around in longitude, so the seam interpolates between the last and first
/// columns; has an extra row on the bottom edge, since latitude does not wrap.
struct Lattice<T, const STEP: usize> {
    width: usize,
    height: usize,
    cols: usize,
    rows: usize,
    values: Vec<T>,
}

impl<T: Blend, const STEP: usize> Lattice<T, STEP> {
    /// Fills the lattice with `f(x, y)` at its texels, rows in parallel.
    fn build(width: usize, height: usize, f: impl Fn(usize, usize) -> T + Sync) -> Self {
        let (cols, rows) = (width.div_ceil(STEP), (height - 1).div_ceil(STEP) + 1);
        let mut values = vec![T::default(); cols * rows];
        values.par_chunks_mut(cols).enumerate().for_each(|(j, row)| {
            let y = (j * STEP).min(height - 1);
            for (i, v) in row.iter_mut().enumerate() {
                *v = f(i * STEP, y);
            }
        });
        Lattice { width, height, cols, rows, values }
    }

    /// Lattice rows above and below texel row `y`, and how far down between them it is.
    #[inline]
    fn row_span(&self, y: usize) -> (usize, usize, f32) {
        let j0 = y / STEP;
        let j1 = (j0 + 1).min(self.rows - 1);
        let gap = (j1 * STEP).min(self.height - 1) - j0 * STEP;
        let t = if gap == 0 { 0.0 } else { (y - j0 * STEP) as f32 / gap as f32 };
        (j0, j1, t)
    }

    /// Lattice columns left and right of texel column `x`, and how far between them.
    #[inline]
    fn col_span(&self, x: usize) -> (usize, usize, f32) {
        let i0 = x / STEP;
        let dx = (x - i0 * STEP) as f32;
        if i0 + 1 < self.cols {
            (i0, i0 + 1, dx * (1.0 / STEP as f32))
        } else {
            // The last gap wraps to column 0 and is short when STEP does not divide the
            // width.
            (i0, 0, dx / (self.width - i0 * STEP) as f32)
        }
    }

    /// The field at texel `(x, y)`.
    fn at(&self, x: usize, y: usize) -> T {
        let (j0, j1, ty) = self.row_span(y);
        let (i0, i1, tx) = self.col_span(x);
        let (row0, row1) = (&self.values[j0 * self.cols..], &self.values[j1 * self.cols..]);
        let top = row0[i0].blend(&row0[i1], tx);
        let bottom = row1[i0].blend(&row1[i1], tx);
        top.blend(&bottom, ty)
    }

    /// The lattice interpolated down to texel row `y`, for [`Lattice::along`]: a whole
    /// row of texels then costs one blend each instead of three.
    fn row(&self, y: usize) -> Vec<T> {
        let (j0, j1, t) = self.row_span(y);
        let (row0, row1) = (&self.values[j0 * self.cols..], &self.values[j1 * self.cols..]);
        row0[..self.cols].iter().zip(row1).map(|(a, b)| a.blend(b, t)).collect()
    }

    /// The field at texel column `x` of a [`Lattice::row`].
    #[inline]
    fn along(&self, row: &[T], x: usize) -> T {
        let (i0, i1, t) = self.col_span(x);
        row[i0].blend(&row[i1], t)
    }
}

fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + t * (b - a)
}

/// The smoothest fields at one sample.
#[derive(Clone, Copy, Debug, Default)]
struct Smooth {
    /// Domain-warp offset.
    warp: Vec3,
    /// Where mountain ranges may rise, in [0, 1].
    belt: f32,
    /// Moisture in [0, 1]: forest where wet, desert where dry.
    wet: f32,
    /// Latitude (radians) where the ice cap starts.
    ice_edge: f32,
}

impl Blend for Smooth {
    fn blend(&self, o: &Self, t: f32) -> Self {
        Smooth {
            warp: self.warp.lerp(o.warp, t),
            belt: lerp(self.belt, o.belt, t),
            wet: lerp(self.wet, o.wet, t),
            ice_edge: lerp(self.ice_edge, o.ice_edge, t),
        }
    }
}

/// The coarse fields at one sample.
#[derive(Clone, Copy, Debug, Default)]
struct Coarse {
    /// Where the fine octaves are evaluated: only lightly warped, since the full warp
    /// would stretch them into streaks.
    fine_at: Vec3,
    /// Unnormalised sum of the height octaves computed so far (coarse, then detail).
    low: f32,
    /// Extra elevation from mountain ranges, in [0, 1].
    ridge: f32,
    wet: f32,
    ice_edge: f32,
}

impl Blend for Coarse {
    fn blend(&self, o: &Self, t: f32) -> Self {
        Coarse {
            fine_at: self.fine_at.lerp(o.fine_at, t),
            low: lerp(self.low, o.low, t),
            ridge: lerp(self.ridge, o.ridge, t),
            wet: lerp(self.wet, o.wet, t),
            ice_edge: lerp(self.ice_edge, o.ice_edge, t),
        }
    }
}

/// One texel after the first pass.
#[derive(Clone, Copy, Debug, Default)]
struct Cell {
    /// Above sea level: elevation, 0 at the shore, about 1 on the highest peaks. Below:
    /// minus the depth, 0 at the shore, -1 in the deepest trenches.
    elevation: f32,
    wet: f32,
    /// How much ice covers it, in [0, 1].
    ice: f32,
}

/// The noise fields of one seed, plus the height levels calibrated on them.
struct World {
    height: Fbm,
    warp: [Fbm; 3],
    ridges: Fbm,
    ranges: Fbm,
    moisture: Fbm,
    ice: Fbm,
    /// Height below which is sea, chosen so that `LAND_FRACTION` of the sphere is land.
    sea_level: f32,
    /// Roughly the deepest and highest heights, to normalise depth and elevation.
    floor: f32,
    peak: f32,
    /// Most the per-texel octaves can add to or take from the (unnormalised) height.
    fine_bound: f32,
}

impl World {
    fn new(seed: u64) -> Self {
        let base = mix_seed(seed);
        let sub = |i: u32| mix_seed((u64::from(base) << 8) | u64::from(i));
        let height = Fbm::new(sub(0), OCTAVES);
        // Gradient noise stays within about ±1; 1.2 leaves a margin.
        let fine_bound = 1.2 * (DETAIL_OCTAVES..OCTAVES).map(|o| height.amplitude(o)).sum::<f32>();
        let mut world = World {
            height,
            warp: [Fbm::new(sub(1), 2), Fbm::new(sub(2), 2), Fbm::new(sub(3), 2)],
            ridges: Fbm::new(sub(4), 2),
            ranges: Fbm::new(sub(5), 2),
            moisture: Fbm::new(sub(6), 3),
            ice: Fbm::new(sub(7), 3),
            sea_level: 0.0,
            floor: -1.0,
            peak: 1.0,
            fine_bound,
        };
        world.calibrate();
        world
    }

    /// Noise heights wander from seed to seed, so fixed thresholds would give one planet
    /// all ocean and the next all land. Instead sample the height on evenly spread
    /// directions (a Fibonacci sphere: equal area, so this is the land fraction a viewer
    /// sees) and read the levels off their quantiles. Independent of map resolution.
    fn calibrate(&mut self) {
        const N: usize = 2048;
        let golden = PI * (3.0 - 5.0f32.sqrt());
        let mut heights: Vec<f32> = (0..N)
            .map(|i| {
                let y = 1.0 - 2.0 * (i as f32 + 0.5) / N as f32;
                let r = (1.0 - y * y).sqrt();
                let (s, c) = (golden * i as f32).sin_cos();
                let d = Vec3::new(r * c, y, r * s);
                let c = self.coarse(d, &self.smooth(d));
                (c.low + self.height.partial(c.fine_at, COARSE_OCTAVES..OCTAVES)) / self.height.norm()
            })
            .collect();
        heights.sort_unstable_by(f32::total_cmp);
        let quantile = |q: f32| heights[((q * (N - 1) as f32) as usize).min(N - 1)];
        self.sea_level = quantile(1.0 - LAND_FRACTION);
        self.floor = quantile(0.02);
        self.peak = quantile(0.998);
    }

    /// The smoothest fields at unit direction `d`.
    fn smooth(&self, d: Vec3) -> Smooth {
        let w = d * 1.6;
        Smooth {
            warp: Vec3::new(
                self.warp[0].sample(w),
                self.warp[1].sample(w + Vec3::splat(5.2)),
                self.warp[2].sample(w - Vec3::splat(3.7)),
            ),
            belt: smoothstep(-0.15, 0.2, self.ranges.sample(d * 1.2 + Vec3::splat(9.1))),
            wet: (self.moisture.sample(d * 2.5) * 1.4 + 0.5).clamp(0.0, 1.0),
            ice_edge: 72f32.to_radians() + 0.2 * self.ice.sample(d * 5.0),
        }
    }

    /// The coarse fields at unit direction `d`, given the smooth ones there.
    fn coarse(&self, d: Vec3, s: &Smooth) -> Coarse {
        // Domain warp: a smoother noise pushes the height noise about, so coastlines get
        // bays and peninsulas instead of round blobs.
        let q = d * 1.4 + s.warp * 0.6;
        // Mountain ranges: the creases of |noise| (lines, not blobs), only inside belts.
        let crease = 1.0 - self.ridges.sample(q * 2.0).abs();
        Coarse {
            fine_at: d * 1.4 + s.warp * 0.15,
            low: self.height.partial(q, 0..COARSE_OCTAVES),
            ridge: crease.powi(5) * s.belt,
            wet: s.wet,
            ice_edge: s.ice_edge,
        }
    }

    /// Adds the detail octaves to coarse fields.
    fn detail(&self, mut c: Coarse) -> Coarse {
        c.low += self.height.partial(c.fine_at, COARSE_OCTAVES..DETAIL_OCTAVES);
        c
    }

    /// One texel, from the fields interpolated off the detail lattice.
    fn cell(&self, c: &Coarse, lat: f32) -> Cell {
        let abs_lat = lat.abs();
        let norm = self.height.norm();
        let abyss = self.sea_level - ABYSS * (self.sea_level - self.floor);
        // Under solid ice, or in the abyss even if every fine octave peaked, the fine
        // octaves cannot change the colour: skip them (a third of the texels or more).
        let fine = if abs_lat >= c.ice_edge + ICE_BLUR || (c.low + self.fine_bound) / norm < abyss {
            0.0
        } else {
            self.height.partial(c.fine_at, DETAIL_OCTAVES..OCTAVES)
        };
        let h = (c.low + fine) / norm;
        let (elevation, ice_edge) = if h < self.sea_level {
            (-((self.sea_level - h) / (self.sea_level - self.floor)).min(1.0), c.ice_edge)
        } else {
            let base = (h - self.sea_level) / (self.peak - self.sea_level);
            // The power keeps broad domes of the height noise from becoming snowfields;
            // ranges rise from the lowlands, not straight out of the sea.
            let e = base * base.sqrt() + 0.6 * c.ridge * smoothstep(0.02, 0.15, base);
            // Ice sheets reach further on land than sea ice does on water.
            (e, c.ice_edge - LAND_ICE - 0.1 * e)
        };
        let ice = smoothstep(ice_edge - ICE_BLUR, ice_edge + ICE_BLUR, abs_lat);
        Cell { elevation, wet: c.wet, ice }
    }
}

const DEEP_OCEAN: Color = Color::new(0.02, 0.05, 0.20);
const OCEAN: Color = Color::new(0.04, 0.13, 0.38);
const SHALLOW: Color = Color::new(0.10, 0.33, 0.58);
const BEACH: Color = Color::new(0.72, 0.67, 0.48);
const FOREST: Color = Color::new(0.10, 0.28, 0.09);
const GRASS: Color = Color::new(0.26, 0.45, 0.15);
const SAVANNA: Color = Color::new(0.55, 0.52, 0.28);
const DESERT: Color = Color::new(0.80, 0.67, 0.45);
const TUNDRA: Color = Color::new(0.42, 0.43, 0.33);
const HIGHLAND: Color = Color::new(0.44, 0.35, 0.23);
const ROCK: Color = Color::new(0.47, 0.44, 0.41);
const SNOW: Color = Color::new(0.95, 0.95, 0.97);
const ICE: Color = Color::new(0.92, 0.95, 0.99);

/// Sea colour by depth.
const SEA: [(f32, Color); 3] = [(0.0, SHALLOW), (0.06, OCEAN), (ABYSS, DEEP_OCEAN)];
/// Lowland colour by dryness.
const VEGETATION: [(f32, Color); 4] = [(0.0, FOREST), (0.35, GRASS), (0.6, SAVANNA), (0.8, DESERT)];

/// What colouring needs of a texel row's latitude, worked out once per row.
struct Band {
    /// How subtropical, in [0, 1]: deserts favour the subtropics, as on Earth.
    subtropics: f32,
    /// How far towards tundra, in [0, 1].
    tundra: f32,
    /// Elevation above which there is snow: it comes down the mountains towards the poles.
    snow_line: f32,
}

impl Band {
    fn new(lat: f32) -> Self {
        let lat_deg = lat.abs().to_degrees();
        Band {
            subtropics: 1.0 - ((lat_deg - 24.0) / 18.0).powi(2).min(1.0),
            tundra: smoothstep(52.0, 64.0, lat_deg),
            snow_line: 1.0 - 0.55 * (lat / FRAC_PI_2).powi(2),
        }
    }
}

/// Final colour of a texel, with the slope (elevation units per radian) lighting land
/// from the north-west, as shaded-relief maps do.
fn shade(cell: &Cell, slope_east: f32, slope_north: f32, band: &Band) -> Color {
    let e = cell.elevation;
    // Blend across the shoreline over about a texel's worth of height, so coasts are
    // not staircases.
    let land_share = smoothstep(-COAST, COAST, e);
    let sea = if land_share < 1.0 { ramp(&SEA, -e) } else { Color::ZERO };
    let ground = if land_share > 0.0 {
        let light = 1.0 + 0.015 * (slope_east - slope_north);
        land(e.max(0.0), cell.wet, band) * light.clamp(0.6, 1.35)
    } else {
        Color::ZERO
    };
    sea.lerp(ground, land_share).lerp(ICE * (0.97 + 0.03 * cell.wet), cell.ice)
}

/// `elevation` 0 at the shore, about 1 on the peaks; `wet` in [0, 1].
fn land(elevation: f32, wet: f32, band: &Band) -> Color {
    let dry = ((1.0 - wet) * (0.7 + 0.6 * band.subtropics)).clamp(0.0, 1.0);
    let green = ramp(&VEGETATION, dry);
    let lowland = green.lerp(TUNDRA, band.tundra);
    let c = ramp(&[(0.0, BEACH), (0.012, lowland), (0.3, lowland), (0.5, HIGHLAND), (0.7, ROCK)], elevation);
    let snow_line = band.snow_line;
    c.lerp(SNOW, smoothstep(snow_line - 0.04, snow_line + 0.04, elevation))
}

/// Piecewise-linear colour ramp through `(position, colour)` stops in increasing order.
fn ramp(stops: &[(f32, Color)], t: f32) -> Color {
    let mut prev = stops[0];
    if t <= prev.0 {
        return prev.1;
    }
    for &stop in &stops[1..] {
        if t < stop.0 {
            return prev.1.lerp(stop.1, (t - prev.0) / (stop.0 - prev.0));
        }
        prev = stop;
    }
    prev.1
}

fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn is_ocean(c: Color) -> bool {
        c.z > 0.5 * (c.x + c.y) + 0.05 && c.z < 0.8
    }

    #[test]
    fn planet_is_deterministic_per_seed_and_varies_between_seeds() {
        let a = planet(256, 128, 7);
        assert_eq!(a, planet(256, 128, 7));
        let b = planet(256, 128, 8);
        let differing = a.texels().iter().zip(b.texels()).filter(|(x, y)| x != y).count();
        assert!(differing > a.texels().len() / 2, "only {differing} texels differ");
    }

    #[test]
    fn planet_does_not_depend_on_thread_count() {
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let three = rayon::ThreadPoolBuilder::new().num_threads(3).build().unwrap();
        assert_eq!(one.install(|| planet(96, 48, 3)), three.install(|| planet(96, 48, 3)));
    }

    #[test]
    fn planet_has_a_plausible_land_fraction() {
        for seed in [1, 2, 3, 42] {
            let m = planet(256, 128, seed);
            // Rows within 60 degrees of the equator: no ice, and less polar stretching.
            let rows = 128 / 6..128 - 128 / 6;
            let (mut land, mut total) = (0usize, 0usize);
            for y in rows {
                for x in 0..256 {
                    total += 1;
                    land += usize::from(!is_ocean(m.texel(x, y)));
                }
            }
            let fraction = land as f32 / total as f32;
            assert!((0.2..=0.6).contains(&fraction), "seed {seed}: land fraction {fraction}");
        }
    }

    #[test]
    fn planet_wraps_seamlessly_from_right_edge_to_left() {
        let m = planet(256, 128, 1);
        let w = m.width();
        // Mean absolute difference between two columns, over all rows.
        let column_diff = |a: u32, b: u32| {
            let sum: f32 = (0..m.height()).map(|y| (m.texel(a, y) - m.texel(b, y)).abs().element_sum()).sum();
            sum / m.height() as f32
        };
        let seam = column_diff(w - 1, 0);
        let neighbours: Vec<f32> = (0..w - 1).map(|x| column_diff(x, x + 1)).collect();
        let mean = neighbours.iter().sum::<f32>() / neighbours.len() as f32;
        let max = neighbours.iter().copied().fold(0.0, f32::max);
        // The seam is no rougher than an ordinary pair of adjacent columns...
        assert!(seam <= max && seam <= 2.0 * mean, "seam {seam}, neighbours mean {mean} max {max}");
        // ...while unrelated columns differ a lot, so the check has teeth.
        let far = column_diff(0, w / 2);
        assert!(far > 2.0 * seam, "far {far} vs seam {seam}");
    }

    #[test]
    fn planet_has_oceans_land_and_ice() {
        let m = planet(256, 128, 1);
        let count = |f: fn(Color) -> bool| m.texels().iter().filter(|c| f(Color::from(**c))).count();
        let blue = count(is_ocean);
        let green = count(|c| c.y > c.x && c.y > c.z);
        let white = count(|c| c.min_element() > 0.85);
        let n = m.texels().len();
        assert!(blue > n / 10, "blue {blue}");
        assert!(green > n / 50, "green {green}");
        assert!(white > n / 50, "white {white}");
    }

    #[test]
    #[ignore = "writes planet.png in the crate root, to look at"]
    fn save_planet_png() {
        let start = std::time::Instant::now();
        let m = planet(1024, 512, 1);
        eprintln!("planet(1024, 512): {:?}", start.elapsed());
        m.save_png(std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/planet.png"))).unwrap();
    }
}
