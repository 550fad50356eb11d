//! lensmap's C ABI (`lensmap.h`, generated from this crate by cbindgen): C and C++ hosts load a
//! scene and its layered EMs and render hybrid frames, on lensmap's own Vulkan device (headless)
//! or on the host's. It wraps the same library API the `lensmap` command line calls
//! ([`lensmap::runner::FrameRunner`], [`lensmap::runner::load_hybrid_scene`]) and adds nothing
//! the command line could not use.
//!
//! Conventions (after rustls-ffi):
//! - Opaque handles with `_new`/`_free` pairs; `_free(NULL)` is a no-op. Every handle lensmap
//!   gives out is registered until freed, so a freed or foreign pointer is refused with
//!   `LENSMAP_RESULT_INVALID_HANDLE` (a double free is detected) instead of being dereferenced.
//! - Every function returns a stable, numbered [`LensmapResult`]; out-pointers are written only
//!   on success.
//! - [`lensmap_last_error`] gives the message of the last failure on the calling thread.
//! - No panic crosses the ABI: every export catches one and returns `LENSMAP_RESULT_PANIC`.
//! - Option structs begin with `struct_size` (set it to `sizeof` the struct): fields can be added
//!   later without breaking callers built against this header.
//!
//! Thread safety: a `LensmapContext` may be used from any thread, by one thread at a time; a
//! call on a context another thread is inside returns `LENSMAP_RESULT_BUSY` (it does not wait).
//! A `LensmapScene` is immutable once loaded and may be rendered by several contexts at once.
//! Freeing a handle while another thread uses it is the caller's error and is not detected.

mod exports;
mod failure;
mod handles;
mod structs;
mod types;

pub use exports::*;
pub use handles::{LensmapContext, LensmapScene};
pub use types::*;
