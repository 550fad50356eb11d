// The lens compositor, both variants (hybrid-rendering paper §5, "Multipass Rendering with
// Layered EM Indexing").
//
// Per-vertex lens data lives in one storage buffer of vec4s, indexed by the vertex index of an
// indexed draw: positions, then F·G per term, then cube-map directions per (term, layer). The
// layered EM of a viewpoint sample is one cube-map array, layer l = cube l.
//
// Multipass: the prime writes (0,0,0,0) to the lens pixels; each layer pass emits
// (texel.rgb·FG·w, texel.α) under the fixed-function blend src·(1−dstα) + dst (front-to-back
// "over"); the alpha clear reuses fs_zero with a colour write mask of A only.
// The convex-hull split: layer 0's draws (and the single pass) draw a lens object's last
// triangles, its hull triangles, in a second draw with `skip_local` set: their layer-0 texel is
// taken as zero.
// Single pass: one draw samples the 2·V (viewpoint, term) textures per layer (V ≤ MAX_VIEWPOINTS
// viewpoint samples, each with its own cube-map array; the directions are shared) and does the
// same arithmetic in registers, in the same order, so it matches the multipass frame.
//
// Every lens vertex shader computes the clip position the same way and marks it invariant, so the
// depth test LESS_OR_EQUAL after the prime passes exactly the primed fragments.

struct LensConstants {
    view_proj: mat4x4<f32>,
    // Weight of viewpoint sample a (multipass: this pass's weight), b and c (single pass only).
    weight_a: f32,
    weight_b: f32,
    weight_c: f32,
    // Multipass: unused. Single pass: number of layers n (≤ MAX_LAYERS).
    layer_count: u32,
    // Single pass: bit 0 = refraction term present, bit 1 = reflection term present. Single pass
    // of path classes: the number of class terms.
    term_mask: u32,
    // Offsets in vec4 units into lens_data.
    position_offset: u32,
    // Multipass: this pass's F·G. Single pass: refraction F·G. Single pass of path classes: the
    // first class's F·G (each class's F·G and n direction arrays follow, vertex_count apart).
    fg_offset_t: u32,
    // Single pass: reflection F·G.
    fg_offset_r: u32,
    // Multipass: this pass's (term, layer) directions. Single pass: refraction layer 0.
    direction_offset_t: u32,
    // Single pass: reflection layer 0.
    direction_offset_r: u32,
    // Vertices in the mesh: the stride between consecutive layers' directions.
    vertex_count: u32,
    // Multipass: which cube of the array this pass samples.
    layer: u32,
    // Programmable blending: 1 where `current` holds the pixel's value before this pass, 0 for
    // the lens object's first layer pass (the value is the prime's zero).
    read_current: u32,
    // Programmable blending: 1 where a group boundary precedes this pass (the alpha clear).
    reset_alpha: u32,
    // 1 for the draw of a lens object's hull triangles (the convex-hull split): layer 0, the
    // local layer, is taken as (0, 0, 0, 0), the identity of every blend. Multipass: set only on
    // layer 0's draws. The fields take 124 bytes (the struct 128 with its padding), within the
    // 128-byte push-constant size every device has: no room is left for another field.
    skip_local: u32,
}


var<immediate> constants: LensConstants;

// The most viewpoint samples the single pass blends: one cube-map array each (layers_a, _b, _c
// below; shaders/build.rs checks the count against this constant, compiles the single pass for
// 1 ..= MAX_VIEWPOINTS and hands the limit to Rust as lensmap_shaders::MAX_VIEWPOINTS). Three
// are the samples of the spherical triangle that holds the camera direction.
const MAX_VIEWPOINTS: u32 = 3u;

// Set 0: the lens data, one cube-map array per blended viewpoint sample (the multipass layer
// passes read layers_a, which their set points at the pass's viewpoint), and the sampler.
@group(0) @binding(0) var<storage, read> lens_data: array<vec4<f32>>;
@group(0) @binding(1) var layers_a: texture_cube_array<f32>;
@group(0) @binding(2) var layers_b: texture_cube_array<f32>;
@group(0) @binding(3) var layers_c: texture_cube_array<f32>;
@group(0) @binding(4) var layer_sampler: sampler;

fn clip_position(vertex: u32) -> vec4<f32> {
    let position = lens_data[constants.position_offset + vertex].xyz;
    return constants.view_proj * vec4<f32>(position, 1.0);
}

@vertex
fn vs_position(@builtin(vertex_index) vertex: u32) -> @builtin(position) @invariant vec4<f32> {
    return clip_position(vertex);
}

@fragment
fn fs_zero() -> @location(0) vec4<f32> {
    return vec4<f32>(0.0);
}

struct LayerVertex {
    @builtin(position) @invariant clip: vec4<f32>,
    @location(0) fg: vec3<f32>,
    @location(1) direction: vec3<f32>,
}

@vertex
fn vs_layer(@builtin(vertex_index) vertex: u32) -> LayerVertex {
    var out: LayerVertex;
    out.clip = clip_position(vertex);
    out.fg = lens_data[constants.fg_offset_t + vertex].xyz;
    out.direction = lens_data[constants.direction_offset_t + vertex].xyz;
    return out;
}

// 0 where this draw takes layer 0 as empty (the convex-hull split's hull triangles), else 1.
fn local_keep() -> f32 {
    return select(1.0, 0.0, constants.skip_local != 0u);
}

@fragment
fn fs_layer(in: LayerVertex) -> @location(0) vec4<f32> {
    let texel = textureSample(layers_a, layer_sampler, in.direction, constants.layer) * local_keep();
    return vec4<f32>(texel.rgb * in.fg * constants.weight_a, texel.a);
}

// Programmable blending: the scratch image the previous layer pass wrote.
@group(1) @binding(0) var current: texture_2d<f32>;

// The layer pass with the blend in the shader: the same source as fs_layer, composited over the
// pixel's current value with the same arithmetic the fixed-function blend does,
// src·(1 − dstα) + dst, after the alpha clear where a group begins.
@fragment
fn fs_layer_programmable(in: LayerVertex) -> @location(0) vec4<f32> {
    let texel = textureSample(layers_a, layer_sampler, in.direction, constants.layer) * local_keep();
    let source = vec4<f32>(texel.rgb * in.fg * constants.weight_a, texel.a);
    var destination = vec4<f32>(0.0);
    if constants.read_current != 0u {
        destination = textureLoad(current, vec2<u32>(in.clip.xy), 0);
    }
    if constants.reset_alpha != 0u {
        destination.a = 0.0;
    }
    return source * (1.0 - destination.a) + destination;
}

// The most layers the single pass composites: one interpolated direction per layer and term
// (t0…t5, r0…r5 below) plus the two F·G make 2·MAX_LAYERS + 2 varyings, within Vulkan's guaranteed
// 16 locations. shaders/build.rs reads this constant: it compiles the single pass for every layer
// count up to it, and Rust takes the limit from there (lensmap_shaders::MAX_LAYERS).
const MAX_LAYERS: u32 = 6u;

struct SinglePassVertex {
    @builtin(position) @invariant clip: vec4<f32>,
    @location(0) fg_t: vec3<f32>,
    @location(1) fg_r: vec3<f32>,
    @location(2) t0: vec3<f32>,
    @location(3) t1: vec3<f32>,
    @location(4) t2: vec3<f32>,
    @location(5) t3: vec3<f32>,
    @location(6) t4: vec3<f32>,
    @location(7) t5: vec3<f32>,
    @location(8) r0: vec3<f32>,
    @location(9) r1: vec3<f32>,
    @location(10) r2: vec3<f32>,
    @location(11) r3: vec3<f32>,
    @location(12) r4: vec3<f32>,
    @location(13) r5: vec3<f32>,
}

fn direction(base: u32, layer: u32, vertex: u32) -> vec3<f32> {
    if layer < constants.layer_count {
        return lens_data[base + layer * constants.vertex_count + vertex].xyz;
    }
    return vec3<f32>(0.0, 0.0, 1.0);
}

@vertex
fn vs_single_pass(@builtin(vertex_index) vertex: u32) -> SinglePassVertex {
    var out: SinglePassVertex;
    out.clip = clip_position(vertex);
    let has_t = (constants.term_mask & 1u) != 0u;
    let has_r = (constants.term_mask & 2u) != 0u;
    out.fg_t = vec3<f32>(0.0);
    out.fg_r = vec3<f32>(0.0);
    let t = constants.direction_offset_t;
    let r = constants.direction_offset_r;
    out.t0 = vec3<f32>(0.0, 0.0, 1.0);
    out.t1 = out.t0; out.t2 = out.t0; out.t3 = out.t0; out.t4 = out.t0; out.t5 = out.t0;
    out.r0 = out.t0; out.r1 = out.t0; out.r2 = out.t0; out.r3 = out.t0; out.r4 = out.t0; out.r5 = out.t0;
    if has_t {
        out.fg_t = lens_data[constants.fg_offset_t + vertex].xyz;
        out.t0 = direction(t, 0u, vertex);
        out.t1 = direction(t, 1u, vertex);
        out.t2 = direction(t, 2u, vertex);
        out.t3 = direction(t, 3u, vertex);
        out.t4 = direction(t, 4u, vertex);
        out.t5 = direction(t, 5u, vertex);
    }
    if has_r {
        out.fg_r = lens_data[constants.fg_offset_r + vertex].xyz;
        out.r0 = direction(r, 0u, vertex);
        out.r1 = direction(r, 1u, vertex);
        out.r2 = direction(r, 2u, vertex);
        out.r3 = direction(r, 3u, vertex);
        out.r4 = direction(r, 4u, vertex);
        out.r5 = direction(r, 5u, vertex);
    }
    return out;
}

// One layer of a (viewpoint, term) group composited front to back onto the running (rgb, α),
// exactly as the blend unit does it: rgb += (1 − α)·texel.rgb·FG·w, α += (1 − α)·texel.α. The
// texel is multiplied by `keep`: 1, or 0 for a layer the draw takes as empty.
fn over_layer(
    running: vec4<f32>,
    layers: texture_cube_array<f32>,
    direction: vec3<f32>,
    layer: u32,
    fg: vec3<f32>,
    weight: f32,
    keep: f32,
) -> vec4<f32> {
    let texel = textureSample(layers, layer_sampler, direction, layer) * keep;
    let rgb = (texel.rgb * fg * weight) * (1.0 - running.a) + running.rgb;
    let alpha = texel.a * (1.0 - running.a) + running.a;
    return vec4<f32>(rgb, alpha);
}

// Specialization (see shaders/build.rs): the layer count n, which terms exist (bit 0 refraction,
// bit 1 reflection) and how many viewpoint samples are blended. With them constant the driver
// drops the code a frame does not need.
override LAYER_COUNT: u32 = 1u;
override TERM_MASK: u32 = 3u;
override VIEWPOINTS: u32 = 2u;

// One (viewpoint, term) group: α starts at 0 (the alpha clear), rgb carries the running sum.
fn composite_group(
    running: vec3<f32>,
    layers: texture_cube_array<f32>,
    d0: vec3<f32>, d1: vec3<f32>, d2: vec3<f32>, d3: vec3<f32>, d4: vec3<f32>, d5: vec3<f32>,
    fg: vec3<f32>,
    weight: f32,
) -> vec4<f32> {
    var result = over_layer(vec4<f32>(running, 0.0), layers, d0, 0u, fg, weight, local_keep());
    if LAYER_COUNT > 1u { result = over_layer(result, layers, d1, 1u, fg, weight, 1.0); }
    if LAYER_COUNT > 2u { result = over_layer(result, layers, d2, 2u, fg, weight, 1.0); }
    if LAYER_COUNT > 3u { result = over_layer(result, layers, d3, 3u, fg, weight, 1.0); }
    if LAYER_COUNT > 4u { result = over_layer(result, layers, d4, 4u, fg, weight, 1.0); }
    if LAYER_COUNT > 5u { result = over_layer(result, layers, d5, 5u, fg, weight, 1.0); }
    return result;
}

// One viewpoint sample's groups (refraction then reflection) onto the running colour.
fn composite_viewpoint(
    running: vec4<f32>,
    in: SinglePassVertex,
    layers: texture_cube_array<f32>,
    weight: f32,
) -> vec4<f32> {
    var result = running;
    if (TERM_MASK & 1u) != 0u {
        result = composite_group(result.rgb, layers, in.t0, in.t1, in.t2, in.t3, in.t4, in.t5, in.fg_t, weight);
    }
    if (TERM_MASK & 2u) != 0u {
        result = composite_group(result.rgb, layers, in.r0, in.r1, in.r2, in.r3, in.r4, in.r5, in.fg_r, weight);
    }
    return result;
}

// The single-pass variant: groups in the multipass order (viewpoint a, b, c; refraction then
// reflection), so the arithmetic matches the multipass frame. With fewer viewpoints, the first
// ones (`layers_a` and `weight_a`, then b) are theirs.
@fragment
fn fs_single_pass_specialized(in: SinglePassVertex) -> @location(0) vec4<f32> {
    var result = composite_viewpoint(vec4<f32>(0.0), in, layers_a, constants.weight_a);
    if VIEWPOINTS > 1u {
        result = composite_viewpoint(result, in, layers_b, constants.weight_b);
    }
    if VIEWPOINTS > 2u {
        result = composite_viewpoint(result, in, layers_c, constants.weight_c);
    }
    return result;
}

// The single pass of path classes: K class terms of n layers each carry K·(n + 1) varyings, the
// F·G and a direction per layer of each class in turn (slot k·(n + 1) is class k's F·G, the n
// after it its directions). shaders/build.rs reads this constant: it compiles the pass for every
// (n, K) with K·(n + 1) ≤ SINGLE_PASS_SLOTS, and Rust takes it as lensmap_shaders::SINGLE_PASS_SLOTS.
// 16 is Vulkan's guaranteed minimum (maxVertexOutputComponents and maxFragmentInputComponents
// of 64): four classes at n ≤ 3.
const SINGLE_PASS_SLOTS: u32 = 16u;

struct ClassesVertex {
    @builtin(position) @invariant clip: vec4<f32>,
    @location(0) s0: vec3<f32>,
    @location(1) s1: vec3<f32>,
    @location(2) s2: vec3<f32>,
    @location(3) s3: vec3<f32>,
    @location(4) s4: vec3<f32>,
    @location(5) s5: vec3<f32>,
    @location(6) s6: vec3<f32>,
    @location(7) s7: vec3<f32>,
    @location(8) s8: vec3<f32>,
    @location(9) s9: vec3<f32>,
    @location(10) s10: vec3<f32>,
    @location(11) s11: vec3<f32>,
    @location(12) s12: vec3<f32>,
    @location(13) s13: vec3<f32>,
    @location(14) s14: vec3<f32>,
    @location(15) s15: vec3<f32>,
}

// Slot `slot` of vertex `vertex`: a class's F·G or one of its layers' directions, as above;
// (0, 0, 1) past the last class (never read).
fn class_slot(slot: u32, vertex: u32) -> vec3<f32> {
    let per_class = constants.layer_count + 1u;
    if slot >= per_class * constants.term_mask {
        return vec3<f32>(0.0, 0.0, 1.0);
    }
    // The data holds each class's F·G array then its n direction arrays: slot order.
    return lens_data[constants.fg_offset_t + slot * constants.vertex_count + vertex].xyz;
}

@vertex
fn vs_single_pass_classes(@builtin(vertex_index) vertex: u32) -> ClassesVertex {
    var out: ClassesVertex;
    out.clip = clip_position(vertex);
    out.s0 = class_slot(0u, vertex); out.s1 = class_slot(1u, vertex);
    out.s2 = class_slot(2u, vertex); out.s3 = class_slot(3u, vertex);
    out.s4 = class_slot(4u, vertex); out.s5 = class_slot(5u, vertex);
    out.s6 = class_slot(6u, vertex); out.s7 = class_slot(7u, vertex);
    out.s8 = class_slot(8u, vertex); out.s9 = class_slot(9u, vertex);
    out.s10 = class_slot(10u, vertex); out.s11 = class_slot(11u, vertex);
    out.s12 = class_slot(12u, vertex); out.s13 = class_slot(13u, vertex);
    out.s14 = class_slot(14u, vertex); out.s15 = class_slot(15u, vertex);
    return out;
}

// The interpolated slot `slot` (a constant once the loops below are unrolled).
fn interpolated(in: ClassesVertex, slot: u32) -> vec3<f32> {
    switch slot {
        case 0u: { return in.s0; }
        case 1u: { return in.s1; }
        case 2u: { return in.s2; }
        case 3u: { return in.s3; }
        case 4u: { return in.s4; }
        case 5u: { return in.s5; }
        case 6u: { return in.s6; }
        case 7u: { return in.s7; }
        case 8u: { return in.s8; }
        case 9u: { return in.s9; }
        case 10u: { return in.s10; }
        case 11u: { return in.s11; }
        case 12u: { return in.s12; }
        case 13u: { return in.s13; }
        case 14u: { return in.s14; }
        default: { return in.s15; }
    }
}

// Specialization of the classes' single pass (see shaders/build.rs): the class terms K.
// LAYER_COUNT and VIEWPOINTS are the ones above.
override CLASS_COUNT: u32 = 1u;

// One viewpoint sample's (viewpoint, class) groups, classes in order, onto the running colour:
// per group α starts at 0 (the alpha clear) and its layers go front to back, as composite_group.
fn composite_viewpoint_classes(
    running: vec4<f32>,
    in: ClassesVertex,
    layers: texture_cube_array<f32>,
    weight: f32,
) -> vec4<f32> {
    var result = running;
    for (var k = 0u; k < CLASS_COUNT; k++) {
        let base = k * (LAYER_COUNT + 1u);
        let fg = interpolated(in, base);
        result = over_layer(vec4<f32>(result.rgb, 0.0), layers, interpolated(in, base + 1u), 0u, fg, weight, local_keep());
        for (var l = 1u; l < LAYER_COUNT; l++) {
            result = over_layer(result, layers, interpolated(in, base + 1u + l), l, fg, weight, 1.0);
        }
    }
    return result;
}

// The single pass of path classes: groups in the multipass order (viewpoint a, b, c; the classes
// in order), so the arithmetic matches the multipass frame.
@fragment
fn fs_single_pass_classes_specialized(in: ClassesVertex) -> @location(0) vec4<f32> {
    var result = composite_viewpoint_classes(vec4<f32>(0.0), in, layers_a, constants.weight_a);
    if VIEWPOINTS > 1u {
        result = composite_viewpoint_classes(result, in, layers_b, constants.weight_b);
    }
    if VIEWPOINTS > 2u {
        result = composite_viewpoint_classes(result, in, layers_c, constants.weight_c);
    }
    return result;
}
