//! The driver's acceleration structures (`VK_KHR_acceleration_structure`), which compute shaders
//! walk with ray queries (`VK_KHR_ray_query`): what the GPU tracer can use instead of its own BVH
//! traversal where the device has them (Mesa 25's lavapipe, most desktop GPUs; not Mesa 22.3's).
//!
//! A device is made with them when it offers both extensions and the features
//! `accelerationStructure`, `rayQuery` and `bufferDeviceAddress` ([`Gpu::ray_queries`]); a host's
//! device ([`Gpu::from_host`]) is used without them.
//!
//! [`BoxScene`] is what the tracer asks: one bottom level per part of axis-aligned boxes, and a
//! top level with one instance per part.

use std::{ffi::CStr, sync::Arc};

use ash::vk;

use super::{Buffer, BufferUsage, Gpu, GpuError, VkContext, context::Shared};

/// The device extensions ray queries need (`VK_KHR_acceleration_structure` requires
/// `VK_KHR_deferred_host_operations`).
pub(super) const EXTENSIONS: [&CStr; 3] = [
    ash::khr::acceleration_structure::NAME,
    ash::khr::ray_query::NAME,
    ash::khr::deferred_host_operations::NAME,
];

/// Whether `physical_device` offers ray queries: the extensions and the features.
pub(super) fn supported(instance: &ash::Instance, physical_device: vk::PhysicalDevice) -> bool {
    // SAFETY: `physical_device` comes from this instance.
    let offered = unsafe { instance.enumerate_device_extension_properties(physical_device) }
        .unwrap_or_default();
    let has = |name: &CStr| {
        offered
            .iter()
            .any(|e| e.extension_name_as_c_str() == Ok(name))
    };
    if !EXTENSIONS.iter().all(|name| has(name)) {
        return false;
    }
    let mut acceleration = vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default();
    let mut ray_query = vk::PhysicalDeviceRayQueryFeaturesKHR::default();
    let mut features12 = vk::PhysicalDeviceVulkan12Features::default();
    let mut features = vk::PhysicalDeviceFeatures2::default()
        .push_next(&mut acceleration)
        .push_next(&mut ray_query)
        .push_next(&mut features12);
    // SAFETY: the chain lives until the call returns; the extensions are offered, so their
    // feature structs are known to the driver.
    unsafe { instance.get_physical_device_features2(physical_device, &mut features) };
    acceleration.acceleration_structure == vk::TRUE
        && ray_query.ray_query == vk::TRUE
        && features12.buffer_device_address == vk::TRUE
}

/// An acceleration structure and the buffer it lives in, destroyed together.
pub struct AccelerationStructure {
    shared: Arc<Shared>,
    /// The Vulkan handle.
    pub handle: vk::AccelerationStructureKHR,
    /// Its address, for an instance that names it.
    address: vk::DeviceAddress,
    _storage: Buffer,
}

impl Drop for AccelerationStructure {
    fn drop(&mut self) {
        if let Some(fns) = &self.shared.acceleration {
            // SAFETY: the owner has waited for every submission using it; its buffer goes after.
            unsafe { fns.destroy_acceleration_structure(self.handle, None) };
        }
    }
}

/// A scene of boxes: per part a bottom level of boxes, and a top level with an instance per part
/// that has any, its custom index the part and its cull mask bit `min(part, 7)`.
pub struct BoxScene {
    /// What shaders bind.
    pub top: AccelerationStructure,
    _bottoms: Vec<AccelerationStructure>,
}

/// The most cull-mask bits: parts from [`MASK_BITS`]` − 1` on share the last bit (the shader
/// tells them apart by the instance's custom index).
const MASK_BITS: u32 = 8;

/// One build: its geometry, and the structure and scratch it builds into.
struct Build<'a> {
    geometry: [vk::AccelerationStructureGeometryKHR<'a>; 1],
    primitives: u32,
    ty: vk::AccelerationStructureTypeKHR,
}

impl BoxScene {
    /// Builds the scene of `parts` (each a list of boxes `[min, max]`; an empty part gets no
    /// instance) on the device, and waits for the build.
    pub fn build(gpu: &Gpu, parts: &[Vec<[f32; 6]>]) -> Result<BoxScene, GpuError> {
        let fns = gpu
            .shared
            .acceleration
            .as_ref()
            .ok_or_else(|| GpuError::BadUpload {
                what: "acceleration structures".into(),
                problem: "the device was made without them".into(),
            })?;
        let mut inputs = Vec::new();
        let mut bottoms = Vec::new();
        let mut builds = Vec::new();
        for (part, boxes) in parts.iter().enumerate().filter(|(_, b)| !b.is_empty()) {
            let data = Buffer::with_data(
                gpu,
                "acceleration boxes",
                bytemuck::cast_slice(boxes),
                BufferUsage::AccelerationInput,
            )?;
            let geometry = vk::AccelerationStructureGeometryKHR::default()
                .geometry_type(vk::GeometryTypeKHR::AABBS)
                .geometry(vk::AccelerationStructureGeometryDataKHR {
                    aabbs: vk::AccelerationStructureGeometryAabbsDataKHR::default()
                        .data(vk::DeviceOrHostAddressConstKHR {
                            device_address: data.device_address(),
                        })
                        .stride(std::mem::size_of::<[f32; 6]>() as u64),
                });
            let build = Build {
                geometry: [geometry],
                primitives: boxes.len() as u32,
                ty: vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
            };
            let (structure, scratch) = create(gpu, fns, &build)?;
            inputs.push(data);
            builds.push((build, scratch, structure.handle, part as u32));
            bottoms.push(structure);
        }
        let instances: Vec<vk::AccelerationStructureInstanceKHR> = builds
            .iter()
            .zip(&bottoms)
            .map(|((_, _, _, part), bottom)| instance(*part, bottom.address))
            .collect();
        // SAFETY: the instance struct is plain data laid out as Vulkan reads it.
        let bytes = unsafe {
            std::slice::from_raw_parts(
                instances.as_ptr().cast::<u8>(),
                std::mem::size_of_val(instances.as_slice()),
            )
        };
        let instance_data = Buffer::with_data(
            gpu,
            "acceleration instances",
            bytes,
            BufferUsage::AccelerationInput,
        )?;
        // Vulkan reads instances from 16-byte aligned addresses and boxes from 8-byte aligned
        // ones; allocations are aligned at least so on the drivers measured, but not by rule.
        let misaligned = (instance_data.device_address() % 16 != 0)
            || inputs.iter().any(|boxes| boxes.device_address() % 8 != 0);
        if misaligned {
            return Err(GpuError::BadUpload {
                what: "acceleration-structure inputs".into(),
                problem: "the allocator placed them off the alignment Vulkan reads them at".into(),
            });
        }
        let top = Build {
            geometry: [vk::AccelerationStructureGeometryKHR::default()
                .geometry_type(vk::GeometryTypeKHR::INSTANCES)
                .geometry(vk::AccelerationStructureGeometryDataKHR {
                    instances: vk::AccelerationStructureGeometryInstancesDataKHR::default().data(
                        vk::DeviceOrHostAddressConstKHR {
                            device_address: instance_data.device_address(),
                        },
                    ),
                })],
            primitives: instances.len() as u32,
            ty: vk::AccelerationStructureTypeKHR::TOP_LEVEL,
        };
        let (top_structure, top_scratch) = create(gpu, fns, &top)?;
        gpu.submit_and_wait(|cb| {
            for (build, scratch, handle, _) in &builds {
                record_build(fns, cb, build, *handle, scratch.1);
            }
            // The bottom levels are built before the top level reads them.
            after_builds(
                gpu,
                cb,
                vk::PipelineStageFlags2::ACCELERATION_STRUCTURE_BUILD_KHR,
            );
            record_build(fns, cb, &top, top_structure.handle, top_scratch.1);
            // The top level is built before any later submission's shaders read it (a barrier
            // orders commands across submissions to one queue).
            after_builds(gpu, cb, vk::PipelineStageFlags2::COMPUTE_SHADER);
            Ok(())
        })?;
        // The inputs and scratch were only read by the build, which is done.
        drop((inputs, instance_data, builds, top_scratch));
        Ok(BoxScene {
            top: top_structure,
            _bottoms: bottoms,
        })
    }
}

/// Records a barrier from the builds recorded so far to reads of what they built at `stage`.
fn after_builds(gpu: &Gpu, cb: vk::CommandBuffer, stage: vk::PipelineStageFlags2) {
    let barrier = [vk::MemoryBarrier2::default()
        .src_stage_mask(vk::PipelineStageFlags2::ACCELERATION_STRUCTURE_BUILD_KHR)
        .src_access_mask(vk::AccessFlags2::ACCELERATION_STRUCTURE_WRITE_KHR)
        .dst_stage_mask(stage)
        .dst_access_mask(vk::AccessFlags2::ACCELERATION_STRUCTURE_READ_KHR)];
    // SAFETY: `cb` is recording (the caller's submit_and_wait began it).
    unsafe {
        gpu.device()
            .cmd_pipeline_barrier2(cb, &vk::DependencyInfo::default().memory_barriers(&barrier))
    };
}

/// The instance of part `part`'s bottom level at `address`: identity transform, custom index
/// `part`, cull mask bit `min(part, MASK_BITS − 1)`.
fn instance(part: u32, address: vk::DeviceAddress) -> vk::AccelerationStructureInstanceKHR {
    let identity = vk::TransformMatrixKHR {
        matrix: [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0],
    };
    vk::AccelerationStructureInstanceKHR {
        transform: identity,
        instance_custom_index_and_mask: vk::Packed24_8::new(part, 1u8 << part.min(MASK_BITS - 1)),
        instance_shader_binding_table_record_offset_and_flags: vk::Packed24_8::new(0, 0),
        acceleration_structure_reference: vk::AccelerationStructureReferenceKHR {
            device_handle: address,
        },
    }
}

/// The build info of `build` (its destination and scratch unset).
fn build_info<'a>(build: &'a Build<'a>) -> vk::AccelerationStructureBuildGeometryInfoKHR<'a> {
    vk::AccelerationStructureBuildGeometryInfoKHR::default()
        .ty(build.ty)
        .flags(vk::BuildAccelerationStructureFlagsKHR::PREFER_FAST_TRACE)
        .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
        .geometries(&build.geometry)
}

/// Creates the structure `build` makes and the scratch buffer its build needs (with room to align
/// its address to `minAccelerationStructureScratchOffsetAlignment`).
fn create(
    gpu: &Gpu,
    fns: &ash::khr::acceleration_structure::Device,
    build: &Build<'_>,
) -> Result<(AccelerationStructure, (Buffer, vk::DeviceAddress)), GpuError> {
    let mut sizes = vk::AccelerationStructureBuildSizesInfoKHR::default();
    // SAFETY: the build info and its geometry live until the call returns.
    unsafe {
        fns.get_acceleration_structure_build_sizes(
            vk::AccelerationStructureBuildTypeKHR::DEVICE,
            &build_info(build),
            &[build.primitives],
            &mut sizes,
        )
    };
    let storage = Buffer::new(
        gpu,
        "acceleration structure",
        sizes.acceleration_structure_size,
        BufferUsage::AccelerationStorage,
    )?;
    // SAFETY: the buffer is live, of the acceleration-structure storage usage, and large enough.
    let handle = unsafe {
        fns.create_acceleration_structure(
            &vk::AccelerationStructureCreateInfoKHR::default()
                .buffer(storage.handle)
                .size(sizes.acceleration_structure_size)
                .ty(build.ty),
            None,
        )
    }
    .vk("vkCreateAccelerationStructureKHR")?;
    // SAFETY: a live structure of this device.
    let address = unsafe {
        fns.get_acceleration_structure_device_address(
            &vk::AccelerationStructureDeviceAddressInfoKHR::default()
                .acceleration_structure(handle),
        )
    };
    let structure = AccelerationStructure {
        shared: gpu.shared.clone(),
        handle,
        address,
        _storage: storage,
    };
    let alignment = u64::from(scratch_alignment(gpu)).max(1);
    let scratch = Buffer::new(
        gpu,
        "acceleration scratch",
        sizes.build_scratch_size + alignment,
        BufferUsage::AccelerationScratch,
    )?;
    let aligned = scratch.device_address().next_multiple_of(alignment);
    Ok((structure, (scratch, aligned)))
}

/// `minAccelerationStructureScratchOffsetAlignment` of `gpu`'s device.
fn scratch_alignment(gpu: &Gpu) -> u32 {
    let vulkan = gpu.vulkan();
    let mut acceleration = vk::PhysicalDeviceAccelerationStructurePropertiesKHR::default();
    let mut properties = vk::PhysicalDeviceProperties2::default().push_next(&mut acceleration);
    // SAFETY: the chain lives until the call returns; the device has the extension.
    unsafe {
        vulkan
            .instance
            .get_physical_device_properties2(vulkan.physical_device, &mut properties)
    };
    acceleration.min_acceleration_structure_scratch_offset_alignment
}

/// Records the build of `build` into `destination` with `scratch`.
fn record_build(
    fns: &ash::khr::acceleration_structure::Device,
    cb: vk::CommandBuffer,
    build: &Build<'_>,
    destination: vk::AccelerationStructureKHR,
    scratch: vk::DeviceAddress,
) {
    let info = build_info(build)
        .dst_acceleration_structure(destination)
        .scratch_data(vk::DeviceOrHostAddressKHR {
            device_address: scratch,
        });
    let ranges =
        [vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(build.primitives)];
    // SAFETY: the geometry's buffers, the destination and the scratch live until the submission
    // is waited for ([`BoxScene::build`]).
    unsafe { fns.cmd_build_acceleration_structures(cb, &[info], &[&ranges[..]]) };
}
