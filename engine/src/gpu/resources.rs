//! Buffers and images with their memory. Each holds the device's shared state, so it frees itself
//! (and the device outlives it) whatever order the owner drops things in.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::{
    MemoryLocation,
    vulkan::{Allocation, AllocationCreateDesc, AllocationScheme},
};

use super::{Gpu, GpuError, VkContext, context::Shared};

/// What a buffer is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BufferUsage {
    /// Vertex attributes, written by the CPU.
    Vertex,
    /// Index data (u32), written by the CPU.
    Index,
    /// A storage buffer read by shaders, written by the CPU.
    Storage,
    /// Transfer source for uploads (staging), written by the CPU.
    Staging,
    /// Transfer destination the CPU reads back.
    Readback,
    /// Written and read by the GPU alone (compute passes): a storage, index and indirect-argument
    /// buffer, and a transfer source and destination (cleared with fills, read back by copies).
    /// Device-local where the device has such memory.
    Device,
    /// Input to an acceleration-structure build (boxes, instances), written by the CPU and read
    /// by its device address.
    AccelerationInput,
    /// Where an acceleration structure lives. Device-local where the device has such memory.
    AccelerationStorage,
    /// An acceleration-structure build's scratch memory, by its device address.
    AccelerationScratch,
}

/// A buffer in host-visible memory (uploads and readbacks need no extra copy on lavapipe or
/// unified-memory GPUs; on a discrete GPU the driver reads it over PCIe, fine at lensmap's sizes).
pub struct Buffer {
    shared: Arc<Shared>,
    /// The Vulkan handle.
    pub handle: vk::Buffer,
    allocation: Option<Allocation>,
    /// Size in bytes.
    pub size: u64,
}

impl Buffer {
    /// Creates a buffer of `size` bytes (at least 4).
    pub fn new(gpu: &Gpu, name: &str, size: u64, usage: BufferUsage) -> Result<Buffer, GpuError> {
        let size = size.max(4);
        let acceleration = matches!(
            usage,
            BufferUsage::AccelerationInput
                | BufferUsage::AccelerationStorage
                | BufferUsage::AccelerationScratch
        );
        if acceleration && gpu.shared.acceleration.is_none() {
            return Err(GpuError::BadUpload {
                what: name.into(),
                problem: "the device was made without acceleration structures".into(),
            });
        }
        let (flags, location) = match usage {
            BufferUsage::Vertex => (
                vk::BufferUsageFlags::VERTEX_BUFFER,
                MemoryLocation::CpuToGpu,
            ),
            BufferUsage::Index => (vk::BufferUsageFlags::INDEX_BUFFER, MemoryLocation::CpuToGpu),
            BufferUsage::Storage => (
                vk::BufferUsageFlags::STORAGE_BUFFER,
                MemoryLocation::CpuToGpu,
            ),
            BufferUsage::Staging => (vk::BufferUsageFlags::TRANSFER_SRC, MemoryLocation::CpuToGpu),
            BufferUsage::Readback => (vk::BufferUsageFlags::TRANSFER_DST, MemoryLocation::GpuToCpu),
            BufferUsage::Device => (
                vk::BufferUsageFlags::STORAGE_BUFFER
                    | vk::BufferUsageFlags::INDEX_BUFFER
                    | vk::BufferUsageFlags::INDIRECT_BUFFER
                    | vk::BufferUsageFlags::TRANSFER_SRC
                    | vk::BufferUsageFlags::TRANSFER_DST,
                MemoryLocation::GpuOnly,
            ),
            BufferUsage::AccelerationInput => (
                vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR
                    | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
                MemoryLocation::CpuToGpu,
            ),
            BufferUsage::AccelerationStorage => (
                vk::BufferUsageFlags::ACCELERATION_STRUCTURE_STORAGE_KHR
                    | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
                MemoryLocation::GpuOnly,
            ),
            BufferUsage::AccelerationScratch => (
                vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
                MemoryLocation::GpuOnly,
            ),
        };
        let device = &gpu.shared.device;
        let info = vk::BufferCreateInfo::default()
            .size(size)
            .usage(flags)
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: valid create info; the buffer is destroyed in Drop.
        let handle = unsafe { device.create_buffer(&info, None) }.vk("vkCreateBuffer")?;
        let mut buffer = Buffer {
            shared: gpu.shared.clone(),
            handle,
            allocation: None,
            size,
        };
        // SAFETY: `handle` is a live buffer of this device.
        let requirements = unsafe { device.get_buffer_memory_requirements(handle) };
        let allocation = allocate(&gpu.shared, name, requirements, location, true)?;
        // SAFETY: fresh allocation satisfying the buffer's requirements, bound once.
        unsafe { device.bind_buffer_memory(handle, allocation.memory(), allocation.offset()) }
            .vk("vkBindBufferMemory")?;
        buffer.allocation = Some(allocation);
        Ok(buffer)
    }

    /// A buffer holding `data`.
    pub fn with_data(
        gpu: &Gpu,
        name: &str,
        data: &[u8],
        usage: BufferUsage,
    ) -> Result<Buffer, GpuError> {
        let mut buffer = Buffer::new(gpu, name, data.len() as u64, usage)?;
        buffer.write(0, data, name)?;
        Ok(buffer)
    }

    /// Copies `data` into the mapped buffer at byte `offset`.
    pub fn write(&mut self, offset: u64, data: &[u8], name: &str) -> Result<(), GpuError> {
        let mapped = self
            .allocation
            .as_mut()
            .and_then(|a| a.mapped_slice_mut())
            .ok_or_else(|| GpuError::BadUpload {
                what: name.into(),
                problem: "buffer is not host-visible".into(),
            })?;
        let start = offset as usize;
        let end = start + data.len();
        let target = mapped
            .get_mut(start..end)
            .ok_or_else(|| GpuError::BadUpload {
                what: name.into(),
                problem: format!("{} bytes at {offset} exceed the buffer", data.len()),
            })?;
        target.copy_from_slice(data);
        Ok(())
    }

    /// The buffer's device address (the acceleration-structure usages, on a device with
    /// `bufferDeviceAddress` enabled: [`Gpu::ray_queries`]).
    pub fn device_address(&self) -> vk::DeviceAddress {
        // SAFETY: a live buffer of this device; its usages that need an address include
        // SHADER_DEVICE_ADDRESS, which only a device with ray queries is asked to make.
        unsafe {
            self.shared.device.get_buffer_device_address(
                &vk::BufferDeviceAddressInfo::default().buffer(self.handle),
            )
        }
    }

    /// The mapped contents (host-visible buffers; empty otherwise).
    pub fn read(&self) -> &[u8] {
        self.allocation
            .as_ref()
            .and_then(|a| a.mapped_slice())
            .unwrap_or(&[])
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        // SAFETY: the owner has waited for every submission using this buffer.
        unsafe { self.shared.device.destroy_buffer(self.handle, None) };
        if let Some(allocation) = self.allocation.take()
            && let Ok(mut allocator) = self.shared.allocator.lock()
        {
            let _ = allocator.free(allocation);
        }
    }
}

/// What an image is.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageDesc {
    /// Debug name.
    pub name: String,
    /// Pixel format.
    pub format: vk::Format,
    /// Width and height of level 0.
    pub extent: vk::Extent2D,
    /// Mip levels (1 for attachments).
    pub mip_levels: u32,
    /// Array layers (6 per cube for cube maps).
    pub array_layers: u32,
    /// Usage flags.
    pub usage: vk::ImageUsageFlags,
    /// Cube-compatible: the full view is a cube array of `array_layers / 6` cubes.
    pub cube: bool,
}

impl ImageDesc {
    /// `layers` framebuffer-sized colour attachments in one 2D-array image, sampled by later
    /// passes (the blending schemes' scratch images).
    pub fn scratch_targets(
        name: &str,
        format: vk::Format,
        width: u32,
        height: u32,
        layers: u32,
    ) -> ImageDesc {
        ImageDesc {
            array_layers: layers.max(1),
            usage: vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::SAMPLED,
            ..ImageDesc::colour_target(name, format, width, height)
        }
    }

    /// A colour attachment that can be read back.
    pub fn colour_target(name: &str, format: vk::Format, width: u32, height: u32) -> ImageDesc {
        ImageDesc {
            name: name.into(),
            format,
            extent: vk::Extent2D { width, height },
            mip_levels: 1,
            array_layers: 1,
            // Sampled: the box filter into a host's image reads it.
            usage: vk::ImageUsageFlags::COLOR_ATTACHMENT
                | vk::ImageUsageFlags::TRANSFER_SRC
                | vk::ImageUsageFlags::SAMPLED,
            cube: false,
        }
    }

    /// A depth attachment (D32_SFLOAT).
    pub fn depth_target(name: &str, width: u32, height: u32) -> ImageDesc {
        ImageDesc {
            name: name.into(),
            format: vk::Format::D32_SFLOAT,
            extent: vk::Extent2D { width, height },
            mip_levels: 1,
            array_layers: 1,
            usage: vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT,
            cube: false,
        }
    }

    /// A sampled 2D texture of one level (a light map).
    pub fn texture_2d(name: &str, format: vk::Format, width: u32, height: u32) -> ImageDesc {
        ImageDesc {
            name: name.into(),
            format,
            extent: vk::Extent2D { width, height },
            mip_levels: 1,
            array_layers: 1,
            usage: vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST,
            cube: false,
        }
    }

    /// `cubes` sampled cube maps of `size`² faces with a full mip chain, as one cube array.
    pub fn cube_array(name: &str, format: vk::Format, size: u32, cubes: u32) -> ImageDesc {
        ImageDesc {
            name: name.into(),
            format,
            extent: vk::Extent2D {
                width: size,
                height: size,
            },
            mip_levels: 32 - size.max(1).leading_zeros(),
            array_layers: 6 * cubes.max(1),
            usage: vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST,
            cube: true,
        }
    }

    fn aspect(&self) -> vk::ImageAspectFlags {
        if self.format == vk::Format::D32_SFLOAT {
            vk::ImageAspectFlags::DEPTH
        } else {
            vk::ImageAspectFlags::COLOR
        }
    }
}

/// An image, its memory and its full view.
pub struct Image {
    shared: Arc<Shared>,
    /// What it is.
    pub desc: ImageDesc,
    /// The Vulkan image.
    pub handle: vk::Image,
    /// A view of every level and layer (2D, 2D array for several layers, or cube array for cube
    /// images).
    pub view: vk::ImageView,
    /// For a 2D image of several layers: a 2D view of each layer (to render into one).
    pub layer_views: Vec<vk::ImageView>,
    allocation: Option<Allocation>,
    uploaded: bool,
}

impl Image {
    /// Creates the image in UNDEFINED layout.
    pub fn new(gpu: &Gpu, desc: ImageDesc) -> Result<Image, GpuError> {
        let device = &gpu.shared.device;
        let info = vk::ImageCreateInfo::default()
            .flags(if desc.cube {
                vk::ImageCreateFlags::CUBE_COMPATIBLE
            } else {
                vk::ImageCreateFlags::empty()
            })
            .image_type(vk::ImageType::TYPE_2D)
            .format(desc.format)
            .extent(vk::Extent3D {
                width: desc.extent.width,
                height: desc.extent.height,
                depth: 1,
            })
            .mip_levels(desc.mip_levels)
            .array_layers(desc.array_layers)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(desc.usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        // SAFETY: valid create info; destroyed in Drop.
        let handle = unsafe { device.create_image(&info, None) }.vk("vkCreateImage")?;
        let mut image = Image {
            shared: gpu.shared.clone(),
            desc,
            handle,
            view: vk::ImageView::null(),
            layer_views: Vec::new(),
            allocation: None,
            uploaded: false,
        };
        // SAFETY: live image of this device.
        let requirements = unsafe { device.get_image_memory_requirements(handle) };
        let allocation = allocate(
            &gpu.shared,
            &image.desc.name,
            requirements,
            MemoryLocation::GpuOnly,
            false,
        )?;
        // SAFETY: fresh allocation satisfying the requirements, bound once.
        unsafe { device.bind_image_memory(handle, allocation.memory(), allocation.offset()) }
            .vk("vkBindImageMemory")?;
        image.allocation = Some(allocation);
        let view_info = vk::ImageViewCreateInfo::default()
            .image(handle)
            .view_type(if image.desc.cube {
                vk::ImageViewType::CUBE_ARRAY
            } else if image.desc.array_layers > 1 {
                vk::ImageViewType::TYPE_2D_ARRAY
            } else {
                vk::ImageViewType::TYPE_2D
            })
            .format(image.desc.format)
            .subresource_range(image.full_range());
        // SAFETY: the view covers the image's own subresources.
        image.view =
            unsafe { device.create_image_view(&view_info, None) }.vk("vkCreateImageView")?;
        if !image.desc.cube && image.desc.array_layers > 1 {
            for layer in 0..image.desc.array_layers {
                let range = vk::ImageSubresourceRange {
                    base_array_layer: layer,
                    layer_count: 1,
                    ..image.full_range()
                };
                let info = view_info
                    .view_type(vk::ImageViewType::TYPE_2D)
                    .subresource_range(range);
                // SAFETY: the view covers one of the image's own layers; destroyed in Drop.
                let view =
                    unsafe { device.create_image_view(&info, None) }.vk("vkCreateImageView")?;
                image.layer_views.push(view);
            }
        }
        Ok(image)
    }

    /// Every level and layer.
    pub fn full_range(&self) -> vk::ImageSubresourceRange {
        vk::ImageSubresourceRange {
            aspect_mask: self.desc.aspect(),
            base_mip_level: 0,
            level_count: self.desc.mip_levels,
            base_array_layer: 0,
            layer_count: self.desc.array_layers,
        }
    }

    /// Uploads one mip level of layers `first_layer..first_layer + layer_count` from tightly packed
    /// texels (layer-major, rows top to bottom), then leaves the image SHADER_READ_ONLY_OPTIMAL.
    /// The first upload moves the whole image from UNDEFINED, so upload every level before
    /// sampling; later uploads may replace any level.
    pub fn upload(
        &mut self,
        gpu: &Gpu,
        level: u32,
        first_layer: u32,
        layer_count: u32,
        bytes: &[u8],
    ) -> Result<(), GpuError> {
        let texel = format_bytes(self.desc.format) as u64;
        let width = (self.desc.extent.width >> level).max(1) as u64;
        let height = (self.desc.extent.height >> level).max(1) as u64;
        let expected = width * height * texel * layer_count as u64;
        if level >= self.desc.mip_levels
            || first_layer + layer_count > self.desc.array_layers
            || bytes.len() as u64 != expected
        {
            return Err(GpuError::BadUpload {
                what: self.desc.name.clone(),
                problem: format!(
                    "level {level}, layers {first_layer}+{layer_count}, {} bytes (expected {expected} bytes, {} levels, {} layers)",
                    bytes.len(),
                    self.desc.mip_levels,
                    self.desc.array_layers
                ),
            });
        }
        let region = vk::BufferImageCopy::default()
            .image_subresource(vk::ImageSubresourceLayers {
                aspect_mask: self.desc.aspect(),
                mip_level: level,
                base_array_layer: first_layer,
                layer_count,
            })
            .image_extent(vk::Extent3D {
                width: width as u32,
                height: height as u32,
                depth: 1,
            });
        let range = vk::ImageSubresourceRange {
            aspect_mask: self.desc.aspect(),
            base_mip_level: level,
            level_count: 1,
            base_array_layer: first_layer,
            layer_count,
        };
        self.copy_from_staging(gpu, bytes, &[region], range)
    }

    /// Uploads every mip level of every layer at once — `levels[l]` tightly packed like
    /// [`Image::upload`]'s bytes for level `l` and all layers — through one staging buffer and
    /// one submission instead of one per level, then leaves the image SHADER_READ_ONLY_OPTIMAL.
    pub fn upload_all(&mut self, gpu: &Gpu, levels: &[Vec<u8>]) -> Result<(), GpuError> {
        let texel = format_bytes(self.desc.format) as u64;
        let layers = self.desc.array_layers;
        let mut offsets = Vec::with_capacity(levels.len());
        let mut total = 0u64;
        for (level, bytes) in levels.iter().enumerate() {
            let width = (self.desc.extent.width >> level).max(1) as u64;
            let height = (self.desc.extent.height >> level).max(1) as u64;
            let expected = width * height * texel * u64::from(layers);
            if bytes.len() as u64 != expected {
                return Err(GpuError::BadUpload {
                    what: self.desc.name.clone(),
                    problem: format!(
                        "level {level}: {} bytes (expected {expected} bytes for {layers} layers)",
                        bytes.len()
                    ),
                });
            }
            offsets.push(total);
            total += expected;
        }
        if levels.len() != self.desc.mip_levels as usize {
            return Err(GpuError::BadUpload {
                what: self.desc.name.clone(),
                problem: format!(
                    "{} levels given, the image has {}",
                    levels.len(),
                    self.desc.mip_levels
                ),
            });
        }
        let range = self.full_range();
        let regions: Vec<vk::BufferImageCopy> = offsets
            .iter()
            .enumerate()
            .map(|(level, &offset)| {
                vk::BufferImageCopy::default()
                    .buffer_offset(offset)
                    .image_subresource(vk::ImageSubresourceLayers {
                        aspect_mask: range.aspect_mask,
                        mip_level: level as u32,
                        base_array_layer: 0,
                        layer_count: layers,
                    })
                    .image_extent(vk::Extent3D {
                        width: (self.desc.extent.width >> level).max(1),
                        height: (self.desc.extent.height >> level).max(1),
                        depth: 1,
                    })
            })
            .collect();
        self.copy_from_staging(gpu, &levels.concat(), &regions, range)
    }

    /// Copies `bytes` through a staging buffer into `regions` of the image in one submission,
    /// with layout transitions over `range` around it (over the whole image on the first upload,
    /// which moves it from UNDEFINED), leaving it SHADER_READ_ONLY_OPTIMAL.
    fn copy_from_staging(
        &mut self,
        gpu: &Gpu,
        bytes: &[u8],
        regions: &[vk::BufferImageCopy],
        range: vk::ImageSubresourceRange,
    ) -> Result<(), GpuError> {
        let staging = Buffer::with_data(gpu, "upload staging", bytes, BufferUsage::Staging)?;
        let (before_range, before_layout) = if self.uploaded {
            (range, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL)
        } else {
            (self.full_range(), vk::ImageLayout::UNDEFINED)
        };
        let device = &gpu.shared.device;
        let handle = self.handle;
        gpu.submit_and_wait(|cb| {
            let to_transfer = [vk::ImageMemoryBarrier2::default()
                .src_stage_mask(vk::PipelineStageFlags2::FRAGMENT_SHADER)
                .src_access_mask(vk::AccessFlags2::NONE)
                .dst_stage_mask(vk::PipelineStageFlags2::COPY)
                .dst_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
                .old_layout(before_layout)
                .new_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
                .image(handle)
                .subresource_range(before_range)];
            let to_read = [vk::ImageMemoryBarrier2::default()
                .src_stage_mask(vk::PipelineStageFlags2::COPY)
                .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
                .dst_stage_mask(vk::PipelineStageFlags2::FRAGMENT_SHADER)
                .dst_access_mask(vk::AccessFlags2::SHADER_SAMPLED_READ)
                .old_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
                .new_layout(vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL)
                .image(handle)
                .subresource_range(before_range)];
            // SAFETY: recording into `cb`; staging and image outlive the wait in submit_and_wait.
            unsafe {
                device.cmd_pipeline_barrier2(
                    cb,
                    &vk::DependencyInfo::default().image_memory_barriers(&to_transfer),
                );
                device.cmd_copy_buffer_to_image(
                    cb,
                    staging.handle,
                    handle,
                    vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                    regions,
                );
                device.cmd_pipeline_barrier2(
                    cb,
                    &vk::DependencyInfo::default().image_memory_barriers(&to_read),
                );
            }
            Ok(())
        })?;
        self.uploaded = true;
        Ok(())
    }
}

impl Drop for Image {
    fn drop(&mut self) {
        // SAFETY: the owner has waited for every submission using this image.
        unsafe {
            for view in &self.layer_views {
                self.shared.device.destroy_image_view(*view, None);
            }
            self.shared.device.destroy_image_view(self.view, None);
            self.shared.device.destroy_image(self.handle, None);
        }
        if let Some(allocation) = self.allocation.take()
            && let Ok(mut allocator) = self.shared.allocator.lock()
        {
            let _ = allocator.free(allocation);
        }
    }
}

/// Bytes per texel of the formats lensmap uses.
pub fn format_bytes(format: vk::Format) -> u32 {
    match format {
        vk::Format::R8G8B8A8_UNORM | vk::Format::D32_SFLOAT => 4,
        vk::Format::R16G16B16A16_SFLOAT => 8,
        vk::Format::R32G32B32A32_SFLOAT => 16,
        _ => 16,
    }
}

fn allocate(
    shared: &Shared,
    name: &str,
    requirements: vk::MemoryRequirements,
    location: MemoryLocation,
    linear: bool,
) -> Result<Allocation, GpuError> {
    let mut allocator = shared.allocator.lock().map_err(|_| {
        GpuError::Internal(format!(
            "{name}: allocator lock poisoned by an earlier panic"
        ))
    })?;
    allocator
        .allocate(&AllocationCreateDesc {
            name,
            requirements,
            location,
            linear,
            allocation_scheme: AllocationScheme::GpuAllocatorManaged,
        })
        .map_err(|source| GpuError::Allocation {
            what: name.into(),
            source,
        })
}
