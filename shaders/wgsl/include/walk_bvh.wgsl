// The GPU tracer's BVH walk: a binary BVH per part, built by obvhs on the CPU
// (engine/src/trace/bvh_gpu.rs) and traversed with a stack; every Vulkan 1.3 device. Its boxes
// are f32 and padded, so a ray in f64 is culled by them conservatively as well.

// BVH nodes, two vec4 each: (min, first index), (max, primitive count); a leaf has a count > 0
// and its first index names a triangle, an inner node's names its first child (the second
// follows it).
@group(0) @binding(0) var<storage, read> nodes: array<vec4<f32>>;
// Root node of each part; NO_NODE for a part without triangles.
@group(0) @binding(3) var<storage, read> roots: array<u32>;

const NO_NODE: u32 = 0xffffffffu;
const STACK_SIZE: u32 = 64u;

fn part_count() -> u32 {
    return arrayLength(&roots);
}

fn safe_inverse(d: vec3<f32>) -> vec3<f32> {
    let tiny = abs(d) < vec3<f32>(1e-30);
    let signed = select(vec3<f32>(1e30), vec3<f32>(-1e30), d < vec3<f32>(0.0));
    return select(1.0 / d, signed, tiny);
}

// Where the ray enters node `node`'s box (0 when it starts inside), or -1 when it misses the box
// or meets it only past `reach` (slab test; the boxes are padded when built).
fn box_entry(node: u32, origin: vec3<f32>, inverse: vec3<f32>, reach: f32) -> f32 {
    let t0 = (nodes[2u * node].xyz - origin) * inverse;
    let t1 = (nodes[2u * node + 1u].xyz - origin) * inverse;
    let near = min(t0, t1);
    let far = max(t0, t1);
    let enter = max(max(near.x, near.y), near.z);
    let leave = min(min(far.x, far.y), far.z);
    if enter <= leave && leave >= 0.0 && enter <= reach {
        return max(enter, 0.0);
    }
    return -1.0;
}

// The closest hit of `ray` on part `part` in (0, max_t), skipping `exclude`; counts its
// triangle tests into `tests`.
fn closest_hit(part: u32, ray: Ray, max_t: real, exclude: u32, tests: ptr<function, u32>) -> Hit {
    var closest = no_hit_yet(max_t);
    let root = roots[part];
    if root == NO_NODE {
        return closest.best;
    }
    let origin = vec3<f32>(ray.origin);
    let inverse = safe_inverse(vec3<f32>(ray.direction));
    // Nodes to visit with the distance at which the ray enters each: the nearer child of a node
    // is visited first, so that the best hit shrinks `reach` before the farther one is opened.
    var stack: array<u32, STACK_SIZE>;
    var entries: array<f32, STACK_SIZE>;
    var size = 0u;
    let root_entry = box_entry(root, origin, inverse, up_to_f32(closest.reach));
    if root_entry >= 0.0 {
        stack[0] = root;
        entries[0] = root_entry;
        size = 1u;
    }
    while size > 0u {
        size -= 1u;
        if entries[size] > up_to_f32(closest.reach) {
            continue;
        }
        let node = stack[size];
        let first = bitcast<u32>(nodes[2u * node].w);
        let count = bitcast<u32>(nodes[2u * node + 1u].w);
        if count == 0u {
            // GpuGeometry refuses a BVH deeper than the stack: both children always fit.
            let entry_a = box_entry(first, origin, inverse, up_to_f32(closest.reach));
            let entry_b = box_entry(first + 1u, origin, inverse, up_to_f32(closest.reach));
            let a_first = entry_a >= 0.0 && (entry_b < 0.0 || entry_a <= entry_b);
            let near = select(first + 1u, first, a_first);
            let far = select(first, first + 1u, a_first);
            let near_entry = select(entry_b, entry_a, a_first);
            let far_entry = select(entry_a, entry_b, a_first);
            if far_entry >= 0.0 && size < STACK_SIZE {
                stack[size] = far;
                entries[size] = far_entry;
                size += 1u;
            }
            if near_entry >= 0.0 && size < STACK_SIZE {
                stack[size] = near;
                entries[size] = near_entry;
                size += 1u;
            }
            continue;
        }
        for (var k = 0u; k < count; k++) {
            let primitive = first + k;
            *tests += 1u;
            if primitive != exclude {
                consider(&closest, primitive, ray);
            }
        }
    }
    return closest.best;
}
