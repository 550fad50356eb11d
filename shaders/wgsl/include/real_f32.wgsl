// f32: the BVH's and the lens data's own precision; every device.
alias real = f32;

// The barycentric slack of the CPU's triangle test in f32: max(1e-10, 8 ulps).
const BARYCENTRIC_SLACK: real = 9.5367432e-7;
// Secondary rays start this far off the surface, relative to the coordinates' magnitude (the
// CPU's offset in f32: 128 ulps).
const ORIGIN_OFFSET: real = 1.5258789e-5;

// The u32 stored in a triangle's w (its bits).
fn word(x: real) -> u32 {
    return bitcast<u32>(x);
}

// A distance as the f32 the walks prune with.
fn up_to_f32(x: real) -> f32 {
    return x;
}
