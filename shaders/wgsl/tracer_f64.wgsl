// The GPU tracer's vertex paths (include/vertex_paths.wgsl) in f64 over its own BVH
// (include/walk_bvh.wgsl): devices with shaderFloat64.

// #include "real_f64.wgsl"
// #include "control.wgsl"
// #include "vertex_paths.wgsl"
// #include "walk_bvh.wgsl"
