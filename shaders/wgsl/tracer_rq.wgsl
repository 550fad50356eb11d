enable wgpu_ray_query;

// The GPU tracer's vertex paths (include/vertex_paths.wgsl) in f32 over the driver's
// acceleration structures (include/walk_rq.wgsl): devices with ray queries.

// #include "real_f32.wgsl"
// #include "control.wgsl"
// #include "vertex_paths.wgsl"
// #include "walk_rq.wgsl"
