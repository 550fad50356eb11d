// The draw list of a lens object's tessellation, made on the GPU so that the lens passes draw it
// with indirect draws and no per-vertex data goes back to the CPU: the output triangles of the
// T-junction removal (tessellate.wgsl) written as an index buffer, the convex-hull split's
// triangles last, each part in the tessellation's order (engine/src/hybrid/frame.rs `hull_last`
// on the CPU), by a stable partition (a prefix sum), so the index buffer is identical run to run;
// and the indirect draw arguments of the whole list, its non-hull part and its hull part.

struct DrawConstants {
    eye: vec3<f32>,
    // 1: the convex-hull split is on (the hull's triangles that face the eye go last).
    hull_split: u32,
}

var<immediate> constants: DrawConstants;

// The tessellation's control words (tessellate.wgsl CONTROL_*); the scan's words are rewritten.
@group(0) @binding(0) var<storage, read_write> control: array<atomic<u32>>;
// Output triangles: (a, b, c, the leaf triangle it lies in).
@group(0) @binding(1) var<storage, read> output: array<vec4<u32>>;
// Triangles of every level, two vec4 each: (a, b, c, input triangle), (edges, state).
@group(0) @binding(2) var<storage, read> tris: array<vec4<u32>>;
// Vertices, two vec4 each, the first holding the position's bits.
@group(0) @binding(3) var<storage, read> vertices: array<vec4<u32>>;
// Per input triangle, 1 when it lies on the convex hull of the lens geometry.
@group(0) @binding(4) var<storage, read> hull: array<u32>;
@group(0) @binding(5) var<storage, read_write> counts: array<vec4<u32>>;
@group(0) @binding(6) var<storage, read_write> block_sums: array<vec4<u32>>;
// Three indices per output triangle: the non-hull triangles, then the hull's.
@group(0) @binding(7) var<storage, read_write> indices: array<u32>;
// Three VkDrawIndexedIndirectCommand (index count, instance count, first index, vertex offset,
// first instance): every triangle, the non-hull ones, the hull's.
@group(0) @binding(8) var<storage, read_write> args: array<u32>;

// #include "control.wgsl"

fn load(word: u32) -> u32 {
    return atomicLoad(&control[word]);
}

// #include "scan.wgsl"

// The output triangles in the list: all of them, or as many as the buffers hold (the scan's
// too).
fn triangle_count() -> u32 {
    let held = min(min(arrayLength(&output), arrayLength(&counts)), arrayLength(&indices) / 3u);
    return min(load(CONTROL_OUTPUT), held);
}

fn position(v: u32) -> vec3<f32> {
    return bitcast<vec3<f32>>(vertices[2u * v].xyz);
}

// Whether output triangle `i` goes in the hull part: its input triangle is on the hull and it
// faces the eye (frame.rs `facing_hull`).
fn on_hull(i: u32) -> bool {
    if constants.hull_split == 0u {
        return false;
    }
    let triangle = output[i];
    let source = tris[2u * triangle.w].w;
    if source >= arrayLength(&hull) || hull[source] == 0u {
        return false;
    }
    let a = position(triangle.x);
    let b = position(triangle.y);
    let c = position(triangle.z);
    return dot(constants.eye - a, cross(b - a, c - a)) > 0.0;
}

// One invocation: the scan and the per-triangle passes run over the output triangles.
@compute @workgroup_size(1)
fn cs_draw_begin() {
    let n = triangle_count();
    atomicStore(&control[CONTROL_SCAN_N], n);
    atomicStore(&control[CONTROL_DISPATCH_ELEMENTS], (n + WORKGROUP - 1u) / WORKGROUP);
    atomicStore(&control[CONTROL_DISPATCH_BLOCKS], (n + SCAN_BLOCK - 1u) / SCAN_BLOCK);
}

@compute @workgroup_size(64)
fn cs_draw_count(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= triangle_count() {
        return;
    }
    let hull_part = u32(on_hull(id.x));
    counts[id.x] = vec4<u32>(1u - hull_part, hull_part, 0u, 0u);
}

// One invocation, after the scan: the three draws' arguments.
@compute @workgroup_size(1)
fn cs_draw_args() {
    let n = triangle_count();
    var rest = 0u;
    if n > 0u {
        rest = scanned(n - 1u).x + u32(!on_hull(n - 1u));
    }
    let commands = array<vec2<u32>, 3>(vec2<u32>(n, 0u), vec2<u32>(rest, 0u), vec2<u32>(n - rest, rest));
    for (var d = 0u; d < 3u; d++) {
        args[5u * d] = 3u * commands[d].x;
        args[5u * d + 1u] = 1u;
        args[5u * d + 2u] = 3u * commands[d].y;
        args[5u * d + 3u] = 0u;
        args[5u * d + 4u] = 0u;
    }
}

@compute @workgroup_size(64)
fn cs_draw_emit(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= triangle_count() {
        return;
    }
    let before = scanned(id.x);
    var slot = before.x;
    if on_hull(id.x) {
        slot = args[5u] / 3u + before.y;
    }
    let triangle = output[id.x];
    indices[3u * slot] = triangle.x;
    indices[3u * slot + 1u] = triangle.y;
    indices[3u * slot + 2u] = triangle.z;
}
