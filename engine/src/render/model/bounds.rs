//! Interval arithmetic for [`super::ModelImage::bounds`]: the blend operations of
//! [`super::blend`] over per-channel intervals, each containing the operation applied to every
//! member, the light map's bilinear range over the sub-texel grid, and [`Bounded`], a model value
//! carried together with its interval through the passes.

use glam::DVec2;

use super::blend::{
    add_masked, alpha_clear, blend_back_to_front, blend_front_to_back, layer_source,
};
use crate::cubemap::sampling::FilterPrecision;
use crate::lightmap::LightMap;

/// A closed interval `[lo, hi]`, one per premultiplied channel in [`super::ModelImage::bounds`].
pub(super) type Interval = [f64; 2];

/// Point intervals `[v, v]`.
pub(super) fn point_bounds(rgba: [f64; 4]) -> [Interval; 4] {
    rgba.map(|v| [v, v])
}

/// `{x·y : x ∈ a, y ∈ b}`, whatever the signs.
pub(super) fn interval_product(a: Interval, b: Interval) -> Interval {
    let products = [a[0] * b[0], a[0] * b[1], a[1] * b[0], a[1] * b[1]];
    [
        products.into_iter().fold(f64::INFINITY, f64::min),
        products.into_iter().fold(f64::NEG_INFINITY, f64::max),
    ]
}

/// [`layer_source`] over a texel interval (weight and F·G exact).
fn layer_source_bounds(group_weight: f64, fg: [f64; 3], texel: [Interval; 4]) -> [Interval; 4] {
    let scale = |c: usize| {
        interval_product(
            interval_product(texel[c], [fg[c], fg[c]]),
            [group_weight, group_weight],
        )
    };
    [scale(0), scale(1), scale(2), texel[3]]
}

/// [`blend_front_to_back`] over intervals: contains the blend of every `dst`, `src` in them.
pub(super) fn blend_front_to_back_bounds(dst: [Interval; 4], src: [Interval; 4]) -> [Interval; 4] {
    let transmittance = [1.0 - dst[3][1], 1.0 - dst[3][0]];
    let mut out: [Interval; 4] = std::array::from_fn(|c| {
        let scaled = interval_product(src[c], transmittance);
        [scaled[0] + dst[c][0], scaled[1] + dst[c][1]]
    });
    // α: src·(1 − dst) + dst rises in both src and dst when both lie in [0, 1], so its ends are
    // exact there (the general form above counts dst twice and is wider).
    let unit = |a: Interval| 0.0 <= a[0] && a[1] <= 1.0;
    if unit(src[3]) && unit(dst[3]) {
        let alpha = |s: f64, d: f64| s * (1.0 - d) + d;
        out[3] = [alpha(src[3][0], dst[3][0]), alpha(src[3][1], dst[3][1])];
    }
    out
}

/// The back-to-front blend `src + dst·(1 − srcα)` (classic "over") over intervals.
fn blend_back_to_front_bounds(dst: [Interval; 4], src: [Interval; 4]) -> [Interval; 4] {
    let transmittance = [1.0 - src[3][1], 1.0 - src[3][0]];
    let mut out: [Interval; 4] = std::array::from_fn(|c| {
        let scaled = interval_product(dst[c], transmittance);
        [src[c][0] + scaled[0], src[c][1] + scaled[1]]
    });
    // α: s + d·(1 − s) rises in both when both lie in [0, 1].
    let unit = |a: Interval| 0.0 <= a[0] && a[1] <= 1.0;
    if unit(src[3]) && unit(dst[3]) {
        let alpha = |s: f64, d: f64| s + d * (1.0 - s);
        out[3] = [alpha(src[3][0], dst[3][0]), alpha(src[3][1], dst[3][1])];
    }
    out
}

/// [`add_masked`] over intervals.
fn add_masked_bounds(dst: [Interval; 4], src: [Interval; 4], mask: u8) -> [Interval; 4] {
    std::array::from_fn(|c| {
        if mask & (1 << c) != 0 {
            [dst[c][0] + src[c][0], dst[c][1] + src[c][1]]
        } else {
            dst[c]
        }
    })
}

/// The alpha clear over intervals: α becomes exactly 0.
fn alpha_clear_bounds(dst: [Interval; 4]) -> [Interval; 4] {
    [dst[0], dst[1], dst[2], [0.0, 0.0]]
}

/// The range of a light map's bilinear rgb at `uv` over fractions snapped to the sub-texel grid
/// (the same rectangle-corner argument as the cube maps', same clamp-to-edge footprint as
/// [`LightMap::sample_bilinear`]).
pub(super) fn light_map_bounds(
    map: &LightMap,
    uv: DVec2,
    precision: FilterPrecision,
) -> [Interval; 3] {
    let step = precision.sub_texel_step();
    let axis = |coordinate: f64, size: u32| {
        let x = coordinate * f64::from(size) - 0.5;
        let base = x.floor();
        let clamp = |i: f64| i.clamp(0.0, f64::from(size - 1)) as u32;
        let fraction = x - base;
        (
            [clamp(base), clamp(base + 1.0)],
            [(fraction - step).max(0.0), (fraction + step).min(1.0)],
        )
    };
    let (xs, fxs) = axis(uv.x, map.width);
    let (ys, fys) = axis(uv.y, map.height);
    let texel = |x: u32, y: u32| map.texel(x, y).map(f64::from);
    let mut bounds = [[f64::INFINITY, f64::NEG_INFINITY]; 3];
    for fx in fxs {
        for fy in fys {
            for (c, bound) in bounds.iter_mut().enumerate() {
                let value = (texel(xs[0], ys[0])[c] * (1.0 - fx) + texel(xs[1], ys[0])[c] * fx)
                    * (1.0 - fy)
                    + (texel(xs[0], ys[1])[c] * (1.0 - fx) + texel(xs[1], ys[1])[c] * fx) * fy;
                *bound = [bound[0].min(value), bound[1].max(value)];
            }
        }
    }
    bounds
}

/// A pixel's model value and its interval, carried through the passes together: each operation
/// applies [`super::blend`]'s arithmetic to the value and its interval counterpart to the bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Bounded {
    /// The model's value.
    pub(super) value: [f64; 4],
    /// Where any conformant implementation's value lies.
    pub(super) bounds: [Interval; 4],
}

impl Bounded {
    /// An exact value: point intervals.
    pub(super) fn point(value: [f64; 4]) -> Bounded {
        Bounded {
            value,
            bounds: point_bounds(value),
        }
    }

    /// The layer shader's output for a texel sample and its bounds.
    pub(super) fn layer_source(
        group_weight: f64,
        fg: [f64; 3],
        texel: [f64; 4],
        texel_bounds: [Interval; 4],
    ) -> Bounded {
        Bounded {
            value: layer_source(group_weight, fg, texel),
            bounds: layer_source_bounds(group_weight, fg, texel_bounds),
        }
    }

    /// The alpha clear.
    pub(super) fn alpha_clear(self) -> Bounded {
        Bounded {
            value: alpha_clear(self.value),
            bounds: alpha_clear_bounds(self.bounds),
        }
    }

    /// `src` blended front to back under this destination.
    pub(super) fn blend_front_to_back(self, src: Bounded) -> Bounded {
        Bounded {
            value: blend_front_to_back(self.value, src.value),
            bounds: blend_front_to_back_bounds(self.bounds, src.bounds),
        }
    }

    /// `src` blended back to front over this destination.
    pub(super) fn blend_back_to_front(self, src: Bounded) -> Bounded {
        Bounded {
            value: blend_back_to_front(self.value, src.value),
            bounds: blend_back_to_front_bounds(self.bounds, src.bounds),
        }
    }

    /// `src` added on the channels of `mask` (bit c: channel c).
    pub(super) fn add_masked(self, src: Bounded, mask: u8) -> Bounded {
        Bounded {
            value: add_masked(self.value, src.value, mask),
            bounds: add_masked_bounds(self.bounds, src.bounds, mask),
        }
    }
}
