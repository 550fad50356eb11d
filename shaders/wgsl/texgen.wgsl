// Texture coordinate generation on the GPU (hybrid-rendering paper §5): each lens vertex's
// outgoing ray per term against each layer shell gives the cube-map direction `hit − EM origin`
// into that layer's EM, and the term's F·G weights it; by the rules of the CPU's texgen
// (engine/src/hybrid/texgen.rs, engine/src/layers/shell.rs) in f32. It reads the tessellation's
// vertices and records where they are (tessellate.wgsl, tracer.wgsl) and writes the lens pass's
// data in the layout lens.wgsl reads: positions, then per term its F·G and its directions per
// layer, `stride` vec4s apart.

struct TexgenConstants {
    // How many of the vertices are input vertices (those traced only when wanted).
    input_vertices: u32,
    // vec4s between consecutive arrays of lens_data.
    stride: u32,
    layer_count: u32,
    // 1 when the lens object has a refraction term (written first); the reflection term always.
    // Under path classes (control word CONTROL_CLASSES), one term per class instead.
    refraction: u32,
}

var<immediate> constants: TexgenConstants;

// The tessellation's vertices: (position, ·), (normal, ·).
@group(0) @binding(0) var<storage, read> vertices: array<vec4<f32>>;
// Per vertex the tracer's record: max(classes, 2) terms of three vec4, then the screen position
// (vertex_paths.wgsl `write_term`).
@group(0) @binding(1) var<storage, read> records: array<vec4<f32>>;
// Per input vertex 1 when it was traced.
@group(0) @binding(2) var<storage, read> wanted: array<u32>;
// Per layer four vec4: (centre, kind), (a, a_w), (b, b_w), (EM origin, 0); see Shell below.
@group(0) @binding(3) var<storage, read> shells: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> lens_data: array<vec4<f32>>;
// The tessellation's control words: the vertex count is word CONTROL_VERTICES, the path
// classes' count CONTROL_CLASSES.
@group(0) @binding(5) var<storage, read> control: array<u32>;

// #include "control.wgsl"

// Shell kinds (engine/src/hybrid/gpu/texgen.rs writes them) and their parameters a, b:
const SHELL_SPHERE: u32 = 0u; // a.w: radius
const SHELL_ELLIPSOID: u32 = 1u; // a: radii
const SHELL_BOX: u32 = 2u; // a: half extents
const SHELL_CYLINDER: u32 = 3u; // a: unit axis, a.w: radius; b.w: half height (< 0: unbounded)
const SHELL_QUAD: u32 = 4u; // a: unit normal, a.w: the forced distance R; b: the u axis

const INFINITY: f32 = 3.4028235e38;

struct Interval {
    near: f32,
    far: f32,
    hit: bool,
}

fn miss() -> Interval {
    return Interval(0.0, 0.0, false);
}

// The t where |offset + t·direction|² ≤ radius_sq, by the CPU's numerically stable roots.
fn sphere_interval(offset: vec3<f32>, direction: vec3<f32>, radius_sq: f32) -> Interval {
    let a = dot(direction, direction);
    if a == 0.0 {
        if dot(offset, offset) <= radius_sq {
            return Interval(-INFINITY, INFINITY, true);
        }
        return miss();
    }
    let b = dot(offset, direction);
    let closest = offset - direction * (b / a);
    let discriminant = a * (radius_sq - dot(closest, closest));
    if !(discriminant >= 0.0) {
        return miss();
    }
    let c = dot(offset, offset) - radius_sq;
    var sign_b = 1.0;
    if b < 0.0 {
        sign_b = -1.0;
    }
    let q = -(b + sign_b * sqrt(discriminant));
    if q == 0.0 {
        return Interval(0.0, 0.0, true);
    }
    let t0 = q / a;
    let t1 = c / q;
    return Interval(min(t0, t1), max(t0, t1), true);
}

fn slab_interval(offset: f32, direction: f32, half: f32) -> Interval {
    if direction == 0.0 {
        if abs(offset) <= half {
            return Interval(-INFINITY, INFINITY, true);
        }
        return miss();
    }
    let t0 = (-half - offset) / direction;
    let t1 = (half - offset) / direction;
    return Interval(min(t0, t1), max(t0, t1), true);
}

fn overlap(a: Interval, b: Interval) -> Interval {
    if !a.hit || !b.hit {
        return miss();
    }
    let near = max(a.near, b.near);
    let far = min(a.far, b.far);
    if near <= far {
        return Interval(near, far, true);
    }
    return miss();
}

// The closed solid's interval along the ray (not for quads).
fn closed_interval(layer: u32, origin: vec3<f32>, direction: vec3<f32>) -> Interval {
    let head = shells[4u * layer];
    let a = shells[4u * layer + 1u];
    let b = shells[4u * layer + 2u];
    let kind = u32(head.w);
    let offset = origin - head.xyz;
    if kind == SHELL_SPHERE {
        return sphere_interval(offset, direction, a.w * a.w);
    }
    if kind == SHELL_ELLIPSOID {
        return sphere_interval(offset / a.xyz, direction / a.xyz, 1.0);
    }
    if kind == SHELL_BOX {
        let x = slab_interval(offset.x, direction.x, a.x);
        let y = slab_interval(offset.y, direction.y, a.y);
        let z = slab_interval(offset.z, direction.z, a.z);
        return overlap(overlap(x, y), z);
    }
    // Cylinder.
    let axis = a.xyz;
    let along = dot(offset, axis);
    let direction_along = dot(direction, axis);
    let radial = sphere_interval(offset - axis * along, direction - axis * direction_along, a.w * a.w);
    if b.w < 0.0 {
        return radial;
    }
    return overlap(radial, slab_interval(along, direction_along, b.w));
}

fn finite(v: vec3<f32>) -> bool {
    return all(abs(v) <= vec3<f32>(INFINITY));
}

// The quad's §4.2 forced point: `centre + R·(in-plane direction)`, the u axis for none.
fn forced_at(layer: u32, in_plane: vec3<f32>) -> vec3<f32> {
    let head = shells[4u * layer];
    let a = shells[4u * layer + 1u];
    var unit = shells[4u * layer + 2u].xyz;
    let length_squared = dot(in_plane, in_plane);
    if length_squared > 0.0 && length_squared <= INFINITY {
        unit = in_plane / sqrt(length_squared);
    }
    return head.xyz + unit * a.w;
}

// The quad's plane hit, or the forced point (engine/src/layers/shell.rs intersect_quad).
fn quad_hit(layer: u32, origin: vec3<f32>, direction: vec3<f32>) -> vec3<f32> {
    let centre = shells[4u * layer].xyz;
    let normal = shells[4u * layer + 1u].xyz;
    let far = shells[4u * layer + 1u].w;
    let denominator = dot(direction, normal);
    if denominator != 0.0 {
        let t = dot(centre - origin, normal) / denominator;
        if t >= 0.0 && t <= INFINITY {
            let point = origin + direction * t;
            let offset = point - centre;
            if !finite(offset) {
                return forced_at(layer, direction - normal * denominator);
            }
            if length(offset) <= far {
                return point;
            }
            return forced_at(layer, offset - normal * dot(offset, normal));
        }
    }
    return forced_at(layer, direction - normal * denominator);
}

// The cube-map direction of the ray in layer `layer`: hit − EM origin, or the direction itself
// when the ray meets no finite point of the shell.
fn texture_direction(layer: u32, origin: vec3<f32>, direction: vec3<f32>) -> vec3<f32> {
    let em_origin = shells[4u * layer + 3u].xyz;
    if !finite(origin) || !finite(direction) || all(direction == vec3<f32>(0.0)) {
        return direction;
    }
    if u32(shells[4u * layer].w) == SHELL_QUAD {
        return quad_hit(layer, origin, direction) - em_origin;
    }
    let interval = closed_interval(layer, origin, direction);
    if !interval.hit || interval.far < 0.0 {
        return direction;
    }
    var t = interval.far;
    if interval.near > 0.0 {
        t = interval.near;
    }
    let point = origin + direction * t;
    // ±INFINITY (f32::MAX) stands for the CPU's ±∞ of an unbounded interval: not finite either.
    if abs(t) >= INFINITY || !finite(point) {
        return direction;
    }
    return point - em_origin;
}

fn record(v: u32, k: u32) -> vec4<f32> {
    return records[(3u * max(control[CONTROL_CLASSES], 2u) + 1u) * v + k];
}

fn has_term(v: u32, term: u32) -> bool {
    return record(v, 3u * term + 2u).w != 0.0;
}

// Writes vertex `v`'s term `term` (greedy: 0 refraction, 1 reflection; else class `term`) into
// slot `slot` of the terms.
fn write_term(v: u32, term: u32, slot: u32, traced: bool) {
    let position = vertices[2u * v].xyz;
    let base = constants.stride * (1u + slot * (1u + constants.layer_count));
    // The term's path, else with F·G = 0 the reflection's (the first class's that has a path,
    // under classes), else none (CPU texgen's `path`).
    let classes = control[CONTROL_CLASSES];
    var k = 3u * term;
    var fg = record(v, k).xyz;
    var has = traced && has_term(v, term);
    if traced && !has {
        // Greedy: the reflection (slot 1); classes: the first that has a path, if any.
        var stand_in = 1u;
        for (var c = classes; c > 0u; c--) {
            if has_term(v, c - 1u) {
                stand_in = c - 1u;
            }
        }
        if (classes == 0u || stand_in < classes) && has_term(v, stand_in) {
            k = 3u * stand_in;
            has = true;
        }
        fg = vec3<f32>(0.0);
    }
    if !has {
        fg = vec3<f32>(0.0);
    }
    lens_data[base + v] = vec4<f32>(fg, 0.0);
    for (var layer = 0u; layer < constants.layer_count; layer++) {
        var direction: vec3<f32>;
        if has {
            direction = texture_direction(layer, record(v, k + 1u).xyz, record(v, k + 2u).xyz);
        } else {
            // No path: the direction from the EM origin to the vertex.
            let away = position - shells[4u * layer + 3u].xyz;
            direction = vec3<f32>(0.0, 0.0, 1.0);
            if dot(away, away) > 0.0 {
                direction = normalize(away);
            }
        }
        lens_data[base + constants.stride * (1u + layer) + v] = vec4<f32>(direction, 0.0);
    }
}

@compute @workgroup_size(64)
fn cs_texgen(@builtin(global_invocation_id) id: vec3<u32>) {
    let v = id.x;
    if v >= control[CONTROL_VERTICES] {
        return;
    }
    lens_data[v] = vec4<f32>(vertices[2u * v].xyz, 1.0);
    let traced = v >= constants.input_vertices || wanted[v] != 0u;
    let classes = control[CONTROL_CLASSES];
    if classes > 0u {
        for (var k = 0u; k < classes; k++) {
            write_term(v, k, k, traced);
        }
        return;
    }
    var slot = 0u;
    if constants.refraction != 0u {
        write_term(v, 0u, 0u, traced);
        slot = 1u;
    }
    write_term(v, 1u, slot, traced);
}
