//! Opaque handles: every context and scene lensmap gives out is registered by address, so a freed
//! or foreign pointer is refused with `LENSMAP_RESULT_INVALID_HANDLE` instead of being
//! dereferenced, and a context is used by one call at a time.
//!
//! A freed handle's contents are dropped, but its allocation is kept as a tombstone for the life
//! of the process. Returned to the allocator, its address could go to the next handle made on any
//! thread, and a second free of the old pointer would then free that handle under its user: the
//! C ABI tests' misuse corpus did this to a context another test thread was rendering with (a
//! crash inside the validation layer, "Invalid VkDevice", in about one run in 50 on Mesa 25.0).
//! A handle's contents are boxed, so a tombstone is 16 bytes.

use std::collections::HashMap;
use std::sync::{Mutex, TryLockError};

use lensmap::hybrid::HybridScene;
use lensmap::runner::FrameRunner;

use crate::failure::{Failure, null};
use crate::types::LensmapResult;

/// A Vulkan device with lensmap's pipelines and per-frame buffers.
pub struct LensmapContext {
    /// Boxed, so that the handle's tombstone is small (see the module documentation).
    pub(crate) runner: Box<Mutex<FrameRunner>>,
    /// Made on a host's device (host images can be rendered into), not lensmap's own.
    pub(crate) on_host: bool,
}

impl LensmapContext {
    /// The device memory lensmap's allocator holds on this context's device
    /// ([`lensmap::gpu::Gpu::device_memory`]), or `None` while a call on another thread is
    /// inside the context. For Rust code linking this crate (the soak test samples it between
    /// frames); not part of `lensmap.h`.
    pub fn device_memory(&self) -> Option<lensmap::gpu::DeviceMemory> {
        let runner = self.runner.try_lock().ok()?;
        Some(runner.gpu().device_memory())
    }
}

/// A scene with its layered EMs and light maps, ready to render.
pub struct LensmapScene {
    /// Boxed, so that the handle's tombstone is small (see the module documentation).
    pub(crate) hybrid: Box<HybridScene>,
}

/// Which kind of handle an address is registered as.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    Context,
    Scene,
}

/// Every handle ever given out, by address, with whether it is still live: a pointer not live
/// here is never dereferenced, and a freed one stays (its address is never given out again).
static LIVE: Mutex<Option<HashMap<usize, (Kind, bool)>>> = Mutex::new(None);

fn live() -> std::sync::MutexGuard<'static, Option<HashMap<usize, (Kind, bool)>>> {
    // A panic while the lock was held left the map consistent (inserts and removes are single
    // operations), so a poisoned lock is taken over.
    LIVE.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

pub(crate) fn register<T>(handle: Box<T>, kind: Kind) -> *mut T {
    let pointer = Box::into_raw(handle);
    live()
        .get_or_insert_with(HashMap::new)
        .insert(pointer as usize, (kind, true));
    pointer
}

pub(crate) fn is_live(pointer: usize, kind: Kind) -> bool {
    live()
        .as_ref()
        .is_some_and(|map| map.get(&pointer) == Some(&(kind, true)))
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
        runner: Box::new(Mutex::new(runner)),
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
    // SAFETY: it was live, made by Box::into_raw as a T, and is marked freed now: its contents
    // are dropped once. The allocation stays as a tombstone (see the module documentation).
    unsafe { std::ptr::drop_in_place(pointer) };
    Ok(())
}

/// Marks `pointer` freed; false when it was not a live handle of `kind`.
pub(crate) fn unregister(pointer: usize, kind: Kind) -> bool {
    let mut guard = live();
    match guard.as_mut().and_then(|map| map.get_mut(&pointer)) {
        Some(entry) if *entry == (kind, true) => {
            entry.1 = false;
            true
        }
        _ => false,
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
