//! The Vulkan backend on ash: instance and device selection, memory through gpu-allocator,
//! buffers, 2D images and cube-map arrays with full mip chains, uploads and readback, pipelines,
//! descriptor sets, query pools and command rings as owned values, debug-utils labels and the
//! validation messenger. Nothing above this room calls ash directly except `render/`, which
//! records command buffers.

pub mod acceleration;
pub mod compute;
pub(crate) mod context;
pub mod copies;
pub(crate) mod descriptors;
mod pipeline;
pub(crate) mod resources;
mod startup;
mod timeline;

pub use ash::vk;
pub use compute::{CommandRing, ComputePipelines, Kernels, Pipeline, QueryPool, QueryPoolRef};
pub use context::{
    DeviceChoice, DeviceId, DeviceMemory, Gpu, GpuOptions, HostDevice, HostFeatures, Semaphores,
    ValidationReport, VulkanHandles,
};
pub use descriptors::DescriptorSet;
pub use pipeline::{GraphicsPipelineDesc, VertexInput};
pub use resources::{Buffer, BufferUsage, Image, ImageDesc, format_bytes};
pub use timeline::Timeline;

/// Errors from the Vulkan backend.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No Vulkan loader or no driver (ICD): the one line the command line prints, exit code 2.
    #[error(
        "no Vulkan driver found ({0}): install the Debian package `mesa-vulkan-drivers` (lavapipe, a CPU Vulkan driver) or your GPU's Vulkan driver"
    )]
    NoDriver(String),
    /// Drivers exist but none offers what lensmap needs, or `LENSMAP_DEVICE` matched nothing.
    #[error("no suitable Vulkan device: {0}")]
    NoSuitableDevice(String),
    /// `LENSMAP_VALIDATION=1` (or the tests) asked for the Khronos validation layer, which is absent.
    #[error(
        "the Khronos validation layer is not installed: install the Debian package `vulkan-validationlayers`, or unset LENSMAP_VALIDATION"
    )]
    ValidationLayerMissing,
    /// A Vulkan call failed.
    #[error("Vulkan call {call} failed: {result}")]
    Vulkan {
        /// The entry point, for the message.
        call: &'static str,
        /// What it returned.
        result: vk::Result,
    },
    /// gpu-allocator could not allocate.
    #[error("GPU memory allocation for {what} failed: {source}")]
    Allocation {
        /// The resource's debug name.
        what: String,
        /// The allocator's error.
        source: gpu_allocator::AllocationError,
    },
    /// Data handed to an upload does not fit the resource, or the resource does not fit the
    /// device.
    #[error("upload to {what}: {problem}")]
    BadUpload {
        /// The resource's debug name.
        what: String,
        /// What does not fit.
        problem: String,
    },
    /// lensmap broke an invariant of its own GPU work (a bug: the message says which).
    #[error("internal error: {0}; this is a bug in lensmap")]
    Internal(String),
}

/// Attaches the failing entry point's name to a `vk::Result`.
pub(crate) trait VkContext<T> {
    /// The value, or [`GpuError::Vulkan`] naming `call` (the Vulkan entry point, e.g.
    /// `"vkCreateImage"`).
    fn vk(self, call: &'static str) -> Result<T, GpuError>;
}

impl<T> VkContext<T> for Result<T, vk::Result> {
    fn vk(self, call: &'static str) -> Result<T, GpuError> {
        self.map_err(|result| GpuError::Vulkan { call, result })
    }
}
