//! Which wide tree rays walk ([`WideBvh`]): the 8-wide one ([`super::wide8`]) where the
//! eight-lane code runs, else the 4-wide one ([`super::wide`]). Apart from both, so that
//! neither tree's module needs the other's.

use super::bvh::{Bvh, Visit};
use super::wide::Bvh4;
use crate::math::Ray;

/// The tree rays walk: 8-wide where the eight-lane code runs ([`super::lanes::avx2`]),
/// else 4-wide. Both reach the
/// same leaves (their box tests are the same arithmetic), so images are the same.
/// `WHITTED_BVH_WIDTH=4` in the environment forces the 4-wide tree, to compare the two.
#[derive(Clone, Debug)]
pub enum WideBvh {
    Four(Bvh4),
    #[cfg(target_arch = "x86_64")]
    Eight(super::wide8::Bvh8),
}

impl Default for WideBvh {
    fn default() -> Self {
        WideBvh::Four(Bvh4::default())
    }
}

impl WideBvh {
    pub fn from_binary(bvh: &Bvh) -> WideBvh {
        WideBvh::with_width(bvh, Self::default_width())
    }

    fn default_width() -> usize {
        let four = std::env::var("WHITTED_BVH_WIDTH").as_deref() == Ok("4");
        if four { 4 } else { 8 }
    }

    /// The width of the tree [`WideBvh::with_width`] (or, for `None`,
    /// [`WideBvh::from_binary`]) makes, known before the binary tree is built.
    pub fn chosen_width(width: Option<usize>) -> usize {
        let wanted = width.unwrap_or_else(Self::default_width);
        #[cfg(target_arch = "x86_64")]
        if wanted == 8 && super::lanes::avx2() && std::is_x86_feature_detected!("avx2") {
            return 8;
        }
        let _ = wanted;
        4
    }

    /// The 8-wide tree if asked for and this processor walks it, else the 4-wide one.
    pub fn with_width(bvh: &Bvh, width: usize) -> WideBvh {
        #[cfg(target_arch = "x86_64")]
        if width == 8
            && super::lanes::avx2()
            && let Some(eight) = super::wide8::Bvh8::from_binary(bvh)
        {
            return WideBvh::Eight(eight);
        }
        let _ = width;
        WideBvh::Four(Bvh4::from_binary(bvh))
    }

    /// Children per node.
    pub fn width(&self) -> usize {
        match self {
            WideBvh::Four(_) => 4,
            #[cfg(target_arch = "x86_64")]
            WideBvh::Eight(_) => 8,
        }
    }

    /// See [`Bvh4::map_leaves`].
    pub fn map_leaves(&mut self, f: impl FnMut(u32, u32) -> (u32, u32)) {
        match self {
            WideBvh::Four(t) => t.map_leaves(f),
            #[cfg(target_arch = "x86_64")]
            WideBvh::Eight(t) => t.map_leaves(f),
        }
    }

    /// Calls `f` with each leaf's first item and count (after [`WideBvh::map_leaves`],
    /// what it gave).
    pub fn each_leaf(&self, f: impl FnMut(u32, u32)) {
        match self {
            WideBvh::Four(t) => t.each_leaf(f),
            #[cfg(target_arch = "x86_64")]
            WideBvh::Eight(t) => t.each_leaf(f),
        }
    }

    pub fn memory_bytes(&self) -> usize {
        match self {
            WideBvh::Four(t) => t.memory_bytes(),
            #[cfg(target_arch = "x86_64")]
            WideBvh::Eight(t) => t.memory_bytes(),
        }
    }

    pub fn node_count(&self) -> usize {
        match self {
            WideBvh::Four(t) => t.node_count(),
            #[cfg(target_arch = "x86_64")]
            WideBvh::Eight(t) => t.node_count(),
        }
    }

    /// See [`Bvh4::traverse`] (`ORDERED`, nearest first) and [`Bvh4::traverse_any`];
    /// `items` are what leaf ranges index, so that the walk can start loading a leaf's
    /// items when it stacks the leaf.
    #[inline]
    pub fn traverse<const ORDERED: bool, T>(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        items: &[T],
        leaf: impl FnMut(std::ops::Range<usize>, f32) -> Visit,
    ) {
        match self {
            WideBvh::Four(t) => t.start::<ORDERED, T>(ray, t_min, t_max, items, leaf),
            #[cfg(target_arch = "x86_64")]
            WideBvh::Eight(t) => t.start::<ORDERED, T>(ray, t_min, t_max, items, leaf),
        }
    }

    /// Nearest-first walks for `N` rays: interleaved on the 8-wide tree
    /// ([`super::wide8::Bvh8::nearest_hits`]), one after another on the 4-wide one.
    /// `leaf(k, range, t_max)` handles ray `k`'s leaf and returns its new bound.
    #[inline]
    pub fn nearest_hits<T, const N: usize>(
        &self,
        rays: [&Ray; N],
        t_min: f32,
        t_max: [f32; N],
        items: &[T],
        mut leaf: impl FnMut(usize, std::ops::Range<usize>, f32) -> f32,
    ) {
        match self {
            WideBvh::Four(t) => {
                for k in 0..N {
                    t.start::<true, T>(rays[k], t_min, t_max[k], items, |range, t| Visit::Continue(leaf(k, range, t)));
                }
            }
            #[cfg(target_arch = "x86_64")]
            WideBvh::Eight(t) => t.nearest_hits(rays, t_min, t_max, items, leaf),
        }
    }

    /// Any-hit walks for `N` rays: interleaved on the 8-wide tree
    /// ([`super::wide8::Bvh8::any_hits`]), one after another on the 4-wide one.
    /// `leaf(k, range)` says whether ray `k` is blocked at `range`; returns which were.
    #[inline]
    pub fn any_hits<T, const N: usize>(
        &self,
        rays: [&Ray; N],
        t_min: f32,
        t_max: [f32; N],
        items: &[T],
        mut leaf: impl FnMut(usize, std::ops::Range<usize>) -> bool,
    ) -> [bool; N] {
        match self {
            WideBvh::Four(t) => std::array::from_fn(|k| {
                let mut blocked = false;
                t.start::<false, T>(rays[k], t_min, t_max[k], items, |range, t| {
                    blocked = leaf(k, range);
                    if blocked { Visit::Stop } else { Visit::Continue(t) }
                });
                blocked
            }),
            #[cfg(target_arch = "x86_64")]
            WideBvh::Eight(t) => t.any_hits(rays, t_min, t_max, items, leaf),
        }
    }
}
