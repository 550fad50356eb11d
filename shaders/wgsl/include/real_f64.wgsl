// f64: the CPU oracle's own precision (devices with shaderFloat64).
alias real = f64;

// The barycentric slack of the CPU's triangle test in f64: max(1e-10, 8 ulps).
const BARYCENTRIC_SLACK: real = 1e-10;
// Secondary rays start this far off the surface, relative to the coordinates' magnitude (the
// CPU's offset in f64).
const ORIGIN_OFFSET: real = 1e-9;

// The u32 stored in a triangle's w (as an f64 value, exact).
fn word(x: real) -> u32 {
    return u32(x);
}

// The smallest f32 not below a positive distance `x`, so that the f32 walks prune with it
// conservatively (the CPU's `round_up`).
fn up_to_f32(x: real) -> f32 {
    let r = f32(x);
    if f64(r) < x {
        return bitcast<f32>(bitcast<u32>(r) + 1u);
    }
    return r;
}
