//! The panic boundary every export goes through: a failure or a panic becomes a stable result
//! code, and its message is kept as the thread's last error ([`crate::lensmap_last_error`]).
//! Library errors that name options are worded with the C struct fields (`options->em_size`).

use std::cell::RefCell;
use std::ffi::CString;
use std::panic::{AssertUnwindSafe, catch_unwind};

use lensmap::error::{Classified, ErrorKind};
use lensmap::gpu::GpuError;
use lensmap::options::{OptionName, OptionWords, Worded};
use lensmap::render::RenderError;
use lensmap::runner::RunError;
use lensmap::scene::SceneError;

use crate::types::LensmapResult;

/// Options as the C ABI names them: the fields of the options struct a call was given, and
/// named values as the header's constants (`LENSMAP_BLEND_PROGRAMMABLE`).
pub(crate) struct StructFields;

impl OptionWords for StructFields {
    fn option(&self, name: OptionName) -> String {
        format!("options->{}", name.c_field.unwrap_or(name.field))
    }

    fn setting(&self, name: OptionName, value: &str) -> String {
        match name.c_constants {
            Some(prefix) => format!(
                "{} {prefix}{}",
                self.option(name),
                value.to_uppercase().replace('-', "_")
            ),
            None => format!("{} {value}", self.option(name)),
        }
    }
}

/// A failed call: its code and the message [`crate::lensmap_last_error`] gives.
pub(crate) struct Failure {
    code: LensmapResult,
    message: String,
}

impl Failure {
    pub(crate) fn new(code: LensmapResult, message: impl Into<String>) -> Failure {
        Failure {
            code,
            message: message.into(),
        }
    }
}

/// The failure of a required pointer argument `name` that is NULL.
pub(crate) fn null(name: &str) -> Failure {
    Failure::new(LensmapResult::NullArgument, format!("{name} is NULL"))
}

/// The result code of a failure of kind `kind`: the one mapping of the library's
/// classification ([`lensmap::error::ErrorKind`]) to the ABI's codes.
fn code(kind: ErrorKind) -> LensmapResult {
    match kind {
        ErrorKind::NoDriver => LensmapResult::NoDriver,
        ErrorKind::Device => LensmapResult::Device,
        ErrorKind::Input => LensmapResult::InvalidArgument,
        ErrorKind::Scene => LensmapResult::Scene,
        // The ABI reads and writes no file but a bake's: a disk that fails, fails the bake.
        ErrorKind::Bake | ErrorKind::Io => LensmapResult::Bake,
        ErrorKind::Failed => LensmapResult::Render,
        ErrorKind::Internal => LensmapResult::Internal,
    }
}

impl Failure {
    /// The failure of a library error: its kind's code, its message worded with the C struct
    /// fields.
    fn classified(error: &(impl Classified + Worded)) -> Failure {
        Failure::new(code(error.kind()), error.worded(&StructFields))
    }
}

impl From<GpuError> for Failure {
    fn from(error: GpuError) -> Failure {
        Failure::new(code(error.kind()), error.to_string())
    }
}

impl From<RenderError> for Failure {
    fn from(error: RenderError) -> Failure {
        Failure::classified(&error)
    }
}

impl From<RunError> for Failure {
    fn from(error: RunError) -> Failure {
        Failure::classified(&error)
    }
}

impl From<SceneError> for Failure {
    fn from(error: SceneError) -> Failure {
        Failure::new(code(error.kind()), error.to_string())
    }
}

thread_local! {
    /// The message of the last failure on this thread.
    pub(crate) static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

fn remember(message: &str) {
    // An interior NUL would end the C string early: it is replaced.
    let text = CString::new(message.replace('\0', "\u{fffd}")).unwrap_or_default();
    LAST_ERROR.with(|last| *last.borrow_mut() = text);
}

/// The panic boundary every export goes through: runs `body`, turns its failure or panic into a
/// code and remembers the message.
pub(crate) fn boundary(body: impl FnOnce() -> Result<(), Failure>) -> LensmapResult {
    let failure = match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => return LensmapResult::Ok,
        Ok(Err(failure)) => failure,
        Err(panic) => {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| (*s).to_owned())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "(no message)".to_owned());
            Failure::new(
                LensmapResult::Panic,
                format!("lensmap panicked (a bug; please report it): {what}"),
            )
        }
    };
    remember(&failure.message);
    failure.code
}

#[cfg(test)]
mod tests {
    use super::*;
    use lensmap::render::{MapBudgetError, MapBytes};

    /// Maps over the device's budget are an invalid argument whose message names the struct
    /// fields that shrink them.
    #[test]
    fn maps_over_the_budget_name_the_struct_fields() {
        let error = RenderError::from(MapBudgetError {
            maps: MapBytes {
                cube_maps: 18,
                largest_em_size: 1024,
                layered_em_bytes: 18 * 6 * 16 * 1_398_101,
                ..MapBytes::default()
            },
            budget: 1 << 30,
        });
        let failure = Failure::from(error);
        assert_eq!(failure.code, LensmapResult::InvalidArgument);
        assert!(
            failure.message.contains("a smaller options->em_size")
                && failure
                    .message
                    .contains("a smaller options->light_map_max_texels")
                && failure.message.contains("2.25 GiB")
                && failure.message.contains("1.00 GiB"),
            "{}",
            failure.message
        );
    }

    /// The codes come from the library's kinds: a broken invariant is `Internal`, wherever the
    /// runner wraps it; the device's failures `Render`; a missing driver `NoDriver`.
    #[test]
    fn codes_come_from_the_librarys_kinds() {
        let internal = Failure::from(RunError::from(RenderError::Internal(
            "a lost upload".into(),
        )));
        assert_eq!(internal.code, LensmapResult::Internal);
        assert!(
            internal.message.contains("a bug in lensmap"),
            "{}",
            internal.message
        );
        let lost = Failure::from(RunError::from(RenderError::from(GpuError::Vulkan {
            call: "vkQueueSubmit2",
            result: lensmap::gpu::vk::Result::ERROR_DEVICE_LOST,
        })));
        assert_eq!(lost.code, LensmapResult::Render);
        let driver = Failure::from(RenderError::from(GpuError::NoDriver("none".into())));
        assert_eq!(driver.code, LensmapResult::NoDriver);
    }
}
