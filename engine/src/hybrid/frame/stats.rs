//! What a frame cost, in the hybrid-rendering paper's categories.

use crate::trace::stats::TraceCounters;

/// What one frame cost, in the paper's categories.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HybridStats {
    /// Ray tracing at vertices (visibility and both paths), ms.
    pub trace_ms: f64,
    /// Adaptive tessellation, excluding the ray tracing it asks for, ms.
    pub tessellation_ms: f64,
    /// Texture coordinate generation, ms.
    pub texgen_ms: f64,
    /// The rest of building the frame on the CPU (far plane, sky dome, viewpoint blend, the
    /// frustum test, gathering the lens meshes), ms.
    pub assemble_ms: f64,
    /// Rays and triangle tests of the vertex tracing.
    pub counters: TraceCounters,
    /// Lens triangles before and after tessellation.
    pub triangles_in: usize,
    /// Lens triangles after tessellation.
    pub triangles_out: usize,
    /// Vertices ray traced.
    pub vertices_traced: usize,
    /// Lens objects skipped because their bounds lie wholly outside the view frustum: neither
    /// traced nor tessellated nor drawn.
    pub lenses_outside_view: usize,
    /// Leaves left unsplit because the frame's vertex budget
    /// ([`crate::hybrid::tessellate::TessellationOptions::max_vertices`], shared by all lens objects in order) was spent.
    pub stopped_by_budget: usize,
    /// Lens objects tessellated with a coarser `t` because their screen footprint is smaller
    /// than [`super::HybridOptions::footprint_subpixels`].
    pub lenses_coarsened: usize,
    /// Whether the camera's direction lies outside the view space the samples cover (2D: in no
    /// triangle of its triangulation; see [`crate::hybrid::ViewSpaceFit::outside`]); the frame then blends the
    /// samples of the nearest point of the region.
    pub outside_view_space: bool,
    /// Viewpoint samples the frame blends (1 to 3), each with its own layered EMs.
    pub viewpoints_blended: usize,
    /// Radiance maps the glossy pass reads (warped, or turned, and blended): per glossy object,
    /// its view samples blended (1 to 3) times its lobes.
    pub glossy_maps: usize,
    /// Lens triangles (after tessellation) drawn with the distant layer only by the convex-hull
    /// split ([`super::HybridOptions::hull_split`]): on the hull of the lens geometry and facing the
    /// camera, in lens objects layered by bounce.
    pub hull_triangles: usize,
    /// Whether the lens vertices were traced on the GPU ([`super::HybridOptions::tracer`]).
    pub traced_on_gpu: bool,
    /// Whether the lens objects were drawn where the GPU tessellation left them: the vertex,
    /// triangle, ray and budget counts above are then the device's, added once the frame was
    /// done ([`crate::runner::FrameRunner`]; for a frame into a host's image, with the next
    /// frame: [`crate::runner::HostFrame::previous`]), and `trace_ms` is the time to prepare the
    /// tessellation's work, which the frame records (its device time is in the frame's
    /// execution).
    pub counted_on_device: bool,
    /// With the GPU tracer [timing its stages](crate::hybrid::gpu::GpuTracer::time_stages): the
    /// device time of the tessellation's split passes and T-junction removal, summed over the
    /// lens objects (`trace_ms` and `texgen_ms` are then the device time of those passes, and,
    /// for a frame read back, `tessellation_ms` the rest: these passes, the submission, the
    /// read-back and rebuilding the mesh on the CPU; timing waits for each tessellation). `None`
    /// otherwise.
    pub gpu_split_ms: Option<f64>,
    /// Whether the frame was reused whole from the previous one (same camera, options and
    /// layered EMs): no vertex traced, tessellated or given texture coordinates.
    pub reused: bool,
    /// Builds of this frame that [`crate::runner::FrameRunner::frame`] made and threw away
    /// before it: each time, the GPU tessellation's buffers stopped splits before the vertex
    /// budget, grew fourfold, and the whole frame (CPU stages, tessellation, render) was built
    /// again. 0 for a frame whose buffers sufficed.
    pub builds_discarded: usize,
    /// The most path-class terms of any lens object of the frame; 0 where every lens object
    /// is shaded by the greedy terms.
    pub class_terms: usize,
    /// The most varyings the single pass of path classes needs for any lens object of the
    /// frame, K·(n + 1) for K classes of n layers; 0 without classes. Past the device's
    /// limit the frame is composited by the multipass variant
    /// ([`crate::runner::FrameOptions::compositing_for`]).
    pub class_slots: usize,
}
