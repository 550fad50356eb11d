//! The compositor's blend arithmetic on premultiplied f64 RGBA: "over", the layer passes' blends
//! front to back and back to front, the alpha clear, the masked add of a group sum, the layer
//! shader's output, and the whole pass sequence at one pixel against the paper's closed form.

/// Premultiplied "over": `front + (1 − front.α)·back` on all four channels.
pub fn over(front: [f64; 4], back: [f64; 4]) -> [f64; 4] {
    std::array::from_fn(|c| front[c] + (1.0 - front[3]) * back[c])
}

/// The layer passes' blend, front to back ("under"): `src·(1 − dst.α) + dst·1` on colour and
/// alpha, i.e. `dst over src`.
pub fn blend_front_to_back(dst: [f64; 4], src: [f64; 4]) -> [f64; 4] {
    std::array::from_fn(|c| src[c] * (1.0 - dst[3]) + dst[c])
}

/// The back-to-front blend on values: `src + dst·(1 − srcα)` on colour and alpha.
pub fn blend_back_to_front(dst: [f64; 4], src: [f64; 4]) -> [f64; 4] {
    std::array::from_fn(|c| src[c] + dst[c] * (1.0 - src[3]))
}

/// The alpha clear between groups: rgb × 1, α × 0.
pub fn alpha_clear(dst: [f64; 4]) -> [f64; 4] {
    [dst[0], dst[1], dst[2], 0.0]
}

/// Adds `src` to `dst` on the channels of `mask` (bit c: channel c), as an additive blend with
/// that colour write mask does.
pub(super) fn add_masked(dst: [f64; 4], src: [f64; 4], mask: u8) -> [f64; 4] {
    std::array::from_fn(|c| {
        if mask & (1 << c) != 0 {
            dst[c] + src[c]
        } else {
            dst[c]
        }
    })
}

/// One (viewpoint, term) group at one pixel: its weight `w_v`, its F·G, and the filtered
/// premultiplied layer samples front to back.
#[derive(Clone, Debug, PartialEq)]
pub struct CompositeGroup {
    /// Viewpoint weight w_v.
    pub weight: f64,
    /// The term's interpolated F·G (rgb).
    pub fg: [f64; 3],
    /// Premultiplied layer samples L1 … Ln, nearest first.
    pub layers: Vec<[f64; 4]>,
}

/// The shader's output for one layer of a group: `(texel.rgb · FG · w, texel.α)`.
pub(super) fn layer_source(group_weight: f64, fg: [f64; 3], texel: [f64; 4]) -> [f64; 4] {
    [
        texel[0] * fg[0] * group_weight,
        texel[1] * fg[1] * group_weight,
        texel[2] * fg[2] * group_weight,
        texel[3],
    ]
}

/// The GPU's pass sequence at one lens pixel, starting from the prime's (0,0,0,0): each group's
/// layers blended front to back, an alpha clear between consecutive groups.
pub fn composite_by_blending(groups: &[CompositeGroup]) -> [f64; 4] {
    let mut dst = [0.0; 4];
    for (index, group) in groups.iter().enumerate() {
        if index > 0 {
            dst = alpha_clear(dst);
        }
        for &layer in &group.layers {
            dst = blend_front_to_back(dst, layer_source(group.weight, group.fg, layer));
        }
    }
    dst
}

/// The paper's closed form at one lens pixel: rgb = Σ_groups w·FG ⊙ (L1 over … over Ln).rgb,
/// α = the last group's (L1 over … over Ln).α.
pub fn composite_closed_form(groups: &[CompositeGroup]) -> [f64; 4] {
    let mut result = [0.0; 4];
    for group in groups {
        let composite = group
            .layers
            .iter()
            .rev()
            .fold([0.0; 4], |back, &front| over(front, back));
        for c in 0..3 {
            result[c] += group.weight * group.fg[c] * composite[c];
        }
        result[3] = composite[3];
    }
    result
}
