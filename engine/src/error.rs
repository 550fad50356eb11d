//! What kind of failure an error is: one classification of every library error, which each
//! front end maps to its own codes (the command line's exit status, the C ABI's
//! `LensmapResult`), so that the two cannot disagree about a cause.
//!
//! The kinds follow who can act on the failure: the user's input (a scene, an option, a bake,
//! the machine's drivers), the work failing where it ran (the device, the disk), or lensmap
//! itself breaking an invariant of its own ([`ErrorKind::Internal`]: a bug to report).

use crate::atomic::lock::LockError;
use crate::gpu::GpuError;
use crate::hybrid::HybridError;
use crate::hybrid::tessellate::TessellationError;
use crate::layers::BakeError;
use crate::options::OptionError;
use crate::render::RenderError;
use crate::runner::RunError;
use crate::scene::SceneError;
use crate::trace::TraceError;

/// What kind of failure an error is ([`Classified::kind`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ErrorKind {
    /// No Vulkan loader or driver: the machine's to fix.
    NoDriver,
    /// No suitable device (or the validation layer asked for is missing).
    Device,
    /// An option, an argument or the frame's data out of range; the message names the field
    /// and the fix.
    Input,
    /// The scene file or one of its assets is wrong.
    Scene,
    /// A bake that is missing, damaged, made for another scene, or locked by another writer.
    Bake,
    /// The file system refused a read or a write.
    Io,
    /// The work failed where it ran: the device was lost or out of memory, a tessellation
    /// outgrew what an index can name.
    Failed,
    /// lensmap broke an invariant of its own: a bug, to be reported with the message.
    Internal,
}

impl ErrorKind {
    /// Whether the failure is the caller's input (a scene, an option, a bake, the drivers)
    /// rather than the work's or lensmap's.
    pub fn is_input(self) -> bool {
        match self {
            ErrorKind::NoDriver
            | ErrorKind::Device
            | ErrorKind::Input
            | ErrorKind::Scene
            | ErrorKind::Bake => true,
            ErrorKind::Io | ErrorKind::Failed | ErrorKind::Internal => false,
        }
    }
}

/// An error that knows its [`ErrorKind`].
pub trait Classified {
    /// The kind of failure.
    fn kind(&self) -> ErrorKind;
}

impl Classified for GpuError {
    fn kind(&self) -> ErrorKind {
        match self {
            GpuError::NoDriver(_) => ErrorKind::NoDriver,
            GpuError::NoSuitableDevice(_) | GpuError::ValidationLayerMissing => ErrorKind::Device,
            GpuError::Internal(_) => ErrorKind::Internal,
            GpuError::Vulkan { .. } | GpuError::Allocation { .. } | GpuError::BadUpload { .. } => {
                ErrorKind::Failed
            }
        }
    }
}

impl Classified for RenderError {
    fn kind(&self) -> ErrorKind {
        match self {
            RenderError::BadInput(_)
            | RenderError::Program(_)
            | RenderError::Framebuffer(_)
            | RenderError::Maps(_) => ErrorKind::Input,
            RenderError::Internal(_) => ErrorKind::Internal,
            RenderError::Gpu(error) => error.kind(),
        }
    }
}

impl Classified for TessellationError {
    fn kind(&self) -> ErrorKind {
        match self {
            // The caller's options and mesh ([`crate::hybrid::tessellate::tessellate`] takes any).
            TessellationError::Option(_)
            | TessellationError::InvalidThreshold(_)
            | TessellationError::IndexOutOfRange { .. }
            | TessellationError::NonFinite { .. }
            | TessellationError::AttributeLength { .. } => ErrorKind::Input,
            // lensmap's oracles answer every vertex they are asked.
            TessellationError::OracleBatchLength { .. } => ErrorKind::Internal,
            TessellationError::TooManyVertices => ErrorKind::Failed,
            TessellationError::Gpu(error) => error.kind(),
        }
    }
}

impl Classified for LockError {
    fn kind(&self) -> ErrorKind {
        match self {
            LockError::Io { .. } => ErrorKind::Io,
            _ => ErrorKind::Bake,
        }
    }
}

impl Classified for BakeError {
    fn kind(&self) -> ErrorKind {
        match self {
            BakeError::Io { .. } => ErrorKind::Io,
            BakeError::Lock(error) => error.kind(),
            _ => ErrorKind::Bake,
        }
    }
}

impl Classified for TraceError {
    fn kind(&self) -> ErrorKind {
        match self {
            TraceError::InvalidScene(_) => ErrorKind::Scene,
            TraceError::InvalidCamera(_) => ErrorKind::Input,
            // Pixels lensmap made that do not fill their image.
            TraceError::InvalidImage(_) => ErrorKind::Internal,
            TraceError::Io { .. } | TraceError::Image { .. } => ErrorKind::Io,
        }
    }
}

impl Classified for HybridError {
    fn kind(&self) -> ErrorKind {
        match self {
            HybridError::Identity(_) | HybridError::BakeMismatch(_) => ErrorKind::Bake,
            HybridError::Trace(_)
            | HybridError::LightMap { .. }
            | HybridError::LightMapBudget(_) => ErrorKind::Scene,
        }
    }
}

impl Classified for RunError {
    fn kind(&self) -> ErrorKind {
        match self {
            RunError::Option(error) => error.kind(),
            RunError::Bake(error) => error.kind(),
            RunError::Hybrid(error) => error.kind(),
            RunError::Tessellation(error) => error.kind(),
            RunError::Render(error) => error.kind(),
            RunError::Tracer(error) => error.kind(),
        }
    }
}

impl Classified for OptionError {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Input
    }
}

impl Classified for SceneError {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Scene
    }
}

/// The kind of the first error in `error`'s chain of sources that is one of the library's
/// ([`Classified`]); `None` when none is. A front end that holds errors as `dyn Error` finds
/// the library's classification here, and adds its own types before calling it.
pub fn kind_in_chain(error: &(dyn std::error::Error + 'static)) -> Option<ErrorKind> {
    let mut cause = Some(error);
    while let Some(error) = cause {
        if let Some(kind) = kind_of(error) {
            return Some(kind);
        }
        cause = error.source();
    }
    None
}

/// The kind of `error` itself when it is one of the library's errors.
pub fn kind_of(error: &(dyn std::error::Error + 'static)) -> Option<ErrorKind> {
    macro_rules! first_of {
        ($($ty:ty),*) => {
            $(if let Some(error) = error.downcast_ref::<$ty>() {
                return Some(error.kind());
            })*
        };
    }
    first_of!(
        RunError,
        RenderError,
        GpuError,
        TessellationError,
        HybridError,
        TraceError,
        BakeError,
        LockError,
        OptionError,
        SceneError
    );
    None
}
