//! The C ABI's types as `lensmap.h` declares them: the ABI version, the named constants, the
//! result codes, the Vulkan handle aliases, and the option and statistics structs.

use std::ffi::{c_char, c_void};

#[cfg(doc)]
use crate::exports::{
    lensmap_context_new, lensmap_context_new_on_host, lensmap_render_to_image, lensmap_scene_load,
};

/// The ABI version this header describes; raised when a struct grows or a function is added.
pub const LENSMAP_ABI_VERSION: u32 = 7;

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
/// `LensmapFrameOptions::viewpoint_blending`: the view space's rule: the two nearest samples
/// along a circle, the three of the spherical triangle holding the camera in a 2D view space
/// (the nearest point of the region outside it).
pub const LENSMAP_VIEWPOINTS_VIEW_SPACE: u32 = 0;
/// `LensmapFrameOptions::viewpoint_blending`: the two samples nearest the camera in angle, in any
/// view space.
pub const LENSMAP_VIEWPOINTS_TWO_NEAREST: u32 = 1;
/// `LensmapFrameOptions::viewpoint_blending`: the nearest sample alone.
pub const LENSMAP_VIEWPOINTS_NEAREST: u32 = 2;
/// `LensmapFrameOptions::tracer`: the lens vertices ray traced on the CPU, in f64 (the paper's
/// reference implementation; what every frame did before ABI 6).
pub const LENSMAP_TRACER_CPU: u32 = 0;
/// `LensmapFrameOptions::tracer`: the lens vertices ray traced on the device by a compute pass, in
/// f32, over the scene's geometry resident there (uploaded with the first such frame).
pub const LENSMAP_TRACER_GPU: u32 = 1;
/// `LensmapFrameOptions::tracer`: the GPU on a hardware device, the CPU on a CPU device such as
/// lavapipe, where the CPU path is measured faster (what `lensmap_scene_frame_options` fills in).
pub const LENSMAP_TRACER_AUTO: u32 = 2;
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
    /// A bug in lensmap: it broke an invariant of its own (the message says which); please
    /// report the message.
    Internal = 14,
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
    /// Light maps: texels of all the scene's atlases together (8 bytes each on the GPU), in
    /// [65536, 4294967296]; over it, every chart's density is lowered by one factor (0: the
    /// default, 4194304). The field to lower when a frame's maps are over the device's budget
    /// (ABI 4; a struct of ABI 3's size, which ends before this field, means the default).
    pub light_map_max_texels: u64,
    /// A radiance-map bake made for this scene by `lensmap bake --radiance-maps`, UTF-8: its
    /// glossy objects are then drawn by reflection-space IBR (the glossy pass) instead of
    /// light-mapped; NULL for light-mapped (ABI 7; a struct of an earlier size ends before this
    /// field).
    pub radiance_dir: *const c_char,
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
    /// `LENSMAP_VIEWPOINTS_*`: which viewpoint samples the frame blends (ABI 4; a struct of an
    /// earlier ABI's size, which ends before this field, means the view space's own rule).
    pub viewpoint_blending: u32,
    /// How each lens vertex evaluates Fresnel: 0 exactly (Schlick for mirrors, exact dielectric
    /// Fresnel for glass); N in [2, 4096]: Schlick with its fifth-order term looked up in a 1D
    /// table of N texels, linearly filtered like a texture (ABI 5; a struct of an earlier ABI's
    /// size, which ends before this field, means exact).
    pub fresnel_texels: u32,
    /// `LENSMAP_TRACER_*`: where the lens vertices are ray traced (ABI 6; a struct of an earlier
    /// ABI's size, which ends before this field, means the CPU).
    pub tracer: u32,
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
    /// Rays cast (primary, secondary and shadow). This and the next three are counted on the
    /// device when the lens vertices are traced there (`traced_on_gpu`): a frame into a host's
    /// image then gives the frame before's, read once it was done (zeros while it is not); a
    /// frame read back gives its own.
    pub rays: u64,
    /// Ray-triangle intersection tests.
    pub triangle_tests: u64,
    /// Lens triangles after tessellation.
    pub lens_triangles: u64,
    /// Lens vertices ray traced.
    pub vertices_traced: u64,
    /// Viewpoint samples the frame blended: 1 to 3 (ABI 4; a struct of ABI 3's size ends before
    /// this field).
    pub viewpoints: u32,
    /// 1 when the camera's direction lies outside the region the view space's samples cover (a
    /// 2D view space: in no triangle; the frame then blends the region's nearest point), else 0
    /// (ABI 4).
    pub outside_view_space: u32,
    /// 1 when the lens vertices were traced on the device (`LENSMAP_TRACER_GPU`, or `_AUTO` on a
    /// hardware device), else 0 (ABI 6).
    pub traced_on_gpu: u32,
    /// Radiance maps the glossy pass read, warped and blended (reflection-space IBR): per
    /// glossy object drawn from a radiance-map bake, its view samples blended (1 to 3) times its
    /// lobes; 0 without one (ABI 7).
    pub glossy_maps: u32,
}

/// A plan to print: the compositor's passes for one lens object's frame of this shape.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct LensmapPlanOptions {
    /// `sizeof(LensmapPlanOptions)`.
    pub struct_size: u32,
    /// Layers per viewpoint sample (1 … 256).
    pub layers: u32,
    /// Viewpoint samples blended (1 to 3: 3 inside a spherical triangle of a 2D view space).
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
