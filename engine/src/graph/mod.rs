//! The pass graph: passes declared with typed resource handles and fixed-function state, compiled
//! into a [`Plan`] (order, culled passes, barriers and layout transitions, render-pass instances)
//! that `render/` records into command buffers. No Vulkan calls live here, so plans are checked by
//! unit tests without a GPU, and `lensmap passes` prints them.
//!
//! The shape follows Granite's render graph: walk back from the outputs and drop passes nobody
//! reads; print every pass with its state and barriers.

mod compile;
mod types;

pub use compile::{CullReason, Plan, RenderingInstance, Step};
pub use types::*;

/// Errors in a graph declaration.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum GraphError {
    /// Two passes share a name.
    #[error("duplicate pass name `{0}`")]
    DuplicatePass(String),
    /// A pass reads (samples, loads or depth-tests) an image no earlier pass wrote and that was not
    /// imported.
    #[error("pass `{pass}` reads image `{image}` before any pass writes it")]
    ReadBeforeWrite {
        /// The reading pass.
        pass: String,
        /// The image's debug name.
        image: String,
    },
    /// A handle that this graph did not create.
    #[error("pass `{pass}` uses an unknown {kind} handle {index}")]
    UnknownResource {
        /// The pass.
        pass: String,
        /// "image" or "buffer".
        kind: &'static str,
        /// The handle's index.
        index: u32,
    },
    /// An export of an image that is not external (the frame's own images are not handed out).
    #[error("pass `{pass}` exports image `{image}`, which is not an external image")]
    NotExternal {
        /// The exporting pass.
        pass: String,
        /// The image's debug name.
        image: String,
    },
    /// A colour format used as depth or the other way round.
    #[error("pass `{pass}` uses image `{image}` as a {role} attachment but its format is {format}")]
    BadAttachment {
        /// The pass.
        pass: String,
        /// The image.
        image: String,
        /// "colour" or "depth".
        role: &'static str,
        /// The image's format.
        format: Format,
    },
}

pub use compile::{Barrier, BufferBarrier};

#[cfg(test)]
mod tests;
