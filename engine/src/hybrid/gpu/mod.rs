//! The hybrid frame's per-vertex work on the GPU: the scene's geometry and BVHs resident in
//! storage buffers, and compute passes that trace the eye ray and both greedy paths at each lens
//! vertex by the CPU oracle's rules (`shaders/wgsl/tracer.wgsl`), tessellate the lens mesh
//! adaptively (`tessellate.wgsl`), give its vertices their texture coordinates (`texgen.wgsl`)
//! and make its draw list (`drawlist.wgsl`). Every submission is a compute work whose passes
//! name what they read and write (`work.rs`), recorded by `render/`: no Vulkan call here.
//!
//! [`GpuTracer::trace_vertices`] runs the vertex-path pass over given vertices and reads the
//! records back: what the agreement with the CPU oracle is measured on.
//!
//! The rooms, leaves first: `buffers` (the shared buffers and an object's input), `texgen` (what
//! texgen needs of a lens object), `assemble` (the CPU tessellator's result from what was read
//! back), `walk` (the BVH or the driver's structures), `work` (the passes declared),
//! `resident` (an object's sets and outputs, a part's counts), `tracer` (the tracer), and
//! `tessellate` (a tessellation read back or left on the device).

mod assemble;
mod buffers;
mod resident;
mod tessellate;
mod texgen;
mod tracer;
mod walk;
mod work;

use crate::gpu::Gpu;

pub use crate::hybrid::paths::PathSettings;
pub use assemble::GpuVertex;
pub use resident::{DeviceCounts, read_counts};
pub use tessellate::{
    DeviceExtras, DeviceTessellation, GPU_MAX_DEPTH, GpuStageMs, GpuTessellation,
    GpuTessellationRequest, PreparedObject,
};
pub use texgen::TexgenRequest;
pub use tracer::{GpuTracer, TracerWalk};
pub use walk::{GpuTraversal, Traversal};
pub use work::{Texgen, planned_part};

/// A device and a tracer resident on it: what a frame's vertices are traced on when the GPU
/// traces them ([`crate::hybrid::frame::GpuReadBack`], [`crate::hybrid::frame::GpuResident`]).
#[derive(Clone, Copy)]
pub struct GpuPaths<'a> {
    /// The device `tracer` was made on.
    pub gpu: &'a Gpu,
    /// The scene's resident geometry and passes.
    pub tracer: &'a GpuTracer,
}
