//! Making the instance and the device: the Vulkan 1.3 instance with the validation layer when
//! asked, the choice among the system's physical devices, and the logical device with the
//! features lensmap needs.

use std::ffi::{CStr, CString};

use ash::vk;

use super::{
    GpuError, VkContext,
    context::{DeviceChoice, GpuOptions, VALIDATION_LAYER},
};

/// The Vulkan 1.3 instance lensmap runs on, with the validation layer (and synchronization
/// validation) when `options` asks; also whether `debug_utils` is on (always when available:
/// it gives pass labels, and the messenger).
pub(super) fn create_instance(
    entry: &ash::Entry,
    options: &GpuOptions,
) -> Result<(ash::Instance, bool), GpuError> {
    let mut layers: Vec<*const i8> = Vec::new();
    let mut extensions: Vec<*const i8> = Vec::new();
    // SAFETY: plain queries on a loaded entry.
    let available_layers = unsafe { entry.enumerate_instance_layer_properties() }
        .vk("vkEnumerateInstanceLayerProperties")?;
    let available_extensions = unsafe { entry.enumerate_instance_extension_properties(None) }
        .vk("vkEnumerateInstanceExtensionProperties")?;
    let has_extension = |name: &CStr| {
        available_extensions
            .iter()
            .any(|e| e.extension_name_as_c_str().is_ok_and(|n| n == name))
    };
    if options.validation {
        let present = available_layers
            .iter()
            .any(|l| l.layer_name_as_c_str().is_ok_and(|n| n == VALIDATION_LAYER));
        if !present {
            return Err(GpuError::ValidationLayerMissing);
        }
        layers.push(VALIDATION_LAYER.as_ptr());
    }
    // debug_utils gives pass labels (always, when available) and the messenger.
    let debug_utils = options.validation || has_extension(ash::ext::debug_utils::NAME);
    if debug_utils {
        extensions.push(ash::ext::debug_utils::NAME.as_ptr());
    }
    for &name in &options.surface_extensions {
        if !has_extension(name) {
            return Err(GpuError::NoDriver(format!(
                "the Vulkan loader offers no {} instance extension: this window system cannot be presented to (render headless instead)",
                name.to_string_lossy()
            )));
        }
        extensions.push(name.as_ptr());
    }

    let app_name = CString::from(c"lensmap");
    let app = vk::ApplicationInfo::default()
        .application_name(&app_name)
        .engine_name(&app_name)
        .api_version(vk::API_VERSION_1_3);
    let enabled_validation = [
        vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION,
        vk::ValidationFeatureEnableEXT::BEST_PRACTICES,
    ];
    let mut validation_features =
        vk::ValidationFeaturesEXT::default().enabled_validation_features(&enabled_validation[..1]);
    let mut create_info = vk::InstanceCreateInfo::default()
        .application_info(&app)
        .enabled_layer_names(&layers)
        .enabled_extension_names(&extensions);
    if options.validation {
        create_info = create_info.push_next(&mut validation_features);
    }
    // SAFETY: create_info and everything it points to live until the call returns.
    match unsafe { entry.create_instance(&create_info, None) } {
        Ok(instance) => Ok((instance, debug_utils)),
        Err(vk::Result::ERROR_INCOMPATIBLE_DRIVER) => Err(GpuError::NoDriver(
            "vkCreateInstance: no driver supports Vulkan 1.3".into(),
        )),
        Err(vk::Result::ERROR_LAYER_NOT_PRESENT) => Err(GpuError::ValidationLayerMissing),
        Err(result) => Err(GpuError::Vulkan {
            call: "vkCreateInstance",
            result,
        }),
    }
}

/// What a device is made with besides what lensmap always needs.
#[derive(Clone, Copy)]
pub(super) struct DeviceFeatures {
    /// `VK_KHR_swapchain`.
    pub(super) presents: bool,
    /// Acceleration structures and ray queries, with buffer device addresses
    /// (`super::acceleration`).
    pub(super) ray_queries: bool,
    /// `shaderFloat64`.
    pub(super) float64: bool,
}

/// A device on `physical_device` with one queue of `queue_family` and the features lensmap
/// needs: cube-map arrays, dynamic rendering, synchronization2 and timeline semaphores; with
/// `VK_KHR_swapchain` when it presents, and ray queries where asked.
pub(super) fn create_device(
    instance: &ash::Instance,
    physical_device: vk::PhysicalDevice,
    queue_family: u32,
    wanted: DeviceFeatures,
) -> ash::prelude::VkResult<ash::Device> {
    let mut extensions = Vec::new();
    if wanted.presents {
        extensions.push(ash::khr::swapchain::NAME.as_ptr());
    }
    if wanted.ray_queries {
        extensions.extend(super::acceleration::EXTENSIONS.map(|name| name.as_ptr()));
    }
    let priorities = [1.0f32];
    let queues = [vk::DeviceQueueCreateInfo::default()
        .queue_family_index(queue_family)
        .queue_priorities(&priorities)];
    let features = vk::PhysicalDeviceFeatures::default()
        .image_cube_array(true)
        .shader_float64(wanted.float64);
    let mut features13 = vk::PhysicalDeviceVulkan13Features::default()
        .dynamic_rendering(true)
        .synchronization2(true);
    // Timeline semaphores are required of every Vulkan 1.2 device: frames in flight are
    // tracked by one counter instead of a fence per submission.
    let mut features12 = vk::PhysicalDeviceVulkan12Features::default()
        .timeline_semaphore(true)
        .buffer_device_address(wanted.ray_queries);
    let mut acceleration =
        vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default().acceleration_structure(true);
    let mut ray_query = vk::PhysicalDeviceRayQueryFeaturesKHR::default().ray_query(true);
    let mut device_info = vk::DeviceCreateInfo::default()
        .queue_create_infos(&queues)
        .enabled_extension_names(&extensions)
        .enabled_features(&features)
        .push_next(&mut features13)
        .push_next(&mut features12);
    if wanted.ray_queries {
        device_info = device_info
            .push_next(&mut acceleration)
            .push_next(&mut ray_query);
    }
    // SAFETY: physical_device comes from this instance; the create info lives until return.
    unsafe { instance.create_device(physical_device, &device_info, None) }
}

/// Picks a device with Vulkan 1.3, a graphics queue and cube-map arrays (and `VK_KHR_swapchain`
/// when it must present).
pub(super) fn choose_device(
    instance: &ash::Instance,
    choice: &DeviceChoice,
    presents: bool,
) -> Result<(vk::PhysicalDevice, u32, vk::PhysicalDeviceProperties), GpuError> {
    // SAFETY: plain queries on a live instance.
    let devices =
        unsafe { instance.enumerate_physical_devices() }.vk("vkEnumeratePhysicalDevices")?;
    if devices.is_empty() {
        return Err(GpuError::NoDriver(
            "the Vulkan loader found no physical device".into(),
        ));
    }
    let mut candidates = Vec::new();
    let mut rejected = Vec::new();
    for device in devices {
        // SAFETY: `device` comes from this instance.
        let properties = unsafe { instance.get_physical_device_properties(device) };
        let features = unsafe { instance.get_physical_device_features(device) };
        let families = unsafe { instance.get_physical_device_queue_family_properties(device) };
        let name = properties
            .device_name_as_c_str()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let graphics = families
            .iter()
            .position(|f| f.queue_flags.contains(vk::QueueFlags::GRAPHICS));
        let too_old = properties.api_version < vk::API_VERSION_1_3;
        let swapchain = !presents || {
            // SAFETY: `device` comes from this instance.
            unsafe { instance.enumerate_device_extension_properties(device) }
                .unwrap_or_default()
                .iter()
                .any(|e| e.extension_name_as_c_str() == Ok(ash::khr::swapchain::NAME))
        };
        match graphics {
            Some(family) if !too_old && swapchain && features.image_cube_array == vk::TRUE => {
                candidates.push((device, family as u32, properties, name));
            }
            _ => rejected.push(name),
        }
    }
    let rank = |t: vk::PhysicalDeviceType| match t {
        vk::PhysicalDeviceType::DISCRETE_GPU => 0,
        vk::PhysicalDeviceType::INTEGRATED_GPU => 1,
        vk::PhysicalDeviceType::VIRTUAL_GPU => 2,
        vk::PhysicalDeviceType::CPU => 3,
        _ => 4,
    };
    let picked = match choice {
        DeviceChoice::Best => candidates
            .into_iter()
            .min_by_key(|(_, _, p, _)| rank(p.device_type)),
        DeviceChoice::NameContains(part) => {
            let part = part.to_lowercase();
            let names: Vec<String> = candidates.iter().map(|c| c.3.clone()).collect();
            let found = candidates
                .into_iter()
                .find(|(_, _, _, name)| name.to_lowercase().contains(&part));
            if found.is_none() {
                return Err(GpuError::NoSuitableDevice(format!(
                    "LENSMAP_DEVICE={part:?} matches none of {names:?}"
                )));
            }
            found
        }
    };
    picked.map(|(d, f, p, _)| (d, f, p)).ok_or_else(|| {
        GpuError::NoSuitableDevice(format!(
            "none offers Vulkan 1.3, a graphics queue and cube-map arrays{} (found {rejected:?})",
            if presents {
                " and VK_KHR_swapchain"
            } else {
                ""
            }
        ))
    })
}
