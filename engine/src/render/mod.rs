//! The compositor: what a frame is made of ([`FrameInput`]), its pass graph ([`plan`]) with typed
//! shader programs ([`program`]), the GPU side in files of one job each (whether a framebuffer
//! fits the device, uploads, descriptor-set layouts and sets, the framebuffer targets, pipelines,
//! recording, the renderer that runs them, the graph's types in Vulkan's words), the read-back
//! image, and the CPU f64 model of the same arithmetic ([`model`]) that tests compare against.

mod budget;
pub mod compute;
pub(crate) mod descriptors;
mod frame_input;
mod glossy;
mod host_image;
mod image;
mod lens_pixels;
pub mod model;
mod pipelines;
pub mod plan;
pub mod program;
mod record;
mod renderer;
pub mod synthetic;
mod targets;
mod upload;
mod vulkan;

use crate::options::{OptionWords, Worded};

pub use budget::{
    FRAMEBUFFER_HEAP_SHARE, FramebufferError, MAP_HEAP_SHARE, MapBudgetError, MapBytes,
    check_framebuffer,
};
pub use frame_input::*;
pub use glossy::{GlossyDraw, GlossyMesh, GlossySlot, MAX_GLOSSY_SLOTS};
pub use host_image::HostImage;
pub use image::RenderedImage;
pub use lens_pixels::frame_lens_pixels;
pub use plan::{
    BlendScheme, Compositing, CompositingError, FramePlan, FrameShape, LensShape, Output,
    PartShape, PassCategory, PlanOptions, TargetFormat, Variant,
};
pub use program::{LimitSource, ProgramError, ShaderProgram, SinglePassLimits, SinglePassProgram};
pub use renderer::{FRAMES_IN_FLIGHT, FrameTimings, RenderOptions, Renderer, Submission};
pub use upload::UploadedFrame;

/// Errors from uploading or rendering a frame.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The frame's data is inconsistent; the message names the field and the fix.
    #[error("frame input: {0}")]
    BadInput(String),
    /// A lens object needs a shader program that does not exist (e.g. more layers than the
    /// single pass supports); the message names the lens and the fix.
    #[error("frame input: {0}")]
    Program(ProgramError),
    /// The framebuffer does not fit the device; the message names the size, the limit and the
    /// options that change it.
    #[error("frame input: {0}")]
    Framebuffer(FramebufferError),
    /// The frame's maps do not fit the device's budget for them; refused before any upload, the
    /// message names the size, the budget and the options that shrink them.
    #[error("frame input: {0}")]
    Maps(MapBudgetError),
    /// The GPU failed.
    #[error(transparent)]
    Gpu(#[from] crate::gpu::GpuError),
    /// lensmap broke an invariant of its own (a bug: the message says which).
    #[error("internal error: {0}; this is a bug in lensmap")]
    Internal(String),
}

// By hand rather than `#[from]`: a `#[from]` field is also the error's source, and a front end
// that prints an error with its sources would then say the same sentence twice.
impl From<ProgramError> for RenderError {
    fn from(error: ProgramError) -> RenderError {
        RenderError::Program(error)
    }
}

impl From<FramebufferError> for RenderError {
    fn from(error: FramebufferError) -> RenderError {
        RenderError::Framebuffer(error)
    }
}

impl From<MapBudgetError> for RenderError {
    fn from(error: MapBudgetError) -> RenderError {
        RenderError::Maps(error)
    }
}

impl Worded for RenderError {
    fn worded(&self, words: &dyn OptionWords) -> String {
        match self {
            RenderError::Framebuffer(error) => format!("frame input: {}", error.worded(words)),
            RenderError::Maps(error) => format!("frame input: {}", error.worded(words)),
            RenderError::BadInput(_)
            | RenderError::Program(_)
            | RenderError::Gpu(_)
            | RenderError::Internal(_) => self.to_string(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Options as a command line would name them, for the tests of worded errors.
    pub(super) struct Flags;

    impl OptionWords for Flags {
        fn option(&self, name: crate::options::OptionName) -> String {
            format!("--{}", name.flag.unwrap_or(name.field))
        }

        fn setting(&self, name: crate::options::OptionName, value: &str) -> String {
            format!("{} {value}", self.option(name))
        }
    }

    #[test]
    fn a_program_error_is_said_once() {
        let error = RenderError::from(ProgramError::TooManyLayers {
            lens: "teapot".into(),
            layers: 7,
            max: 6,
            bound: LimitSource::Shader,
        });
        assert!(std::error::Error::source(&error).is_none());
        assert_eq!(error.to_string().matches("7 layers").count(), 1, "{error}");
    }
}
