//! Where in a pixel the camera rays go. Every pixel seeds its own generator from its
//! coordinates, so an image does not depend on thread count or tile order.

use crate::math::Vec2;

/// PCG32 (O'Neill 2014): small state, good statistics, cheap enough to make one per pixel.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
}

const PCG_MUL: u64 = 6364136223846793005;
const PCG_INC: u64 = 1442695040888963407;

/// SplitMix64 finaliser: spreads neighbouring pixel coordinates to unrelated seeds.
fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58476d1ce4e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d049bb133111eb);
    z ^ (z >> 31)
}

impl Rng {
    pub fn new(seed: u64) -> Self {
        let mut r = Rng { state: mix64(seed).wrapping_add(PCG_INC) };
        r.next_u32();
        r
    }

    /// The generator for pixel (`x`, `y`) of frame `frame`.
    pub fn for_pixel(x: u32, y: u32, frame: u32) -> Self {
        Rng::new(((y as u64) << 32 | x as u64) ^ mix64(frame as u64 + 0x9e3779b97f4a7c15))
    }

    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(PCG_MUL).wrapping_add(PCG_INC);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        xorshifted.rotate_right((old >> 59) as u32)
    }

    /// Uniform in [0, 1).
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }

    /// Uniform in [0, n).
    pub fn below(&mut self, n: u32) -> u32 {
        ((self.next_u32() as u64 * n as u64) >> 32) as u32
    }
}

/// The sub-pixel positions (in [0, 1)², relative to the pixel's top-left corner) of
/// `spp` samples:
/// - 1: the pixel centre, as the original did without anti-aliasing;
/// - a square k²: a k × k grid, one jittered sample per cell;
/// - any other count: N-rooks (Latin hypercube), one sample in each of `spp` rows and
///   each of `spp` columns, shuffled, so the area is still covered evenly.
///
/// Writes into `out`, which the caller reuses across pixels (no allocation per pixel).
pub fn pixel_samples(spp: u32, rng: &mut Rng, out: &mut Vec<Vec2>) {
    out.clear();
    if spp <= 1 {
        out.push(Vec2::splat(0.5));
        return;
    }
    let k = (spp as f64).sqrt().round() as u32;
    if k * k == spp {
        let cell = 1.0 / k as f32;
        for j in 0..k {
            for i in 0..k {
                out.push(Vec2::new((i as f32 + rng.next_f32()) * cell, (j as f32 + rng.next_f32()) * cell));
            }
        }
    } else {
        let cell = 1.0 / spp as f32;
        for i in 0..spp {
            out.push(Vec2::new((i as f32 + rng.next_f32()) * cell, (i as f32 + rng.next_f32()) * cell));
        }
        // Fisher–Yates on the y coordinates decouples rows from columns.
        for i in (1..spp as usize).rev() {
            let j = rng.below(i as u32 + 1) as usize;
            let (a, b) = (out[i].y, out[j].y);
            out[i].y = b;
            out[j].y = a;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_sample_is_the_pixel_centre() {
        let mut v = Vec::new();
        pixel_samples(1, &mut Rng::new(1), &mut v);
        assert_eq!(v, vec![Vec2::splat(0.5)]);
    }

    #[test]
    fn square_counts_put_one_sample_in_every_cell() {
        let mut v = Vec::new();
        pixel_samples(16, &mut Rng::for_pixel(3, 4, 0), &mut v);
        assert_eq!(v.len(), 16);
        let mut seen = [false; 16];
        for s in &v {
            assert!(s.x >= 0.0 && s.x < 1.0 && s.y >= 0.0 && s.y < 1.0);
            seen[(s.y * 4.0) as usize * 4 + (s.x * 4.0) as usize] = true;
        }
        assert!(seen.iter().all(|&b| b), "{v:?}");
    }

    #[test]
    fn other_counts_are_n_rooks() {
        let mut v = Vec::new();
        pixel_samples(5, &mut Rng::for_pixel(7, 1, 0), &mut v);
        let mut cols = [0; 5];
        let mut rows = [0; 5];
        for s in &v {
            cols[(s.x * 5.0) as usize] += 1;
            rows[(s.y * 5.0) as usize] += 1;
        }
        assert_eq!(cols, [1; 5]);
        assert_eq!(rows, [1; 5]);
    }

    #[test]
    fn pixels_get_different_but_repeatable_jitter() {
        let (mut a, mut b, mut c) = (Vec::new(), Vec::new(), Vec::new());
        pixel_samples(4, &mut Rng::for_pixel(10, 20, 0), &mut a);
        pixel_samples(4, &mut Rng::for_pixel(10, 20, 0), &mut b);
        pixel_samples(4, &mut Rng::for_pixel(11, 20, 0), &mut c);
        assert_eq!(a, b);
        assert_ne!(a, c);
    }

    #[test]
    fn rng_is_roughly_uniform() {
        let mut r = Rng::new(42);
        let mut bins = [0u32; 10];
        for _ in 0..100_000 {
            bins[(r.next_f32() * 10.0) as usize] += 1;
        }
        assert!(bins.iter().all(|&b| (9_000..11_000).contains(&b)), "{bins:?}");
    }
}
