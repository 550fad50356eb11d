// The GPU tracer's walk over the driver's acceleration structures (VK_KHR_acceleration_structure,
// VK_KHR_ray_query), where the device has them: engine/src/gpu/acceleration.rs builds one bottom
// level per part of axis-aligned boxes, one per triangle, and a top level with an instance per
// part. The driver walks the boxes; each box it reports is tested here with the same triangle
// test and tie rule as the BVH walk (walk_bvh.wgsl), so both find the same hits. Boxes rather
// than the driver's own triangles: its triangle test and its order of candidates would decide
// hits at shared vertices and edges, where the CPU's rule (lowest id among near-ties) must.
// The driver's rays are f32; the boxes are padded, so an f64 ray is culled conservatively.

// The scene's top level: instance `part` (custom index) has the cull mask bit min(part, 7).
@group(0) @binding(0) var scene: acceleration_structure;
// Per part: its first triangle and its triangle count.
@group(0) @binding(3) var<storage, read> parts: array<vec2<u32>>;

// Cull-mask bits: one per part up to the last, which the parts from it on share.
const LAST_MASK_BIT: u32 = 7u;

fn part_count() -> u32 {
    return arrayLength(&parts);
}

// The closest hit of `ray` on part `part` in (0, max_t), skipping `exclude`; counts the boxes
// the driver reports as triangle tests into `tests`.
fn closest_hit(part: u32, ray: Ray, max_t: real, exclude: u32, tests: ptr<function, u32>) -> Hit {
    var closest = no_hit_yet(max_t);
    let range = parts[part];
    if range.y == 0u {
        return closest.best;
    }
    var query: ray_query;
    let mask = 1u << min(part, LAST_MASK_BIT);
    let origin = vec3<f32>(ray.origin);
    let direction = vec3<f32>(ray.direction);
    // What the driver prunes boxes beyond: the reach of the search (never past max_t).
    var committed = up_to_f32(max_t);
    rayQueryInitialize(&query, scene, RayDesc(RAY_FLAG_NONE, mask, 0.0, committed, origin, direction));
    while rayQueryProceed(&query) {
        let candidate = rayQueryGetCandidateIntersection(&query);
        if candidate.instance_custom_data != part {
            continue;
        }
        *tests += 1u;
        let primitive = range.x + candidate.primitive_index;
        if primitive == exclude {
            continue;
        }
        consider(&closest, primitive, ray);
        // Named first: naga 30 loses a load written inside the call's arguments.
        let reach = up_to_f32(closest.reach);
        if reach < committed {
            // Commits the reach, not the hit: boxes up to it may still hold a tie that wins.
            committed = reach;
            rayQueryGenerateIntersection(&query, reach);
        }
    }
    return closest.best;
}
