// The box filter of supersampling on the GPU, for frames rendered into a host's image (no
// readback): each pixel of the image is the mean of its k×k subpixels of the colour target. The
// sum runs in the CPU filter's order (rows of the block top to bottom, each left to right) and is
// scaled by the same f32 1/k², so with Vulkan's correctly rounded additions and multiplications
// the two filters agree bit for bit (`RenderedImage::box_downsample`).

struct ResolveConstants {
    supersampling: u32,
    scale: f32,
    // Each subpixel is clamped to ±limit first: 65504 for an RGBA16F framebuffer, whose
    // overflowed texels hold ±Inf (the CPU readback clamps them the same way), else +Inf.
    limit: f32,
}

var<immediate> constants: ResolveConstants;

@group(0) @binding(0) var subpixels: texture_2d<f32>;

// #include "full_screen.wgsl"

@fragment
fn fs_box_filter(@builtin(position) pixel: vec4<f32>) -> @location(0) vec4<f32> {
    let k = constants.supersampling;
    // Fragment centres are at half-integer coordinates: the pixel's index is their floor.
    let origin = vec2<u32>(pixel.xy) * k;
    var sum = vec4<f32>(0.0);
    for (var dy = 0u; dy < k; dy++) {
        for (var dx = 0u; dx < k; dx++) {
            let texel = textureLoad(subpixels, origin + vec2<u32>(dx, dy), 0);
            sum += clamp(texel, vec4<f32>(-constants.limit), vec4<f32>(constants.limit));
        }
    }
    return sum * constants.scale;
}
