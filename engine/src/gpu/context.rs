//! Instance, device and queue; the allocator; one-shot command submission; the validation layer
//! and a messenger that counts every warning and error it reports.

use std::{
    ffi::{CStr, CString, c_void},
    mem::ManuallyDrop,
    sync::{Arc, Mutex},
};

use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};

use super::{
    GpuError, Timeline, VkContext,
    startup::{DeviceFeatures, choose_device, create_device, create_instance},
};

/// How to choose among the system's Vulkan devices.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum DeviceChoice {
    /// Discrete GPU, then integrated, then virtual, then CPU (lavapipe).
    #[default]
    Best,
    /// The first device whose name contains this substring (case-insensitive).
    NameContains(String),
}

/// Options for [`Gpu::new`].
#[derive(Clone, Debug, Default)]
pub struct GpuOptions {
    /// Which device to use.
    pub device: DeviceChoice,
    /// Enable the Khronos validation layer (with synchronization validation) and count its messages.
    pub validation: bool,
    /// The instance extensions a window system needs to present (`VK_KHR_surface` and the
    /// platform's, as `ash_window::enumerate_required_extensions` lists them). When given, the
    /// device is chosen among those with `VK_KHR_swapchain` and created with it; empty (the
    /// default) for a GPU that renders headless.
    pub surface_extensions: Vec<&'static CStr>,
    /// Take the largest device-local heap as at most this many bytes (`None`, the default: its
    /// real size). The memory budgets checked before any allocation (framebuffer targets,
    /// maps) are shares of that heap, so a host sharing the device with other work keeps
    /// lensmap within less, and a test reaches a refusal without allocating gigabytes.
    pub heap_limit_bytes: Option<u64>,
}

impl GpuOptions {
    /// Options from the environment: `LENSMAP_DEVICE=<name substring>` and `LENSMAP_VALIDATION=1`.
    pub fn from_env() -> Self {
        let device = match std::env::var("LENSMAP_DEVICE") {
            Ok(name) if !name.is_empty() => DeviceChoice::NameContains(name),
            _ => DeviceChoice::Best,
        };
        let validation = std::env::var("LENSMAP_VALIDATION").is_ok_and(|v| v == "1");
        GpuOptions {
            device,
            validation,
            surface_extensions: Vec::new(),
            heap_limit_bytes: None,
        }
    }
}

/// Validation messages seen so far (warnings and errors of every type).
#[derive(Clone, Debug, Default)]
pub struct ValidationReport {
    /// Whether the validation layer is on at all.
    pub enabled: bool,
    /// The messages, in order.
    pub messages: Vec<String>,
}

/// The device memory lensmap holds through its allocator, which makes every buffer and image
/// lensmap creates ([`Gpu::device_memory`]): what a long-running host watches for growth. It
/// does not count what the driver keeps for itself (pipelines, descriptor pools, command
/// buffers), which a CPU driver such as lavapipe keeps in the process's resident memory.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DeviceMemory {
    /// Bytes of the live buffers' and images' allocations (their memory requirements' sizes).
    pub allocated_bytes: u64,
    /// Bytes of the device memory blocks the allocator holds from the driver
    /// (`vkAllocateMemory`), at least `allocated_bytes`: what the device has given lensmap.
    pub reserved_bytes: u64,
    /// Live allocations.
    pub allocations: u64,
    /// Device memory blocks held.
    pub blocks: u64,
}

/// Everything that must outlive every resource: resources hold an `Arc` of it, so the device and
/// instance are destroyed only after the last buffer and image.
pub(crate) struct Shared {
    /// The Vulkan loader; held so that the library stays loaded while the instance lives.
    pub(crate) entry: ash::Entry,
    /// The Vulkan instance, destroyed last.
    pub(crate) instance: ash::Instance,
    /// The logical device with its one graphics queue.
    pub(crate) device: ash::Device,
    /// gpu-allocator's allocator for every buffer and image; dropped by hand before the device.
    pub(crate) allocator: ManuallyDrop<Mutex<Allocator>>,
    debug_instance: Option<ash::ext::debug_utils::Instance>,
    /// Debug-utils command-buffer labels around passes; `None` when the extension is absent.
    pub(crate) debug_device: Option<ash::ext::debug_utils::Device>,
    /// `VK_KHR_acceleration_structure`'s entry points, where the device was made with ray
    /// queries ([`Gpu::ray_queries`]).
    pub(crate) acceleration: Option<ash::khr::acceleration_structure::Device>,
    messenger: vk::DebugUtilsMessengerEXT,
    messages: Box<Mutex<Vec<String>>>,
    /// Whether lensmap created the instance and device (and destroys them), or a host lent them
    /// ([`Gpu::from_host`]: only what lensmap made on them is destroyed).
    owned: bool,
}

impl Drop for Shared {
    fn drop(&mut self) {
        // SAFETY: every resource holding an Arc<Shared> is gone; the allocator frees its blocks
        // before the device goes, and the messenger is destroyed before the instance.
        unsafe {
            let _ = self.device.device_wait_idle();
            ManuallyDrop::drop(&mut self.allocator);
            if self.owned {
                self.device.destroy_device(None);
                if let Some(debug) = &self.debug_instance {
                    debug.destroy_debug_utils_messenger(self.messenger, None);
                }
                self.instance.destroy_instance(None);
            }
        }
    }
}

/// A Vulkan device with one graphics queue, ready to render headless.
pub struct Gpu {
    /// The instance, device and allocator, shared with every resource made from this GPU.
    pub(crate) shared: Arc<Shared>,
    /// The graphics queue (queue 0 of the chosen family) every submission goes to.
    pub(crate) queue: vk::Queue,
    /// The queue's family.
    queue_family: u32,
    /// The physical device the device was made from.
    physical_device: vk::PhysicalDevice,
    /// The pool of that family's command buffers, resettable one by one.
    pub(crate) command_pool: vk::CommandPool,
    /// Command buffers of finished one-off submissions ([`Gpu::submit_and_wait`]), reset and
    /// reused by the next ones instead of one allocated and freed per submission: Debian 12's
    /// Khronos validation layer (1.3.239, synchronization validation on) never frees the state
    /// it makes for each allocated command buffer (KhronosGroup/Vulkan-ValidationLayers#6033),
    /// which heaptrack measured at 3.1 KB a call, 1.7 calls a frame in the soak
    /// (docs/results.md#soak). They die with the pool.
    spare_command_buffers: std::sync::Mutex<Vec<vk::CommandBuffer>>,
    /// The chosen physical device's properties (limits, API version, name).
    pub(crate) properties: vk::PhysicalDeviceProperties,
    /// The largest device-local memory heap, bytes: what budgets of GPU memory are checked
    /// against before any work starts.
    device_local_heap_bytes: u64,
    /// The device and the driver behind it.
    device: DeviceId,
    /// Whether shaders may compute in f64 (`shaderFloat64` enabled).
    float64: bool,
}

/// A device and its driver, as `VkPhysicalDeviceProperties` and `VkPhysicalDeviceDriverProperties`
/// name them. The device name alone does not tell drivers apart: Mesa 22.3's and Mesa 25.0's
/// lavapipe are both `llvmpipe (LLVM 15.0.6, 256 bits)`; their `driverInfo` differs.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct DeviceId {
    /// `deviceName`.
    pub device: String,
    /// `driverName`, e.g. `llvmpipe`.
    pub driver: String,
    /// `driverInfo`, the driver's version: `Mesa 25.0.7-2~bpo12+1 (LLVM 15.0.6)`.
    pub driver_info: String,
}

impl DeviceId {
    /// The driver and its version: `llvmpipe, Mesa 25.0.7-2~bpo12+1 (LLVM 15.0.6)`.
    pub fn driver_description(&self) -> String {
        match (self.driver.is_empty(), self.driver_info.is_empty()) {
            (false, false) => format!("{}, {}", self.driver, self.driver_info),
            (false, true) => self.driver.clone(),
            (true, false) => self.driver_info.clone(),
            (true, true) => String::from("(driver not named)"),
        }
    }
}

impl std::fmt::Display for DeviceId {
    /// `llvmpipe (LLVM 15.0.6, 256 bits), driver llvmpipe, Mesa 25.0.7-2~bpo12+1 (LLVM 15.0.6)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}, driver {}", self.device, self.driver_description())
    }
}

pub(super) const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

unsafe extern "system" fn count_message(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: the layer passes valid callback data for the duration of the call; `user` is the
    // Box<Mutex<Vec<String>>> owned by Shared, which outlives the messenger.
    let text = unsafe {
        let data = &*data;
        if data.p_message.is_null() {
            String::from("(no message)")
        } else {
            CStr::from_ptr(data.p_message)
                .to_string_lossy()
                .into_owned()
        }
    };
    let line = format!("validation {severity:?}: {text}");
    // Not eprintln!: a closed stderr must not panic inside a Vulkan callback.
    {
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), "{line}");
    }
    // SAFETY: see above.
    let messages = unsafe { &*(user as *const Mutex<Vec<String>>) };
    if let Ok(mut messages) = messages.lock() {
        messages.push(line);
    }
    vk::FALSE
}

/// A created or lent device before lensmap's allocator and command pool are made on it.
struct Parts {
    entry: ash::Entry,
    instance: ash::Instance,
    physical_device: vk::PhysicalDevice,
    device: ash::Device,
    queue_family: u32,
    queue: vk::Queue,
    properties: vk::PhysicalDeviceProperties,
    debug_instance: Option<ash::ext::debug_utils::Instance>,
    messenger: vk::DebugUtilsMessengerEXT,
    messages: Box<Mutex<Vec<String>>>,
    /// Whether the device was made with ray queries (`super::acceleration`).
    ray_queries: bool,
    /// Whether the device was made with `shaderFloat64`.
    float64: bool,
}

/// What lensmap needs enabled on a host's device, as the host declares it: Vulkan gives no way
/// to ask a `VkDevice` which features it was created with.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HostFeatures {
    /// `VkPhysicalDeviceVulkan13Features::dynamicRendering`.
    pub dynamic_rendering: bool,
    /// `VkPhysicalDeviceVulkan13Features::synchronization2`.
    pub synchronization2: bool,
    /// `VkPhysicalDeviceVulkan12Features::timelineSemaphore`.
    pub timeline_semaphore: bool,
    /// `VkPhysicalDeviceFeatures::imageCubeArray`.
    pub image_cube_array: bool,
}

impl HostFeatures {
    /// Every feature lensmap needs.
    pub const ALL: HostFeatures = HostFeatures {
        dynamic_rendering: true,
        synchronization2: true,
        timeline_semaphore: true,
        image_cube_array: true,
    };

    /// The names of the needed features that are not enabled.
    fn missing(&self) -> Vec<&'static str> {
        [
            (self.dynamic_rendering, "dynamicRendering"),
            (self.synchronization2, "synchronization2"),
            (self.timeline_semaphore, "timelineSemaphore"),
            (self.image_cube_array, "imageCubeArray"),
        ]
        .into_iter()
        .filter(|(enabled, _)| !enabled)
        .map(|(_, name)| name)
        .collect()
    }
}

/// The Vulkan objects under a [`Gpu`] ([`Gpu::vulkan`]), borrowed from it.
#[derive(Clone, Copy)]
pub struct VulkanHandles<'a> {
    /// The loader.
    pub entry: &'a ash::Entry,
    /// The instance.
    pub instance: &'a ash::Instance,
    /// The physical device.
    pub physical_device: vk::PhysicalDevice,
    /// The device.
    pub device: &'a ash::Device,
    /// The family of `queue`.
    pub queue_family: u32,
    /// The graphics queue every submission of the GPU goes to.
    pub queue: vk::Queue,
}

/// A host's Vulkan objects lent to lensmap ([`Gpu::from_host`]).
#[derive(Clone, Copy)]
pub struct HostDevice {
    /// The loader's `vkGetInstanceProcAddr`.
    pub get_instance_proc_addr: vk::PFN_vkGetInstanceProcAddr,
    /// The host's instance (Vulkan 1.3).
    pub instance: vk::Instance,
    /// The physical device `device` was made from.
    pub physical_device: vk::PhysicalDevice,
    /// The host's device.
    pub device: vk::Device,
    /// The queue family of `queue`, with graphics.
    pub queue_family: u32,
    /// The queue lensmap submits to.
    pub queue: vk::Queue,
    /// The features the host enabled on `device`.
    pub enabled: HostFeatures,
}

/// The semaphores of one submission ([`Gpu::record_submit`]).
#[derive(Clone, Copy)]
pub struct Semaphores<'a> {
    /// Signalled with `value` when the submission completes.
    pub timeline: &'a Timeline,
    /// Greater than any value signalled on `timeline` before.
    pub value: u64,
    /// Waited for before any colour attachment output (semaphore, value: the value matters for
    /// timeline semaphores only).
    pub waits: &'a [(vk::Semaphore, u64)],
    /// Signalled with the timeline: a host's semaphores around a frame rendered into its image.
    pub signals: &'a [(vk::Semaphore, u64)],
}

impl Gpu {
    /// A GPU on a host's own instance, device and queue (an engine embedding lensmap): lensmap
    /// records and submits on `host.queue` and makes its own allocator, command pool and
    /// resources on `host.device`, destroying only those. The host keeps the instance and
    /// device alive until the `Gpu` is dropped, does not use the queue from another thread while
    /// lensmap submits, and must have enabled what lensmap needs ([`HostDevice::enabled`]);
    /// a missing feature, a queue family without graphics or a device older than Vulkan 1.3 is
    /// refused naming it.
    ///
    /// # Safety
    /// Every handle in `host` must be valid and come from the same instance, `host.queue` must
    /// belong to `host.queue_family` of `host.device`, and `get_instance_proc_addr` must be the
    /// loader's (or the driver's) `vkGetInstanceProcAddr`.
    pub unsafe fn from_host(host: &HostDevice) -> Result<Gpu, GpuError> {
        let static_fn = ash::StaticFn {
            get_instance_proc_addr: host.get_instance_proc_addr,
        };
        // SAFETY: the caller gives the loader's vkGetInstanceProcAddr and live handles.
        let (entry, instance) = unsafe {
            let entry = ash::Entry::from_static_fn(static_fn);
            let instance = ash::Instance::load(entry.static_fn(), host.instance);
            (entry, instance)
        };
        // SAFETY: the physical device comes from this instance (the caller's promise).
        let (properties, families, features) = unsafe {
            (
                instance.get_physical_device_properties(host.physical_device),
                instance.get_physical_device_queue_family_properties(host.physical_device),
                instance.get_physical_device_features(host.physical_device),
            )
        };
        let mut missing = host.enabled.missing();
        if features.image_cube_array != vk::TRUE {
            missing.push("imageCubeArray (the device does not support it)");
        }
        if properties.api_version < vk::API_VERSION_1_3 {
            return Err(GpuError::NoSuitableDevice(
                "the host's device is older than Vulkan 1.3; lensmap needs 1.3 (dynamic rendering, synchronization2)".into(),
            ));
        }
        let graphics = families
            .get(host.queue_family as usize)
            .is_some_and(|f| f.queue_flags.contains(vk::QueueFlags::GRAPHICS));
        if !graphics {
            return Err(GpuError::NoSuitableDevice(format!(
                "the host's queue family {} has no graphics queue (the device has {} families); give a family with VK_QUEUE_GRAPHICS_BIT",
                host.queue_family,
                families.len()
            )));
        }
        if !missing.is_empty() {
            return Err(GpuError::NoSuitableDevice(format!(
                "the host's device lacks {}: enable it when creating the VkDevice (VkPhysicalDeviceFeatures / Vulkan12Features / Vulkan13Features) and say so in the enabled features",
                missing.join(", ")
            )));
        }
        // SAFETY: the device comes from this instance (the caller's promise).
        let device = unsafe { ash::Device::load(instance.fp_v1_0(), host.device) };
        let parts = Parts {
            entry,
            instance,
            physical_device: host.physical_device,
            device,
            queue_family: host.queue_family,
            queue: host.queue,
            properties,
            debug_instance: None,
            messenger: vk::DebugUtilsMessengerEXT::null(),
            messages: Box::default(),
            // A host's device: Vulkan cannot tell whether it enabled them.
            ray_queries: false,
            float64: false,
        };
        Gpu::assemble(parts, false).map_err(|(error, _)| error)
    }

    /// The allocator, command pool and name over a created (or lent) device; on failure the
    /// parts come back for the caller to destroy what it owns.
    fn assemble(parts: Parts, owned: bool) -> Result<Gpu, (GpuError, Box<Parts>)> {
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: parts.instance.clone(),
            device: parts.device.clone(),
            physical_device: parts.physical_device,
            debug_settings: Default::default(),
            // Acceleration structures are built from buffers' device addresses.
            buffer_device_address: parts.ray_queries,
            allocation_sizes: Default::default(),
        });
        let allocator = match allocator {
            Ok(allocator) => allocator,
            Err(source) => {
                let error = GpuError::Allocation {
                    what: "the allocator".into(),
                    source,
                };
                return Err((error, Box::new(parts)));
            }
        };
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(parts.queue_family)
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        // SAFETY: valid device and queue family; the pool is destroyed in Gpu::drop.
        let command_pool = match unsafe { parts.device.create_command_pool(&pool_info, None) } {
            Ok(pool) => pool,
            Err(result) => {
                drop(allocator);
                let error = GpuError::Vulkan {
                    call: "vkCreateCommandPool",
                    result,
                };
                return Err((error, Box::new(parts)));
            }
        };
        // SAFETY: the physical device comes from this instance.
        let memory = unsafe {
            parts
                .instance
                .get_physical_device_memory_properties(parts.physical_device)
        };
        let device_local_heap_bytes = memory
            .memory_heaps_as_slice()
            .iter()
            .filter(|heap| heap.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
            .map(|heap| heap.size)
            .max()
            .unwrap_or(0);
        let Parts {
            entry,
            instance,
            physical_device,
            device,
            queue_family,
            queue,
            properties,
            debug_instance,
            messenger,
            messages,
            ray_queries,
            float64,
            ..
        } = parts;
        let debug_device = debug_instance
            .as_ref()
            .map(|_| ash::ext::debug_utils::Device::new(&instance, &device));
        let acceleration =
            ray_queries.then(|| ash::khr::acceleration_structure::Device::new(&instance, &device));
        // From here the Shared owns (or borrows) the device and destroys it in its Drop.
        let shared = Arc::new(Shared {
            entry,
            instance,
            device,
            allocator: ManuallyDrop::new(Mutex::new(allocator)),
            debug_instance,
            debug_device,
            acceleration,
            messenger,
            messages,
            owned,
        });
        let name = properties
            .device_name_as_c_str()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|_| String::from("(unnamed device)"));
        let mut driver_properties = vk::PhysicalDeviceDriverProperties::default();
        let mut properties2 =
            vk::PhysicalDeviceProperties2::default().push_next(&mut driver_properties);
        // SAFETY: the physical device comes from this instance, which is Vulkan 1.3 (the driver
        // properties are core since 1.2); the chain lives until the call returns.
        unsafe {
            shared
                .instance
                .get_physical_device_properties2(physical_device, &mut properties2)
        };
        let text = |chars: Result<&CStr, _>| {
            chars.map_or_else(
                |_| String::new(),
                |c: &CStr| c.to_string_lossy().into_owned(),
            )
        };
        let device = DeviceId {
            device: name,
            driver: text(driver_properties.driver_name_as_c_str()),
            driver_info: text(driver_properties.driver_info_as_c_str()),
        };
        Ok(Gpu {
            shared,
            queue,
            queue_family,
            physical_device,
            command_pool,
            spare_command_buffers: std::sync::Mutex::new(Vec::new()),
            properties,
            device_local_heap_bytes,
            device,
            float64,
        })
    }

    /// Loads Vulkan at run time, creates an instance (with validation if asked) and the chosen
    /// device. Fails with [`GpuError::NoDriver`] when there is no loader or no driver.
    pub fn new(options: &GpuOptions) -> Result<Gpu, GpuError> {
        // SAFETY: loading the system's libvulkan; its initialisation has no preconditions.
        let entry = unsafe { ash::Entry::load() }
            .map_err(|e| GpuError::NoDriver(format!("cannot load libvulkan: {e}")))?;

        let (instance, debug_utils) = create_instance(&entry, options)?;

        let messages: Box<Mutex<Vec<String>>> = Box::default();
        let (debug_instance, messenger) = if debug_utils {
            let debug = ash::ext::debug_utils::Instance::new(&entry, &instance);
            let messenger = if options.validation {
                let info = vk::DebugUtilsMessengerCreateInfoEXT::default()
                    .message_severity(
                        vk::DebugUtilsMessageSeverityFlagsEXT::WARNING
                            | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR,
                    )
                    .message_type(
                        vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                            | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                            | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
                    )
                    .pfn_user_callback(Some(count_message))
                    .user_data(&*messages as *const Mutex<Vec<String>> as *mut c_void);
                // SAFETY: the callback's user data (the boxed Mutex) outlives the messenger: both
                // live in Shared, which destroys the messenger first.
                unsafe { debug.create_debug_utils_messenger(&info, None) }
                    .vk("vkCreateDebugUtilsMessengerEXT")?
            } else {
                vk::DebugUtilsMessengerEXT::null()
            };
            (Some(debug), messenger)
        } else {
            (None, vk::DebugUtilsMessengerEXT::null())
        };
        let destroy_instance = |instance: &ash::Instance| {
            // SAFETY: nothing created from the instance is alive on this error path but the messenger.
            unsafe {
                if let Some(debug) = &debug_instance {
                    debug.destroy_debug_utils_messenger(messenger, None);
                }
                instance.destroy_instance(None);
            }
        };

        let presents = !options.surface_extensions.is_empty();
        let chosen = match choose_device(&instance, &options.device, presents) {
            Ok(chosen) => chosen,
            Err(e) => {
                destroy_instance(&instance);
                return Err(e);
            }
        };
        let (physical_device, queue_family, properties) = chosen;
        let ray_queries = super::acceleration::supported(&instance, physical_device);
        // SAFETY: the physical device comes from this instance.
        let float64 = unsafe { instance.get_physical_device_features(physical_device) }
            .shader_float64
            == vk::TRUE;

        let features = DeviceFeatures {
            presents,
            ray_queries,
            float64,
        };
        let device = match create_device(&instance, physical_device, queue_family, features) {
            Ok(device) => device,
            Err(result) => {
                destroy_instance(&instance);
                return Err(GpuError::Vulkan {
                    call: "vkCreateDevice",
                    result,
                });
            }
        };
        // SAFETY: valid device and queue family.
        let queue = unsafe { device.get_device_queue(queue_family, 0) };
        let parts = Parts {
            entry,
            instance,
            physical_device,
            device,
            queue_family,
            queue,
            properties,
            debug_instance,
            messenger,
            messages,
            ray_queries,
            float64,
        };
        match Gpu::assemble(parts, true) {
            Ok(mut gpu) => {
                if let Some(limit) = options.heap_limit_bytes {
                    gpu.device_local_heap_bytes = gpu.device_local_heap_bytes.min(limit);
                }
                Ok(gpu)
            }
            Err((error, parts)) => {
                // SAFETY: the device has no children (the allocator and pool were not made or
                // are gone); the messenger goes before its instance.
                unsafe {
                    parts.device.destroy_device(None);
                    if let Some(debug) = &parts.debug_instance {
                        debug.destroy_debug_utils_messenger(parts.messenger, None);
                    }
                    parts.instance.destroy_instance(None);
                }
                Err(error)
            }
        }
    }

    /// The Vulkan objects under this GPU, for a front end that presents its frames itself (a
    /// window's surface and swapchain on the same device and queue, the way a host lends its
    /// image to [`crate::runner::FrameRunner::frame_into`]). The caller submits to the queue only
    /// from the thread that renders with this GPU, and destroys what it makes on these
    /// handles before the `Gpu` is dropped.
    pub fn vulkan(&self) -> VulkanHandles<'_> {
        VulkanHandles {
            entry: &self.shared.entry,
            instance: &self.shared.instance,
            physical_device: self.physical_device,
            device: &self.shared.device,
            queue_family: self.queue_family,
            queue: self.queue,
        }
    }

    /// The device's name as the driver reports it (`llvmpipe (LLVM 15.0.6, 256 bits)` on lavapipe).
    pub fn device_name(&self) -> &str {
        &self.device.device
    }

    /// Whether shaders may compute in f64 (the device has `shaderFloat64`, enabled where
    /// offered; a host's device is used without it).
    pub fn shader_float64(&self) -> bool {
        self.float64
    }

    /// Whether the device was made with acceleration structures and ray queries, which the GPU
    /// tracer may walk instead of its own BVH (`crate::gpu::acceleration`).
    pub fn ray_queries(&self) -> bool {
        self.shared.acceleration.is_some()
    }

    /// The device and its driver (name and version): what a report should name, since two
    /// drivers can give one device name.
    pub fn device_id(&self) -> &DeviceId {
        &self.device
    }

    /// The physical device's properties.
    pub fn properties(&self) -> &vk::PhysicalDeviceProperties {
        &self.properties
    }

    /// Valid bits of the timestamps of the queue (0: no timestamps).
    pub fn queue_timestamp_bits(&self) -> u32 {
        let vulkan = self.vulkan();
        // SAFETY: the physical device belongs to the instance.
        let families = unsafe {
            vulkan
                .instance
                .get_physical_device_queue_family_properties(vulkan.physical_device)
        };
        families
            .get(vulkan.queue_family as usize)
            .map_or(0, |family| family.timestamp_valid_bits)
    }

    /// The queue's timestamp period, nanoseconds a tick.
    pub fn timestamp_period(&self) -> f32 {
        self.properties.limits.timestamp_period
    }

    /// Whether the device is a CPU implementation (lavapipe), not a hardware GPU.
    pub fn is_cpu_device(&self) -> bool {
        self.properties.device_type == vk::PhysicalDeviceType::CPU
    }

    /// The texture-filtering precision the device reports (`subTexelPrecisionBits`,
    /// `mipmapPrecisionBits`).
    pub fn filter_precision(&self) -> crate::cubemap::sampling::FilterPrecision {
        let limits = &self.properties.limits;
        crate::cubemap::sampling::FilterPrecision {
            sub_texel_bits: limits.sub_texel_precision_bits,
            mipmap_bits: limits.mipmap_precision_bits,
        }
    }

    /// The size of the device's largest device-local memory heap, bytes (at most
    /// [`GpuOptions::heap_limit_bytes`]).
    pub fn device_local_heap_bytes(&self) -> u64 {
        self.device_local_heap_bytes
    }

    /// The logical device, for `render/`.
    pub fn device(&self) -> &ash::Device {
        &self.shared.device
    }

    /// The device memory held through lensmap's allocator now ([`DeviceMemory`]): its totals,
    /// summed from gpu-allocator's report under the allocator's lock (microseconds; every
    /// allocation is listed, so not for a per-draw loop).
    pub fn device_memory(&self) -> DeviceMemory {
        // A panic while the lock was held leaves the allocator's bookkeeping readable: only
        // totals are read here, nothing is changed.
        let allocator = self
            .shared
            .allocator
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        let report = allocator.generate_report();
        DeviceMemory {
            allocated_bytes: report.total_allocated_bytes,
            reserved_bytes: report.total_capacity_bytes,
            allocations: report.allocations.len() as u64,
            blocks: report.blocks.len() as u64,
        }
    }

    /// The validation messages counted so far.
    pub fn validation_report(&self) -> ValidationReport {
        ValidationReport {
            enabled: self.shared.messenger != vk::DebugUtilsMessengerEXT::null(),
            messages: self
                .shared
                .messages
                .lock()
                .map(|m| m.clone())
                .unwrap_or_default(),
        }
    }

    /// Opens a debug-utils label region on `command_buffer` (no-op without debug utils).
    pub fn begin_label(&self, command_buffer: vk::CommandBuffer, name: &str) {
        if let Some(debug) = &self.shared.debug_device {
            let name = CString::new(name.replace('\0', " ")).unwrap_or_default();
            let label = vk::DebugUtilsLabelEXT::default().label_name(&name);
            // SAFETY: the command buffer is recording; the label lives until return.
            unsafe { debug.cmd_begin_debug_utils_label(command_buffer, &label) };
        }
    }

    /// Closes the label region opened by [`Gpu::begin_label`].
    pub fn end_label(&self, command_buffer: vk::CommandBuffer) {
        if let Some(debug) = &self.shared.debug_device {
            // SAFETY: matches a begin_label on the same recording command buffer.
            unsafe { debug.cmd_end_debug_utils_label(command_buffer) };
        }
    }

    /// Allocates a primary command buffer from the device's pool; free with
    /// [`Gpu::free_command_buffer`].
    pub fn allocate_command_buffer(&self) -> Result<vk::CommandBuffer, GpuError> {
        let info = vk::CommandBufferAllocateInfo::default()
            .command_pool(self.command_pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: the pool belongs to this device.
        let buffers = unsafe { self.shared.device.allocate_command_buffers(&info) }
            .vk("vkAllocateCommandBuffers")?;
        Ok(buffers[0])
    }

    /// Returns a command buffer to the pool. It must not be executing.
    pub fn free_command_buffer(&self, command_buffer: vk::CommandBuffer) {
        // SAFETY: the caller has waited for the buffer's submission.
        unsafe {
            self.shared
                .device
                .free_command_buffers(self.command_pool, &[command_buffer])
        };
    }

    /// Records `record` into a command buffer (a spare one reset, else a new one), submits it
    /// and waits for it to finish.
    pub fn submit_and_wait(
        &self,
        record: impl FnOnce(vk::CommandBuffer) -> Result<(), GpuError>,
    ) -> Result<(), GpuError> {
        let spares = || {
            self.spare_command_buffers
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner)
        };
        let spare = spares().pop();
        let command_buffer = match spare {
            Some(command_buffer) => command_buffer,
            None => self.allocate_command_buffer()?,
        };
        let result = self.record_submit_wait(command_buffer, record);
        match result {
            // Finished: the next submission resets and records it.
            Ok(()) => spares().push(command_buffer),
            // A failed record, submission or wait: freed, as before there were spares.
            Err(_) => self.free_command_buffer(command_buffer),
        }
        result
    }

    /// Records into an existing command buffer (reset first) and submits it with the
    /// semaphores of `sync`; does not wait (see [`Timeline::wait`]).
    pub fn record_submit(
        &self,
        command_buffer: vk::CommandBuffer,
        record: impl FnOnce(vk::CommandBuffer) -> Result<(), GpuError>,
        sync: Semaphores<'_>,
    ) -> Result<(), GpuError> {
        let Semaphores {
            timeline,
            value,
            waits,
            signals,
        } = sync;
        self.record_into(command_buffer, record)?;
        let buffers = [vk::CommandBufferSubmitInfo::default().command_buffer(command_buffer)];
        let waits: Vec<vk::SemaphoreSubmitInfo> = waits
            .iter()
            .map(|&(semaphore, value)| {
                vk::SemaphoreSubmitInfo::default()
                    .semaphore(semaphore)
                    .value(value)
                    .stage_mask(vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT)
            })
            .collect();
        let signals: Vec<vk::SemaphoreSubmitInfo> = std::iter::once((timeline.handle(), value))
            .chain(signals.iter().copied())
            .map(|(semaphore, value)| {
                vk::SemaphoreSubmitInfo::default()
                    .semaphore(semaphore)
                    .value(value)
                    .stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
            })
            .collect();
        let submit = vk::SubmitInfo2::default()
            .command_buffer_infos(&buffers)
            .wait_semaphore_infos(&waits)
            .signal_semaphore_infos(&signals);
        // SAFETY: recorded above; the timeline is a live semaphore of this device and `value`
        // is greater than any value signalled on it before (the caller counts up); the caller's
        // semaphores are live ones of this device (its promise).
        unsafe {
            self.shared
                .device
                .queue_submit2(self.queue, &[submit], vk::Fence::null())
                .vk("vkQueueSubmit2")
        }
    }

    /// Resets `command_buffer`, begins it for one submission, lets `record` fill it and ends it.
    /// The command buffer must not be pending (its last submission completed).
    fn record_into(
        &self,
        command_buffer: vk::CommandBuffer,
        record: impl FnOnce(vk::CommandBuffer) -> Result<(), GpuError>,
    ) -> Result<(), GpuError> {
        let device = &self.shared.device;
        let begin = vk::CommandBufferBeginInfo::default()
            .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
        // SAFETY: the caller waited for the command buffer's previous submission.
        unsafe {
            device
                .reset_command_buffer(command_buffer, vk::CommandBufferResetFlags::empty())
                .vk("vkResetCommandBuffer")?;
            device
                .begin_command_buffer(command_buffer, &begin)
                .vk("vkBeginCommandBuffer")?;
        }
        record(command_buffer)?;
        // SAFETY: begun above, recorded by `record`.
        unsafe { device.end_command_buffer(command_buffer) }.vk("vkEndCommandBuffer")
    }

    /// Records into an existing command buffer (reset first), submits and waits.
    pub fn record_submit_wait(
        &self,
        command_buffer: vk::CommandBuffer,
        record: impl FnOnce(vk::CommandBuffer) -> Result<(), GpuError>,
    ) -> Result<(), GpuError> {
        let device = &self.shared.device;
        self.record_into(command_buffer, record)?;
        // SAFETY: recorded above; the fence is waited on and destroyed before return.
        unsafe {
            let fence = device
                .create_fence(&vk::FenceCreateInfo::default(), None)
                .vk("vkCreateFence")?;
            let buffers = [command_buffer];
            let submit = vk::SubmitInfo::default().command_buffers(&buffers);
            let submitted = device
                .queue_submit(self.queue, &[submit], fence)
                .vk("vkQueueSubmit")
                .and_then(|()| {
                    device
                        .wait_for_fences(&[fence], true, u64::MAX)
                        .vk("vkWaitForFences")
                });
            device.destroy_fence(fence, None);
            submitted
        }
    }
}

impl Drop for Gpu {
    fn drop(&mut self) {
        // SAFETY: all submissions were waited for; the pool's buffers die with it.
        unsafe {
            let _ = self.shared.device.device_wait_idle();
            self.shared
                .device
                .destroy_command_pool(self.command_pool, None);
        }
    }
}
