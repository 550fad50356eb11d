// The opaque environment: vertex-coloured meshes drawn first, with depth test and write.

struct EnvironmentConstants {
    view_proj: mat4x4<f32>,
}

var<immediate> constants: EnvironmentConstants;

struct VertexOut {
    @builtin(position) @invariant clip: vec4<f32>,
    @location(0) colour: vec3<f32>,
}

@vertex
fn vs_environment(@location(0) position: vec3<f32>, @location(1) colour: vec3<f32>) -> VertexOut {
    var out: VertexOut;
    out.clip = constants.view_proj * vec4<f32>(position, 1.0);
    out.colour = colour;
    return out;
}

@fragment
fn fs_environment(in: VertexOut) -> @location(0) vec4<f32> {
    return vec4<f32>(in.colour, 1.0);
}
