//! The compositor: the frame's pass graph ([`plan`]), its recording on the GPU ([`frame`]) and the
//! CPU f64 model of the same arithmetic ([`model`]) that tests compare against.

pub mod frame;
mod frame_input;
pub mod model;
pub mod plan;
pub mod synthetic;

pub use frame::{FrameTimings, RenderedImage, Renderer, UploadedFrame};
pub use frame_input::*;
pub use plan::{FrameShape, TargetFormat, Variant};

/// Errors from uploading or rendering a frame.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The frame's data is inconsistent; the message names the field and the fix.
    #[error("frame input: {0}")]
    BadInput(String),
    /// The GPU failed.
    #[error(transparent)]
    Gpu(#[from] crate::gpu::GpuError),
}
