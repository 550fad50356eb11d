// The full-screen vertex stage of the passes that run once per pixel (the group sum, the box
// filter), pasted into their files by shaders/build.rs where they say `// #include`.

// One triangle covering the viewport: vertices (-1,-1), (3,-1), (-1,3) in clip space.
@vertex
fn vs_full_screen(@builtin(vertex_index) index: u32) -> @builtin(position) vec4<f32> {
    let corner = vec2<f32>(f32((index << 1u) & 2u), f32(index & 2u));
    return vec4<f32>(corner * 2.0 - 1.0, 0.0, 1.0);
}
