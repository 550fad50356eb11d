//! Opaque handles: every context and scene lensmap gives out is registered by address until it is
//! freed, so a freed or foreign pointer is refused with `LENSMAP_RESULT_INVALID_HANDLE` instead
//! of being dereferenced, and a context is used by one call at a time.

use std::collections::HashMap;
use std::sync::{Mutex, TryLockError};

use lensmap::hybrid::HybridScene;
use lensmap::runner::FrameRunner;

use crate::failure::{Failure, null};
use crate::types::LensmapResult;

/// A Vulkan device with lensmap's pipelines and per-frame buffers.
pub struct LensmapContext {
    pub(crate) runner: Mutex<FrameRunner>,
    /// Made on a host's device (host images can be rendered into), not lensmap's own.
    pub(crate) on_host: bool,
}

/// A scene with its layered EMs and light maps, ready to render.
pub struct LensmapScene {
    pub(crate) hybrid: HybridScene,
}

/// Which kind of handle an address is registered as.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    Context,
    Scene,
}

/// Every live handle, by address: a pointer not here is never dereferenced.
static LIVE: Mutex<Option<HashMap<usize, Kind>>> = Mutex::new(None);

fn live() -> std::sync::MutexGuard<'static, Option<HashMap<usize, Kind>>> {
    // A panic while the lock was held left the map consistent (inserts and removes are single
    // operations), so a poisoned lock is taken over.
    LIVE.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

pub(crate) fn register<T>(handle: Box<T>, kind: Kind) -> *mut T {
    let pointer = Box::into_raw(handle);
    live()
        .get_or_insert_with(HashMap::new)
        .insert(pointer as usize, kind);
    pointer
}

pub(crate) fn is_live(pointer: usize, kind: Kind) -> bool {
    live()
        .as_ref()
        .is_some_and(|map| map.get(&pointer) == Some(&kind))
}

/// Registers a new context for `runner` and writes it to `*out`.
///
/// # Safety
/// `out` must be non-null and writable.
pub(crate) unsafe fn hand_out_context(
    runner: FrameRunner,
    on_host: bool,
    out: *mut *mut LensmapContext,
) {
    let context = LensmapContext {
        runner: Mutex::new(runner),
        on_host,
    };
    // SAFETY: the caller's promise.
    unsafe { *out = register(Box::new(context), Kind::Context) };
}

/// Frees the live handle `pointer` of `kind` (NULL: nothing to do); refuses one that is not live
/// (a second free) with `refusal`, freeing nothing.
///
/// # Safety
/// `pointer` must be NULL, not live, or a live handle of `kind` made by [`register`] as a `T`.
pub(crate) unsafe fn free_handle<T>(
    pointer: *mut T,
    kind: Kind,
    refusal: &str,
) -> Result<(), Failure> {
    if pointer.is_null() {
        return Ok(());
    }
    if !unregister(pointer as usize, kind) {
        return Err(Failure::new(
            LensmapResult::InvalidHandle,
            format!("{refusal} (freed twice?); nothing freed"),
        ));
    }
    // SAFETY: it was live, made by Box::into_raw as a T, and is unregistered now: freed once.
    drop(unsafe { Box::from_raw(pointer) });
    Ok(())
}

/// Removes `pointer` from the live handles; false when it was not one of `kind`.
pub(crate) fn unregister(pointer: usize, kind: Kind) -> bool {
    let mut guard = live();
    let Some(map) = guard.as_mut() else {
        return false;
    };
    if map.get(&pointer) == Some(&kind) {
        map.remove(&pointer);
        if map.is_empty() {
            // No handle is live: the table itself goes too, so that a host that freed
            // everything holds nothing of lensmap's (what leak checkers look for at exit).
            *guard = None;
        }
        true
    } else {
        false
    }
}

/// The handle `pointer` of `kind` (`name` in messages), or a failure: NULL, or not live
/// (`refusal` says why it is refused).
///
/// # Safety
/// `pointer` must be NULL, a live handle of `kind` made by [`register`] as a `T`, or a pointer
/// lensmap never gave out.
unsafe fn live_ref<'a, T>(
    pointer: *const T,
    kind: Kind,
    name: &str,
    refusal: &str,
) -> Result<&'a T, Failure> {
    if pointer.is_null() {
        return Err(null(name));
    }
    if !is_live(pointer as usize, kind) {
        return Err(Failure::new(LensmapResult::InvalidHandle, refusal));
    }
    // SAFETY: a live handle points to its `T` until it is freed.
    Ok(unsafe { &*pointer })
}

/// The context behind a handle, locked for this call.
///
/// # Safety
/// `context` must be NULL, a live context, or a pointer lensmap never gave out.
pub(crate) unsafe fn lock_context<'a>(
    context: *mut LensmapContext,
) -> Result<std::sync::MutexGuard<'a, FrameRunner>, Failure> {
    // SAFETY: the caller's promise; a context is only ever registered as Kind::Context.
    let context: &LensmapContext = unsafe {
        live_ref(
            context,
            Kind::Context,
            "context",
            "context is not a live LensmapContext (freed already, or not made by lensmap_context_new)",
        )
    }?;
    match context.runner.try_lock() {
        Ok(runner) => Ok(runner),
        Err(TryLockError::WouldBlock) => Err(Failure::new(
            LensmapResult::Busy,
            "the context is in use by a call on another thread; use a context from one thread at a time (or one context per thread)",
        )),
        // A panic inside an earlier call on this context was caught at the boundary; the
        // runner's state may be half updated, so the context is not used again.
        Err(TryLockError::Poisoned(_)) => Err(Failure::new(
            LensmapResult::Render,
            "the context is unusable after an earlier call panicked; free it and create another",
        )),
    }
}

/// The scene behind a handle.
///
/// # Safety
/// `scene` must be NULL, a live scene, or a pointer lensmap never gave out.
pub(crate) unsafe fn scene_ref<'a>(
    scene: *const LensmapScene,
) -> Result<&'a LensmapScene, Failure> {
    // SAFETY: the caller's promise; a scene is only ever registered as Kind::Scene.
    unsafe {
        live_ref(
            scene,
            Kind::Scene,
            "scene",
            "scene is not a live LensmapScene (freed already, or not made by lensmap_scene_load)",
        )
    }
}
