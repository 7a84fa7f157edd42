//! What the eight-lane code shares with the rest of the crate on every platform: whether
//! it runs ([`avx2`]) and the hits it finds ([`Best8`]). Where it does not run (no AVX2,
//! not x86-64, or `WHITTED_PORTABLE=1`), the portable code takes the same rays: 4-wide
//! trees and one ray at a time, giving the same images.

use crate::geometry::Hit;
use crate::math::Vec2;
use std::sync::OnceLock;

/// Whether the eight-lane AVX2 code runs: on x86-64 processors with AVX2, unless
/// `WHITTED_PORTABLE=1` in the environment forces the portable path (read once), so that
/// it is tested on x86-64 too.
pub fn avx2() -> bool {
    static AVX2: OnceLock<bool> = OnceLock::new();
    *AVX2.get_or_init(|| std::env::var_os("WHITTED_PORTABLE").is_none_or(|v| v != "1") && has_avx2())
}

#[cfg(target_arch = "x86_64")]
fn has_avx2() -> bool {
    std::is_x86_feature_detected!("avx2")
}

#[cfg(not(target_arch = "x86_64"))]
fn has_avx2() -> bool {
    false
}

/// Per lane, the nearest hit so far, field by field ([`Hit`]'s), and the object hit
/// (`u32::MAX`: none yet). Its distance is the exclusive bound for the next object.
pub struct Best8 {
    pub t: [f32; 8],
    pub u: [f32; 8],
    pub v: [f32; 8],
    pub(super) part: [u8; 8],
    pub(super) prim: [u32; 8],
    pub index: [u32; 8],
    /// The object that took lanes last, and the lanes that hold it: [`Best8::taken_by`]
    /// without reading `index` back whole, just after it was written lane by lane.
    pub(super) owner: u32,
    pub(super) owned: u32,
}

impl Default for Best8 {
    fn default() -> Self {
        Best8::new()
    }
}

impl Best8 {
    pub fn new() -> Self {
        let none = u32::MAX;
        let (t, u, v) = ([f32::INFINITY; 8], [0.0; 8], [0.0; 8]);
        Best8 { t, u, v, part: [0; 8], prim: [0; 8], index: [none; 8], owner: none, owned: 0 }
    }

    /// No hit yet, each lane's bound from `t`.
    pub fn within(t: [f32; 8]) -> Self {
        Best8 { t, ..Best8::new() }
    }

    pub fn set(&mut self, lane: usize, h: Hit, index: u32) {
        (self.t[lane], self.u[lane], self.v[lane], self.part[lane], self.prim[lane]) =
            (h.t, h.uv.x, h.uv.y, h.part, h.prim);
        self.index[lane] = index;
        // Objects are tested one after another, each once: lanes taken by one before
        // this one hold other objects.
        self.owned = if index == self.owner { self.owned | 1 << lane } else { 1 << lane };
        self.owner = index;
    }

    /// The lanes that hold object `index`, if it was the last one to take any.
    pub fn taken_by(&self, index: u32) -> u32 {
        if self.owner == index { self.owned } else { 0 }
    }

    pub fn get(&self, lane: usize) -> (Hit, u32) {
        let uv = Vec2::new(self.u[lane], self.v[lane]);
        (Hit { t: self.t[lane], uv, part: self.part[lane], prim: self.prim[lane] }, self.index[lane])
    }
}

#[cfg(test)]
mod tests {
    /// CI runs the tests once more with `WHITTED_PORTABLE=1`: then the eight-lane code
    /// must not run, whatever the processor.
    #[test]
    fn the_portable_path_is_forced_when_asked() {
        if std::env::var_os("WHITTED_PORTABLE").is_some_and(|v| v == "1") {
            assert!(!super::avx2(), "WHITTED_PORTABLE=1 but the AVX2 code runs");
        } else {
            eprintln!("eight-lane AVX2 code runs here: {}", super::avx2());
        }
    }
}
