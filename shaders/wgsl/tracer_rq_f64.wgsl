enable wgpu_ray_query;

// The GPU tracer's vertex paths (include/vertex_paths.wgsl) in f64 over the driver's
// acceleration structures (include/walk_rq.wgsl): devices with ray queries and shaderFloat64.

// #include "real_f64.wgsl"
// #include "control.wgsl"
// #include "vertex_paths.wgsl"
// #include "walk_rq.wgsl"
