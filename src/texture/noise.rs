//! Seeded 3-D gradient noise and its fractal sum, for procedural textures.
//!
//! Hand-written rather than a crate so the output is ours to keep stable: a scene that
//! names a seed must render the same planet in every version of the program.

use std::ops::Range;

use crate::math::Vec3;

/// Perlin's twelve cube-edge gradients, padded to 16 so a 4-bit hash picks one without
/// a modulo (the four repeats are his, and keep the bias negligible).
const GRADIENTS: [[f32; 3]; 16] = [
    [1.0, 1.0, 0.0],
    [-1.0, 1.0, 0.0],
    [1.0, -1.0, 0.0],
    [-1.0, -1.0, 0.0],
    [1.0, 0.0, 1.0],
    [-1.0, 0.0, 1.0],
    [1.0, 0.0, -1.0],
    [-1.0, 0.0, -1.0],
    [0.0, 1.0, 1.0],
    [0.0, -1.0, 1.0],
    [0.0, 1.0, -1.0],
    [0.0, -1.0, -1.0],
    [1.0, 1.0, 0.0],
    [-1.0, 1.0, 0.0],
    [0.0, -1.0, 1.0],
    [0.0, -1.0, -1.0],
];

/// Spreads a 64-bit seed over 32 bits so that nearby seeds (1, 2, 3…) give unrelated
/// lattices (splitmix64 finaliser).
pub(crate) fn mix_seed(seed: u64) -> u32 {
    let mut z = seed.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    (z ^ (z >> 31)) as u32
}

/// Adding 1.5·2²³ to a float of magnitude under 2²² rounds it to an integer, which then
/// sits in the low bits of the sum's representation.
const MAGIC: f32 = 12_582_912.0;

/// `(floor(x), lattice key of floor(x))`, where the key is an integer that differs for
/// every integer under 2²² in magnitude. Done in float arithmetic because `f32::floor`
/// is a libm call on baseline x86-64 (no SSE4.1), which cost an eighth of the planet's
/// time, and a saturating `as i32` round trip still 6 % more than this. Non-finite or
/// huge input gives garbage, never a panic.
#[inline(always)]
fn floor(x: f32) -> (f32, u32) {
    let nearest = (x + MAGIC) - MAGIC;
    let down = if nearest > x { nearest - 1.0 } else { nearest };
    (down, (down + MAGIC).to_bits())
}

/// Quintic fade: its zero second derivative at lattice planes keeps the creases out.
#[inline(always)]
fn fade(t: Vec3) -> Vec3 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// Gradient noise at `p` (Perlin 2002), roughly in [-1, 1], zero on lattice points.
#[inline]
pub(crate) fn gradient(seed: u32, p: Vec3) -> f32 {
    let ((fx, ix), (fy, iy), (fz, iz)) = (floor(p.x), floor(p.y), floor(p.z));
    let f = p - Vec3::new(fx, fy, fz);
    // Lattice hash: the primes decorrelate the axes, and one multiply mixes them into
    // the top four bits, which pick the gradient. (A full finaliser costs 10 % more and
    // shows no difference in the fractal sums.)
    let (x0, x1) = (ix.wrapping_mul(0x8da6_b343), ix.wrapping_add(1).wrapping_mul(0x8da6_b343));
    let (y0, y1) = (iy.wrapping_mul(0xd816_3841), iy.wrapping_add(1).wrapping_mul(0xd816_3841));
    let (z0, z1) = (iz.wrapping_mul(0xcb1a_b31f), iz.wrapping_add(1).wrapping_mul(0xcb1a_b31f));
    let corner = |hx: u32, hy: u32, hz: u32, d: Vec3| {
        let h = (seed ^ hx ^ hy ^ hz).wrapping_mul(0x2c1b_3c6d);
        let g = GRADIENTS[(h >> 28) as usize];
        g[0] * d.x + g[1] * d.y + g[2] * d.z
    };
    let n000 = corner(x0, y0, z0, f);
    let n100 = corner(x1, y0, z0, f - Vec3::X);
    let n010 = corner(x0, y1, z0, f - Vec3::Y);
    let n110 = corner(x1, y1, z0, f - Vec3::new(1.0, 1.0, 0.0));
    let n001 = corner(x0, y0, z1, f - Vec3::Z);
    let n101 = corner(x1, y0, z1, f - Vec3::new(1.0, 0.0, 1.0));
    let n011 = corner(x0, y1, z1, f - Vec3::new(0.0, 1.0, 1.0));
    let n111 = corner(x1, y1, z1, f - Vec3::ONE);
    let w = fade(f);
    let lerp = |a: f32, b: f32, t: f32| a + t * (b - a);
    let nx00 = lerp(n000, n100, w.x);
    let nx10 = lerp(n010, n110, w.x);
    let nx01 = lerp(n001, n101, w.x);
    let nx11 = lerp(n011, n111, w.x);
    lerp(lerp(nx00, nx10, w.y), lerp(nx01, nx11, w.y), w.z)
}

/// Most octaves an [`Fbm`] can have; past about 8 they are finer than any texel.
pub(crate) const MAX_OCTAVES: usize = 8;

/// Frequency ratio between octaves; slightly off 2 so their lattices never line up.
const LACUNARITY: f32 = 2.03;
/// Amplitude ratio between octaves.
const GAIN: f32 = 0.5;

/// Fractal Brownian motion: octaves of [`gradient`] noise, each about twice as fine and
/// half as strong, normalised back to roughly [-1, 1].
#[derive(Clone, Copy, Debug)]
pub(crate) struct Fbm {
    octaves: usize,
    /// Per octave, tabulated because `powi` with a variable exponent is a libm call.
    seed: [u32; MAX_OCTAVES],
    amplitude: [f32; MAX_OCTAVES],
    frequency: [f32; MAX_OCTAVES],
    norm: f32,
}

impl Fbm {
    /// # Panics
    /// If `octaves` is 0 or more than [`MAX_OCTAVES`].
    pub fn new(seed: u32, octaves: usize) -> Self {
        assert!((1..=MAX_OCTAVES).contains(&octaves), "{octaves} octaves");
        let mut f = Fbm {
            octaves,
            seed: [0; MAX_OCTAVES],
            amplitude: [0.0; MAX_OCTAVES],
            frequency: [0.0; MAX_OCTAVES],
            norm: 0.0,
        };
        let (mut amp, mut freq) = (1.0, 1.0);
        for o in 0..MAX_OCTAVES {
            // A fresh lattice per octave, so octaves do not all vanish at the origin.
            f.seed[o] = seed.wrapping_add((o as u32).wrapping_mul(0x9e37_79b9));
            f.amplitude[o] = amp;
            f.frequency[o] = freq;
            amp *= GAIN;
            freq *= LACUNARITY;
        }
        f.norm = f.amplitude[..octaves].iter().sum();
        f
    }

    /// Normalised sum of all octaves, roughly in [-1, 1].
    #[inline]
    pub fn sample(&self, p: Vec3) -> f32 {
        self.partial(p, 0..self.octaves) / self.norm
    }

    /// Unnormalised sum of some of the octaves: the smooth low ones can then be computed
    /// on a coarse grid and interpolated, and only the fine ones evaluated everywhere.
    #[inline]
    pub fn partial(&self, p: Vec3, octaves: Range<usize>) -> f32 {
        let octaves = octaves.start.min(self.octaves)..octaves.end.min(self.octaves);
        octaves.map(|o| self.amplitude[o] * gradient(self.seed[o], p * self.frequency[o])).sum()
    }

    /// Weight of octave `o` in the unnormalised sums.
    pub fn amplitude(&self, o: usize) -> f32 {
        self.amplitude[o]
    }

    /// Sum of all octaves' amplitudes, which [`Fbm::partial`] sums must be divided by.
    pub fn norm(&self) -> f32 {
        self.norm
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gradient_noise_vanishes_on_lattice_points() {
        for p in [Vec3::ZERO, Vec3::new(3.0, -7.0, 12.0), Vec3::new(-1.0, 0.0, 5.0)] {
            assert_eq!(gradient(17, p), 0.0);
        }
    }

    #[test]
    fn gradient_noise_is_bounded_and_varies_with_seed() {
        let mut differs = false;
        for i in 0..1000 {
            let p = Vec3::new(i as f32 * 0.137, i as f32 * -0.071, i as f32 * 0.291);
            let a = gradient(1, p);
            assert!(a.abs() <= 1.5, "{a} at {p}");
            differs |= a != gradient(2, p);
        }
        assert!(differs);
    }

    #[test]
    fn gradient_noise_survives_nan_and_huge_inputs() {
        let _ = gradient(3, Vec3::NAN);
        let _ = gradient(3, Vec3::splat(f32::INFINITY));
        let _ = gradient(3, Vec3::splat(-3.0e38));
    }

    #[test]
    fn fbm_partial_sums_add_up_to_the_whole() {
        let f = Fbm::new(9, 6);
        let p = Vec3::new(0.3, -1.7, 2.2);
        let split = (f.partial(p, 0..2) + f.partial(p, 2..6)) / f.norm();
        assert!((split - f.sample(p)).abs() < 1e-6);
    }

    #[test]
    fn integer_floor_rounds_down_on_both_sides_of_zero() {
        for x in [1.5f32, -1.5, -2.0, 0.0, -0.0, 0.999_999_94, -0.000_001, 4_000_000.5, -4_000_000.5] {
            assert_eq!(floor(x).0, x.floor(), "{x}");
        }
        // Neighbouring integers get keys one apart, so the lattice hash sees them differ.
        for i in -5..5 {
            let x = i as f32 + 0.25;
            assert_eq!(floor(x + 1.0).1, floor(x).1.wrapping_add(1), "{x}");
        }
        let _ = (floor(f32::NAN), floor(f32::INFINITY), floor(-1e30));
    }

    #[test]
    fn mixed_seeds_of_neighbouring_integers_differ() {
        assert_ne!(mix_seed(1), mix_seed(2));
        assert_ne!(mix_seed(0), 0);
    }
}
