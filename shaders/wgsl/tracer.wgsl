// The GPU tracer's vertex paths (include/vertex_paths.wgsl) in f32 over its own BVH
// (include/walk_bvh.wgsl): every Vulkan 1.3 device. tracer_rq.wgsl walks the driver's
// acceleration structures instead, the *_f64 files trace in f64.

// #include "real_f32.wgsl"
// #include "control.wgsl"
// #include "vertex_paths.wgsl"
// #include "walk_bvh.wgsl"
