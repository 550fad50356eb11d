//! lensmap's C ABI (`lensmap.h`, generated from this file by cbindgen): C and C++ hosts load a
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

use std::cell::RefCell;
use std::collections::HashMap;
use std::ffi::{CStr, CString, c_char, c_void};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::{Mutex, TryLockError};

use lensmap::gpu::{Gpu, GpuError, GpuOptions, HostDevice, HostFeatures, vk};
use lensmap::hybrid::{HybridOptions, HybridScene};
use lensmap::layers::projected::{DEFAULT_EM_SIZE, ProjectedOptions};
use lensmap::options::{OptionWords, Worded};
use lensmap::render::{
    BlendScheme, FrameShape, RenderError, TargetFormat, Variant,
    plan::{Output, PlanOptions, frame_graph},
};
use lensmap::runner::{EmSource, FrameOptions, FrameRunner, RunError, load_hybrid_scene};
use lensmap::scene::{Camera, Scene, SceneError};

/// The ABI version this header describes; raised when a struct grows or a function is added.
pub const LENSMAP_ABI_VERSION: u32 = 3;

/// `LensmapFrameOptions::variant`: the single-pass compositor (one draw per lens object).
pub const LENSMAP_VARIANT_SINGLE_PASS: u32 = 0;
/// `LensmapFrameOptions::variant`: the paper's 4n-pass compositor with alpha clears.
pub const LENSMAP_VARIANT_MULTIPASS: u32 = 1;
/// `LensmapFrameOptions::blend`: the paper's scheme (layers front to back, alpha clears between
/// groups); the only one the single pass takes.
pub const LENSMAP_BLEND_FRONT_TO_BACK: u32 = 0;
/// `LensmapFrameOptions::blend`: layers back to front into a scratch image, added per group.
pub const LENSMAP_BLEND_BACK_TO_FRONT: u32 = 1;
/// `LensmapFrameOptions::blend`: each group into its own image, one pass summing them.
pub const LENSMAP_BLEND_GROUP_TARGETS: u32 = 2;
/// `LensmapFrameOptions::blend`: the blend done in the fragment shader.
pub const LENSMAP_BLEND_PROGRAMMABLE: u32 = 3;
/// `LensmapFrameOptions::format`: an 8-bit unorm framebuffer.
pub const LENSMAP_FORMAT_RGBA8: u32 = 0;
/// `LensmapFrameOptions::format`: a 16-bit float framebuffer.
pub const LENSMAP_FORMAT_RGBA16F: u32 = 1;
/// `LensmapFrameOptions::format`: a 32-bit float framebuffer.
pub const LENSMAP_FORMAT_RGBA32F: u32 = 2;

/// `LensmapHostDevice::enabled_features`: `VkPhysicalDeviceVulkan13Features::dynamicRendering`.
pub const LENSMAP_FEATURE_DYNAMIC_RENDERING: u32 = 1;
/// `LensmapHostDevice::enabled_features`: `VkPhysicalDeviceVulkan13Features::synchronization2`.
pub const LENSMAP_FEATURE_SYNCHRONIZATION2: u32 = 2;
/// `LensmapHostDevice::enabled_features`: `VkPhysicalDeviceVulkan12Features::timelineSemaphore`.
pub const LENSMAP_FEATURE_TIMELINE_SEMAPHORE: u32 = 4;
/// `LensmapHostDevice::enabled_features`: `VkPhysicalDeviceFeatures::imageCubeArray`.
pub const LENSMAP_FEATURE_IMAGE_CUBE_ARRAY: u32 = 8;
/// Every feature lensmap needs enabled on a host's device.
pub const LENSMAP_FEATURES_REQUIRED: u32 = 15;

/// What a call did. The numbers are stable: new codes are only ever added.
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LensmapResult {
    /// Success.
    Ok = 0,
    /// A required pointer argument was NULL.
    NullArgument = 1,
    /// A handle is not a live one of this kind (freed already, or never made by lensmap).
    InvalidHandle = 2,
    /// An option struct's `struct_size` is not a size this lensmap knows.
    StructSize = 3,
    /// A value is out of range or malformed (the message names the field and the fix).
    InvalidArgument = 4,
    /// No Vulkan loader or driver (install `mesa-vulkan-drivers` for lavapipe).
    NoDriver = 5,
    /// No suitable device, or the host's device lacks a feature lensmap needs.
    Device = 6,
    /// The scene file or a scene asset is wrong (the message names file, field and fix).
    Scene = 7,
    /// The bake directory is missing, damaged or made for another scene.
    Bake = 8,
    /// An image format lensmap cannot render to.
    UnsupportedFormat = 9,
    /// The caller's buffer is too small (the message gives the size needed).
    BufferTooSmall = 10,
    /// The handle is in use by a call on another thread.
    Busy = 11,
    /// The work failed on the GPU or the CPU (the message says where).
    Render = 12,
    /// A bug in lensmap, caught at the ABI boundary: please report the message.
    Panic = 13,
}

/// A Vulkan instance (`VkInstance` from vulkan/vulkan.h; a dispatchable handle).
pub type VkInstance = *mut c_void;
/// A Vulkan physical device (`VkPhysicalDevice`; a dispatchable handle).
pub type VkPhysicalDevice = *mut c_void;
/// A Vulkan device (`VkDevice`; a dispatchable handle).
pub type VkDevice = *mut c_void;
/// A Vulkan queue (`VkQueue`; a dispatchable handle).
pub type VkQueue = *mut c_void;
/// A Vulkan image (`VkImage`; a non-dispatchable handle, a pointer on 64-bit hosts).
pub type VkImage = *mut c_void;
/// A Vulkan image view (`VkImageView`; non-dispatchable).
pub type VkImageView = *mut c_void;
/// A Vulkan semaphore (`VkSemaphore`; non-dispatchable).
pub type VkSemaphore = *mut c_void;
/// A `VkFormat` (a C enum: an `int`).
pub type VkFormat = i32;
/// A `VkImageLayout` (a C enum: an `int`).
pub type VkImageLayout = i32;

// Non-dispatchable handles are pointers in vulkan.h on 64-bit targets only (uint64_t elsewhere):
// the aliases above are ABI-identical there, and this library is built for 64-bit hosts.
const _: () = assert!(std::mem::size_of::<*mut c_void>() == 8);

/// The loader's `vkGetInstanceProcAddr` (`PFN_vkGetInstanceProcAddr`).
#[allow(
    non_camel_case_types,
    reason = "vulkan.h's name, which the header uses"
)]
pub type PFN_vkGetInstanceProcAddr = Option<
    unsafe extern "system" fn(
        instance: VkInstance,
        name: *const c_char,
    ) -> Option<unsafe extern "system" fn()>,
>;

/// Options of [`lensmap_context_new`].
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct LensmapContextOptions {
    /// `sizeof(LensmapContextOptions)`.
    pub struct_size: u32,
    /// Non-zero: enable the Khronos validation layer (its messages go to stderr and are counted).
    pub validation: u32,
    /// A substring of the device name to use, or NULL for the best device (discrete GPU first).
    pub device_name: *const c_char,
}

/// A host's Vulkan objects lent to [`lensmap_context_new_on_host`]. The host keeps them alive
/// until the context is freed and does not use `queue` from another thread during a lensmap
/// call.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct LensmapHostDevice {
    /// `sizeof(LensmapHostDevice)`.
    pub struct_size: u32,
    /// The loader's `vkGetInstanceProcAddr`.
    pub get_instance_proc_addr: PFN_vkGetInstanceProcAddr,
    /// The host's instance (Vulkan 1.3).
    pub instance: VkInstance,
    /// The physical device `device` was made from.
    pub physical_device: VkPhysicalDevice,
    /// The host's device.
    pub device: VkDevice,
    /// The queue family of `queue` (it must support graphics).
    pub queue_family: u32,
    /// The queue lensmap records and submits on.
    pub queue: VkQueue,
    /// The `LENSMAP_FEATURE_*` bits the host enabled when creating `device`; all of
    /// `LENSMAP_FEATURES_REQUIRED` are needed (Vulkan cannot be asked which were enabled).
    pub enabled_features: u32,
}

/// Options of [`lensmap_scene_load`].
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct LensmapSceneOptions {
    /// `sizeof(LensmapSceneOptions)`.
    pub struct_size: u32,
    /// A built-in scene name (`teapot-room`, `glass-sphere`, `mirror-teapot`) or the path of a
    /// scene `.toml`, UTF-8.
    pub scene: *const c_char,
    /// A bake directory made for this scene by `lensmap bake`, UTF-8; NULL for layered EMs
    /// projected from the scene onto its layer shells.
    pub bake_dir: *const c_char,
    /// Projected EMs: the cube-map face size, a power of two (0: the default, 128).
    pub em_size: u32,
    /// Non-zero: use `bake_dir` even if it was made for another scene (deliberate reuse).
    pub accept_any_bake: u32,
}

/// One frame: the camera, the tessellation threshold, the compositor and the framebuffer.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct LensmapFrameOptions {
    /// `sizeof(LensmapFrameOptions)`.
    pub struct_size: u32,
    /// Camera position, metres (right-handed, y up).
    pub position: [f32; 3],
    /// The point the camera looks at, metres.
    pub look_at: [f32; 3],
    /// The up vector (not parallel to the view direction).
    pub up: [f32; 3],
    /// Vertical field of view, degrees, in (0, 180).
    pub vfov_degrees: f32,
    /// Image width, pixels (≥ 1).
    pub width: u32,
    /// Image height, pixels (≥ 1).
    pub height: u32,
    /// k for k×k supersampling (≥ 1; the frame is box-filtered down to width × height).
    pub supersampling: u32,
    /// Tessellation threshold: triangles stop splitting when their edges are shorter than t
    /// subpixels (> 0; 0 means the default, 3).
    pub t: f32,
    /// `LENSMAP_VARIANT_*`.
    pub variant: u32,
    /// `LENSMAP_FORMAT_*`: the framebuffer's precision.
    pub format: u32,
    /// `LENSMAP_BLEND_*`: how the multipass compositor combines layers and groups (ABI 3; a
    /// struct of ABI 2's size, which ends before this field, means front-to-back).
    pub blend: u32,
}

/// A host's image to render a frame into ([`lensmap_render_to_image`]), on the device of a
/// context made by [`lensmap_context_new_on_host`]. Its size is the frame's `width × height`.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct LensmapHostImage {
    /// `sizeof(LensmapHostImage)`.
    pub struct_size: u32,
    /// The image: 2D, created with `VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT`.
    pub image: VkImage,
    /// A 2D view of one level and one layer of it: `mip_level` and `array_layer`.
    pub view: VkImageView,
    /// The level the view shows (lensmap's barriers cover that level alone).
    pub mip_level: u32,
    /// The array layer the view shows (lensmap's barriers cover that layer alone).
    pub array_layer: u32,
    /// Its format: `VK_FORMAT_R8G8B8A8_UNORM`, `_R16G16B16A16_SFLOAT`, `_R32G32B32A32_SFLOAT`,
    /// `_B8G8R8A8_UNORM`, `_R8G8B8A8_SRGB` or `_B8G8R8A8_SRGB` (sRGB formats encode on write).
    pub format: VkFormat,
    /// The layout it is in when the frame's work begins (after the wait semaphores): a
    /// colour-image layout, `UNDEFINED` when its contents do not matter.
    pub current_layout: VkImageLayout,
    /// The layout the frame leaves it in (what the host does next: `TRANSFER_SRC_OPTIMAL`,
    /// `SHADER_READ_ONLY_OPTIMAL`, `PRESENT_SRC_KHR`, …; not `UNDEFINED` or `PREINITIALIZED`).
    pub final_layout: VkImageLayout,
    /// Semaphores the frame waits for before it writes any colour attachment.
    pub wait_count: u32,
    /// `wait_count` semaphores (NULL when 0).
    pub wait_semaphores: *const VkSemaphore,
    /// The value to wait for per semaphore (timeline semaphores; ignored for binary ones), or
    /// NULL: all binary.
    pub wait_values: *const u64,
    /// Semaphores the frame signals when all its work is done.
    pub signal_count: u32,
    /// `signal_count` semaphores (NULL when 0).
    pub signal_semaphores: *const VkSemaphore,
    /// The value to signal per semaphore (timeline semaphores; ignored for binary ones), or
    /// NULL: all binary.
    pub signal_values: *const u64,
}

/// Where a frame's time went and what it cost (the paper's table). Set `struct_size`; lensmap
/// fills the fields that fit in it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct LensmapFrameStats {
    /// `sizeof(LensmapFrameStats)`.
    pub struct_size: u32,
    /// Passes the compositor recorded.
    pub passes: u32,
    /// 1 when the frame reused the scene's previous one (the same camera and options: a still
    /// camera costs only the GPU pass, and traces no ray), else 0.
    pub reused: u32,
    /// Ray tracing at the lens vertices, ms.
    pub trace_ms: f64,
    /// Texture coordinate generation, ms.
    pub texgen_ms: f64,
    /// Adaptive tessellation, ms.
    pub tessellation_ms: f64,
    /// Upload, recording, GPU execution, readback and box filter, ms.
    pub other_ms: f64,
    /// The whole frame, ms.
    pub total_ms: f64,
    /// Rays cast (primary, secondary and shadow).
    pub rays: u64,
    /// Ray-triangle intersection tests.
    pub triangle_tests: u64,
    /// Lens triangles after tessellation.
    pub lens_triangles: u64,
    /// Lens vertices ray traced.
    pub vertices_traced: u64,
}

/// A plan to print: the compositor's passes for one lens object's frame of this shape.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct LensmapPlanOptions {
    /// `sizeof(LensmapPlanOptions)`.
    pub struct_size: u32,
    /// Layers per viewpoint sample (1 … 256).
    pub layers: u32,
    /// Viewpoint samples blended (1 or 2).
    pub viewpoints: u32,
    /// Shading terms: 2 (glass: refraction and reflection) or 1 (mirror).
    pub terms: u32,
    /// `LENSMAP_VARIANT_*`.
    pub variant: u32,
    /// `LENSMAP_FORMAT_*`.
    pub format: u32,
    /// `LENSMAP_BLEND_*` (ABI 3; a struct of ABI 2's size, which ends before this field, means
    /// front-to-back).
    pub blend: u32,
}

/// A Vulkan device with lensmap's pipelines and per-frame buffers.
pub struct LensmapContext {
    runner: Mutex<FrameRunner>,
    /// Made on a host's device (host images can be rendered into), not lensmap's own.
    on_host: bool,
}

/// A scene with its layered EMs and light maps, ready to render.
pub struct LensmapScene {
    hybrid: HybridScene,
}

/// Which kind of handle an address is registered as.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
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

fn register<T>(handle: Box<T>, kind: Kind) -> *mut T {
    let pointer = Box::into_raw(handle);
    live()
        .get_or_insert_with(HashMap::new)
        .insert(pointer as usize, kind);
    pointer
}

fn is_live(pointer: usize, kind: Kind) -> bool {
    live()
        .as_ref()
        .is_some_and(|map| map.get(&pointer) == Some(&kind))
}

/// Registers a new context for `runner` and writes it to `*out`.
///
/// # Safety
/// `out` must be non-null and writable.
unsafe fn hand_out_context(runner: FrameRunner, on_host: bool, out: *mut *mut LensmapContext) {
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
unsafe fn free_handle<T>(pointer: *mut T, kind: Kind, refusal: &str) -> Result<(), Failure> {
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
fn unregister(pointer: usize, kind: Kind) -> bool {
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

/// A failed call: its code and the message [`lensmap_last_error`] gives.
/// Options as the C ABI names them: the fields of the options struct a call was given.
struct StructFields;

impl OptionWords for StructFields {
    fn option(&self, field: &str) -> String {
        format!("options->{field}")
    }

    fn setting(&self, field: &str, value: &str) -> String {
        format!("options->{field} {value}")
    }
}

struct Failure {
    code: LensmapResult,
    message: String,
}

impl Failure {
    fn new(code: LensmapResult, message: impl Into<String>) -> Failure {
        Failure {
            code,
            message: message.into(),
        }
    }
}

impl From<GpuError> for Failure {
    fn from(error: GpuError) -> Failure {
        let code = match error {
            GpuError::NoDriver(_) => LensmapResult::NoDriver,
            GpuError::NoSuitableDevice(_) | GpuError::ValidationLayerMissing => {
                LensmapResult::Device
            }
            _ => LensmapResult::Render,
        };
        Failure::new(code, error.to_string())
    }
}

impl From<RenderError> for Failure {
    fn from(error: RenderError) -> Failure {
        match error {
            RenderError::Gpu(error) => error.into(),
            RenderError::BadInput(_) | RenderError::Program(_) | RenderError::Framebuffer(_) => {
                Failure::new(LensmapResult::InvalidArgument, error.to_string())
            }
        }
    }
}

impl From<RunError> for Failure {
    fn from(error: RunError) -> Failure {
        let code = match &error {
            RunError::Render(_) => {
                return match error {
                    RunError::Render(render) => render.into(),
                    other => Failure::new(LensmapResult::Render, other.to_string()),
                };
            }
            RunError::Option(_) => LensmapResult::InvalidArgument,
            RunError::Bake(_) => LensmapResult::Bake,
            RunError::Hybrid(lensmap::hybrid::HybridError::BakeMismatch(_)) => LensmapResult::Bake,
            RunError::Hybrid(_) => LensmapResult::Scene,
            RunError::Tessellation(_) => LensmapResult::Render,
        };
        Failure::new(code, error.to_string())
    }
}

impl From<SceneError> for Failure {
    fn from(error: SceneError) -> Failure {
        Failure::new(LensmapResult::Scene, error.to_string())
    }
}

thread_local! {
    /// The message of the last failure on this thread.
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

fn remember(message: &str) {
    // An interior NUL would end the C string early: it is replaced.
    let text = CString::new(message.replace('\0', "\u{fffd}")).unwrap_or_default();
    LAST_ERROR.with(|last| *last.borrow_mut() = text);
}

/// The panic boundary every export goes through: runs `body`, turns its failure or panic into a
/// code and remembers the message.
fn boundary(body: impl FnOnce() -> Result<(), Failure>) -> LensmapResult {
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

/// `*pointer`, or a NullArgument failure naming it.
///
/// # Safety
/// A non-null `pointer` must point to a readable `T`.
unsafe fn read_struct<T: Copy>(pointer: *const T, name: &str) -> Result<T, Failure> {
    if pointer.is_null() {
        return Err(Failure::new(
            LensmapResult::NullArgument,
            format!("{name} is NULL"),
        ));
    }
    // SAFETY: non-null, and readable by the caller's promise. Its first field is the size.
    let size = unsafe { *(pointer as *const u32) };
    if size as usize != std::mem::size_of::<T>() {
        return Err(Failure::new(
            LensmapResult::StructSize,
            format!(
                "{name}->struct_size is {size}, but this lensmap (ABI {LENSMAP_ABI_VERSION}) knows {} bytes; set it to sizeof the struct from the lensmap.h this library ships",
                std::mem::size_of::<T>()
            ),
        ));
    }
    // SAFETY: the caller says a whole T is there, and the size it wrote agrees.
    Ok(unsafe { *pointer })
}

/// `*pointer` of a struct that grew at its end: its `struct_size` may be this library's size or
/// `older`, an earlier ABI's (the struct up to the first field that version lacked); the
/// missing fields read as zero (each one's zero is the earlier behaviour).
///
/// # Safety
/// A non-null `pointer` must point to a readable struct of the size its first field says, and
/// `T` must be a `repr(C)` struct of integers and floats (all-zero bytes are a valid `T`).
unsafe fn read_versioned<T: Copy>(
    pointer: *const T,
    name: &str,
    older: usize,
) -> Result<T, Failure> {
    if pointer.is_null() {
        return Err(Failure::new(
            LensmapResult::NullArgument,
            format!("{name} is NULL"),
        ));
    }
    // SAFETY: non-null, and readable by the caller's promise. Its first field is the size.
    let size = unsafe { *(pointer as *const u32) } as usize;
    let current = std::mem::size_of::<T>();
    debug_assert!(
        older < current,
        "an earlier ABI's struct is a prefix of this one"
    );
    if size != current && size != older {
        return Err(Failure::new(
            LensmapResult::StructSize,
            format!(
                "{name}->struct_size is {size}, but this lensmap (ABI {LENSMAP_ABI_VERSION}) knows {current} bytes (or {older} from an earlier ABI); set it to sizeof the struct from the lensmap.h this library ships"
            ),
        ));
    }
    // SAFETY: all-zero bytes are a valid T (the caller's promise); the caller's struct holds
    // `size` ≤ size_of::<T>() readable bytes, copied over the zeros.
    let mut value: T = unsafe { std::mem::zeroed() };
    unsafe {
        std::ptr::copy_nonoverlapping(pointer as *const u8, &mut value as *mut T as *mut u8, size)
    };
    Ok(value)
}

/// ABI 2's `sizeof(LensmapFrameOptions)`: everything before `blend` (ABI 2 had no trailing
/// padding, so its size is the new field's offset; pinned, so a reordering cannot move it).
const FRAME_OPTIONS_ABI2: usize = 68;

/// ABI 2's `sizeof(LensmapPlanOptions)`: everything before `blend`.
const PLAN_OPTIONS_ABI2: usize = 24;

const _: () = assert!(
    FRAME_OPTIONS_ABI2 == std::mem::offset_of!(LensmapFrameOptions, blend)
        && PLAN_OPTIONS_ABI2 == std::mem::offset_of!(LensmapPlanOptions, blend),
    "ABI 2's structs end where `blend` begins"
);

/// A UTF-8 C string, or a failure naming the field.
///
/// # Safety
/// A non-null `text` must be NUL-terminated and readable.
unsafe fn read_text(text: *const c_char, name: &str) -> Result<Option<String>, Failure> {
    if text.is_null() {
        return Ok(None);
    }
    // SAFETY: the caller's promise.
    let text = unsafe { CStr::from_ptr(text) };
    text.to_str().map(|s| Some(s.to_owned())).map_err(|_| {
        Failure::new(
            LensmapResult::InvalidArgument,
            format!("{name} is not UTF-8"),
        )
    })
}

fn null(name: &str) -> Failure {
    Failure::new(LensmapResult::NullArgument, format!("{name} is NULL"))
}

fn variant(value: u32, field: &str) -> Result<Variant, Failure> {
    match value {
        LENSMAP_VARIANT_SINGLE_PASS => Ok(Variant::SinglePass),
        LENSMAP_VARIANT_MULTIPASS => Ok(Variant::Multipass),
        other => Err(Failure::new(
            LensmapResult::InvalidArgument,
            format!(
                "{field} is {other}; give LENSMAP_VARIANT_SINGLE_PASS (0) or LENSMAP_VARIANT_MULTIPASS (1)"
            ),
        )),
    }
}

fn blend(value: u32, field: &str) -> Result<BlendScheme, Failure> {
    match value {
        LENSMAP_BLEND_FRONT_TO_BACK => Ok(BlendScheme::FrontToBack),
        LENSMAP_BLEND_BACK_TO_FRONT => Ok(BlendScheme::BackToFront),
        LENSMAP_BLEND_GROUP_TARGETS => Ok(BlendScheme::GroupTargets),
        LENSMAP_BLEND_PROGRAMMABLE => Ok(BlendScheme::Programmable),
        other => Err(Failure::new(
            LensmapResult::InvalidArgument,
            format!(
                "{field} is {other}; give LENSMAP_BLEND_FRONT_TO_BACK (0), _BACK_TO_FRONT (1), _GROUP_TARGETS (2) or _PROGRAMMABLE (3)"
            ),
        )),
    }
}

/// `options->variant` and `options->blend`, checked together: the single pass takes only
/// front-to-back.
fn compositing(variant_value: u32, blend_value: u32) -> Result<(Variant, BlendScheme), Failure> {
    let (variant, scheme) = (
        variant(variant_value, "options->variant")?,
        blend(blend_value, "options->blend")?,
    );
    if variant == Variant::SinglePass && scheme != BlendScheme::FrontToBack {
        return Err(Failure::new(
            LensmapResult::InvalidArgument,
            format!(
                "options->blend is {blend_value} ({}); the single pass takes only LENSMAP_BLEND_FRONT_TO_BACK: set options->variant to LENSMAP_VARIANT_MULTIPASS or options->blend to 0",
                scheme.name()
            ),
        ));
    }
    Ok((variant, scheme))
}

fn format(value: u32, field: &str) -> Result<TargetFormat, Failure> {
    match value {
        LENSMAP_FORMAT_RGBA8 => Ok(TargetFormat::Rgba8),
        LENSMAP_FORMAT_RGBA16F => Ok(TargetFormat::Rgba16f),
        LENSMAP_FORMAT_RGBA32F => Ok(TargetFormat::Rgba32f),
        other => Err(Failure::new(
            LensmapResult::UnsupportedFormat,
            format!(
                "{field} is {other}; lensmap renders to LENSMAP_FORMAT_RGBA8 (0), LENSMAP_FORMAT_RGBA16F (1) or LENSMAP_FORMAT_RGBA32F (2)"
            ),
        )),
    }
}

/// The context behind a handle, locked for this call.
///
/// # Safety
/// `context` must be NULL, a live context, or a pointer lensmap never gave out.
unsafe fn lock_context<'a>(
    context: *mut LensmapContext,
) -> Result<std::sync::MutexGuard<'a, FrameRunner>, Failure> {
    if context.is_null() {
        return Err(null("context"));
    }
    if !is_live(context as usize, Kind::Context) {
        return Err(Failure::new(
            LensmapResult::InvalidHandle,
            "context is not a live LensmapContext (freed already, or not made by lensmap_context_new)",
        ));
    }
    // SAFETY: a live handle points to a LensmapContext until it is freed.
    let context = unsafe { &*context };
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
unsafe fn scene_ref<'a>(scene: *const LensmapScene) -> Result<&'a LensmapScene, Failure> {
    if scene.is_null() {
        return Err(null("scene"));
    }
    if !is_live(scene as usize, Kind::Scene) {
        return Err(Failure::new(
            LensmapResult::InvalidHandle,
            "scene is not a live LensmapScene (freed already, or not made by lensmap_scene_load)",
        ));
    }
    // SAFETY: a live handle points to a LensmapScene until it is freed.
    Ok(unsafe { &*scene })
}

/// The ABI version of the loaded library ([`LENSMAP_ABI_VERSION`] of its header).
#[unsafe(no_mangle)]
pub extern "C" fn lensmap_abi_version() -> u32 {
    LENSMAP_ABI_VERSION
}

/// The message of the last failure on the calling thread, NUL-terminated UTF-8; an empty string
/// before any failure. Successful calls leave it as it is. The pointer stays valid until the
/// next failing call on this thread; copy the text to keep it.
#[unsafe(no_mangle)]
pub extern "C" fn lensmap_last_error() -> *const c_char {
    LAST_ERROR.with(|last| last.borrow().as_ptr())
}

/// Creates a context on lensmap's own Vulkan instance and device (headless). `options` may be
/// NULL for the defaults (best device, no validation). On success `*out` is a new context to
/// free with [`lensmap_context_free`].
///
/// # Safety
/// `options` must be NULL or point to a `LensmapContextOptions`; `out` must be writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn lensmap_context_new(
    options: *const LensmapContextOptions,
    out: *mut *mut LensmapContext,
) -> LensmapResult {
    boundary(|| {
        if out.is_null() {
            return Err(null("out"));
        }
        let mut gpu_options = GpuOptions::default();
        if !options.is_null() {
            // SAFETY: the caller's promise.
            let options = unsafe { read_struct(options, "options") }?;
            gpu_options.validation = options.validation != 0;
            // SAFETY: the caller's promise.
            if let Some(name) = unsafe { read_text(options.device_name, "options->device_name") }? {
                gpu_options.device = lensmap::gpu::DeviceChoice::NameContains(name);
            }
        }
        let runner = FrameRunner::new(Gpu::new(&gpu_options)?)?;
        // SAFETY: checked non-null; writable by the caller's promise.
        unsafe { hand_out_context(runner, false, out) };
        Ok(())
    })
}

/// Creates a context on the host's Vulkan instance, device and queue: lensmap makes its own
/// allocator, command pool and resources on the host's device and destroys only those. The host
/// must have enabled `LENSMAP_FEATURES_REQUIRED` and say so in `enabled_features`; a missing
/// feature returns `LENSMAP_RESULT_DEVICE` naming it.
///
/// # Safety
/// `host` must point to a `LensmapHostDevice` whose handles are valid and belong together;
/// `out` must be writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn lensmap_context_new_on_host(
    host: *const LensmapHostDevice,
    out: *mut *mut LensmapContext,
) -> LensmapResult {
    boundary(|| {
        if out.is_null() {
            return Err(null("out"));
        }
        // SAFETY: the caller's promise.
        let host = unsafe { read_struct(host, "host") }?;
        let Some(get_instance_proc_addr) = host.get_instance_proc_addr else {
            return Err(null("host->get_instance_proc_addr"));
        };
        for (pointer, name) in [
            (host.instance, "host->instance"),
            (host.physical_device, "host->physical_device"),
            (host.device, "host->device"),
            (host.queue, "host->queue"),
        ] {
            if pointer.is_null() {
                return Err(null(name));
            }
        }
        let bits = host.enabled_features;
        let enabled = HostFeatures {
            dynamic_rendering: bits & LENSMAP_FEATURE_DYNAMIC_RENDERING != 0,
            synchronization2: bits & LENSMAP_FEATURE_SYNCHRONIZATION2 != 0,
            timeline_semaphore: bits & LENSMAP_FEATURE_TIMELINE_SEMAPHORE != 0,
            image_cube_array: bits & LENSMAP_FEATURE_IMAGE_CUBE_ARRAY != 0,
        };
        use vk::Handle as _;
        let lent = HostDevice {
            // SAFETY: the C and Rust signatures of vkGetInstanceProcAddr are the same ABI.
            get_instance_proc_addr: unsafe {
                std::mem::transmute::<
                    unsafe extern "system" fn(
                        VkInstance,
                        *const c_char,
                    )
                        -> Option<unsafe extern "system" fn()>,
                    vk::PFN_vkGetInstanceProcAddr,
                >(get_instance_proc_addr)
            },
            instance: vk::Instance::from_raw(host.instance as u64),
            physical_device: vk::PhysicalDevice::from_raw(host.physical_device as u64),
            device: vk::Device::from_raw(host.device as u64),
            queue_family: host.queue_family,
            queue: vk::Queue::from_raw(host.queue as u64),
            enabled,
        };
        // SAFETY: the caller promises valid handles that belong together.
        let gpu = unsafe { Gpu::from_host(&lent) }?;
        let runner = FrameRunner::new(gpu)?;
        // SAFETY: checked non-null; writable by the caller's promise.
        unsafe { hand_out_context(runner, true, out) };
        Ok(())
    })
}

/// Frees a context (waiting for its device to be idle). NULL is a no-op; a pointer that is not
/// a live context (a second free) returns `LENSMAP_RESULT_INVALID_HANDLE` and frees nothing.
///
/// # Safety
/// No other thread may be using `context`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn lensmap_context_free(context: *mut LensmapContext) -> LensmapResult {
    boundary(|| {
        // SAFETY: a context is only ever registered as Kind::Context.
        unsafe {
            free_handle(
                context,
                Kind::Context,
                "lensmap_context_free: not a live LensmapContext",
            )
        }
    })
}

/// Writes into `*count` the number of Vulkan validation messages the context has seen (0 when
/// validation is off, or on a host's device, whose messages go to the host's messenger).
///
/// # Safety
/// `context` must be a handle from this library (or NULL); `count` must be writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn lensmap_context_validation_messages(
    context: *mut LensmapContext,
    count: *mut u64,
) -> LensmapResult {
    boundary(|| {
        if count.is_null() {
            return Err(null("count"));
        }
        // SAFETY: the caller's promise.
        let runner = unsafe { lock_context(context) }?;
        let messages = runner.gpu().validation_report().messages.len() as u64;
        // SAFETY: checked non-null; writable by the caller's promise.
        unsafe { *count = messages };
        Ok(())
    })
}

/// Loads a scene and its layered EMs (a bake directory, or projected from the scene) and its
/// light maps. On success `*out` is a new scene to free with [`lensmap_scene_free`].
///
/// # Safety
/// `options` must point to a `LensmapSceneOptions` whose strings are NUL-terminated or NULL;
/// `out` must be writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn lensmap_scene_load(
    options: *const LensmapSceneOptions,
    out: *mut *mut LensmapScene,
) -> LensmapResult {
    boundary(|| {
        if out.is_null() {
            return Err(null("out"));
        }
        // SAFETY: the caller's promise.
        let options = unsafe { read_struct(options, "options") }?;
        // SAFETY: the caller's promise.
        let Some(name) = (unsafe { read_text(options.scene, "options->scene") })? else {
            return Err(null("options->scene"));
        };
        // SAFETY: the caller's promise.
        let bake = unsafe { read_text(options.bake_dir, "options->bake_dir") }?;
        let scene = Scene::load_named(&name)?;
        let ems = match bake {
            Some(dir) if options.accept_any_bake != 0 => EmSource::AnyBake(dir.into()),
            Some(dir) => EmSource::Bake(dir.into()),
            None => {
                let size = if options.em_size == 0 {
                    DEFAULT_EM_SIZE
                } else {
                    options.em_size
                };
                let projected = ProjectedOptions::with_size(size);
                projected.validate().map_err(|error| {
                    Failure::new(LensmapResult::InvalidArgument, error.worded(&StructFields))
                })?;
                EmSource::Projected(projected)
            }
        };
        let (hybrid, _) = load_hybrid_scene(scene, &ems)?;
        let handle = register(Box::new(LensmapScene { hybrid }), Kind::Scene);
        // SAFETY: checked non-null; writable by the caller's promise.
        unsafe { *out = handle };
        Ok(())
    })
}

/// Frees a scene. NULL is a no-op; a pointer that is not a live scene (a second free) returns
/// `LENSMAP_RESULT_INVALID_HANDLE` and frees nothing.
///
/// # Safety
/// No other thread may be using `scene`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn lensmap_scene_free(scene: *mut LensmapScene) -> LensmapResult {
    boundary(|| {
        // SAFETY: a scene is only ever registered as Kind::Scene.
        unsafe {
            free_handle(
                scene,
                Kind::Scene,
                "lensmap_scene_free: not a live LensmapScene",
            )
        }
    })
}

/// The camera and frame options of a `LensmapFrameOptions`, validated.
fn frame_settings(options: &LensmapFrameOptions) -> Result<(Camera, FrameOptions), Failure> {
    let camera = Camera {
        position: glam::Vec3::from_array(options.position),
        look_at: glam::Vec3::from_array(options.look_at),
        up: glam::Vec3::from_array(options.up),
        vfov_radians: options.vfov_degrees.to_radians(),
        width: options.width,
        height: options.height,
        supersampling: options.supersampling,
    };
    lensmap::trace::image::validate_camera(&camera).map_err(|error| {
        Failure::new(
            LensmapResult::InvalidArgument,
            format!(
                "options (position, look_at, up, vfov_degrees, width, height, supersampling): {error}"
            ),
        )
    })?;
    let t = if options.t == 0.0 {
        lensmap::hybrid::tessellate::DEFAULT_T
    } else {
        options.t
    };
    let (variant, blend) = compositing(options.variant, options.blend)?;
    let frame_options = FrameOptions {
        hybrid: HybridOptions::with_t(t),
        variant,
        blend,
        format: format(options.format, "options->format")?,
    };
    frame_options.validate().map_err(|error| {
        Failure::new(LensmapResult::InvalidArgument, error.worded(&StructFields))
    })?;
    Ok((camera, frame_options))
}

/// The size a caller gave its `LensmapFrameStats` (NULL: none wanted), checked: at least the
/// first two fields, at most the whole struct this library knows.
///
/// # Safety
/// A non-null `stats` must be readable for its first field.
unsafe fn stats_size(stats: *mut LensmapFrameStats) -> Result<Option<usize>, Failure> {
    if stats.is_null() {
        return Ok(None);
    }
    // SAFETY: non-null and readable by the caller's promise; its first field is the size.
    let size = unsafe { *(stats as *const u32) } as usize;
    if size < 8 || size > std::mem::size_of::<LensmapFrameStats>() {
        return Err(Failure::new(
            LensmapResult::StructSize,
            format!(
                "stats->struct_size is {size}; set it to sizeof(LensmapFrameStats) ({})",
                std::mem::size_of::<LensmapFrameStats>()
            ),
        ));
    }
    Ok(Some(size))
}

/// Copies the fields of `filled` that fit in the caller's `size` bytes into `stats`.
///
/// # Safety
/// `stats` must be writable for `size` ≤ `sizeof(LensmapFrameStats)` bytes.
unsafe fn write_stats(stats: *mut LensmapFrameStats, size: usize, filled: LensmapFrameStats) {
    let filled = LensmapFrameStats {
        struct_size: size as u32,
        ..filled
    };
    // SAFETY: the caller's promise; `size` ≤ sizeof(LensmapFrameStats), so only the fields that
    // fit are copied.
    unsafe {
        std::ptr::copy_nonoverlapping(
            &filled as *const LensmapFrameStats as *const u8,
            stats as *mut u8,
            size,
        );
    }
}

/// The paper's table of a frame: its CPU stages and counters, with the passes, the total and
/// "other" (everything but the three CPU stages).
fn frame_stats(
    stats: &lensmap::hybrid::HybridStats,
    passes: usize,
    total_ms: f64,
    other_ms: f64,
) -> LensmapFrameStats {
    let counters = stats.counters;
    LensmapFrameStats {
        struct_size: 0,
        passes: passes as u32,
        reused: u32::from(stats.reused),
        trace_ms: stats.trace_ms,
        texgen_ms: stats.texgen_ms,
        tessellation_ms: stats.tessellation_ms,
        other_ms,
        total_ms,
        rays: counters.all_rays(),
        triangle_tests: counters.triangle_tests,
        lens_triangles: stats.triangles_out as u64,
        vertices_traced: stats.vertices_traced as u64,
    }
}

/// Renders one hybrid frame of `scene` and reads it back into `rgba`: `width × height` pixels,
/// rows top to bottom, 4 floats each (linear, premultiplied RGBA), `rgba_floats` ≥
/// `4 × width × height`. `stats` may be NULL; else set its `struct_size` and lensmap fills it.
///
/// # Safety
/// `context` and `scene` must be handles from this library (or NULL); `options` must point to a
/// `LensmapFrameOptions` readable for its `struct_size` bytes; `rgba` must be writable for `rgba_floats` floats; `stats` NULL or
/// writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn lensmap_render_to_memory(
    context: *mut LensmapContext,
    scene: *const LensmapScene,
    options: *const LensmapFrameOptions,
    rgba: *mut f32,
    rgba_floats: usize,
    stats: *mut LensmapFrameStats,
) -> LensmapResult {
    boundary(|| {
        // SAFETY: the caller's promise.
        let options = unsafe { read_versioned(options, "options", FRAME_OPTIONS_ABI2) }?;
        if rgba.is_null() {
            return Err(null("rgba"));
        }
        // SAFETY: the caller's promise.
        let stats_size = unsafe { stats_size(stats) }?;
        let (camera, frame_options) = frame_settings(&options)?;
        let needed = 4 * camera.width as usize * camera.height as usize;
        if rgba_floats < needed {
            return Err(Failure::new(
                LensmapResult::BufferTooSmall,
                format!(
                    "rgba holds {rgba_floats} floats; a {}×{} frame needs {needed} (4 per pixel)",
                    camera.width, camera.height
                ),
            ));
        }
        // SAFETY: the caller's promise for both handles.
        let scene = unsafe { scene_ref(scene) }?;
        // SAFETY: as above.
        let mut runner = unsafe { lock_context(context) }?;
        runner.check_framebuffer(&camera, frame_options.format)?;
        let frame = runner.frame(&scene.hybrid, &camera, &frame_options)?;
        // SAFETY: writable for rgba_floats ≥ needed floats (the caller's promise, checked).
        let out = unsafe { std::slice::from_raw_parts_mut(rgba, needed) };
        for (chunk, pixel) in out.chunks_exact_mut(4).zip(&frame.image.pixels) {
            chunk.copy_from_slice(pixel);
        }
        if let Some(size) = stats_size {
            let filled = frame_stats(
                &frame.stats,
                frame.render.passes,
                frame.total_ms,
                frame.other_ms(),
            );
            // SAFETY: the caller set struct_size to what it can hold (checked above).
            unsafe { write_stats(stats, size, filled) };
        }
        Ok(())
    })
}

/// `count` semaphores and their values (NULL values: zeros) from a host's arrays.
///
/// # Safety
/// Non-null arrays must be readable for `count` elements.
unsafe fn semaphores(
    count: u32,
    handles: *const VkSemaphore,
    values: *const u64,
    name: &str,
) -> Result<Vec<(vk::Semaphore, u64)>, Failure> {
    if count == 0 {
        return Ok(Vec::new());
    }
    if handles.is_null() {
        return Err(null(&format!(
            "image->{name}_semaphores (with {name}_count {count})"
        )));
    }
    use vk::Handle as _;
    (0..count as usize)
        .map(|i| {
            // SAFETY: readable for `count` elements by the caller's promise.
            let handle = unsafe { *handles.add(i) };
            if handle.is_null() {
                return Err(null(&format!("image->{name}_semaphores[{i}]")));
            }
            let value = if values.is_null() {
                0
            } else {
                // SAFETY: as above.
                unsafe { *values.add(i) }
            };
            Ok((vk::Semaphore::from_raw(handle as u64), value))
        })
        .collect()
}

/// Renders one hybrid frame of `scene` into the host's image `image` and returns once it is
/// submitted on the host's queue: no readback, no wait. lensmap renders its framebuffer as
/// always and box-filters it (supersampling) into the image on the GPU, with the barriers from
/// `current_layout` to `final_layout`; the submission waits for `image`'s wait semaphores and
/// signals its signal semaphores when done, which is how the host learns the image is ready (or
/// from later work on the same queue). The context must have been made by
/// [`lensmap_context_new_on_host`] on the image's device. `stats` may be NULL; its GPU part is
/// the host's to time (`other_ms` covers upload, recording and submission).
///
/// On failure nothing was submitted: the wait semaphores were not waited on (a binary one stays
/// signalled) and the signal semaphores will not be signalled by this call. The call may wait
/// on the CPU for lensmap's own earlier work (a still camera for the previous frame, a moving
/// one for the frame two calls back, which reuse their buffers), never for this call's wait
/// semaphores; so a host must not make an earlier frame's wait semaphores depend on a later
/// lensmap call.
///
/// # Safety
/// `context` and `scene` must be handles from this library (or NULL); `options` must point to a
/// `LensmapFrameOptions` readable for its `struct_size` bytes and `image` to a `LensmapHostImage` whose handles are live objects of
/// the context's device, kept alive until the frame's signal semaphores are signalled; `stats`
/// NULL or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn lensmap_render_to_image(
    context: *mut LensmapContext,
    scene: *const LensmapScene,
    options: *const LensmapFrameOptions,
    image: *const LensmapHostImage,
    stats: *mut LensmapFrameStats,
) -> LensmapResult {
    boundary(|| {
        // SAFETY: the caller's promise.
        let options = unsafe { read_versioned(options, "options", FRAME_OPTIONS_ABI2) }?;
        // SAFETY: the caller's promise.
        let lent = unsafe { read_struct(image, "image") }?;
        // SAFETY: the caller's promise.
        let stats_size = unsafe { stats_size(stats) }?;
        let (camera, frame_options) = frame_settings(&options)?;
        let format = vk::Format::from_raw(lent.format);
        if !lensmap::render::HostImage::supports(format) {
            return Err(Failure::new(
                LensmapResult::UnsupportedFormat,
                format!(
                    "image->format is {format:?} ({}); lensmap renders into {}",
                    lent.format,
                    lensmap::render::HostImage::FORMATS
                        .map(|f| format!("VK_FORMAT_{f:?}"))
                        .join(", ")
                ),
            ));
        }
        for (pointer, name) in [(lent.image, "image->image"), (lent.view, "image->view")] {
            if pointer.is_null() {
                return Err(null(name));
            }
        }
        use vk::Handle as _;
        let host = lensmap::render::HostImage {
            image: vk::Image::from_raw(lent.image as u64),
            view: vk::ImageView::from_raw(lent.view as u64),
            mip_level: lent.mip_level,
            array_layer: lent.array_layer,
            format,
            width: camera.width,
            height: camera.height,
            current_layout: vk::ImageLayout::from_raw(lent.current_layout),
            final_layout: vk::ImageLayout::from_raw(lent.final_layout),
            // SAFETY: the caller's promise for both arrays.
            wait: unsafe {
                semaphores(
                    lent.wait_count,
                    lent.wait_semaphores,
                    lent.wait_values,
                    "wait",
                )
            }?,
            // SAFETY: as above.
            signal: unsafe {
                semaphores(
                    lent.signal_count,
                    lent.signal_semaphores,
                    lent.signal_values,
                    "signal",
                )
            }?,
        };
        // SAFETY: the caller's promise for both handles.
        let scene = unsafe { scene_ref(scene) }?;
        // SAFETY: as above.
        let mut runner = unsafe { lock_context(context) }?;
        // SAFETY: live (lock_context checked it) until freed, which the caller does not do now.
        if !unsafe { &*context }.on_host {
            return Err(Failure::new(
                LensmapResult::InvalidArgument,
                "context was made by lensmap_context_new on lensmap's own device: rendering into a host's image needs a context made by lensmap_context_new_on_host on the image's device",
            ));
        }
        runner.check_framebuffer(&camera, frame_options.format)?;
        let frame = runner.frame_into(&scene.hybrid, &camera, &frame_options, &host)?;
        if let Some(size) = stats_size {
            let filled = frame_stats(&frame.stats, frame.passes, frame.total_ms, frame.other_ms());
            // SAFETY: the caller set struct_size to what it can hold (checked above).
            unsafe { write_stats(stats, size, filled) };
        }
        Ok(())
    })
}

/// The f32 degrees that [`frame_settings`] turns back into exactly `radians`: `to_degrees` and
/// `to_radians` are not inverses in f32, and a camera one ulp off is another frame. The nearest
/// value within a few ulps of `radians.to_degrees()` that converts back exactly.
fn degrees_of(radians: f32) -> f32 {
    let first = radians.to_degrees();
    // Fields of view are positive and finite: their neighbours are one bit pattern apart.
    let bits = first.to_bits();
    (0..=8u32)
        .flat_map(|step| [bits.saturating_add(step), bits.saturating_sub(step)])
        .map(f32::from_bits)
        .find(|d| d.to_radians() == radians)
        .unwrap_or(first)
}

/// Fills `options` (whose `struct_size` the caller set; the other fields are not read) with what
/// `lensmap render --scene`
/// renders by default: the scene's camera (position, look-at, up, vertical field of view,
/// width, height, supersampling), t = 3, the single-pass compositor (front-to-back) and an
/// RGBA16F framebuffer. Change what differs, then render. An ABI 2 caller's smaller struct is
/// filled up to its own size.
///
/// # Safety
/// `scene` must be a handle from this library (or NULL); `options` must point to a
/// `LensmapFrameOptions` writable for its `struct_size` bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn lensmap_scene_frame_options(
    scene: *const LensmapScene,
    options: *mut LensmapFrameOptions,
) -> LensmapResult {
    boundary(|| {
        if options.is_null() {
            return Err(null("options"));
        }
        // SAFETY: non-null and points to a LensmapFrameOptions (the caller's promise); only its
        // first field, the size, is read: the rest may be unset.
        let size = unsafe { *(options as *const u32) } as usize;
        let current = std::mem::size_of::<LensmapFrameOptions>();
        if size != current && size != FRAME_OPTIONS_ABI2 {
            return Err(Failure::new(
                LensmapResult::StructSize,
                format!(
                    "options->struct_size is {size}, but this lensmap (ABI {LENSMAP_ABI_VERSION}) knows {current} bytes (or {FRAME_OPTIONS_ABI2} from ABI 2); set it to sizeof(LensmapFrameOptions)"
                ),
            ));
        }
        // SAFETY: the caller's promise.
        let scene = unsafe { scene_ref(scene) }?;
        let camera = scene.hybrid.scene.camera;
        let filled = LensmapFrameOptions {
            struct_size: size as u32,
            position: camera.position.to_array(),
            look_at: camera.look_at.to_array(),
            up: camera.up.to_array(),
            vfov_degrees: degrees_of(camera.vfov_radians),
            width: camera.width,
            height: camera.height,
            supersampling: camera.supersampling,
            t: lensmap::hybrid::tessellate::DEFAULT_T,
            variant: LENSMAP_VARIANT_SINGLE_PASS,
            format: LENSMAP_FORMAT_RGBA16F,
            blend: LENSMAP_BLEND_FRONT_TO_BACK,
        };
        // SAFETY: writable for `size` bytes by the caller's promise (a struct of that ABI's
        // size, checked above): only those are written.
        unsafe {
            std::ptr::copy_nonoverlapping(
                &filled as *const LensmapFrameOptions as *const u8,
                options as *mut u8,
                size,
            )
        };
        Ok(())
    })
}

/// Writes the compositor's plan for a frame of this shape as text (the table `lensmap passes`
/// prints) into `buffer`, NUL-terminated, and its length without the NUL into `*length`. With
/// `buffer` NULL only `*length` is written (a size query: allocate `*length + 1` bytes). A
/// `capacity` of `*length` or less returns `LENSMAP_RESULT_BUFFER_TOO_SMALL` and writes nothing.
///
/// # Safety
/// `options` must point to a `LensmapPlanOptions` readable for its `struct_size` bytes; `buffer`
/// NULL or writable for `capacity`
/// bytes; `length` writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn lensmap_plan_text(
    options: *const LensmapPlanOptions,
    buffer: *mut c_char,
    capacity: usize,
    length: *mut usize,
) -> LensmapResult {
    boundary(|| {
        // SAFETY: the caller's promise.
        let options = unsafe { read_versioned(options, "options", PLAN_OPTIONS_ABI2) }?;
        if length.is_null() {
            return Err(null("length"));
        }
        let most = FrameShape::MAX_EXPERIMENT_LAYERS;
        if !(1..=most).contains(&(options.layers as usize)) {
            return Err(Failure::new(
                LensmapResult::InvalidArgument,
                format!("options->layers is {}; give 1 to {most}", options.layers),
            ));
        }
        let terms: &[lensmap::trace::Term] = match options.terms {
            2 => &[
                lensmap::trace::Term::Refraction,
                lensmap::trace::Term::Reflection,
            ],
            1 => &[lensmap::trace::Term::Reflection],
            other => {
                return Err(Failure::new(
                    LensmapResult::InvalidArgument,
                    format!("options->terms is {other}; give 2 (glass) or 1 (mirror)"),
                ));
            }
        };
        if !(1..=2).contains(&options.viewpoints) {
            return Err(Failure::new(
                LensmapResult::InvalidArgument,
                format!("options->viewpoints is {}; give 1 or 2", options.viewpoints),
            ));
        }
        let shape = FrameShape::synthetic(
            640,
            480,
            options.layers as usize,
            options.viewpoints as usize,
            terms,
        );
        let (variant, blend) = compositing(options.variant, options.blend)?;
        let (graph, _) = frame_graph(
            &shape,
            &PlanOptions {
                variant,
                blend,
                format: format(options.format, "options->format")?,
                output: Output::Readback,
            },
        )
        .map_err(|error| Failure::new(LensmapResult::InvalidArgument, error.to_string()))?;
        let plan = graph
            .compile()
            .map_err(|error| Failure::new(LensmapResult::Render, error.to_string()))?;
        let text = plan.to_string();
        if buffer.is_null() {
            // SAFETY: checked non-null; writable by the caller's promise.
            unsafe { *length = text.len() };
            return Ok(());
        }
        if capacity <= text.len() {
            return Err(Failure::new(
                LensmapResult::BufferTooSmall,
                format!(
                    "the plan is {} bytes and its NUL; the buffer holds {capacity}",
                    text.len()
                ),
            ));
        }
        // SAFETY: writable for capacity > text.len() bytes (the caller's promise, checked).
        unsafe {
            std::ptr::copy_nonoverlapping(text.as_ptr(), buffer as *mut u8, text.len());
            *buffer.add(text.len()) = 0;
            *length = text.len();
        }
        Ok(())
    })
}
