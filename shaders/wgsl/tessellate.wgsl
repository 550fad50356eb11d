// Adaptive tessellation of a lens object on the GPU (hybrid-rendering paper §5, "Adaptive
// Tessellation"), by the rules of the CPU tessellator (engine/src/hybrid/tessellate.rs), level by
// level, with every record kept on the GPU:
//
// - per level: the vertex pass of tracer.wgsl (`cs_level_paths`) traces the level's new vertices;
//   `cs_decide` applies the paper's criteria (occlusion, view, path difference, edge length in
//   subpixels, depth cap) and each splitting triangle asks for its long edges' midpoints with an
//   atomic minimum of its index; `cs_count` counts what each triangle will create (only the
//   lowest-indexed asker of an edge creates its midpoint, as on the CPU, where the first asker in
//   order does); a stable exclusive prefix sum (`cs_scan_blocks`, `cs_scan_top`) gives every
//   triangle its place; `cs_apply` refuses splits past the vertex budget (the prefix sums are
//   monotone, so the refused are a suffix, as on the CPU) and creates the midpoints; `cs_emit`
//   writes the children; `cs_advance` sets up the next level's ranges and dispatches.
// - Midpoints are shared through the edges: every edge of the base mesh, and every edge a split
//   creates, is a record with its midpoint and two half edges once split (hierarchical edges), so
//   neighbours meet at one vertex. Indices come from the prefix sums, never from the order in
//   which atomics land: the output is identical run to run.
// - Then T-junction removal per leaf (`cs_leaf_count`, a prefix sum, `cs_leaf_emit`): a leaf whose
//   sides carry vertices of finer neighbours is re-triangulated through them by fans that never
//   join two vertices of one side (so no triangle is degenerate and no vertex lies on a chord).

struct TessellateConstants {
    // World → Vulkan clip space.
    view_proj: mat4x4<f32>,
    eye: vec3<f32>,
    // Screen-space edge threshold in subpixels.
    t: f32,
    // Two outgoing directions differ when their cosine is below this.
    cos_threshold: f32,
    // The CPU's TessellationOptions::max_depth.
    max_depth: u32,
    // Vertices, edges and triangles the buffers hold: splitting stops before passing them.
    vertex_capacity: u32,
    edge_capacity: u32,
    triangle_capacity: u32,
    input_vertices: u32,
    input_triangles: u32,
    base_edges: u32,
    // 1: back-facing input triangles are subdivided too.
    back_faces: u32,
}

var<immediate> constants: TessellateConstants;

// Half an edge's split: its midpoint vertex and halves (NONE until split), and the lowest index
// (within the level) of a triangle asking for its midpoint.
struct EdgeState {
    mid: u32,
    child0: u32,
    child1: u32,
    request: atomic<u32>,
}

// Vertices, two vec4 each: (position, the lower origin vertex), (unit normal, the higher origin
// vertex), the floats as their bits (so that the origins are stored as integers, not as float
// bit patterns a driver might flush); origins are NONE for an input vertex. The tracer and
// texgen read the same buffer as floats.
@group(0) @binding(0) var<storage, read_write> vertices: array<vec4<u32>>;
// Per vertex the tracer's record, seven vec4 (tracer.wgsl VertexRecord).
@group(0) @binding(1) var<storage, read> records: array<vec4<f32>>;
// Ranges, dispatch arguments and counts: CONTROL_* below.
@group(0) @binding(2) var<storage, read_write> control: array<atomic<u32>>;
// Per input vertex: 1 when a triangle that is subdivided uses it (only those are traced).
@group(0) @binding(3) var<storage, read_write> wanted: array<atomic<u32>>;
// Triangles of every level, two vec4 each: (a, b, c, input triangle), (edge ab, bc, ca, state).
@group(0) @binding(4) var<storage, read_write> tris: array<vec4<u32>>;
// Edges: (v0, v1); a split edge's halves are (v0, mid) and (mid, v1).
@group(0) @binding(5) var<storage, read_write> edge_ends: array<vec2<u32>>;
@group(0) @binding(6) var<storage, read_write> edge_state: array<EdgeState>;
// Per element of a prefix sum its counts, replaced by its exclusive prefix within its block.
@group(0) @binding(7) var<storage, read_write> counts: array<vec4<u32>>;
// Per block of SCAN_BLOCK elements its total, replaced by its exclusive prefix.
@group(0) @binding(8) var<storage, read_write> block_sums: array<vec4<u32>>;
// Output triangles: (a, b, c, the leaf triangle it lies in).
@group(0) @binding(9) var<storage, read_write> output: array<vec4<u32>>;
// The input mesh, resident: vertices like `vertices`, triangles (a, b, c, 0), (edge ab, bc, ca, 0)
// (edges NONE for a degenerate triangle), and the base edges' ends.
@group(0) @binding(10) var<storage, read> input_vertices: array<vec4<u32>>;
@group(0) @binding(11) var<storage, read> input_triangles: array<vec4<u32>>;
@group(0) @binding(12) var<storage, read> base_edges: array<vec2<u32>>;

const NONE: u32 = 0xffffffffu;

// #include "control.wgsl"

// A triangle's state word: its stop reason (STOP_*; 0 while active), its long edges (bits 4-6)
// and its depth (bits 8 and up).
const STOP_BACK_FACING: u32 = 1u;
const STOP_DEGENERATE: u32 = 2u;
const STOP_OCCLUDED: u32 = 3u;
const STOP_OFF_SCREEN: u32 = 4u;
const STOP_SIMILAR: u32 = 5u;
const STOP_SMALL: u32 = 6u;
const STOP_MAX_DEPTH: u32 = 7u;
const STOP_BUDGET: u32 = 8u;
const SPLIT: u32 = 15u;

// Entries of an edge walk's stack: two per level of an edge's split tree and one (the depth cap
// is at most 30 on the GPU, so a tree has at most 31 levels).
const WALK_STACK: u32 = 64u;
// Marks a stack entry of an edge walk as a vertex to emit (vertex indices stay below 2³¹).
const EMIT: u32 = 0x80000000u;

fn stop_of(state: u32) -> u32 {
    return state & 15u;
}

fn depth_of(state: u32) -> u32 {
    return state >> 8u;
}

fn long_of(state: u32) -> u32 {
    return (state >> 4u) & 7u;
}

fn position(v: u32) -> vec3<f32> {
    return bitcast<vec3<f32>>(vertices[2u * v].xyz);
}

fn input_position(v: u32) -> vec3<f32> {
    return bitcast<vec3<f32>>(input_vertices[2u * v].xyz);
}

fn load(word: u32) -> u32 {
    return atomicLoad(&control[word]);
}

// ---- Setting up a frame ---------------------------------------------------------------------

// Copies the input vertices and base edges into the frame's buffers (edges unsplit).
@compute @workgroup_size(64)
fn cs_begin(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i == 0u {
        let budget = max(load(CONTROL_FRAME_BUDGET), constants.input_vertices);
        atomicStore(&control[CONTROL_OBJECT_BUDGET], budget);
        atomicStore(&control[CONTROL_VERTEX_LIMIT], min(constants.vertex_capacity, budget));
    }
    if i < constants.input_vertices {
        vertices[2u * i] = input_vertices[2u * i];
        vertices[2u * i + 1u] = input_vertices[2u * i + 1u];
    }
    if i < constants.base_edges {
        edge_ends[i] = base_edges[i];
        reset_edge(i);
    }
}

fn reset_edge(e: u32) {
    edge_state[e].mid = NONE;
    edge_state[e].child0 = NONE;
    edge_state[e].child1 = NONE;
    atomicStore(&edge_state[e].request, NONE);
}

fn faces_eye(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> bool {
    return dot(constants.eye - a, cross(b - a, c - a)) > 0.0;
}

// Level 0: the input triangles, classified as the CPU does (degenerate, back-facing, active);
// an active triangle's corners are traced.
@compute @workgroup_size(64)
fn cs_classify(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= constants.input_triangles {
        return;
    }
    let corners = input_triangles[2u * i];
    let edges = input_triangles[2u * i + 1u];
    var stop = 0u;
    if corners.x == corners.y || corners.y == corners.z || corners.z == corners.x {
        stop = STOP_DEGENERATE;
    } else if !faces_eye(
        input_position(corners.x),
        input_position(corners.y),
        input_position(corners.z),
    ) {
        atomicAdd(&control[STAT_BACK], 1u);
        if constants.back_faces == 0u {
            stop = STOP_BACK_FACING;
        }
    } else {
        atomicAdd(&control[STAT_FRONT], 1u);
    }
    if stop == 0u {
        atomicStore(&wanted[corners.x], 1u);
        atomicStore(&wanted[corners.y], 1u);
        atomicStore(&wanted[corners.z], 1u);
    }
    tris[2u * i] = vec4<u32>(corners.xyz, i);
    tris[2u * i + 1u] = vec4<u32>(edges.xyz, stop);
}

// ---- One level ------------------------------------------------------------------------------

// A vertex's record: max(classes, 2) terms of three vec4 (the greedy refraction and reflection
// terms, or one per path class), then the screen position (tracer.wgsl `write_term`). The
// path classes' count and the record's vec4s, read from the control words once per invocation
// by `decide` (the only reader of records).
var<private> class_count: u32;
var<private> record_stride: u32;

fn record(v: u32, k: u32) -> vec4<f32> {
    return records[record_stride * v + k];
}

fn screen(v: u32) -> vec4<f32> {
    return record(v, record_stride - 1u);
}

// Whether vertex p has term `term`, and the term's topology (interfaces, reflections).
fn has_term(p: u32, base: u32) -> bool {
    return record(p, base + 2u).w != 0.0;
}

fn topology(p: u32, base: u32) -> vec2<u32> {
    return vec2<u32>(bitcast<u32>(record(p, base).w), bitcast<u32>(record(p, base + 1u).w));
}

// Whether two vertices' paths differ (PathOracle::differ): a term one has and the other has not,
// another topology, or outgoing directions more than the angle threshold apart. Under path
// classes (classes_differ), each class's angle weighted by its F·G (the larger of the two
// vertices', its largest channel) against the threshold; a class at one vertex only, or of
// another topology, counts as π.
fn differ(p: u32, q: u32) -> bool {
    let classes = class_count;
    if classes > 0u {
        let threshold = acos(clamp(constants.cos_threshold, -1.0, 1.0));
        for (var k = 0u; k < classes; k++) {
            let base = 3u * k;
            let has_p = has_term(p, base);
            let has_q = has_term(q, base);
            var angle = 0.0;
            if has_p && has_q && all(topology(p, base) == topology(q, base)) {
                angle = acos(clamp(dot(record(p, base + 2u).xyz, record(q, base + 2u).xyz), -1.0, 1.0));
            } else if has_p || has_q {
                angle = 3.14159265358979;
            }
            var weight = 0.0;
            if has_p {
                let fg = record(p, base).xyz;
                weight = max(max(max(fg.x, fg.y), fg.z), 0.0);
            }
            if has_q {
                let fg = record(q, base).xyz;
                weight = max(weight, max(max(fg.x, fg.y), fg.z));
            }
            if weight * angle > threshold {
                return true;
            }
        }
        return false;
    }
    for (var term = 0u; term < 2u; term++) {
        let base = 3u * term;
        let has_p = has_term(p, base);
        let has_q = has_term(q, base);
        if has_p != has_q {
            return true;
        }
        if has_p {
            if any(topology(p, base) != topology(q, base)) {
                return true;
            }
            if dot(record(p, base + 2u).xyz, record(q, base + 2u).xyz) < constants.cos_threshold {
                return true;
            }
        }
    }
    return false;
}

// Whether the projected edge is at least t subpixels long; unprojectable edges are short.
fn edge_is_long(p: u32, q: u32) -> bool {
    let sp = screen(p);
    let sq = screen(q);
    return sp.z != 0.0 && sq.z != 0.0 && distance(sp.xy, sq.xy) >= constants.t;
}

// Whether the triangle lies wholly beyond one side or the near plane of the view volume.
fn outside_view(corners: vec3<u32>) -> bool {
    let a = constants.view_proj * vec4<f32>(position(corners.x), 1.0);
    let b = constants.view_proj * vec4<f32>(position(corners.y), 1.0);
    let c = constants.view_proj * vec4<f32>(position(corners.z), 1.0);
    let xs = vec3<f32>(a.x, b.x, c.x);
    let ys = vec3<f32>(a.y, b.y, c.y);
    let zs = vec3<f32>(a.z, b.z, c.z);
    let ws = vec3<f32>(a.w, b.w, c.w);
    return all(xs < -ws) || all(xs > ws) || all(ys < -ws) || all(ys > ws) || all(zs < vec3<f32>(0.0));
}

// The CPU's criteria in its order: occlusion, view, difference, size, depth cap.
fn decide(corners: vec3<u32>, depth: u32) -> u32 {
    class_count = load(CONTROL_CLASSES);
    record_stride = 3u * max(class_count, 2u) + 1u;
    let visible = screen(corners.x).w != 0.0 || screen(corners.y).w != 0.0
        || screen(corners.z).w != 0.0;
    if !visible {
        return STOP_OCCLUDED;
    }
    if outside_view(corners) {
        return STOP_OFF_SCREEN;
    }
    if !(differ(corners.x, corners.y) || differ(corners.y, corners.z) || differ(corners.z, corners.x)) {
        return STOP_SIMILAR;
    }
    var long = 0u;
    if edge_is_long(corners.x, corners.y) {
        long |= 1u;
    }
    if edge_is_long(corners.y, corners.z) {
        long |= 2u;
    }
    if edge_is_long(corners.z, corners.x) {
        long |= 4u;
    }
    if long == 0u {
        return STOP_SMALL;
    }
    if depth >= constants.max_depth {
        return STOP_MAX_DEPTH;
    }
    return SPLIT | (long << 4u);
}

// The level's triangle `id` (absolute index), or NONE past the level.
fn level_triangle(id: u32) -> u32 {
    let t = load(CONTROL_LEVEL_LO) + id;
    if t >= load(CONTROL_LEVEL_HI) {
        return NONE;
    }
    return t;
}

@compute @workgroup_size(64)
fn cs_decide(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = level_triangle(id.x);
    if t == NONE {
        return;
    }
    let head = tris[2u * t];
    let edges = tris[2u * t + 1u];
    if stop_of(edges.w) != 0u {
        return;
    }
    let depth = depth_of(edges.w);
    let decision = decide(head.xyz, depth);
    tris[2u * t + 1u].w = decision | (depth << 8u);
    if stop_of(decision) != SPLIT {
        atomicMax(&control[STAT_MAX_DEPTH_REACHED], depth);
        if decision == STOP_MAX_DEPTH {
            atomicAdd(&control[STAT_AT_MAX_DEPTH], 1u);
        } else if decision == STOP_OCCLUDED {
            atomicAdd(&control[STAT_OCCLUDED], 1u);
        }
        return;
    }
    let long = long_of(decision);
    for (var s = 0u; s < 3u; s++) {
        if (long & (1u << s)) != 0u && edge_state[edges[s]].mid == NONE {
            atomicMin(&edge_state[edges[s]].request, id.x);
        }
    }
}

// The CPU's rotation of a split triangle: its long edges first (for one, it is ab; for two, the
// short one is ca).
fn rotation(long: u32) -> u32 {
    let count = countOneBits(long);
    if count == 1u {
        return firstTrailingBit(long);
    }
    if count == 2u {
        return (firstTrailingBit(~long & 7u) + 1u) % 3u;
    }
    return 0u;
}

// Which of the triangle's long edges (in rotated order) it creates the midpoint of: bit r for
// rotated edge r.
fn owned_edges(t: u32, local: u32) -> u32 {
    let edges = tris[2u * t + 1u];
    let long = long_of(edges.w);
    let r = rotation(long);
    var owned = 0u;
    for (var k = 0u; k < countOneBits(long); k++) {
        let e = edges[(k + r) % 3u];
        if atomicLoad(&edge_state[e].request) == local {
            owned |= 1u << k;
        }
    }
    return owned;
}

// Per triangle: new vertices, new edges (two halves per new midpoint, one inside per long edge),
// children.
@compute @workgroup_size(64)
fn cs_count(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = level_triangle(id.x);
    if t == NONE {
        return;
    }
    let state = tris[2u * t + 1u].w;
    var c = vec4<u32>(0u);
    if stop_of(state) == SPLIT {
        let k = countOneBits(long_of(state));
        let owned = countOneBits(owned_edges(t, id.x));
        c = vec4<u32>(owned, 2u * owned + k, k + 1u, 0u);
    }
    counts[id.x] = c;
}

// #include "scan.wgsl"

// A unit normal for a midpoint: the renormalized sum of its ends' normals, or (when they cancel)
// the input triangle's face normal.
fn midpoint_normal(lo: u32, hi: u32, source: u32) -> vec3<f32> {
    let sum = bitcast<vec3<f32>>(vertices[2u * lo + 1u].xyz)
        + bitcast<vec3<f32>>(vertices[2u * hi + 1u].xyz);
    let length_squared = dot(sum, sum);
    if length_squared > 0.0 && length_squared < 3.0e38 {
        return sum / sqrt(length_squared);
    }
    let corners = input_triangles[2u * source].xyz;
    let a = input_position(corners.x);
    let face = cross(input_position(corners.y) - a, input_position(corners.z) - a);
    let face_squared = dot(face, face);
    if face_squared > 0.0 {
        return face / sqrt(face_squared);
    }
    return vec3<f32>(0.0);
}

fn new_edge(e: u32, ends: vec2<u32>) {
    edge_ends[e] = ends;
    reset_edge(e);
}

// Refuses a split past a capacity (marking it BUDGET), or creates the midpoints it owns.
@compute @workgroup_size(64)
fn cs_apply(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = level_triangle(id.x);
    if t == NONE {
        return;
    }
    let head = tris[2u * t];
    let edges = tris[2u * t + 1u];
    if stop_of(edges.w) != SPLIT {
        return;
    }
    let depth = depth_of(edges.w);
    let before = scanned(id.x);
    let vertex_base = load(CONTROL_VERTICES);
    let edge_base = load(CONTROL_EDGES);
    let triangle_base = load(CONTROL_LEVEL_HI);
    // A split adds at most 3 vertices, 9 edges and 4 triangles: none once they would not fit.
    let fits = vertex_base + before.x + 3u <= load(CONTROL_VERTEX_LIMIT)
        && edge_base + before.y + 9u <= constants.edge_capacity
        && triangle_base + before.z + 4u <= constants.triangle_capacity;
    if !fits {
        tris[2u * t + 1u].w = STOP_BUDGET | (depth << 8u);
        atomicAdd(&control[STAT_BUDGET], 1u);
        atomicMax(&control[STAT_MAX_DEPTH_REACHED], depth);
        return;
    }
    let long = long_of(edges.w);
    let k = countOneBits(long);
    let owned = owned_edges(t, id.x);
    let r = rotation(long);
    var made = 0u;
    for (var j = 0u; j < k; j++) {
        if (owned & (1u << j)) == 0u {
            continue;
        }
        let e = edges[(j + r) % 3u];
        let ends = edge_ends[e];
        let lo = min(ends.x, ends.y);
        let hi = max(ends.x, ends.y);
        let v = vertex_base + before.x + made;
        let half = edge_base + before.y + 2u * made;
        vertices[2u * v] = vec4<u32>(bitcast<vec3<u32>>((position(lo) + position(hi)) * 0.5), lo);
        vertices[2u * v + 1u] = vec4<u32>(bitcast<vec3<u32>>(midpoint_normal(lo, hi, head.w)), hi);
        new_edge(half, vec2<u32>(ends.x, v));
        new_edge(half + 1u, vec2<u32>(v, ends.y));
        edge_state[e].mid = v;
        edge_state[e].child0 = half;
        edge_state[e].child1 = half + 1u;
        made += 1u;
    }
    atomicAdd(&control[STAT_SPLITS + k - 1u], 1u);
    atomicAdd(&control[STAT_CREATED], made);
    atomicAdd(&control[STAT_REQUESTS], k);
    atomicMax(&control[CONTROL_NEXT_VERTICES], vertex_base + before.x + made);
    atomicMax(&control[CONTROL_NEXT_EDGES], edge_base + before.y + 2u * made + k);
    atomicMax(&control[CONTROL_NEXT_HI], triangle_base + before.z + k + 1u);
    counts[id.x] = vec4<u32>(before.xyz, made);
}

// The half of split edge `e` that ends at `corner`.
fn half_at(e: u32, corner: u32) -> u32 {
    if edge_ends[e].x == corner {
        return edge_state[e].child0;
    }
    return edge_state[e].child1;
}

// Writes child `slot` of the level's children.
fn child(slot: u32, corners: vec3<u32>, edges: vec3<u32>, source: u32, depth: u32) {
    tris[2u * slot] = vec4<u32>(corners, source);
    tris[2u * slot + 1u] = vec4<u32>(edges, depth << 8u);
}

// Writes an accepted split's children (the CPU's, in its order) and the edges inside it; every
// triangle of the level then clears its edges' requests for the next level.
@compute @workgroup_size(64)
fn cs_emit(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = level_triangle(id.x);
    if t == NONE {
        return;
    }
    let head = tris[2u * t];
    let edges = tris[2u * t + 1u];
    if stop_of(edges.w) == SPLIT {
        emit_children(t, id.x, head, edges);
    }
    for (var s = 0u; s < 3u; s++) {
        if edges[s] != NONE {
            atomicStore(&edge_state[edges[s]].request, NONE);
        }
    }
}

fn emit_children(t: u32, local: u32, head: vec4<u32>, edges: vec4<u32>) {
    let before = counts[local];
    let long = long_of(edges.w);
    let k = countOneBits(long);
    let r = rotation(long);
    let depth = depth_of(edges.w) + 1u;
    let a = head[r];
    let b = head[(r + 1u) % 3u];
    let c = head[(r + 2u) % 3u];
    let e_ab = edges[r];
    let e_bc = edges[(r + 1u) % 3u];
    let e_ca = edges[(r + 2u) % 3u];
    let inner = load(CONTROL_EDGES) + before.y + 2u * before.w;
    let slot = load(CONTROL_LEVEL_HI) + before.z;
    let ab = edge_state[e_ab].mid;
    if k == 1u {
        new_edge(inner, vec2<u32>(ab, c));
        child(slot, vec3<u32>(a, ab, c), vec3<u32>(half_at(e_ab, a), inner, e_ca), head.w, depth);
        child(slot + 1u, vec3<u32>(ab, b, c), vec3<u32>(half_at(e_ab, b), e_bc, inner), head.w, depth);
        return;
    }
    let bc = edge_state[e_bc].mid;
    if k == 2u {
        // The quad a, ab, bc, c is cut along its shorter diagonal (the CPU's rule).
        new_edge(inner, vec2<u32>(bc, ab));
        child(slot, vec3<u32>(ab, b, bc), vec3<u32>(half_at(e_ab, b), half_at(e_bc, b), inner), head.w, depth);
        let a_bc = dot(position(a) - position(bc), position(a) - position(bc));
        let ab_c = dot(position(ab) - position(c), position(ab) - position(c));
        if a_bc <= ab_c {
            new_edge(inner + 1u, vec2<u32>(a, bc));
            child(slot + 1u, vec3<u32>(a, ab, bc), vec3<u32>(half_at(e_ab, a), inner, inner + 1u), head.w, depth);
            child(slot + 2u, vec3<u32>(a, bc, c), vec3<u32>(inner + 1u, half_at(e_bc, c), e_ca), head.w, depth);
        } else {
            new_edge(inner + 1u, vec2<u32>(ab, c));
            child(slot + 1u, vec3<u32>(a, ab, c), vec3<u32>(half_at(e_ab, a), inner + 1u, e_ca), head.w, depth);
            child(slot + 2u, vec3<u32>(ab, bc, c), vec3<u32>(inner, half_at(e_bc, c), inner + 1u), head.w, depth);
        }
        return;
    }
    let ca = edge_state[e_ca].mid;
    new_edge(inner, vec2<u32>(ab, ca));
    new_edge(inner + 1u, vec2<u32>(ab, bc));
    new_edge(inner + 2u, vec2<u32>(bc, ca));
    child(slot, vec3<u32>(a, ab, ca), vec3<u32>(half_at(e_ab, a), inner, half_at(e_ca, a)), head.w, depth);
    child(slot + 1u, vec3<u32>(ab, b, bc), vec3<u32>(half_at(e_ab, b), half_at(e_bc, b), inner + 1u), head.w, depth);
    child(slot + 2u, vec3<u32>(ca, bc, c), vec3<u32>(inner + 2u, half_at(e_bc, c), half_at(e_ca, c)), head.w, depth);
    child(slot + 3u, vec3<u32>(ab, bc, ca), vec3<u32>(inner + 1u, inner + 2u, inner), head.w, depth);
}

fn groups(n: u32, size: u32) -> u32 {
    return (n + size - 1u) / size;
}

// Dispatch arguments of the per-element passes and the prefix sum over `n` elements.
fn set_element_dispatch(n: u32) {
    atomicStore(&control[CONTROL_SCAN_N], n);
    atomicStore(&control[CONTROL_DISPATCH_ELEMENTS], groups(n, WORKGROUP));
    atomicStore(&control[CONTROL_DISPATCH_BLOCKS], groups(n, SCAN_BLOCK));
}

// One invocation: the next level's triangles are this level's children, its vertices to trace
// the midpoints just made.
@compute @workgroup_size(1)
fn cs_advance() {
    let lo = load(CONTROL_LEVEL_HI);
    let hi = load(CONTROL_NEXT_HI);
    let vertex_lo = load(CONTROL_VERTICES);
    let vertex_hi = load(CONTROL_NEXT_VERTICES);
    atomicStore(&control[CONTROL_LEVEL_LO], lo);
    atomicStore(&control[CONTROL_LEVEL_HI], hi);
    atomicStore(&control[CONTROL_VERTEX_LO], vertex_lo);
    atomicStore(&control[CONTROL_VERTEX_HI], vertex_hi);
    atomicStore(&control[CONTROL_VERTICES], vertex_hi);
    atomicStore(&control[CONTROL_EDGES], load(CONTROL_NEXT_EDGES));
    atomicAdd(&control[CONTROL_LEVEL], 1u);
    atomicStore(&control[CONTROL_DISPATCH_TRACE], groups(vertex_hi - vertex_lo, WORKGROUP));
    set_element_dispatch(hi - lo);
}

// ---- T-junction removal -----------------------------------------------------------------------

// One invocation after the last level: the leaf passes run over every triangle made, and the
// texgen pass over every vertex.
@compute @workgroup_size(1)
fn cs_leaves_begin() {
    atomicStore(&control[CONTROL_LEVEL_LO], 0u);
    set_element_dispatch(load(CONTROL_LEVEL_HI));
    // The levels are traced: the trace arguments now cover every vertex (texgen.wgsl's pass).
    let vertices = load(CONTROL_VERTICES);
    atomicStore(&control[CONTROL_DISPATCH_TRACE], groups(vertices, WORKGROUP));
    let budget = load(CONTROL_FRAME_BUDGET);
    atomicStore(&control[CONTROL_FRAME_BUDGET], budget - min(budget, vertices));
}

// An in-order walk of the vertices a split edge's tree places strictly inside it, from vertex `start`.
struct EdgeWalk {
    stack: array<u32, 64>,
    top: u32,
    reversed: bool,
}

fn walk_start(e: u32, start: u32) -> EdgeWalk {
    var walk: EdgeWalk;
    walk.stack[0] = e;
    walk.top = 1u;
    walk.reversed = edge_ends[e].x != start;
    return walk;
}

// The walk's next vertex, NONE at the end.
fn walk_next(walk: ptr<function, EdgeWalk>) -> u32 {
    while (*walk).top > 0u {
        (*walk).top -= 1u;
        let entry = (*walk).stack[(*walk).top];
        if (entry & EMIT) != 0u {
            return entry & ~EMIT;
        }
        // Field by field: the struct holds an atomic, which WGSL does not load whole.
        let mid = edge_state[entry].mid;
        if mid == NONE || (*walk).top + 3u > WALK_STACK {
            continue;
        }
        var first = edge_state[entry].child0;
        var second = edge_state[entry].child1;
        if (*walk).reversed {
            let swap = first;
            first = second;
            second = swap;
        }
        (*walk).stack[(*walk).top] = second;
        (*walk).stack[(*walk).top + 1u] = mid | EMIT;
        (*walk).stack[(*walk).top + 2u] = first;
        (*walk).top += 3u;
    }
    return NONE;
}

fn side_count(e: u32, start: u32) -> u32 {
    var walk = walk_start(e, start);
    var n = 0u;
    while walk_next(&walk) != NONE {
        n += 1u;
    }
    return n;
}

// A leaf's vertices on each side (0 for a split triangle or a degenerate one).
fn sides(head: vec4<u32>, edges: vec4<u32>) -> vec3<u32> {
    if stop_of(edges.w) == SPLIT || stop_of(edges.w) == STOP_DEGENERATE {
        return vec3<u32>(0u);
    }
    return vec3<u32>(side_count(edges.x, head.x), side_count(edges.y, head.y), side_count(edges.z, head.z));
}

@compute @workgroup_size(64)
fn cs_leaf_count(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = level_triangle(id.x);
    if t == NONE {
        return;
    }
    let edges = tris[2u * t + 1u];
    var n = 0u;
    if stop_of(edges.w) != SPLIT {
        let on_sides = sides(tris[2u * t], edges);
        let extra = on_sides.x + on_sides.y + on_sides.z;
        n = extra + 1u;
        if extra > 0u {
            atomicAdd(&control[STAT_T_JUNCTION_LEAVES], 1u);
            atomicAdd(&control[STAT_T_JUNCTION_VERTICES], extra);
        }
    }
    counts[id.x] = vec4<u32>(n, 0u, 0u, 0u);
}

fn put(slot: u32, corners: vec3<u32>, leaf: u32) {
    if slot < arrayLength(&output) {
        output[slot] = vec4<u32>(corners, leaf);
    }
}

// A leaf's output triangles. With vertices on its sides: apex A is the corner opposite the
// first side BC that carries some, p1 … p(m-1) those on BC from B. The triangles are the fan
// from p1 over side AB, the fan from A over p1 … p(m-1), and the fan from p(m-1) over side CA;
// none joins two vertices of one side.
@compute @workgroup_size(64)
fn cs_leaf_emit(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = level_triangle(id.x);
    if t == NONE {
        return;
    }
    let head = tris[2u * t];
    let edges = tris[2u * t + 1u];
    if stop_of(edges.w) == SPLIT {
        return;
    }
    var slot = scanned(id.x).x;
    let on_sides = sides(head, edges);
    atomicMax(&control[CONTROL_OUTPUT], slot + on_sides.x + on_sides.y + on_sides.z + 1u);
    if all(on_sides == vec3<u32>(0u)) {
        put(slot, head.xyz, t);
        return;
    }
    var base = 0u;
    if on_sides.x == 0u {
        base = select(2u, 1u, on_sides.y > 0u);
    }
    let apex = (base + 2u) % 3u;
    let a = head[apex];
    let b = head[base];
    let c = head[(base + 1u) % 3u];
    var bc = walk_start(edges[base], b);
    let p1 = walk_next(&bc);
    // Fan from p1 over AB.
    var ab = walk_start(edges[apex], a);
    var previous = a;
    for (var q = walk_next(&ab); q != NONE; q = walk_next(&ab)) {
        put(slot, vec3<u32>(previous, q, p1), t);
        slot += 1u;
        previous = q;
    }
    put(slot, vec3<u32>(previous, b, p1), t);
    slot += 1u;
    // Fan from A over BC's vertices.
    previous = p1;
    for (var p = walk_next(&bc); p != NONE; p = walk_next(&bc)) {
        put(slot, vec3<u32>(a, previous, p), t);
        slot += 1u;
        previous = p;
    }
    // Fan from p(m-1) over CA.
    let last = previous;
    var ca = walk_start(edges[(base + 1u) % 3u], c);
    previous = c;
    for (var q = walk_next(&ca); q != NONE; q = walk_next(&ca)) {
        put(slot, vec3<u32>(last, previous, q), t);
        slot += 1u;
        previous = q;
    }
    put(slot, vec3<u32>(last, previous, a), t);
}
