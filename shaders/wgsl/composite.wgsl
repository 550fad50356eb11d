// The resolve of the back-to-front and group-targets blending schemes: each (viewpoint, term)
// group was composited into a layer of the scratch images; a full-screen pass adds their colour
// into the framebuffer (whose lens pixels the prime left at zero) and takes the last group's α,
// which is the paper's closed form Σ w·FG ⊙ composite.rgb, α = the last group's. Outside the
// lens the scratch images are zero (cleared), so adding them changes nothing.

struct GroupSumConstants {
    // Scratch layers 0..groups are summed.
    groups: u32,
}

var<immediate> constants: GroupSumConstants;

@group(0) @binding(0) var groups: texture_2d_array<f32>;

// #include "full_screen.wgsl"

@fragment
fn fs_group_sum(@builtin(position) pixel: vec4<f32>) -> @location(0) vec4<f32> {
    var sum = vec4<f32>(0.0);
    for (var group = 0u; group < constants.groups; group++) {
        let value = textureLoad(groups, vec2<u32>(pixel.xy), group, 0);
        sum = vec4<f32>(sum.rgb + value.rgb, value.a);
    }
    return sum;
}
