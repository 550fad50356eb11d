// The opaque environment, drawn first with depth test and write: vertex colour times the object's
// light map (ray-traced outgoing radiance, sampled bilinearly). A mesh without a light map binds a
// white 1×1 map, so its vertex colour shows as it is.

struct EnvironmentConstants {
    view_proj: mat4x4<f32>,
}

var<immediate> constants: EnvironmentConstants;

@group(0) @binding(0) var light_map: texture_2d<f32>;
@group(0) @binding(1) var light_map_sampler: sampler;

struct VertexOut {
    @builtin(position) @invariant clip: vec4<f32>,
    @location(0) colour: vec3<f32>,
    @location(1) uv: vec2<f32>,
}

@vertex
fn vs_environment(
    @location(0) position: vec3<f32>,
    @location(1) colour: vec3<f32>,
    @location(2) uv: vec2<f32>,
) -> VertexOut {
    var out: VertexOut;
    out.clip = constants.view_proj * vec4<f32>(position, 1.0);
    out.colour = colour;
    out.uv = uv;
    return out;
}

@fragment
fn fs_environment(in: VertexOut) -> @location(0) vec4<f32> {
    // One level, bilinear: textureSampleLevel keeps the lookup free of derivatives.
    let radiance = textureSampleLevel(light_map, light_map_sampler, in.uv, 0.0).rgb;
    return vec4<f32>(in.colour * radiance, 1.0);
}
